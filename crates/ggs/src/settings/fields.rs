//! The settings struct, its fields with their meaning and units, and the presets' values.

use crate::pipeline::{
    FinalStage, FirstLook, PolishConfig, Preset, VerifyConfig, VerifyScore, AUTO_VOXEL_CELLS,
    AUTO_VOXEL_SPACINGS,
};
use crate::refine::{Method, RefineConfig, RobustKernel, DEFAULT_DISTANCE_QUANTILE};
use crate::rotations::DEFAULT_SET;
use crate::search::{CoarseToFine, Precision, ProgressFn, COARSE_LEVEL_HYPOTHESES};
use serde::{Deserialize, Serialize};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// How the rotations are searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SearchKind {
    /// Every rotation scored at the voxel size (the GGS search).
    Exhaustive,
    /// Every rotation at `coarse_factor` × voxel, then the best (`coarse_keep`) and their
    /// grid neighbours at the voxel size.
    #[serde(alias = "c2f")]
    CoarseToFine,
}

/// Every setting of a registration (see the module documentation). Lengths are in the
/// clouds' units, angles in degrees unless a name says otherwise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Settings {
    /// Voxel edge `s`; `None`: automatic, the larger of the target's longest side /
    /// `auto_voxel_cells` and `auto_voxel_spacings` × the clouds' point spacing, rounded to
    /// 2 significant digits.
    #[serde(default)]
    pub voxel: Option<f64>,
    /// Voxels along the target's longest side of an automatic voxel.
    pub auto_voxel_cells: usize,
    /// An automatic voxel is at least this many point spacings.
    pub auto_voxel_spacings: f64,
    /// Built-in rotation set ([`NAMES`](crate::rotations::NAMES)), or a `.npy` file of shape
    /// `[N, 3, 3]`.
    pub rotations: String,
    /// Drop rotations within this angle of an earlier one in the set; `None`: keep all.
    #[serde(default)]
    pub dedup: Option<f64>,
    /// Exhaustive or coarse-to-fine.
    pub search: SearchKind,
    /// Arithmetic of the correlations (both give the same picks).
    pub precision: Precision,
    /// Coarse voxel = `coarse_factor` × voxel (coarse-to-fine).
    pub coarse_factor: f64,
    /// Fraction of the rotations kept from the coarse level (coarse-to-fine).
    pub coarse_keep: f64,
    /// Keep at least this many rotations from the coarse level (coarse-to-fine).
    pub coarse_keep_min: usize,
    /// Also re-score every rotation within this angle of a kept one; `None`: the set's step
    /// × 1.01 (its nearest grid neighbours).
    #[serde(default)]
    pub coarse_neighbour: Option<f64>,
    /// Distinct hypotheses of the coarse level itself that are verified, each with its own
    /// translation at the coarse voxel (coarse-to-fine with verification; 0: none).
    pub coarse_hypotheses: usize,
    /// Distinct coarse hypotheses reported, of the whole search (a first look then does not
    /// run); `None`: as many as are verified (1 without verification).
    #[serde(default)]
    pub top_k: Option<usize>,
    /// Rotations closer than this to a better one are not distinct; `None`: 2 × the set's
    /// step.
    #[serde(default)]
    pub distinct_radius: Option<f64>,
    /// Memory budget of the search in bytes (a file or flag may say `"2G"`, `"512M"`);
    /// `None`: half of physical memory.
    #[serde(default, deserialize_with = "super::serde_forms::optional_size")]
    pub max_memory: Option<u64>,
    /// Verify the coarse level's best few first and stop there when they settle the pair
    /// (coarse-to-fine with verification).
    pub first_look: bool,
    /// Rotations the first look scores at the voxel size.
    pub first_look_rotations: usize,
    /// Distinct hypotheses of those the first look verifies.
    pub first_look_hypotheses: usize,
    /// The least verification score the first look accepts.
    pub first_look_accept_score: f64,
    /// The first look screens the coarse level's alternatives by ICP on cells of this many
    /// voxels (0: the verification's own cells).
    pub first_look_screen_cell: f64,
    /// Verify the distinct hypotheses by ICP and a fixed-distance score (`false`: take the
    /// coarse winner).
    pub verify: bool,
    /// Verify at most this many distinct hypotheses.
    pub max_hypotheses: usize,
    /// Verify the hypotheses whose match score is at least this fraction of the winner's.
    pub margin: f64,
    /// How a point within the verification distance `D` counts.
    pub verify_score: VerifyScore,
    /// `D` is at least this many voxels.
    pub verify_distance_voxels: f64,
    /// `D` is at least this many target point spacings.
    pub verify_distance_spacings: f64,
    /// `D` is at least this fraction of the median range of a cloud taken as a scan from its
    /// origin.
    pub verify_distance_range: f64,
    /// The verification's ICP runs on clouds thinned to cells of this many voxels.
    pub verify_cell: f64,
    /// ICP iterations before a hypothesis is compared with the best so far.
    pub verify_check_iterations: usize,
    /// ICP iterations per hypothesis, in all.
    pub verify_iterations: usize,
    /// A hypothesis scoring below this fraction of the best so far at the check stops.
    pub reject_ratio: f64,
    /// Contested poses are refined again on cells of this many voxels (0: never).
    pub verify_fine_cell: f64,
    /// ICP iterations of that second refinement.
    pub verify_fine_iterations: usize,
    /// Its fixed correspondence distance, in voxels (0: the refinement's own rule).
    pub verify_fine_distance: f64,
    /// Every hypothesis scoring at least this fraction of the best, stopped at its check or
    /// not, is a contender of that second refinement.
    pub settle_ratio: f64,
    /// Two distinct poses verifying within this ratio of each other make the result
    /// ambiguous.
    pub ambiguous_ratio: f64,
    /// `λ`: the score loses `λ · max(0, v − v₀)` for a share `v` of points in the other
    /// scan's seen free space.
    pub free_space_weight: f64,
    /// `v₀`: the share of points allowed in the other scan's free space.
    pub free_space_tolerance: f64,
    /// A point violates the free space at least this many voxels in front of the surface
    /// seen in its direction.
    pub free_space_margin: f64,
    /// Polish each hypothesis on a finer rotation grid before its ICP.
    pub polish: bool,
    /// The polish's first step, as a fraction of the rotation set's step.
    pub polish_step_fraction: f64,
    /// Polish levels; each divides the step by 3.
    pub polish_levels: usize,
    /// Moves of the centre the polish allows at each level.
    pub polish_max_moves: usize,
    /// The final refinement: gicp, p2plane, p2p, or none.
    #[serde(
        serialize_with = "super::serde_forms::write_refinement",
        deserialize_with = "super::serde_forms::read_refinement"
    )]
    pub refine: Option<Method>,
    /// Fixed correspondence distance of the refinement; `None`: the `distance_quantile`
    /// quantile of the nearest-neighbour distances at the start.
    #[serde(default)]
    pub max_distance: Option<f64>,
    /// Quantile of the nearest-neighbour distances taken as correspondence distance.
    pub distance_quantile: f64,
    /// Robust kernel: none, huber:K, cauchy:K or geman-mcclure:K (K in cloud units).
    #[serde(
        serialize_with = "super::serde_forms::write_kernel",
        deserialize_with = "super::serde_forms::read_kernel"
    )]
    pub kernel: RobustKernel,
    /// Iteration cap of the final refinement.
    pub max_iterations: usize,
    /// Neighbours for normals and covariances.
    pub neighbors: usize,
    /// GICP covariance along the normal, `ε`.
    pub gicp_epsilon: f64,
    /// The final refinement runs on both clouds thinned to one point per cell of this many
    /// voxels (0: full resolution).
    pub refine_cell: f64,
    /// The final refinement stops when an update rotates by less than this (radians) and
    /// moves by less than this many source radii.
    pub refine_min_step: f64,
    /// Aligning a set of scans (`ggs align`): a registration places a scan when at least
    /// this share of its points then lie within 3 point spacings of the model.
    pub align_min_overlap: f64,
    /// … and its confidence (`1 − s₂/s₁`, the margin of the chosen pose over the runner-up)
    /// is at least this.
    pub align_min_confidence: f64,
    /// The model of a quick try holds at most this many placed scans, those whose shape
    /// descriptors are nearest to the scan's (a whole search's model holds every placed
    /// scan).
    pub align_model_scans: usize,
    /// Registrations onto one model decided together, run side by side (on one pool of
    /// threads, or as Ray tasks); the result depends on this number, not on how they run.
    pub align_batch: usize,
}

