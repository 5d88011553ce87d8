//! What a grid search is asked to do: voxel, threads, hypotheses, mode, precision.

use crate::cloud::Cloud;
use crate::error::{GgsError, Result};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Callback told how many rotations have been scored so far.
pub type ProgressFn = Arc<dyn Fn(usize) + Send + Sync>;

/// Parameters of a grid search.
#[derive(Clone)]
pub struct SearchConfig {
    /// Voxel edge length `s`, in the clouds' units.
    pub voxel: f64,
    /// Worker threads; 0 means one per available core.
    pub threads: usize,
    /// Number of distinct hypotheses to return (≥ 1).
    pub top_k: usize,
    /// Distinct hypotheses after the runner-up are returned only while their match score is
    /// at least this fraction of a positive winner's (none after the runner-up when the
    /// winner's is not positive); `None`: all `top_k`. A caller that uses no hypothesis below
    /// that (the verification's `margin`) saves the exact re-scoring of the rotations that
    /// could only rank there.
    pub min_match_fraction: Option<f64>,
    /// Rotations closer than this (degrees, geodesic) to a better one are not distinct: they
    /// are skipped for `top_k` and for the ambiguity. Default: 2 × the set's step.
    pub distinct_radius_deg: Option<f64>,
    /// Memory budget in bytes; default half of physical memory.
    pub max_memory: Option<u64>,
    /// Called after each scored rotation with the number scored so far.
    pub progress: Option<ProgressFn>,
    /// Set to `true` from another thread to stop the search ([`GgsError::Cancelled`]).
    pub cancel: Option<Arc<AtomicBool>>,
    /// Exhaustive (every rotation at full resolution) or coarse-to-fine.
    pub mode: SearchMode,
    /// Arithmetic of the correlations.
    pub precision: Precision,
}

/// How rotations are searched.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum SearchMode {
    /// Score every rotation at the voxel size (the GGS search).
    Exhaustive,
    /// Score every rotation at a coarser voxel, then only the best and their neighbours at
    /// the voxel size (exactly as the exhaustive search scores them).
    CoarseToFine(CoarseToFine),
}

/// Parameters of the coarse-to-fine search.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CoarseToFine {
    /// Coarse voxel = `factor` × voxel.
    pub factor: f64,
    /// Fraction of the rotations kept from the coarse level (the best by coarse score).
    pub keep_fraction: f64,
    /// Keep at least this many rotations.
    pub keep_min: usize,
    /// Also re-score every rotation within this angle (degrees) of a kept one; default: the
    /// set's step × 1.01 (its nearest grid neighbours).
    pub neighbour_deg: Option<f64>,
    /// Report this many distinct hypotheses of the coarse level itself (best first by coarse
    /// score, rotations more than the distinct radius apart), each with its own offset at the
    /// coarse voxel: [`CoarseLevel::hypotheses`](super::CoarseLevel::hypotheses). A coarser
    /// voxel tolerates the grid's rotation error where the overlap is small, so these rank
    /// the right pose higher on low-overlap pairs (docs/pipeline.md, "Coarse-level
    /// hypotheses"). 0: none.
    pub hypotheses: usize,
    /// Stop doubling the kept list as soon as a doubling leaves the winner where it was.
    /// False (the registration's rule): double while the winner ranks in the lower half of
    /// the kept list, which finds the exhaustive search's winner but can score every
    /// rotation when the coarse ranking is flat (a scan that fits nowhere). The alignment's
    /// whole searches stop early: a scan they do not place is tried again on a larger model.
    pub stop_when_winner_holds: bool,
}

impl SearchMode {
    /// `exhaustive`, or `coarse-to-fine` (also `c2f`) with the parameters `c2f`.
    pub fn from_name(name: &str, c2f: CoarseToFine) -> Result<Self> {
        match name {
            "exhaustive" => Ok(SearchMode::Exhaustive),
            "coarse-to-fine" | "c2f" => Ok(SearchMode::CoarseToFine(c2f)),
            other => Err(GgsError::param(
                "search",
                format!("unknown mode '{other}' (exhaustive or coarse-to-fine)"),
            )),
        }
    }
}

impl std::str::FromStr for Precision {
    type Err = GgsError;
    /// `mixed` or `f64`.
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "mixed" => Ok(Precision::Mixed),
            "f64" => Ok(Precision::F64),
            other => Err(GgsError::param(
                "precision",
                format!("unknown '{other}' (mixed or f64)"),
            )),
        }
    }
}

