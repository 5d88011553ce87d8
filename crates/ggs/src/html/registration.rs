//! The registration report (`ggs register --report out.html`, Python `Result.report_html`):
//! one self-contained page that shows a registration instead of describing it.
//!
//! Sections: the verdict (confident, ambiguous, low evidence), the target and the source
//! before and after in three orthogonal views (the target's principal axes, rendered by
//! [`crate::render`]), an interactive 3-D view (a small inline script drawing on a canvas;
//! drag to turn, wheel to zoom), the hypotheses with their coarse scores and verification,
//! the quality report with each definition one click away, the search's parameters, the time
//! of each stage, and the command line that reproduces it.
//!
//! The pictures show at most [`render::DISPLAY_POINTS`] points per cloud and the 3-D view at
//! most [`VIEWER_POINTS`] (evenly strided), so the page stays near 1 MB for any cloud size.

use super::{definition, escape, legend, num, page};
use crate::cloud::Cloud;
use crate::error::Result;
use crate::pipeline::{Registration, Verification};
use crate::render::{self, Image, Layer, View};
use crate::transform::{rotation_angle_deg, Point, Rigid};
use std::fmt::Write;
use std::path::Path;

/// Points per cloud at most in the interactive 3-D view.
pub const VIEWER_POINTS: usize = 20_000;

/// Pixels of one orthogonal view in the report.
const VIEW_SIZE: (usize, usize) = (380, 300);

/// Everything the report shows: the registration, display samples of both clouds (the
/// source as given, before `T`), their names and the command that made it.
#[derive(Debug, Clone)]
pub struct RegistrationReport {
    pub source_name: String,
    pub target_name: String,
    /// Point counts of the full clouds.
    pub source_points: usize,
    pub target_points: usize,
    source: Vec<Point>,
    target: Vec<Point>,
    pub registration: Registration,
    /// The command line that reproduces the result, shown verbatim.
    pub command: Option<String>,
    /// Reading both clouds, and the whole process, ms (front ends that measure them).
    pub read_ms: Option<f64>,
    pub total_ms: Option<f64>,
}

impl RegistrationReport {
    /// A report of `registration` of `source` onto `target` (both are subsampled for display).
    pub fn new(source: &Cloud, target: &Cloud, registration: Registration) -> Self {
        RegistrationReport {
            source_name: "source".into(),
            target_name: "target".into(),
            source_points: source.len(),
            target_points: target.len(),
            source: source.strided(render::DISPLAY_POINTS),
            target: target.strided(render::DISPLAY_POINTS),
            registration,
            command: None,
            read_ms: None,
            total_ms: None,
        }
    }

    /// Write the page to `path` atomically (a temporary file renamed into place).
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::io::write_atomic(path, self.html().as_bytes())
    }

    /// The page.
    pub fn html(&self) -> String {
        let reg = &self.registration;
        let mut body = format!(
            "<h1>ggs registration</h1><p class=\"sub\">{} ({} points) onto {} ({} points)</p>",
            escape(&self.source_name),
            self.source_points,
            escape(&self.target_name),
            self.target_points
        );
        body += &verdict_html(reg);
        let views = render::principal_views(&self.target);
        body += &self.views_html(&views);
        body += &viewer_html(&self.target, &self.source, &reg.transform, &views[1]);
        body += &hypotheses_html(reg);
        body += &quality_html(reg);
        body += &search_html(reg);
        body += &timings_html(reg, self.read_ms, self.total_ms);
        body += &command_html(self.command.as_deref());
        body += &settings_html(reg);
        let title = format!("ggs: {} onto {}", self.source_name, self.target_name);
        page(&title, &body, &[VIEWER_SCRIPT])
    }

    /// Before and after, three views each, framed on the target's principal axes.
    fn views_html(&self, views: &[View; 3]) -> String {
        let moved: Vec<Point> = self
            .source
            .iter()
            .map(|p| self.registration.transform.apply(p))
            .collect();
        let mut s = String::from("<h2>Before and after</h2>");
        s += &legend();
        for (title, source) in [
            ("Before: the source as given", &self.source),
            ("After: the source moved by T", &moved),
        ] {
            let _ = write!(s, "<h3>{title}</h3><div class=\"views\">");
            for view in views {
                let img = view_image(&self.target, source, view);
                let _ = write!(
                    s,
                    "<figure><img alt=\"{title}, {name} view\" src=\"{}\"><figcaption>{name} view \
                     (target's principal axes)</figcaption></figure>",
                    img.data_url(),
                    name = view.name
                );
            }
            s += "</div>";
        }
        s
    }
}

