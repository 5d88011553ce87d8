//! What the verification found: each verified hypothesis with its evidence, the choice and
//! the runner-up.

use super::verify::{Evidence, VerifyScore};
use crate::transform::Rigid;

/// A hypothesis whose verification ICP has, at the check, brought it within this angle
/// (degrees) and [`SAME_POSE_VOXELS`] (where the source's centroid lands) of an earlier
/// verified pose stops there: it is on its way to the same pose.
pub const SAME_POSE_DEG: f64 = 1.0;
/// See [`SAME_POSE_DEG`].
pub const SAME_POSE_VOXELS: f64 = 0.25;

/// One coarse hypothesis after polish and verification.
#[derive(Debug, Clone, serde::Serialize)]
pub struct VerifiedHypothesis {
    /// Position in the verified list: the voxel size's distinct hypotheses in coarse rank
    /// order (0: the search's winner), then the coarse level's.
    pub rank: usize,
    /// Which level of the search proposed it.
    pub level: HypothesisLevel,
    pub rotation_index: usize,
    /// Coarse match score `5·n11 − n01` at the grid rotation, and after the polish.
    pub match_score: i64,
    pub polished_match_score: i64,
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub coarse_transform: Rigid,
    /// After the polish and the verification's ICP.
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub transform: Rigid,
    pub evidence: Evidence,
    pub iterations: usize,
    pub rejected_early: bool,
    /// Rejected on a random part of the sample (`evidence.points`), whose estimate
    /// of the score lay far below the threshold (`verify::finish`).
    pub rejected_on_subsample: bool,
    /// Refined again on finer cells because another distinct pose also survived.
    pub settled: bool,
    /// Stopped at the check on the pose of this earlier verified hypothesis (its `rank`),
    /// whose evidence it carries (within [`SAME_POSE_DEG`] and [`SAME_POSE_VOXELS`]).
    pub same_as: Option<usize>,
    /// Verified by the first look's screening: its ICP ran on the coarser cells of
    /// [`super::FirstLook::screen_cell_voxels`], not on the verification's.
    pub screened: bool,
}

#[cfg(test)]
impl VerifiedHypothesis {
    /// For tests: hypothesis `rank` at `transform` (from a voxel-size rotation of that
    /// index), its ICP stopped after 10 iterations, both sides scoring `score`.
    pub(crate) fn scoring(rank: usize, transform: Rigid, score: f64) -> Self {
        VerifiedHypothesis {
            rank,
            level: HypothesisLevel::Voxel,
            rotation_index: rank,
            match_score: 100,
            polished_match_score: 100,
            coarse_transform: transform,
            transform,
            evidence: Evidence {
                fitness_source: score,
                fitness_target: score,
                score,
                points: [100, 100],
                free_space_violations: None,
            },
            iterations: 10,
            rejected_early: false,
            rejected_on_subsample: false,
            settled: false,
            same_as: None,
            screened: false,
        }
    }
}

/// The level of the grid search a hypothesis comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum HypothesisLevel {
    /// The voxel size: an exact argmax (`SearchResult::hypotheses`).
    Voxel,
    /// The coarse level of a coarse-to-fine search (`CoarseLevel::hypotheses`).
    Coarse,
}

/// What the verification found.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Verification {
    /// The verified hypotheses: the voxel size's in coarse rank order, then the coarse level's.
    pub hypotheses: Vec<VerifiedHypothesis>,
    /// Index into `hypotheses` of the chosen one.
    pub chosen: usize,
    /// Index of the best-scoring hypothesis distinct from the chosen one.
    pub runner_up: Option<usize>,
    /// The verification distance `D`, cloud units.
    pub distance: f64,
    /// ICP cell size of the verification, cloud units.
    pub cell: f64,
    /// How a point within `D` counted.
    pub score: VerifyScore,
    /// Whether the source and the target were taken as scans from their origins, whose seen
    /// free space the score checks ([`super::free_space`]).
    pub scanners: [bool; 2],
    /// The free-space margin `m`, cloud units (used only where `scanners` says so).
    pub free_space_margin: f64,
}