impl Settings {
    /// The settings of `preset` (see [`Preset`]).
    pub fn preset(preset: Preset) -> Settings {
        match preset {
            Preset::Default => Settings::default_preset(),
            Preset::Paper => Settings::paper_preset(),
        }
    }

    /// ggs's best for clouds with no initial guess.
    fn default_preset() -> Settings {
        let c2f = CoarseToFine::for_verification();
        let look = FirstLook::default();
        let v = VerifyConfig::default();
        let p = PolishConfig::default();
        let r = RefineConfig::default();
        let stage = FinalStage::THINNED;
        Settings {
            voxel: None,
            auto_voxel_cells: AUTO_VOXEL_CELLS,
            auto_voxel_spacings: AUTO_VOXEL_SPACINGS,
            rotations: DEFAULT_SET.to_string(),
            dedup: None,
            search: SearchKind::CoarseToFine,
            precision: Precision::Mixed,
            coarse_factor: c2f.factor,
            coarse_keep: c2f.keep_fraction,
            coarse_keep_min: c2f.keep_min,
            coarse_neighbour: c2f.neighbour_deg,
            coarse_hypotheses: COARSE_LEVEL_HYPOTHESES,
            top_k: None,
            distinct_radius: None,
            max_memory: None,
            first_look: true,
            first_look_rotations: look.rotations,
            first_look_hypotheses: look.hypotheses,
            first_look_accept_score: look.accept_score,
            first_look_screen_cell: look.screen_cell_voxels,
            verify: true,
            max_hypotheses: v.max_hypotheses,
            margin: v.margin,
            verify_score: v.score,
            verify_distance_voxels: v.distance_voxels,
            verify_distance_spacings: v.spacing_factor,
            verify_distance_range: v.scan_distance_fraction,
            verify_cell: v.cell_voxels,
            verify_check_iterations: v.check_iterations,
            verify_iterations: v.max_iterations,
            reject_ratio: v.reject_ratio,
            verify_fine_cell: v.fine_cell_voxels,
            verify_fine_iterations: v.fine_iterations,
            verify_fine_distance: v.fine_distance_voxels,
            settle_ratio: v.settle_ratio,
            ambiguous_ratio: v.ambiguous_ratio,
            free_space_weight: v.free_space_weight,
            free_space_tolerance: v.free_space_tolerance,
            free_space_margin: v.free_space_margin_voxels,
            polish: false,
            polish_step_fraction: p.step_fraction,
            polish_levels: p.levels,
            polish_max_moves: p.max_moves,
            refine: Some(r.method),
            max_distance: None,
            distance_quantile: DEFAULT_DISTANCE_QUANTILE,
            kernel: r.kernel,
            max_iterations: stage.max_iterations.min(r.max_iterations),
            neighbors: r.neighbors,
            gicp_epsilon: r.epsilon,
            refine_cell: stage.cell_voxels,
            refine_min_step: stage.min_step,
            // A right placement leaves 45–100 % of a turntable scan on the model, a wrong
            // one 20–35 % (docs/align.md).
            align_min_overlap: 0.4,
            align_min_confidence: 0.3,
            align_model_scans: 8,
            align_batch: 2,
        }
    }