/// Target and source in one view, at the report's size.
pub fn view_image(target: &[Point], source: &[Point], view: &View) -> Image {
    let layers = [
        Layer {
            points: target,
            color: render::TARGET_COLOR,
        },
        Layer {
            points: source,
            color: render::SOURCE_COLOR,
        },
    ];
    render::render(&layers, view, VIEW_SIZE.0, VIEW_SIZE.1)
}

/// The verdict banner, the warnings and the transform.
fn verdict_html(reg: &Registration) -> String {
    let (class, verdict) = if reg.ambiguous {
        (
            "bad",
            "Ambiguous: two distinct poses explain the data about equally well",
        )
    } else if !reg.warnings.is_empty() {
        ("warn", "Registered, with warnings")
    } else {
        ("ok", "Registered: one pose explains the data clearly best")
    };
    let mut s = format!(
        "<div class=\"banner {class}\">{verdict} (confidence {})</div>",
        num(reg.confidence, 3)
    );
    for w in &reg.warnings {
        let _ = write!(s, "<p class=\"banner warn\">warning: {}</p>", escape(w));
    }
    let _ = write!(
        s,
        "<h2>Transform</h2><p class=\"sub\">p<sub>target</sub> = T · p<sub>source</sub></p><pre>{}</pre>",
        escape(&reg.transform.to_text())
    );
    s
}

/// Angle between the rotations of two transforms, degrees.
fn angle(a: &Rigid, b: &Rigid) -> f64 {
    rotation_angle_deg(&a.rotation, &b.rotation)
}

/// The hypotheses: verified ones with their evidence, else the grid search's list.
fn hypotheses_html(reg: &Registration) -> String {
    let mut s = String::from("<h2>Hypotheses</h2>");
    s += &first_look_html(reg);
    match &reg.verification {
        Some(v) => s += &verified_table(v),
        None => {
            s += "<p class=\"sub\">Not verified (preset without verification): the coarse \
                  search's distinct hypotheses, best first.</p><table><thead><tr><th>rank</th>\
                  <th>rotation #</th><th>score Σ S·K</th><th>match 5·n11 − n01</th>\
                  <th>° from the winner</th></tr></thead><tbody>";
            let best = reg.search.hypotheses.first().map(|h| h.transform);
            for (k, h) in reg.search.hypotheses.iter().enumerate() {
                let off = best.map(|b| angle(&b, &h.transform)).unwrap_or(0.0);
                let _ = write!(
                    s,
                    "<tr{}><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                    if k == 0 { " class=\"chosen\"" } else { "" },
                    k + 1,
                    h.rotation_index,
                    h.score,
                    h.match_score,
                    num(off, 1)
                );
            }
            s += "</tbody></table>";
        }
    }
    s += &definition(
        "match score",
        "5·n11 − n01",
        "n11: occupied source voxels that land on occupied target voxels; n01: occupied source \
         voxels that land on empty target space, both at the best translation of the rotation. \
         An exact integer, computed by FFT cross-correlation for every rotation of the set.",
    );
    s += &definition(
        "verification score",
        "(f_s + f_t) / 2 within D",
        "After a short ICP from the hypothesis on thinned clouds: f_s sums over the source \
         points w(d), d the distance to the nearest target point, divided by their number; f_t \
         the same for the target points against the moved source. w(d) = 1 − d²/D² within D, \
         0 beyond (score `tight`, the default); w = 1 within D (`fitness`); `oriented`: as \
         `tight`, where the two points' normals face the same way. D = max(0.2 voxel, 1.5 × \
         the target's point spacing). A hypothesis whose ICP reaches an earlier verified pose \
         stops and carries that pose's score. The best score is chosen; confidence = 1 − \
         runner-up / chosen, where the runner-up is the best pose more than the distinct \
         radius in rotation (or 3 voxels in where it puts the source's centroid) from the \
         chosen one.",
    );
    s
}

/// What the first look did, as one line (nothing where it did not run).
fn first_look_html(reg: &Registration) -> String {
    let Some(f) = &reg.first_look else {
        return String::new();
    };
    let runner_up = f.runner_up_score.map_or("none".into(), |r| num(r, 3));
    let outcome = if f.accepted {
        "it settled the pair: the hypotheses below are its own, the whole search did not run"
    } else {
        "it did not settle the pair: the hypotheses below are the whole search's"
    };
    format!(
        "<p class=\"sub\">First look: the coarse level's best {} rotations at the voxel size, \
         {} hypotheses verified, best {}, distinct runner-up {} (taken at {} or more with no \
         distinct pose at 0.6 of it); {outcome}.</p>",
        f.rotations,
        f.verified,
        num(f.score, 3),
        runner_up,
        num(f.accept_score, 2)
    )
}

