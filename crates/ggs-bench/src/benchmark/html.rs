//! The benchmark report, `report.html` beside `summary.md`: one self-contained page with the
//! summary table, recall curves, RRE / RTE histograms, the time per stage, a sortable table
//! of every pair and a gallery of failed pairs (the estimate and the ground truth side by
//! side, with the right pose's rank), so that a researcher sees why a method fails.
//!
//! While a run is in progress the page is rewritten at most every [`REWRITE_EVERY_S`] seconds
//! and reloads itself every 10 s; the final page has no reload. The gallery shows the first
//! [`GALLERY_MAX`] failed pairs inline (their pictures are in `gallery/`, one PNG per failed
//! pair, written as the pair finishes), so the page stays small for thousands of pairs.

use super::report::{recall_curves_svg, Summary};
use super::row::PairRow;
use base64::Engine;
use ggs::error::Result;
use ggs::html::{bar_chart_svg, escape, legend, log_histogram_svg, num, page, SORT_SCRIPT};
use ggs::render::{self, Image, Layer};
use ggs::transform::{Point, Rigid};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Failed pairs shown inline in the gallery at most.
pub const GALLERY_MAX: usize = 48;
/// Seconds between rewrites of the report while a run is in progress.
pub const REWRITE_EVERY_S: f64 = 2.0;
/// Pixels of one view in a gallery picture.
const THUMB: (usize, usize) = (180, 140);

/// The gallery picture of a pair: target and source in the target's three principal views,
/// the source as given (top row), moved by the estimate (middle) and by the ground truth
/// (bottom).
pub fn failure_picture(
    source: &[Point],
    target: &[Point],
    estimate: &Rigid,
    truth: &Rigid,
) -> Image {
    let source = render::display_sample(source, render::DISPLAY_POINTS / 4);
    let target = render::display_sample(target, render::DISPLAY_POINTS / 4);
    let views = render::principal_views(&target);
    let mut cells = Vec::with_capacity(9);
    for t in [&Rigid::identity(), estimate, truth] {
        let moved: Vec<Point> = source.iter().map(|p| t.apply(p)).collect();
        for view in &views {
            let layers = [
                Layer {
                    points: &target,
                    color: render::TARGET_COLOR,
                },
                Layer {
                    points: &moved,
                    color: render::SOURCE_COLOR,
                },
            ];
            cells.push(render::render(&layers, view, THUMB.0, THUMB.1));
        }
    }
    Image::grid(&cells, 3, 2)
}

/// Where the gallery picture of pair `id` goes: `out/gallery/<id, made file-safe>-<hash>.png`
/// (the hash of the full id keeps `a/b` and `a_b` apart).
pub fn picture_path(out: &Path, id: &str) -> PathBuf {
    let safe: String = id
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    // FNV-1a, 32 bits: stable across versions and platforms.
    let hash = id.bytes().fold(0x811c_9dc5u32, |h, b| {
        (h ^ b as u32).wrapping_mul(0x0100_0193)
    });
    out.join("gallery").join(format!("{safe}-{hash:08x}.png"))
}

/// What the report needs besides the rows.
pub struct ReportContext<'a> {
    pub protocol: &'a str,
    /// Pairs in the run (rows may be fewer while it is in progress).
    pub total_pairs: usize,
    /// Distances in metres (RTE shown in cm).
    pub metres: bool,
    pub out: &'a Path,
}

/// Write `out/report.html` for `rows` (atomically).
pub fn write_report(ctx: &ReportContext, rows: &[PairRow]) -> Result<()> {
    let html = report_html(ctx, rows);
    ggs::io::write_atomic(&ctx.out.join("report.html"), html.as_bytes())
}

/// The page.
pub fn report_html(ctx: &ReportContext, rows: &[PairRow]) -> String {
    let summary = Summary::of(ctx.protocol, rows);
    let in_progress = rows.len() < ctx.total_pairs;
    let mut body = format!("<h1>ggs bench: {}</h1>", escape(ctx.protocol));
    if in_progress {
        let _ = write!(
            body,
            "<meta http-equiv=\"refresh\" content=\"10\"><div class=\"banner warn\">In progress: \
             {} of {} pairs done (this page reloads every 10 s).</div>",
            rows.len(),
            ctx.total_pairs
        );
    }
    body += &summary_html(&summary, ctx.metres);
    body += "<h2>Recall against the thresholds</h2>";
    body += &recall_curves_svg(ctx.protocol, rows);
    body += &histograms_html(rows);
    body += &stage_times_html(rows);
    body += &gallery_html(ctx.out, rows);
    body += &pairs_table_html(rows);
    page(
        &format!("ggs bench: {}", ctx.protocol),
        &body,
        &[SORT_SCRIPT],
    )
}

