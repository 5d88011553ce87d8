//! How each pair of a run is registered and judged ([`RunConfig`]), and the record that
//! pins it in a run directory.

use ggs::error::{GgsError, Result};
use ggs::Settings;
use std::path::Path;

/// A voxel size forced on every pair of a benchmark (`--voxel`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BenchVoxel {
    /// This edge length, in the clouds' units; the RTE threshold is 3 of them.
    Fixed(f64),
    /// The automatic voxel of `ggs register` with no flag ([`VoxelSize::AUTO`](ggs::pipeline::VoxelSize::AUTO)), so that the
    /// benchmark measures what a user who gives no flag gets. The success thresholds stay
    /// the pair's (or the protocol's): 3 × its own voxel for the RTE.
    Auto,
}

impl std::str::FromStr for BenchVoxel {
    type Err = GgsError;
    /// `auto` or a positive number.
    fn from_str(s: &str) -> Result<Self> {
        if s == "auto" {
            return Ok(BenchVoxel::Auto);
        }
        match s.parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(BenchVoxel::Fixed(v)),
            _ => Err(GgsError::param(
                "voxel",
                format!("'{s}' is neither 'auto' nor a positive number"),
            )),
        }
    }
}

impl BenchVoxel {
    /// As it appears in `run.json`: the number, or `"auto"`.
    fn to_json(self) -> serde_json::Value {
        match self {
            BenchVoxel::Fixed(v) => serde_json::json!(v),
            BenchVoxel::Auto => serde_json::json!("auto"),
        }
    }
}

/// How to run each pair.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// Forced voxel size; otherwise the pair's, otherwise the protocol's.
    pub voxel: Option<BenchVoxel>,
    /// The registration's settings; the voxel is set per pair.
    pub settings: Settings,
    /// Worker threads per pair (0: all cores); the results do not depend on it.
    pub threads: usize,
    /// Set to `true` from another thread to stop the pair that runs (its row records the
    /// cancellation).
    pub cancel: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    pub max_rre_deg: f64,
    /// `None`: 3 × the pair's voxel.
    pub max_rte: Option<f64>,
    /// Used when neither `voxel` nor the pair gives one.
    pub default_voxel: Option<f64>,
    /// Move every source by a random rigid motion drawn from this seed and the pair's id
    /// ([`motion::random_motion`](super::motion::random_motion)), composing the ground truth with it.
    pub motion_seed: Option<u64>,
}

impl RunConfig {
    /// Everything that decides a row's result, as JSON (the thread count is left out: results
    /// do not depend on it). Written to `run.json` in the run directory; a resumed run must
    /// match it.
    pub fn fingerprint(&self, protocol: &str) -> serde_json::Value {
        serde_json::json!({
            "ggs": env!("CARGO_PKG_VERSION"),
            "protocol": protocol,
            "voxel": self.voxel.map(BenchVoxel::to_json),
            "default_voxel": self.default_voxel,
            "max_rre_deg": self.max_rre_deg,
            "max_rte": self.max_rte,
            "motion_seed": self.motion_seed,
            "settings": self.settings.to_json(),
        })
    }
}

/// Write `value` as pretty JSON to `path` (atomically) if there is no file, or require the
/// file there to hold exactly that text: `differ` is the error otherwise, and `missing`, when
/// given, the error for an absent file (a resumed run whose record is gone).
pub(crate) fn pin_json(
    path: &Path,
    value: &impl serde::Serialize,
    differ: &str,
    missing: Option<&str>,
) -> Result<()> {
    let text = serde_json::to_string_pretty(value).expect("serializable") + "\n";
    match (std::fs::read_to_string(path), missing) {
        (Ok(earlier), _) if earlier == text => Ok(()),
        (Ok(_), _) => Err(GgsError::in_file(path, differ)),
        (Err(_), Some(why)) => Err(GgsError::in_file(path, why)),
        (Err(_), None) => ggs::io::write_atomic(path, text.as_bytes()),
    }
}