fn verified_table(v: &Verification) -> String {
    let chosen = v.hypotheses[v.chosen].transform;
    let mut s = format!(
        "<p class=\"sub\">{} verified at D = {}; the chosen one is highlighted.</p>\
         <table><thead><tr><th>coarse rank</th><th>rotation #</th><th>match</th>\
         <th>after polish</th><th>score</th><th>f<sub>s</sub></th><th>f<sub>t</sub></th>\
         <th>ICP iterations</th><th>° from chosen</th><th class=\"l\">note</th></tr></thead><tbody>",
        v.hypotheses.len(),
        super::trim_number(v.distance)
    );
    for (k, h) in v.hypotheses.iter().enumerate() {
        let note = if k == v.chosen {
            "chosen"
        } else if Some(k) == v.runner_up {
            "runner-up"
        } else if h.rejected_on_subsample {
            "rejected on a subsample"
        } else if h.rejected_early {
            "rejected early"
        } else if h.same_as.is_some() {
            "stopped on an earlier pose"
        } else {
            ""
        };
        let note = match (h.screened, note) {
            (true, "") => "screened on coarser cells".to_string(),
            (true, n) => format!("{n} (screened on coarser cells)"),
            (false, n) => n.to_string(),
        };
        let _ =
            write!(
            s,
            "<tr{}><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td><td class=\"l\">{note}</td></tr>",
            if k == v.chosen { " class=\"chosen\"" } else { "" },
            h.rank + 1,
            h.rotation_index,
            h.match_score,
            h.polished_match_score,
            num(h.evidence.score, 3),
            num(h.evidence.fitness_source, 3),
            num(h.evidence.fitness_target, 3),
            h.iterations,
            num(angle(&chosen, &h.transform), 1),
        );
    }
    s + "</tbody></table>"
}

/// The final refinement's quality report, each figure with its definition.
fn quality_html(reg: &Registration) -> String {
    let mut s = String::from("<h2>Quality</h2>");
    let Some(r) = &reg.refine else {
        return s + "<p>No refinement ran (the coarse pose is the answer).</p>";
    };
    let q = &r.report;
    let _ = write!(
        s,
        "<p class=\"sub\">{} after {} iteration(s), {} ({}).</p>",
        r.method.name(),
        q.iterations,
        q.convergence(),
        escape(&q.stop_reason)
    );
    let d = super::trim_number(q.correspondence_distance);
    s += &definition("fitness (source)", &num(q.fitness_source, 3), &format!(
        "Share of source points whose nearest target point is within d_c = {d} after T (Open3D's fitness). Not an overlap ratio: d_c is a quantile of the starting distances."));
    s += &definition(
        "fitness (target)",
        &num(q.fitness_target, 3),
        "Share of target points whose nearest moved source point is within d_c.",
    );
    s += &definition("inlier RMSE", &num(q.inlier_rmse, 5), &format!(
        "Root mean square distance, in cloud units, of the {} source points within d_c of the target.", q.inliers));
    s += &definition("correspondence distance d_c", &d,
        "Pairs farther apart than this are not used by the last iteration nor counted in the fitness.");
    s += &definition(
        "degenerate",
        if q.degenerate { "<b>yes</b>" } else { "no" },
        "Whether the smallest eigenvalue of the information matrix H = (1/n)·Σ JᵀJ is below 1e-3 of the largest: \
         a motion the data barely constrains (a plane sliding, a corridor, a sphere turning).",
    );
    let _ = write!(
        s,
        "<p class=\"sub\">Refined on clouds thinned to cells of {} (0: full resolution).</p>",
        super::trim_number(reg.refine_cell)
    );
    s
}