fn summary_html(s: &Summary, metres: bool) -> String {
    let (unit, scale) = if metres {
        ("cm", 100.0)
    } else {
        ("units", 1.0)
    };
    let class = if s.successes == s.pairs { "ok" } else { "warn" };
    format!(
        "<div class=\"banner {class}\">{} of {} pairs registered ({} %)</div>\
         <table><thead><tr><th class=\"l\">benchmark</th><th>pairs</th><th>RR %</th><th>RRE °</th>\
         <th>RTE {unit}</th><th>RRE ° (all)</th><th>RTE {unit} (all)</th><th>could not run</th>\
         <th>median s / pair</th></tr></thead><tbody><tr><td class=\"l\">{}</td><td>{}</td>\
         <td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\
         </tbody></table><p class=\"sub\">RR: successes over all pairs; RRE / RTE means over the \
         successful pairs, \"all\" over every pair with an estimate.</p>\
         <p class=\"sub\">Flagged (ambiguous, a warning, or no result): {} of {} failures; {} of {} \
         successes (false alarms).</p>",
        s.successes,
        s.pairs,
        num(100.0 * s.recall, 2),
        escape(&s.protocol),
        s.pairs,
        num(100.0 * s.recall, 2),
        num(s.mean_rre_success, 3),
        num(scale * s.mean_rte_success, 3),
        num(s.mean_rre_all, 3),
        num(scale * s.mean_rte_all, 3),
        s.failed_to_run,
        num(s.median_total_ms / 1e3, 2),
        s.failures_flagged,
        s.pairs - s.successes,
        s.successes_flagged,
        s.successes
    )
}

/// RRE and RTE histograms (log bins); RTE over each pair's threshold when thresholds differ.
fn histograms_html(rows: &[PairRow]) -> String {
    let ran: Vec<&PairRow> = rows.iter().filter(|r| r.error.is_none()).collect();
    let rre: Vec<f64> = ran.iter().map(|r| r.rre).collect();
    let max_rre = ran.first().map_or(f64::NAN, |r| r.max_rre_deg);
    let uniform = ran.windows(2).all(|w| w[0].max_rte == w[1].max_rte);
    let (rte, threshold, title): (Vec<f64>, f64, String) = match ran.first() {
        Some(r) if uniform => (
            ran.iter().map(|r| r.rte).collect(),
            r.max_rte,
            "RTE (cloud units)".into(),
        ),
        _ => (
            ran.iter().map(|r| r.rte / r.max_rte).collect(),
            1.0,
            "RTE / the pair's threshold".into(),
        ),
    };
    let t = if threshold.is_finite() && threshold > 0.0 {
        threshold
    } else {
        1.0
    };
    let mut s = String::from("<h2>Error histograms</h2><div>");
    s += &log_histogram_svg("RRE (degrees)", &rre, 0.01, 180.0, max_rre);
    s += &log_histogram_svg(&title, &rte, t / 1e3, t * 1e3, t);
    s + "</div>"
}

/// One stage's time of a row, ms.
type StageTime = fn(&PairRow) -> f64;

/// Means and medians of each stage over the pairs that ran.
fn stage_times_html(rows: &[PairRow]) -> String {
    let ran: Vec<&PairRow> = rows.iter().filter(|r| r.error.is_none()).collect();
    let stat = |f: StageTime| {
        let mut v: Vec<f64> = ran.iter().map(|r| f(r)).collect();
        v.sort_by(f64::total_cmp);
        let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
        (mean, v.get(v.len() / 2).copied().unwrap_or(f64::NAN))
    };
    let stages: [(&str, StageTime); 5] = [
        ("read", |r| r.read_ms),
        ("grid search", |r| r.coarse_ms),
        ("verification", |r| r.verify_ms),
        ("final refinement", |r| r.refine_ms),
        ("total", |r| r.total_ms),
    ];
    let mut items = Vec::new();
    let mut table = String::from(
        "<table><thead><tr><th class=\"l\">stage</th><th>mean ms</th><th>median ms</th></tr></thead><tbody>",
    );
    for (name, f) in stages {
        let (mean, median) = stat(f);
        items.push((format!("{name} (mean)"), mean));
        let _ = write!(
            table,
            "<tr><td class=\"l\">{name}</td><td>{}</td><td>{}</td></tr>",
            num(mean, 1),
            num(median, 1)
        );
    }
    format!(
        "<h2>Time per stage</h2>{}{table}</tbody></table>",
        bar_chart_svg(&items, "ms")
    )
}

