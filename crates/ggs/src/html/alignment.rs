//! The alignment report (`ggs align --out DIR` writes `DIR/report.html`): the placed scans
//! in one frame, each in its own colour, in three orthogonal views; the pose graph with its
//! accepted and rejected edges; each scan's pose, confidence and overlap, or why it is not
//! placed; every registration tried; the times and the settings.

use super::{escape, num, page, settings_table, SORT_SCRIPT};
use crate::align::{AlignScan, Alignment};
use crate::error::Result;
use crate::render::{self, Layer};
use crate::transform::Point;
use std::fmt::Write;
use std::path::Path;

/// Pixels of one view.
const VIEW_SIZE: (usize, usize) = (380, 300);
/// Points per scan at most in the pictures.
const POINTS_PER_SCAN: usize = 30_000;
/// Side of the pose graph's picture, pixels.
const GRAPH_SIZE: f64 = 420.0;

/// A colour per scan: evenly spaced hues, bright enough on white.
pub fn scan_color(i: usize, n: usize) -> [u8; 3] {
    let h = (i as f64 / n.max(1) as f64) * 6.0;
    let x = 1.0 - ((h % 2.0) - 1.0).abs();
    let (r, g, b) = match h as usize {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    [r, g, b].map(|c| (40.0 + 190.0 * c) as u8)
}

/// The folder of `ggs align --out DIR`: the alignment's files ([`crate::align::write_folder`])
/// and `report.html`, with `command` shown as the line that reproduces it.
pub fn write_folder_and_report(
    dir: &Path,
    scans: &[AlignScan],
    alignment: &Alignment,
    command: Option<String>,
) -> Result<()> {
    let (folder, report) = rayon::join(
        || crate::align::write_folder(dir, scans, alignment),
        || AlignmentReport {
            command,
            ..AlignmentReport::new(scans, alignment)
        },
    );
    folder?;
    report.write(&dir.join("report.html"))
}

/// Everything the report shows: the alignment and display samples of the placed scans,
/// moved into the common frame.
pub struct AlignmentReport<'a> {
    alignment: &'a Alignment,
    moved: Vec<Option<Vec<Point>>>,
    /// The command line that reproduces the result, shown verbatim.
    pub command: Option<String>,
}

impl<'a> AlignmentReport<'a> {
    pub fn new(scans: &[AlignScan], alignment: &'a Alignment) -> Self {
        let moved = scans
            .iter()
            .zip(&alignment.scans)
            .map(|(scan, out)| {
                let pose = out.pose?;
                Some(
                    scan.cloud
                        .strided(POINTS_PER_SCAN)
                        .iter()
                        .map(|p| pose.apply(p))
                        .collect(),
                )
            })
            .collect();
        AlignmentReport {
            alignment,
            moved,
            command: None,
        }
    }

    /// Write the page to `path` atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::io::write_atomic(path, self.html().as_bytes())
    }

    /// The page.
    pub fn html(&self) -> String {
        let a = self.alignment;
        let placed = a.scans.iter().filter(|s| s.pose.is_some()).count();
        let mut body = format!(
            "<h1>ggs alignment</h1><p class=\"sub\">{} scans; the common frame is that of {}</p>",
            a.scans.len(),
            escape(&a.anchor)
        );
        let class = if placed == a.scans.len() {
            "ok"
        } else {
            "warn"
        };
        let _ = write!(
            body,
            "<div class=\"banner {class}\">{placed} of {} scans placed, {} registrations, {} of {} \
             pose-graph edges accepted, {:.2} s</div>",
            a.scans.len(),
            a.registrations,
            a.edges.iter().filter(|e| e.accepted).count(),
            a.edges.len(),
            a.times.total_ms / 1e3
        );
        for w in &a.warnings {
            let _ = write!(body, "<div class=\"banner warn\">{}</div>", escape(w));
        }
        body += &self.views_html();
        body += &graph_html(a);
        body += &scans_html(a);
        body += &attempts_html(a);
        body += &edges_html(a);
        body += &times_html(a);
        if let Some(c) = &self.command {
            let _ = write!(body, "<h2>Command</h2><pre>{}</pre>", escape(c));
        }
        body += &settings_table(&a.settings);
        page("ggs alignment", &body, &[SORT_SCRIPT])
    }

    /// The placed scans, one colour each, in the merged model's three principal views.
    fn views_html(&self) -> String {
        let n = self.moved.len();
        let all: Vec<Point> = self.moved.iter().flatten().flatten().copied().collect();
        let views = render::principal_views(&all);
        let layers: Vec<Layer> = self
            .moved
            .iter()
            .enumerate()
            .filter_map(|(i, m)| {
                m.as_ref().map(|points| Layer {
                    points,
                    color: scan_color(i, n),
                })
            })
            .collect();
        let mut s = String::from("<h2>The scans in one frame</h2><p class=\"legend\">");
        for (i, out) in self.alignment.scans.iter().enumerate() {
            if out.pose.is_some() {
                let [r, g, b] = scan_color(i, n);
                let _ = write!(
                    s,
                    "<i style=\"background:rgb({r},{g},{b})\"></i>{}",
                    escape(&out.name)
                );
            }
        }
        s += "</p><div class=\"views\">";
        for view in &views {
            let img = render::render(&layers, view, VIEW_SIZE.0, VIEW_SIZE.1);
            let _ = write!(
                s,
                "<figure><img alt=\"the placed scans, {name} view\" src=\"{}\"><figcaption>{name} \
                 view (the merged scans' principal axes)</figcaption></figure>",
                img.data_url(),
                name = view.name
            );
        }
        s + "</div>"
    }
}

