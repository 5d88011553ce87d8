//! Benchmark summaries (docs/benchmarks.md): registration recall, mean errors, the Markdown table in
//! the layout of the papers' tables, and recall-versus-threshold curves as SVG.
//!
//! - RR = successes / pairs, over every pair of the run (a pair that failed to run counts as
//!   a failure);
//! - mean RRE and RTE over the successful pairs (the papers' convention), and, labelled
//!   "all", over every pair that produced an estimate.

use super::row::PairRow;

/// Aggregate figures of a run.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    pub protocol: String,
    pub pairs: usize,
    pub successes: usize,
    /// Pairs that could not be registered at all (unreadable file, ...).
    pub failed_to_run: usize,
    /// Registration recall, in [0, 1].
    pub recall: f64,
    /// Means over the successful pairs (NaN when there is none).
    pub mean_rre_success: f64,
    pub mean_rte_success: f64,
    /// Means over all pairs with an estimate.
    pub mean_rre_all: f64,
    pub mean_rte_all: f64,
    /// Median of the per-pair total time, ms.
    pub median_total_ms: f64,
    /// Unsuccessful pairs whose result says it may be wrong ([`PairRow::flagged`]): wrong
    /// answers that are not silent.
    pub failures_flagged: usize,
    /// Successful pairs flagged all the same: false alarms.
    pub successes_flagged: usize,
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

impl Summary {
    pub fn of(protocol: &str, rows: &[PairRow]) -> Summary {
        let ran: Vec<&PairRow> = rows.iter().filter(|r| r.error.is_none()).collect();
        let ok: Vec<&PairRow> = rows.iter().filter(|r| r.success).collect();
        let mut times: Vec<f64> = rows.iter().map(|r| r.total_ms).collect();
        times.sort_by(f64::total_cmp);
        Summary {
            protocol: protocol.to_string(),
            pairs: rows.len(),
            successes: ok.len(),
            failed_to_run: rows.len() - ran.len(),
            recall: if rows.is_empty() {
                f64::NAN
            } else {
                ok.len() as f64 / rows.len() as f64
            },
            mean_rre_success: mean(ok.iter().map(|r| r.rre)),
            mean_rte_success: mean(ok.iter().map(|r| r.rte)),
            mean_rre_all: mean(ran.iter().map(|r| r.rre)),
            mean_rte_all: mean(ran.iter().map(|r| r.rte)),
            median_total_ms: times.get(times.len() / 2).copied().unwrap_or(f64::NAN),
            failures_flagged: rows.iter().filter(|r| !r.success && r.flagged()).count(),
            successes_flagged: ok.iter().filter(|r| r.flagged()).count(),
        }
    }

    /// The Markdown summary: the paper-style table (RR %, RRE °, RTE in cm when `metres`,
    /// else in the clouds' units), the thresholds, and every unsuccessful pair.
    pub fn markdown(&self, rows: &[PairRow], metres: bool) -> String {
        let (unit, scale) = if metres {
            ("cm", 100.0)
        } else {
            ("units", 1.0)
        };
        let mut s = format!("# ggs bench: {}\n\n", self.protocol);
        s += &format!(
            "| benchmark | pairs | RR % | RRE ° | RTE {unit} | RRE ° (all) | RTE {unit} (all) | median s / pair |\n"
        );
        s += "|---|---|---|---|---|---|---|---|\n";
        s += &format!(
            "| {} | {} | {:.2} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} |\n\n",
            self.protocol,
            self.pairs,
            100.0 * self.recall,
            self.mean_rre_success,
            scale * self.mean_rte_success,
            self.mean_rre_all,
            scale * self.mean_rte_all,
            self.median_total_ms / 1e3,
        );
        let mut thresholds: Vec<(String, String)> = rows
            .iter()
            .filter(|r| r.error.is_none())
            .map(|r| (trim(r.max_rre_deg), trim(r.max_rte)))
            .collect();
        thresholds.sort();
        thresholds.dedup();
        let success = match thresholds.as_slice() {
            [] => "-".to_string(),
            [(r, t)] => format!("RRE < {r}° and RTE < {t}"),
            _ => "per pair (columns max_rre_deg, max_rte of pairs.csv)".to_string(),
        };
        s += &format!(
            "Success: {success}. RR over all {} pairs ({} could not run); RRE/RTE means over \
             the successful pairs, \"all\" over every pair with an estimate.\n",
            self.pairs, self.failed_to_run
        );
        s += &format!(
            "Flagged (ambiguous, a warning, or no result): {} of {} failures; {} of {} \
             successes (false alarms).\n",
            self.failures_flagged,
            self.pairs - self.successes,
            self.successes_flagged,
            self.successes
        );
        let failed: Vec<&PairRow> = rows.iter().filter(|r| !r.success).collect();
        if !failed.is_empty() {
            s += &format!("\n## Unsuccessful pairs ({})\n\n", failed.len());
            s += "| pair | RRE ° | RTE | coarse RRE ° | coarse RTE | chosen rank / verified | confidence | ambiguous | warnings | error |\n|---|---|---|---|---|---|---|---|---|---|\n";
            for r in failed {
                let rank = match (r.chosen_rank, r.verified) {
                    (Some(c), Some(v)) => format!("{} / {v}", c + 1),
                    _ => "n/a".into(),
                };
                s += &format!(
                    "| {} | {:.3} | {:.4} | {:.3} | {:.4} | {rank} | {:.3} | {} | {} | {} |\n",
                    r.id,
                    r.rre,
                    r.rte,
                    r.coarse_rre,
                    r.coarse_rte,
                    r.confidence,
                    if r.ambiguous { "yes" } else { "no" },
                    r.warnings.replace('|', "/"),
                    r.error.as_deref().unwrap_or("").replace('|', "/")
                );
            }
        }
        s
    }
}