    /// The GGS paper's configuration: `limited15`, exhaustive, the single best hypothesis,
    /// GICP with the reference parameters at full resolution.
    fn paper_preset() -> Settings {
        let c2f = CoarseToFine::default();
        Settings {
            rotations: "limited15".to_string(),
            search: SearchKind::Exhaustive,
            coarse_factor: c2f.factor,
            coarse_keep: c2f.keep_fraction,
            coarse_keep_min: c2f.keep_min,
            coarse_hypotheses: c2f.hypotheses,
            first_look: false,
            verify: false,
            max_iterations: RefineConfig::default().max_iterations,
            refine_cell: FinalStage::FULL.cell_voxels,
            refine_min_step: FinalStage::FULL.min_step,
            ..Settings::default_preset()
        }
    }
}

impl Default for Settings {
    /// The default preset.
    fn default() -> Self {
        Settings::preset(Preset::Default)
    }
}

/// What a run needs beside its [`Settings`]; none of it changes the result.
#[derive(Clone, Default)]
pub struct Runtime {
    /// Worker threads of every stage; 0: one per available core.
    pub threads: usize,
    /// Called after each scored rotation with the number scored so far.
    pub progress: Option<ProgressFn>,
    /// Set to `true` from another thread to stop the run
    /// ([`GgsError::Cancelled`](crate::GgsError::Cancelled)).
    pub cancel: Option<Arc<AtomicBool>>,
}
