//! What a registration is asked to do, stage by stage: the voxel rule, the presets' names,
//! the final refinement's schedule and [`RegistrationConfig`], which
//! [`Settings::plan`](crate::Settings::plan) builds from the settings.

use super::first_look::FirstLook;
use super::polish::PolishConfig;
use super::verify::VerifyConfig;
use crate::cloud::Cloud;
use crate::error::{GgsError, Result};
use crate::refine::RefineConfig;
use crate::rotations::RotationSet;
use crate::search::{auto_voxel, round_2_digits, SearchConfig};

/// Voxels along the target's longest side when the voxel size is chosen automatically.
pub const AUTO_VOXEL_CELLS: usize = 32;

/// An automatic voxel is at least this many point spacings (the median distance from a point
/// to its nearest other point, the larger of the two clouds'): a voxel finer than the spacing
/// leaves holes between the points of one surface, and the grid score then counts exact point
/// coincidences instead of overlapping surfaces. Measured on PCL's 400-point bunny scans
/// (spacing 6.2 mm, side / 32 = 4.6 mm): wrong pose at 0.74 spacings, right from 0.9 to 2.4.
pub const AUTO_VOXEL_SPACINGS: f64 = 1.5;

/// How the voxel size is chosen.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum VoxelSize {
    /// The larger of the target's longest side / `cells` and `spacings` × the clouds' point
    /// spacing ([`AUTO_VOXEL_SPACINGS`]), rounded to 2 significant digits.
    Auto { cells: usize, spacings: f64 },
    /// A fixed edge length in the clouds' units.
    Fixed(f64),
}

impl VoxelSize {
    /// The automatic rule of the presets.
    pub const AUTO: VoxelSize = VoxelSize::Auto {
        cells: AUTO_VOXEL_CELLS,
        spacings: AUTO_VOXEL_SPACINGS,
    };

    /// The voxel edge for `target`, and how it was chosen (`None`: fixed); `spacing` gives
    /// the clouds' point spacing (the larger of the two) when the rule needs it.
    pub fn resolve(
        &self,
        target: &Cloud,
        spacing: impl FnOnce() -> f64,
    ) -> Result<(f64, Option<String>)> {
        match *self {
            VoxelSize::Fixed(v) if v.is_finite() && v > 0.0 => Ok((v, None)),
            VoxelSize::Fixed(v) => Err(GgsError::param(
                "voxel",
                format!("must be a positive number, got {v}"),
            )),
            VoxelSize::Auto { cells, spacings } => {
                let by_extent = auto_voxel(target, cells).ok_or_else(|| {
                    GgsError::param(
                        "voxel",
                        "cannot choose a voxel size: the target has zero extent; give one",
                    )
                })?;
                let spacing = spacing();
                if spacings * spacing > by_extent {
                    let v = round_2_digits(spacings * spacing);
                    let spacing = round_2_digits(spacing);
                    let why = format!("auto: {spacings} × the point spacing {spacing}");
                    Ok((v, Some(why)))
                } else {
                    let why = format!("auto: target's longest side / {cells}");
                    Ok((by_extent, Some(why)))
                }
            }
        }
    }
}

/// A named configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Preset {
    /// ggs's best for clouds with no initial guess (see the module documentation).
    Default,
    /// The GGS paper's configuration.
    Paper,
}

impl Preset {
    pub const NAMES: &'static [&'static str] = &["default", "paper"];

    pub fn name(&self) -> &'static str {
        match self {
            Preset::Default => "default",
            Preset::Paper => "paper",
        }
    }
}

impl std::str::FromStr for Preset {
    type Err = GgsError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "default" => Ok(Preset::Default),
            "paper" => Ok(Preset::Paper),
            other => Err(GgsError::param(
                "preset",
                format!("unknown preset '{other}' (default or paper)"),
            )),
        }
    }
}

/// The final refinement's schedule, on top of its [`RefineConfig`].
///
/// Measured on the 8 bunny pairs the defaults solve (from the verified pose; GICP, reference
/// parameters otherwise): thinned to 0.2 voxel (1 mm cells; 40k → ≈ 10k points) and stopped
/// at steps below 1e-5 rad and 1e-5 source radii, the final pose lies within 0.055° and
/// 0.075 mm of GICP's at full resolution run to its relative-change criterion, in a third of
/// its time (docs/performance.md). The step tolerance alone changes the pose by ≤ 0.002°.
/// Stopping at 1e-4 instead (the default) moves the pose by at most 0.005°
/// and 0.014 mm more on the real bunny pairs (0.0008 voxel on the scenes) and saves 1–4
/// iterations, 6 ms on the bunny pair (docs/pipeline.md, "The final refinement").
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FinalStage {
    /// Thin both clouds to one point (the mean) per cell of this many voxels before the final
    /// refinement (0: full resolution). Clouds sparser than the cell keep their points.
    pub cell_voxels: f64,
    /// Stop when an update rotates by less than this (radians) and moves by less than this
    /// many source radii; the [`RefineConfig`]'s own tolerances when those are larger.
    pub min_step: f64,
    /// At most this many iterations (the [`RefineConfig`]'s cap when smaller). Every pair
    /// solved on the benchmarks converged within 28 from its verified pose; a wrong pose can
    /// wander for the reference's 500 (1.2 s on a bunny pair).
    pub max_iterations: usize,
}

impl FinalStage {
    /// Full resolution, the refinement's own stopping rules (the reference GICP).
    pub const FULL: FinalStage = FinalStage {
        cell_voxels: 0.0,
        min_step: 0.0,
        max_iterations: usize::MAX,
    };
    /// The default preset's.
    pub const THINNED: FinalStage = FinalStage {
        cell_voxels: 0.2,
        min_step: 1e-4,
        max_iterations: 100,
    };

    /// Refuses a negative or non-finite cell or step, naming them by their settings keys.
    pub fn validate(&self) -> Result<()> {
        for (key, v) in [
            ("refine_cell", self.cell_voxels),
            ("refine_min_step", self.min_step),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(GgsError::param(
                    key,
                    format!("must be a number ≥ 0, got {v}"),
                ));
            }
        }
        Ok(())
    }
}

/// Everything a registration needs.
#[derive(Debug, Clone)]
pub struct RegistrationConfig {
    pub voxel: VoxelSize,
    pub rotations: RotationSet,
    /// The grid search. Its `voxel` and `threads` are set from this config's. Its `top_k`
    /// hypotheses are reported in the result; the search looks for at least
    /// [`VerifyConfig::max_hypotheses`] when verifying.
    pub search: SearchConfig,
    /// Finer rotations around each hypothesis (`None`: the grid's rotation is kept).
    pub polish: Option<PolishConfig>,
    /// Verification of the distinct hypotheses (`None`: the coarse winner is taken).
    pub verify: Option<VerifyConfig>,
    /// Verify the coarse level's best few first and stop there when they settle the pair
    /// (coarse-to-fine with verification only; `None`: the whole search always).
    pub first_look: Option<FirstLook>,
    /// How the final refinement runs (resolution, stopping step).
    pub final_stage: FinalStage,
    /// Refinement of the chosen hypothesis (`None`: none). Verification
    /// runs the same estimator (GICP when this is `None`) on thinned clouds.
    pub refine: Option<RefineConfig>,
    /// Worker threads of every stage (0: one per core); the result does not depend on it.
    pub threads: usize,
}