/// The pose graph: the scans on a circle (unplaced ones hollow and grey), accepted edges as
/// green lines whose width grows with the overlap, rejected edges as dashed red lines.
fn graph_html(a: &Alignment) -> String {
    let n = a.scans.len();
    let c = GRAPH_SIZE / 2.0;
    let r = c - 40.0;
    let at = |i: usize| {
        let t = std::f64::consts::TAU * i as f64 / n as f64 - std::f64::consts::FRAC_PI_2;
        (c + r * t.cos(), c + r * t.sin())
    };
    let mut svg = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{GRAPH_SIZE}\" height=\"{GRAPH_SIZE}\" \
         role=\"img\" aria-label=\"pose graph\">"
    );
    for e in &a.edges {
        let ((x1, y1), (x2, y2)) = (at(e.from), at(e.to));
        let style = if e.accepted {
            format!(
                "stroke=\"#2e8b45\" stroke-width=\"{:.1}\"",
                1.0 + 5.0 * e.overlap
            )
        } else {
            "stroke=\"#c0392b\" stroke-width=\"1.5\" stroke-dasharray=\"5 4\"".to_string()
        };
        let _ = write!(
            svg,
            "<line x1=\"{x1:.1}\" y1=\"{y1:.1}\" x2=\"{x2:.1}\" y2=\"{y2:.1}\" {style}><title>{} – {}: \
             overlap {:.2}{}</title></line>",
            escape(&a.scans[e.from].name),
            escape(&a.scans[e.to].name),
            e.overlap,
            e.reason.as_deref().map(|r| format!(", rejected: {}", escape(r))).unwrap_or_default()
        );
    }
    for (i, s) in a.scans.iter().enumerate() {
        let (x, y) = at(i);
        let [cr, cg, cb] = scan_color(i, n);
        let fill = if s.pose.is_some() {
            format!("rgb({cr},{cg},{cb})")
        } else {
            "#fff".into()
        };
        let stroke = if s.pose.is_some() { "#333" } else { "#999" };
        let _ = write!(
            svg,
            "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"11\" fill=\"{fill}\" stroke=\"{stroke}\"><title>{}</title></circle>\
             <text x=\"{x:.1}\" y=\"{:.1}\" font-size=\"11\" text-anchor=\"middle\">{}</text>",
            escape(&s.name),
            y + 4.0,
            i + 1
        );
    }
    svg += "</svg>";
    format!(
        "<h2>Pose graph</h2><p class=\"sub\">Scans by number (the table below); green: accepted \
         edges (wider: more overlap), dashed red: rejected; a hollow grey scan is not placed.</p>{svg}"
    )
}