/// The failed pairs' pictures, read from `out/gallery/`.
fn gallery_html(out: &Path, rows: &[PairRow]) -> String {
    let failed: Vec<&PairRow> = rows.iter().filter(|r| !r.success).collect();
    let mut s = format!("<h2>Failed pairs ({})</h2>", failed.len());
    if failed.is_empty() {
        return s + "<p>None.</p>";
    }
    s += &legend();
    s += "<p class=\"sub\">Top row: the source as given; middle row: moved by the estimate; \
          bottom row: moved by the ground truth (the target's plan, front and side views). The right pose's rank is the coarse \
          rank of the first hypothesis that meets the thresholds (absent: none did).</p>\
          <div class=\"gallery\">";
    for r in failed.iter().take(GALLERY_MAX) {
        let picture = std::fs::read(picture_path(out, &r.id))
            .map(|png| {
                format!(
                    "<img alt=\"{}\" src=\"data:image/png;base64,{}\">",
                    escape(&r.id),
                    base64::engine::general_purpose::STANDARD.encode(png)
                )
            })
            .unwrap_or_else(|_| "<p class=\"sub\">(no picture)</p>".into());
        let why = match &r.error {
            Some(e) => format!("could not run: {}", escape(e)),
            None => format!(
                "RRE {}°, RTE {}, chosen rank {}, right pose's rank {}, confidence {}{}",
                num(r.rre, 2),
                num(r.rte, 4),
                r.chosen_rank.map_or("–".into(), |k| k.to_string()),
                r.right_rank.map_or("absent".into(), |k| k.to_string()),
                num(r.confidence, 2),
                if r.ambiguous { ", ambiguous" } else { "" }
            ),
        };
        let _ = write!(
            s,
            "<figure>{picture}<figcaption><b>{}</b>: {why}</figcaption></figure>",
            escape(&r.id)
        );
    }
    s += "</div>";
    if failed.len() > GALLERY_MAX {
        let _ = write!(
            s,
            "<p class=\"sub\">{} more failed pairs: their pictures are in gallery/.</p>",
            failed.len() - GALLERY_MAX
        );
    }
    s
}