/// Fraction of `rows` with `rre < x` and `rte < max_rte` (the pair's own), for the rotation
/// curve, or `rte < x` (`rte < x · max_rte` when `relative`) and `rre < max_rre_deg`, for the
/// translation curve.
fn recall_at(rows: &[PairRow], x: f64, rotation: bool, relative: bool) -> f64 {
    if rows.is_empty() {
        return 0.0;
    }
    let ok = rows
        .iter()
        .filter(|r| {
            r.error.is_none()
                && if rotation {
                    r.rre < x && r.rte < r.max_rte
                } else {
                    r.rte < if relative { x * r.max_rte } else { x } && r.rre < r.max_rre_deg
                }
        })
        .count();
    ok as f64 / rows.len() as f64
}

/// Two panels: recall against the RRE threshold (RTE threshold fixed) and against the RTE
/// threshold (RRE threshold fixed), from 0 to twice the protocol's thresholds.
pub fn recall_curves_svg(title: &str, rows: &[PairRow]) -> String {
    const W: f64 = 360.0;
    const H: f64 = 260.0;
    const M: f64 = 48.0;
    let max_r = rows
        .iter()
        .map(|r| r.max_rre_deg)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let max_t = rows
        .iter()
        .map(|r| r.max_rte)
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" font-size=\"11\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{}\" y=\"16\" text-anchor=\"middle\" font-size=\"13\">{}</text>\n",
        2.0 * W,
        H + 24.0,
        W,
        escape(title)
    );
    // Pairs of different scales (a manifest) share one axis as multiples of their own
    // RTE threshold.
    let relative = rows
        .iter()
        .filter(|r| r.max_rte.is_finite())
        .any(|r| r.max_rte != max_t);
    let (max_t, t_label) = if relative {
        (1.0, "RTE threshold (× each pair's τ_t)")
    } else {
        (max_t, "RTE threshold")
    };
    for (panel, (rotation, limit, label)) in
        [(true, max_r, "RRE threshold (°)"), (false, max_t, t_label)]
            .into_iter()
            .enumerate()
    {
        let frame = Panel {
            x0: panel as f64 * W + M,
            top: 24.0 + 8.0,
            width: W - M - 12.0,
            height: H - M - 12.0,
            x_max: if limit > 0.0 { 2.0 * limit } else { 1.0 },
        };
        svg += &frame.axes(label);
        // The protocol's threshold.
        svg += &format!(
            "<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"#c33\" stroke-dasharray=\"4 3\"/>\n",
            frame.px(limit),
            frame.top,
            frame.top + frame.height
        );
        let points: Vec<String> = (0..=200)
            .map(|k| {
                let x = frame.x_max * k as f64 / 200.0;
                let y = recall_at(rows, x, rotation, relative);
                format!("{:.1},{:.1}", frame.px(x), frame.py(y))
            })
            .collect();
        svg += &format!(
            "<polyline fill=\"none\" stroke=\"#1f5fbf\" stroke-width=\"2\" points=\"{}\"/>\n",
            points.join(" ")
        );
    }
    svg += "</svg>\n";
    svg
}