/// Voxel, rotation set, grids and the coarse-to-fine level.
fn search_html(reg: &Registration) -> String {
    let r = &reg.search;
    let g = &r.stats.geometry;
    let mut s = String::from("<h2>Search</h2><table><tbody>");
    let mut row = |k: &str, v: String| {
        let _ = write!(
            s,
            "<tr><th class=\"l\">{k}</th><td class=\"l\">{v}</td></tr>"
        );
    };
    row(
        "voxel",
        format!(
            "{}{}",
            super::trim_number(reg.voxel),
            reg.voxel_rule
                .as_ref()
                .map(|rule| format!(" ({})", escape(rule)))
                .unwrap_or_default()
        ),
    );
    row(
        "rotations",
        format!(
            "{} ({}), {}",
            r.stats.rotations,
            escape(&r.stats.rotation_set),
            match r.stats.mode {
                crate::search::SearchMode::Exhaustive => "exhaustive",
                crate::search::SearchMode::CoarseToFine(_) => "coarse-to-fine",
            }
        ),
    );
    row("rotations scored at the voxel", r.stats.scored.to_string());
    row(
        "grids",
        format!(
            "target {}×{}×{} ({} occupied), FFT {}×{}×{}",
            g.kernel_dims[0],
            g.kernel_dims[1],
            g.kernel_dims[2],
            r.stats.target_occupied,
            g.fft_len[0],
            g.fft_len[1],
            g.fft_len[2]
        ),
    );
    row(
        "source points searched",
        format!("{} of {}", r.stats.searched_points, r.stats.source_points),
    );
    if let Some(c) = &r.stats.coarse_level {
        row(
            "coarse level",
            format!(
                "voxel {}, kept {} rotations (+ neighbours within {:.1}°), winner ranked {} there",
                super::trim_number(c.voxel),
                c.kept,
                c.neighbour_deg,
                c.winner_rank
            ),
        );
    }
    row("threads", r.stats.threads.to_string());
    s + "</tbody></table>"
}

/// Time of each stage, as bars and as numbers.
fn timings_html(reg: &Registration, read_ms: Option<f64>, total_ms: Option<f64>) -> String {
    let t = &reg.timings;
    let st = &reg.search.timings;
    let mut items: Vec<(String, f64)> = Vec::new();
    if let Some(r) = read_ms {
        items.push(("read both clouds".into(), r));
    }
    items.push(("target kernel".into(), st.target_ms));
    items.push(("rotated extents".into(), st.extents_ms));
    if reg.search.stats.coarse_level.is_some() {
        items.push(("coarse level".into(), st.coarse_level_ms));
    }
    items.push(("scoring at the voxel".into(), st.search_ms));
    items.push(("verification".into(), t.verify_ms));
    items.push(("final refinement".into(), t.refine_ms));
    let mut s = String::from("<h2>Time per stage</h2>");
    s += &super::bar_chart_svg(&items, "ms");
    let _ = write!(
        s,
        "<p class=\"sub\">registration {} ms{} on {} thread(s).</p>",
        num(t.total_ms, 1),
        total_ms
            .map(|v| format!(", whole process {} ms", num(v, 1)))
            .unwrap_or_default(),
        reg.search.stats.threads
    );
    s
}

fn command_html(command: Option<&str>) -> String {
    match command {
        Some(c) => format!(
            "<h2>Reproduce</h2><pre>{}</pre><p class=\"sub\">The result does not depend on the \
             thread count.</p>",
            escape(c)
        ),
        None => String::new(),
    }
}

/// Every setting in force, folded: the table `ggs settings` would print for this run.
fn settings_html(reg: &Registration) -> String {
    reg.settings
        .as_ref()
        .map_or_else(String::new, super::settings_table)
}

/// The 3-D view: target, source before and source after `T`, quantized to 16 bits in the
/// `front` view's frame (so it opens as the "front" picture, slightly turned).
fn viewer_html(target: &[Point], source: &[Point], t: &Rigid, front: &View) -> String {
    let target = render::display_sample(target, VIEWER_POINTS);
    let before = render::display_sample(source, VIEWER_POINTS);
    let after: Vec<Point> = before.iter().map(|p| t.apply(p)).collect();
    let axes = [front.right, front.up, front.toward_viewer()];
    let frame = |p: &Point| {
        let v = nalgebra::Vector3::new(p[0], p[1], p[2]);
        axes.map(|a| a.dot(&v))
    };
    let all: Vec<[f64; 3]> = target
        .iter()
        .chain(&before)
        .chain(&after)
        .map(frame)
        .collect();
    let bounds = crate::cloud::bounds(&all);
    let (centre, half) = match bounds {
        Some(b) => {
            let c = [0, 1, 2].map(|k| (b.min[k] + b.max[k]) / 2.0);
            let h = (0..3)
                .map(|k| (b.max[k] - b.min[k]) / 2.0)
                .fold(0.0, f64::max);
            (c, if h > 0.0 { h } else { 1.0 })
        }
        None => ([0.0; 3], 1.0),
    };
    let mut bytes = Vec::with_capacity(all.len() * 6);
    for p in &all {
        for k in 0..3 {
            let q = ((p[k] - centre[k]) / half * 32767.0).round() as i16;
            bytes.extend_from_slice(&q.to_le_bytes());
        }
    }
    use base64::Engine;
    let data = base64::engine::general_purpose::STANDARD.encode(&bytes);
    format!(
        "<h2>3-D view</h2><p class=\"sub\">Drag to turn, wheel to zoom; {} target and {} source \
         points shown.</p><p><button id=\"ggs-toggle\" type=\"button\">show before</button></p>\
         <canvas id=\"ggs-viewer\" width=\"760\" height=\"520\"></canvas>\
         <script>var GGS_VIEW={{nt:{},ns:{},data:\"{data}\"}};</script>",
        target.len(),
        before.len(),
        target.len(),
        before.len()
    )
}