impl Default for CoarseToFine {
    /// Coarse voxel 2 × voxel, 2 % kept: the exhaustive search's pick on every benchmark pair
    /// measured (docs/performance.md).
    fn default() -> Self {
        CoarseToFine {
            factor: 2.0,
            keep_fraction: 0.02,
            keep_min: 16,
            neighbour_deg: None,
            hypotheses: 0,
            stop_when_winner_holds: false,
        }
    }
}

/// Coarse-level hypotheses the default preset reports (and verifies).
pub const COARSE_LEVEL_HYPOTHESES: usize = 8;

impl CoarseToFine {
    /// The default preset's: coarse voxel 4 × voxel, 1 % kept. Its candidates are checked by
    /// the verification's ICP and score, so it need not pick the exhaustive winner; measured:
    /// the same recall as [`CoarseToFine::default`] on every benchmark of the project, with a
    /// coarse level 4× and a fine level 2× cheaper (docs/performance.md).
    pub fn for_verification() -> Self {
        CoarseToFine {
            factor: 4.0,
            keep_fraction: 0.01,
            hypotheses: COARSE_LEVEL_HYPOTHESES,
            ..CoarseToFine::default()
        }
    }
}

/// Arithmetic of the correlations; both give the same picks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// f32 transforms with a proven error bound for every rotation, then an exact
    /// re-scoring of every rotation whose bound reaches the best exact score (the default;
    /// 2–3× faster).
    Mixed,
    /// f64 for every rotation: every score is an exact integer.
    F64,
}

impl std::fmt::Debug for SearchConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SearchConfig")
            .field("voxel", &self.voxel)
            .field("threads", &self.threads)
            .field("top_k", &self.top_k)
            .field("min_match_fraction", &self.min_match_fraction)
            .field("distinct_radius_deg", &self.distinct_radius_deg)
            .field("max_memory", &self.max_memory)
            .field("mode", &self.mode)
            .field("precision", &self.precision)
            .finish_non_exhaustive()
    }
}

impl SearchConfig {
    /// Defaults with the given voxel size.
    pub fn with_voxel(voxel: f64) -> Self {
        SearchConfig {
            voxel,
            threads: 0,
            top_k: 1,
            min_match_fraction: None,
            distinct_radius_deg: None,
            max_memory: None,
            progress: None,
            cancel: None,
            mode: SearchMode::Exhaustive,
            precision: Precision::Mixed,
        }
    }
}

/// Voxel size for which the target grid spans about `cells` voxels along its longest side,
/// rounded to 2 significant digits (so it reads well in reports).
pub fn auto_voxel(target: &Cloud, cells: usize) -> Option<f64> {
    let e = target.aabb()?.extent();
    let longest = e[0].max(e[1]).max(e[2]);
    if longest <= 0.0 || !longest.is_finite() {
        return None;
    }
    Some(round_2_digits(longest / cells.max(1) as f64))
}

/// `x` rounded to 2 significant digits (positive, finite `x`).
pub fn round_2_digits(x: f64) -> f64 {
    let e = x.log10().floor() as i32 - 1;
    // Divide by a power of ten above 1 (exact) rather than multiply by one below (inexact):
    // 93 / 1e4 prints as 0.0093, 93 × 1e-4 as 0.009300000000000001.
    if e < 0 {
        let m = 10f64.powi(-e);
        (x * m).round() / m
    } else {
        let m = 10f64.powi(e);
        (x / m).round() * m
    }
}

impl CoarseToFine {
    /// Refuses a factor below 1, a fraction outside [0, 1] and a negative neighbour angle.
    pub(crate) fn validate(&self) -> Result<()> {
        if !(self.factor.is_finite() && self.factor >= 1.0) {
            return Err(GgsError::param(
                "coarse_factor",
                format!("must be a number ≥ 1, got {}", self.factor),
            ));
        }
        if !(self.keep_fraction.is_finite() && (0.0..=1.0).contains(&self.keep_fraction)) {
            return Err(GgsError::param(
                "coarse_keep",
                format!("must be in [0, 1], got {}", self.keep_fraction),
            ));
        }
        if let Some(d) = self.neighbour_deg {
            if !(d.is_finite() && d >= 0.0) {
                return Err(GgsError::param(
                    "coarse_neighbour",
                    format!("must be a non-negative number of degrees, got {d}"),
                ));
            }
        }
        Ok(())
    }
}