/// One panel of the recall curves: its frame in SVG units and its x range `[0, x_max]`
/// (recall runs from 0 to 1 upwards).
struct Panel {
    x0: f64,
    top: f64,
    width: f64,
    height: f64,
    x_max: f64,
}

impl Panel {
    fn px(&self, x: f64) -> f64 {
        self.x0 + self.width * x / self.x_max
    }

    fn py(&self, y: f64) -> f64 {
        self.top + self.height * (1.0 - y)
    }

    /// The frame, five ticks on each axis and the x label.
    fn axes(&self, label: &str) -> String {
        let (x0, top, pw, ph) = (self.x0, self.top, self.width, self.height);
        let mut svg = format!(
            "<rect x=\"{x0}\" y=\"{top}\" width=\"{pw}\" height=\"{ph}\" fill=\"none\" stroke=\"#888\"/>\n"
        );
        for k in 0..=4 {
            let y = k as f64 / 4.0;
            let x = self.x_max * k as f64 / 4.0;
            svg += &format!(
                "<text x=\"{}\" y=\"{}\" text-anchor=\"end\">{}%</text>\n\
                 <text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
                x0 - 4.0,
                self.py(y) + 4.0,
                (100.0 * y) as u32,
                self.px(x),
                top + ph + 14.0,
                trim(x)
            );
        }
        svg += &format!(
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
            x0 + pw / 2.0,
            top + ph + 30.0,
            label
        );
        svg
    }
}

/// At most 6 decimals, trailing zeros dropped.
fn trim(x: f64) -> String {
    let s = format!("{x:.6}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(id: &str, rre: f64, rte: f64, success: bool) -> PairRow {
        let mut r = PairRow::new(id, None);
        r.rre = rre;
        r.rte = rte;
        r.success = success;
        r.max_rre_deg = 15.0;
        r.max_rte = 0.3;
        r
    }

    #[test]
    fn failures_and_successes_flagged_are_counted_apart() {
        let mut silent = row("silent", 90.0, 2.0, false);
        silent.confidence = 0.7;
        let mut ambiguous = row("ambiguous", 170.0, 1.0, false);
        ambiguous.ambiguous = true;
        let mut warned = row("warned", 45.0, 1.0, false);
        warned.warnings = "free space: 9.0 % of the points lie …".into();
        let mut unreadable = row("unreadable", f64::NAN, f64::NAN, false);
        unreadable.error = Some("unreadable".into());
        let mut alarm = row("alarm", 1.0, 0.1, true);
        alarm.ambiguous = true;
        let rows = vec![
            silent,
            ambiguous,
            warned,
            unreadable,
            alarm,
            row("clear", 1.0, 0.1, true),
        ];
        let s = Summary::of("scenes", &rows);
        assert_eq!((s.failures_flagged, s.successes_flagged), (3, 1));
        let md = s.markdown(&rows, true);
        assert!(
            md.contains("3 of 4 failures; 1 of 2 successes (false alarms)"),
            "{md}"
        );
        assert!(md.contains("free space: 9.0 %"), "{md}");
    }

    #[test]
    fn recall_and_means() {
        let mut failed = row("c", f64::NAN, f64::NAN, false);
        failed.error = Some("unreadable".into());
        let rows = vec![
            row("a", 1.0, 0.1, true),
            row("b", 3.0, 0.2, true),
            row("d", 90.0, 2.0, false),
            failed,
        ];
        let s = Summary::of("3dmatch", &rows);
        assert_eq!((s.pairs, s.successes, s.failed_to_run), (4, 2, 1));
        assert_eq!(s.recall, 0.5);
        assert_eq!(s.mean_rre_success, 2.0);
        assert!((s.mean_rte_success - 0.15).abs() < 1e-15);
        assert_eq!(s.mean_rre_all, 94.0 / 3.0);
        let md = s.markdown(&rows, true);
        assert!(
            md.contains("| 3dmatch | 4 | 50.00 | 2.000 | 15.000 |"),
            "{md}"
        );
        assert!(
            md.contains("## Unsuccessful pairs (2)") && md.contains("unreadable"),
            "{md}"
        );
        assert_eq!(recall_at(&rows, 2.0, true, false), 0.25);
        assert_eq!(recall_at(&rows, 1e9, false, false), 0.5);
        assert_eq!(recall_at(&rows, 0.5, false, true), 0.25);
        let svg = recall_curves_svg("3dmatch <test>", &rows);
        assert!(svg.starts_with("<svg") && svg.contains("&lt;test&gt;"));
        assert_eq!(svg.matches("<polyline").count(), 2);
    }
}
