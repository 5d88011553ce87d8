//! What an alignment reports: each scan's pose or why it has none, the registrations tried,
//! the pose graph, the times and the settings.

use super::graph::Edge;
use super::placement::Attempt;
use super::scan::AlignScan;
use crate::cloud::Point;
use crate::transform::Rigid;
use serde::Serialize;

/// The format tag of an [`Alignment`] written as JSON.
pub const ALIGNMENT_FORMAT: &str = "ggs-alignment/1";

/// One scan's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct ScanPose {
    /// The scan's name as given.
    pub name: String,
    /// `p_model = pose · p_scan`, 4×4 row-major; `null` when the scan is not placed.
    #[serde(serialize_with = "serialize_optional_rows")]
    pub pose: Option<Rigid>,
    /// The confidence of the registration that placed the scan (`1 − s₂/s₁`, as a pairwise
    /// registration's; 1 for the anchor, 0 when not placed).
    pub confidence: f64,
    /// Share of the scan's points within the overlap distance of the other placed scans at
    /// the final poses (0 when not placed).
    pub overlap: f64,
    /// Why the scan is not placed, or what makes its pose doubtful.
    pub reason: Option<String>,
}

/// Wall times of the stages, in milliseconds.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct AlignTimes {
    pub prepare_ms: f64,
    pub place_ms: f64,
    pub graph_ms: f64,
    pub joint_ms: f64,
    pub total_ms: f64,
}

/// The result of aligning a set of scans into the frame of its anchor.
#[derive(Debug, Clone, Serialize)]
pub struct Alignment {
    /// [`ALIGNMENT_FORMAT`].
    pub format: &'static str,
    /// Name of the scan whose frame is the common frame.
    pub anchor: String,
    /// Name of the scan the placements started from.
    pub seed: String,
    /// What a user should know about the whole set (the anchor not placed).
    pub warnings: Vec<String>,
    /// In the order given.
    pub scans: Vec<ScanPose>,
    /// Every registration run, in order (scan indices as in `scans`).
    pub attempts: Vec<Attempt>,
    /// The pose graph's edges, accepted and rejected.
    pub edges: Vec<Edge>,
    /// Cell of the merged model ([`Alignment::merged_model`]):
    /// [`THIN_SPACINGS`](super::scan::THIN_SPACINGS) × the
    /// coarsest point spacing of the set, in the clouds' units.
    pub model_cell: f64,
    /// Number of global registrations run.
    pub registrations: usize,
    pub times: AlignTimes,
    /// The settings in force.
    pub settings: serde_json::Value,
}

fn serialize_optional_rows<S: serde::Serializer>(
    t: &Option<Rigid>,
    s: S,
) -> Result<S::Ok, S::Error> {
    match t {
        Some(t) => crate::transform::serialize_rows(t, s),
        None => s.serialize_none(),
    }
}

impl Alignment {
    /// Names of the scans not placed, in the order given.
    pub fn unplaced(&self) -> Vec<&str> {
        self.scans
            .iter()
            .filter(|s| s.pose.is_none())
            .map(|s| s.name.as_str())
            .collect()
    }

    /// The poses as text: per scan a line `# name (confidence c)` and its 4 rows, or
    /// `# name: not placed (reason)`.
    pub fn poses_text(&self) -> String {
        let mut out = format!(
            "# ggs alignment: p_model = pose · p_scan, model frame = {}\n",
            self.anchor
        );
        for s in &self.scans {
            match &s.pose {
                Some(p) => {
                    out.push_str(&format!("# {} (confidence {:.3})\n", s.name, s.confidence));
                    out.push_str(&p.to_text());
                }
                None => out.push_str(&format!(
                    "# {}: not placed ({})\n",
                    s.name,
                    s.reason.as_deref().unwrap_or("no registration placed it")
                )),
            }
        }
        out
    }

    /// The placed scans moved into the common frame, merged and thinned to one point per
    /// cell of `model_cell`.
    pub fn merged_model(&self, scans: &[AlignScan]) -> Vec<Point> {
        let mut points = Vec::new();
        for (scan, out) in scans.iter().zip(&self.scans) {
            if let Some(pose) = &out.pose {
                points.extend(scan.cloud.iter().map(|p| pose.apply(&p)));
            }
        }
        if self.model_cell > 0.0 {
            crate::thin::cell_centroids(&points, self.model_cell)
        } else {
            points
        }
    }
}