fn scans_html(a: &Alignment) -> String {
    let n = a.scans.len();
    let mut s = String::from(
        "<h2>Scans</h2><table class=\"sortable\"><thead><tr><th>#</th><th class=\"l\">scan</th>\
         <th class=\"l\">placed</th><th>confidence</th><th>overlap</th><th class=\"l\">pose (row-major) or reason</th>\
         </tr></thead><tbody>",
    );
    for (i, out) in a.scans.iter().enumerate() {
        let [r, g, b] = scan_color(i, n);
        let (placed, detail, row) = match &out.pose {
            Some(p) => ("yes", pose_rows(p), ""),
            None => (
                "no",
                escape(out.reason.as_deref().unwrap_or("")),
                " class=\"fail\"",
            ),
        };
        let _ = write!(
            s,
            "<tr{row}><td>{}</td><td class=\"l\"><i style=\"display:inline-block;width:10px;height:10px;\
             background:rgb({r},{g},{b})\"></i> {}</td><td class=\"l\">{placed}</td><td>{}</td><td>{}</td>\
             <td class=\"l\"><code>{detail}</code></td></tr>",
            i + 1,
            escape(&out.name),
            num(out.confidence, 3),
            num(out.overlap, 2)
        );
    }
    s + "</tbody></table>"
}

/// A pose's four rows, 6 decimals each, one line each.
fn pose_rows(p: &crate::transform::Rigid) -> String {
    let rows: Vec<String> = p
        .to_rows()
        .iter()
        .map(|r| {
            r.iter()
                .map(|v| format!("{v:.6}"))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect();
    rows.join("<br>")
}

fn attempts_html(a: &Alignment) -> String {
    let mut s = String::from(
        "<h2>Registrations</h2><p class=\"sub\">In the order run: the scan, the placed scans \
         that made the model, a quick try (first look only) or the whole search, and what came \
         of it.</p><div class=\"scroll\"><table class=\"sortable\"><thead><tr><th>#</th>\
         <th class=\"l\">scan</th><th class=\"l\">model</th><th class=\"l\">kind</th><th>confidence</th>\
         <th>overlap</th><th class=\"l\">outcome</th><th>ms</th></tr></thead><tbody>",
    );
    for (k, t) in a.attempts.iter().enumerate() {
        let model: Vec<String> = t.model.iter().map(|m| (m + 1).to_string()).collect();
        let outcome = t.reason.as_deref().map_or("placed".to_string(), escape);
        let _ = write!(
            s,
            "<tr{}><td>{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td><td class=\"l\">{}</td>\
             <td>{}</td><td>{}</td><td class=\"l\">{outcome}</td><td>{:.0}</td></tr>",
            if t.placed { "" } else { " class=\"fail\"" },
            k + 1,
            escape(&a.scans[t.scan].name),
            model.join(", "),
            if t.quick { "quick" } else { "whole" },
            num(t.confidence, 3),
            num(t.overlap, 2),
            t.ms
        );
    }
    s + "</tbody></table></div>"
}

fn edges_html(a: &Alignment) -> String {
    let mut s = String::from(
        "<h2>Edges</h2><table class=\"sortable\"><thead><tr><th class=\"l\">scans</th><th>overlap</th>\
         <th>ICP moved (°)</th><th>ICP moved (distance)</th><th class=\"l\">outcome</th></tr></thead><tbody>",
    );
    for e in &a.edges {
        let _ = write!(
            s,
            "<tr{}><td class=\"l\">{} – {}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"l\">{}</td></tr>",
            if e.accepted { "" } else { " class=\"fail\"" },
            e.from + 1,
            e.to + 1,
            num(e.overlap, 2),
            num(e.moved_deg, 3),
            num(e.moved_distance, 5),
            e.reason.as_deref().map_or("accepted".to_string(), escape)
        );
    }
    s + "</tbody></table>"
}

fn times_html(a: &Alignment) -> String {
    let t = &a.times;
    let mut s = String::from("<h2>Time</h2><table><tbody>");
    for (stage, ms) in [
        ("preparing the scans", t.prepare_ms),
        ("placing (registrations)", t.place_ms),
        ("pose graph", t.graph_ms),
        ("joint refinement", t.joint_ms),
        ("total", t.total_ms),
    ] {
        let _ = write!(
            s,
            "<tr><td class=\"l\">{stage}</td><td>{:.0} ms</td></tr>",
            ms
        );
    }
    s + "</tbody></table>"
}