/// Draws `GGS_VIEW` (16-bit coordinates in [-1, 1]: target, source before, source after)
/// into the canvas with a z-buffer; pointer drags turn it, the wheel zooms.
const VIEWER_SCRIPT: &str = r#"
(function () {
  if (typeof GGS_VIEW === 'undefined') return;
  var V = GGS_VIEW, raw = atob(V.data), dv = new DataView(new ArrayBuffer(raw.length));
  for (var i = 0; i < raw.length; i++) dv.setUint8(i, raw.charCodeAt(i));
  var q = new Float32Array(raw.length / 2);
  for (i = 0; i < q.length; i++) q[i] = dv.getInt16(2 * i, true) / 32767;
  var cv = document.getElementById('ggs-viewer'), ctx = cv.getContext('2d');
  var W = cv.width, H = cv.height, img = ctx.createImageData(W, H), zb = new Float32Array(W * H);
  var yaw = 0.5, pitch = 0.3, zoom = 1, after = true, fit = 1e-6;
  for (i = 0; i < 3 * V.nt; i++) fit = Math.max(fit, Math.abs(q[i]));
  function layer(first, count, col, ca, sa, cp, sp, s) {
    var px = img.data;
    for (var i = first; i < first + count; i++) {
      var x = q[3 * i], y = q[3 * i + 1], z = q[3 * i + 2];
      var x1 = ca * x + sa * z, z1 = -sa * x + ca * z;
      var y2 = cp * y - sp * z1, z2 = sp * y + cp * z1;
      var u = Math.floor(W / 2 + x1 * s), v = Math.floor(H / 2 - y2 * s);
      if (u < 0 || v < 0 || u >= W - 1 || v >= H - 1) continue;
      var f = 0.45 + 0.55 * Math.min(1, Math.max(0, (z2 + 1.75) / 3.5));
      for (var dy = 0; dy < 2; dy++) for (var dx = 0; dx < 2; dx++) {
        var k = (v + dy) * W + u + dx;
        if (z2 < zb[k]) continue;
        zb[k] = z2;
        px[4 * k] = col[0] * f; px[4 * k + 1] = col[1] * f; px[4 * k + 2] = col[2] * f;
      }
    }
  }
  function draw() {
    img.data.fill(255); zb.fill(-Infinity);
    var ca = Math.cos(yaw), sa = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
    var s = 0.45 * Math.min(W, H) * zoom / fit;
    layer(0, V.nt, [40, 110, 230], ca, sa, cp, sp, s);
    layer(after ? V.nt + V.ns : V.nt, V.ns, [245, 130, 20], ca, sa, cp, sp, s);
    ctx.putImageData(img, 0, 0);
  }
  var drag = null;
  cv.addEventListener('pointerdown', function (e) { drag = [e.clientX, e.clientY]; cv.setPointerCapture(e.pointerId); });
  cv.addEventListener('pointerup', function () { drag = null; });
  cv.addEventListener('pointermove', function (e) {
    if (!drag) return;
    yaw += (e.clientX - drag[0]) * 0.01; pitch += (e.clientY - drag[1]) * 0.01;
    drag = [e.clientX, e.clientY]; draw();
  });
  cv.addEventListener('wheel', function (e) { e.preventDefault(); zoom *= e.deltaY < 0 ? 1.1 : 1 / 1.1; draw(); }, { passive: false });
  var b = document.getElementById('ggs-toggle');
  b.addEventListener('click', function () { after = !after; b.textContent = after ? 'show before' : 'show after'; draw(); });
  draw();
})();
"#;