/// Every pair, sortable by any column (click a heading).
fn pairs_table_html(rows: &[PairRow]) -> String {
    let mut s = String::from(
        "<h2>Every pair</h2><p class=\"sub\">Click a heading to sort.</p><div class=\"scroll\">\
         <table class=\"sortable\"><thead><tr><th class=\"l\">pair</th><th>success</th>\
         <th>RRE °</th><th>RTE</th><th>coarse RRE °</th><th>confidence</th><th>chosen rank</th>\
         <th>right rank</th><th>points (source / target)</th><th>voxel</th><th>total ms</th>\
         <th class=\"l\">error</th></tr></thead><tbody>",
    );
    for r in rows {
        let _ = write!(
            s,
            "<tr{}><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td><td data-v=\"{}\">{} / {}</td><td>{}</td><td>{}</td>\
             <td class=\"l\">{}</td></tr>",
            if r.success { "" } else { " class=\"fail\"" },
            escape(&r.id),
            if r.success { "yes" } else { "no" },
            num(r.rre, 3),
            num(r.rte, 4),
            num(r.coarse_rre, 2),
            num(r.confidence, 3),
            r.chosen_rank.map_or("–".into(), |k| k.to_string()),
            r.right_rank.map_or("–".into(), |k| k.to_string()),
            r.source_points,
            r.source_points,
            r.target_points,
            ggs::html::trim_number(r.voxel),
            num(r.total_ms, 0),
            escape(r.error.as_deref().unwrap_or(""))
        );
    }
    s + "</tbody></table></div>"
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(id: &str, success: bool) -> PairRow {
        let mut r = PairRow::new(id, None);
        r.success = success;
        r.rre = if success { 0.5 } else { 120.0 };
        r.rte = if success { 0.01 } else { 1.0 };
        r.max_rre_deg = 10.0;
        r.max_rte = 0.05;
        r.total_ms = 100.0;
        r
    }

    #[test]
    fn picture_paths_are_file_safe_and_distinct() {
        let out = Path::new("/x");
        let a = picture_path(out, "scene/0_1");
        let b = picture_path(out, "scene_0_1");
        assert_ne!(a, b);
        assert!(a.starts_with("/x/gallery"));
        let name = a.file_name().unwrap().to_str().unwrap();
        assert!(
            name.starts_with("scene_0_1-") && name.ends_with(".png"),
            "{name}"
        );
    }

    #[test]
    fn the_report_lists_every_pair_and_says_when_it_is_in_progress() {
        let dir = std::env::temp_dir().join(format!("ggs-html-{}", std::process::id()));
        let rows = vec![row("a", true), row("b<&>", false), row("c", true)];
        let ctx = ReportContext {
            protocol: "demo",
            total_pairs: 5,
            metres: false,
            out: &dir,
        };
        let html = report_html(&ctx, &rows);
        assert!(html.contains("In progress: 3 of 5") && html.contains("http-equiv=\"refresh\""));
        assert!(html.contains("b&lt;&amp;&gt;") && !html.contains("b<&>"));
        assert_eq!(html.matches("<tr class=\"fail\">").count(), 1);
        assert!(html.contains("Failed pairs (1)") && html.contains("(no picture)"));
        let done = report_html(
            &ReportContext {
                total_pairs: 3,
                ..ctx
            },
            &rows,
        );
        assert!(!done.contains("refresh") && !done.contains("In progress"));
    }

    #[test]
    fn a_report_of_1724_pairs_stays_small() {
        // FPv1's size; one pair in five failed (more than any method here).
        let rows: Vec<PairRow> = (0..1724)
            .map(|k| {
                let mut r = row(&format!("tr_reg_{:03}/view_{k}", k / 20), k % 5 != 0);
                r.rre = 0.05 + (k % 97) as f64 * 1.7;
                r.chosen_rank = Some(k % 3);
                r.right_rank = if k % 5 == 0 { None } else { Some(0) };
                r
            })
            .collect();
        let dir = std::env::temp_dir().join(format!("ggs-html-big-{}", std::process::id()));
        let ctx = ReportContext {
            protocol: "fpv1",
            total_pairs: rows.len(),
            metres: false,
            out: &dir,
        };
        let html = report_html(&ctx, &rows);
        assert_eq!(html.matches("<tr class=\"fail\">").count(), 345);
        assert_eq!(
            html.matches("<figure>").count(),
            GALLERY_MAX,
            "the gallery is capped"
        );
        assert!(html.contains("297 more failed pairs"));
        // Without pictures; each inline picture adds 50–100 kB (docs/reports.md).
        assert!(html.len() < 1_000_000, "{} bytes", html.len());
        // GGS_REPORT_SAMPLE=DIR: the same page with a picture for every failure, to measure
        // its size and load time (docs/reports.md).
        if let Some(sample) = std::env::var_os("GGS_REPORT_SAMPLE") {
            let sample = Path::new(&sample);
            let sphere: Vec<Point> = (0..40_000)
                .map(|k| {
                    let (t, p) = (
                        k as f64 * 2.399963,
                        (1.0 - 2.0 * (k as f64 + 0.5) / 4e4).acos(),
                    );
                    [p.sin() * t.cos(), p.sin() * t.sin() * 0.6, p.cos() * 1.4]
                })
                .collect();
            let half: Vec<Point> = sphere.iter().filter(|p| p[0] > -0.2).copied().collect();
            let turned = Rigid::new(
                *nalgebra::Rotation3::from_euler_angles(0.0, 2.0, 0.5).matrix(),
                nalgebra::Vector3::new(0.3, 0.0, 0.0),
            );
            let png = failure_picture(&half, &sphere, &turned, &Rigid::identity()).png();
            for r in rows.iter().filter(|r| !r.success) {
                let path = picture_path(sample, &r.id);
                std::fs::create_dir_all(path.parent().unwrap()).unwrap();
                std::fs::write(path, &png).unwrap();
            }
            let ctx = ReportContext { out: sample, ..ctx };
            write_report(&ctx, &rows).unwrap();
        }
    }
}
