//! What a grid search returns: the hypotheses, the statistics of the search, the timings.

use super::config::{Precision, SearchMode};
use super::geometry::Geometry;
use crate::transform::Rigid;

/// One (rotation, translation) candidate.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Hypothesis {
    /// Index of the rotation in the set.
    pub rotation_index: usize,
    /// Score `Σ S_pad·K` (PV = 5, NV = PPV = −1), an exact integer.
    pub score: i64,
    /// Offset-free match score `5·n11 − n01` (docs/method.md, "Exact integers"); same argmax as `score`.
    pub match_score: i64,
    /// Best offset `a` in cells (x, y, z).
    pub offset: [usize; 3],
    /// The transform, `p_target = T · p_source`.
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub transform: Rigid,
}

/// Wall-clock and CPU times of the stages, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Timings {
    /// Target voxelization and the correlator's plans (wall). The kernel spectrum is computed
    /// when a rotation is first correlated by the transforms, so it counts in the scoring.
    pub target_ms: f64,
    /// Rotated source extents for all rotations (wall).
    pub extents_ms: f64,
    /// Scoring the rotations at the voxel size and selecting the winner (wall).
    pub search_ms: f64,
    /// Everything in `grid_search` (wall).
    pub total_ms: f64,
    /// CPU time summed over workers and over both levels: voxelizing rotated sources.
    pub cpu_voxelize_ms: f64,
    /// CPU time: forward FFTs along z and y.
    pub cpu_forward_ms: f64,
    /// CPU time: FFT along x, product with the kernel spectrum, inverse along x.
    pub cpu_product_ms: f64,
    /// CPU time: inverse FFTs along y and z and the argmax.
    pub cpu_inverse_ms: f64,
    /// CPU time: direct correlation of small grids and sparse correlation of sparse ones,
    /// where either is cheaper than the transforms (`search::direct`, `search::sparse`).
    pub cpu_direct_ms: f64,
    /// Coarse level of a coarse-to-fine search: thinning, its kernel and extents, scoring
    /// every rotation, ranking (wall; not included in the other fields).
    pub coarse_level_ms: f64,
    /// Exact re-scoring of the rotations whose f32 bound reached the best (wall; included in
    /// `search_ms`).
    pub rescore_ms: f64,
}

/// Result of a grid search: the hypotheses, what the search did, how long it took.
#[derive(Debug, Clone)]
pub struct SearchResult {
    /// The `top_k` best distinct hypotheses, best first: `hypotheses[0]` is the winner
    /// ([`SearchResult::winner`]). Never empty.
    pub hypotheses: Vec<Hypothesis>,
    /// Best hypothesis whose rotation is more than `stats.distinct_radius_deg` from the
    /// winner's (found even when `top_k` is 1).
    pub runner_up: Option<Hypothesis>,
    /// `runner_up.match_score / match_score` (when the winner's is positive): near 1, another
    /// pose explains the data about as well; near 0 or below, the answer is clear.
    pub ambiguity: Option<f64>,
    pub stats: SearchStats,
    pub timings: Timings,
}

/// What a grid search did: its parameters as resolved, the sizes of its problem, its work.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SearchStats {
    /// Rotations closer than this (degrees) to a better hypothesis were not distinct.
    pub distinct_radius_deg: f64,
    pub voxel: f64,
    pub rotation_set: String,
    pub rotations: usize,
    pub source_points: usize,
    /// Source points the search voxelized: all, or their representatives
    /// ([`representatives`](super::representatives)).
    pub searched_points: usize,
    pub target_points: usize,
    /// Occupied target voxels.
    pub target_occupied: usize,
    pub geometry: Geometry,
    pub threads: usize,
    /// Estimated peak of the search's large buffers, in bytes.
    pub memory_estimate_bytes: u64,
    /// Largest distance of an f64 FFT output from its integer (exactness check; ≪ 0.5).
    pub max_rounding_error: f64,
    pub mode: SearchMode,
    pub precision: Precision,
    /// Rotations scored at the voxel size (all of them when exhaustive).
    pub scored: usize,
    /// Rotations re-scored exactly because their f32 bound reached the best (mixed precision;
    /// a rotation asked again under a lower floor counts again).
    pub rescored: usize,
    /// Coarse level of a coarse-to-fine search.
    pub coarse_level: Option<CoarseLevel>,
    /// Nominal floating-point operations of all FFT correlations run (both levels and the
    /// re-scoring), in GFLOP ([`Geometry::flops`]).
    pub fft_gflop: f64,
}

impl SearchResult {
    /// The best hypothesis.
    pub fn winner(&self) -> &Hypothesis {
        &self.hypotheses[0]
    }

    /// The winner's transform, `p_target = T · p_source`.
    pub fn transform(&self) -> Rigid {
        self.winner().transform
    }
}

/// The JSON layout of a [`SearchResult`] (unchanged since the first release): the winner's
/// fields at the top level, then the hypotheses, the statistics and the timings.
#[derive(serde::Serialize)]
struct SearchResultJson<'a> {
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    transform: Rigid,
    rotation_index: usize,
    score: i64,
    match_score: i64,
    offset: [usize; 3],
    runner_up: Option<Hypothesis>,
    ambiguity: Option<f64>,
    hypotheses: &'a [Hypothesis],
    #[serde(flatten)]
    stats: &'a SearchStats,
    timings: Timings,
}

impl serde::Serialize for SearchResult {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let w = self.winner();
        SearchResultJson {
            transform: w.transform,
            rotation_index: w.rotation_index,
            score: w.score,
            match_score: w.match_score,
            offset: w.offset,
            runner_up: self.runner_up,
            ambiguity: self.ambiguity,
            hypotheses: &self.hypotheses,
            stats: &self.stats,
            timings: self.timings,
        }
        .serialize(s)
    }
}

/// A hypothesis of the coarse level: a rotation, the offset of its largest approximate
/// (f32) correlation output at the coarse voxel, and the transform of that offset. Its score
/// is approximate, within `error_bound` of the exact one; it serves as a start for the
/// verification, never as the search's pick.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct LevelHypothesis {
    pub rotation_index: usize,
    /// Approximate match score `5·n11 − n01` at the coarse voxel.
    pub match_score: f64,
    pub error_bound: f64,
    pub offset: [usize; 3],
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub transform: Rigid,
}

/// What the coarse level of a coarse-to-fine search did.
#[derive(Debug, Clone, serde::Serialize)]
pub struct CoarseLevel {
    pub voxel: f64,
    /// Source points after thinning to one per cell of a quarter of the coarse voxel.
    pub source_points: usize,
    pub geometry: Geometry,
    /// Rotations kept by coarse score, before adding neighbours (after the last round).
    pub kept: usize,
    pub neighbour_deg: f64,
    /// Rank (0 = best) of the final winner by coarse score: how much margin `kept` had.
    pub winner_rank: usize,
    /// Rounds of fine scoring: `kept` doubled after each round whose winner ranked in the
    /// lower half of it (1 when the coarse ranking was clear; 0 when only the `kept` leading
    /// rotations were scored at the voxel size, without neighbours:
    /// [`Search::score_leading`](super::Search::score_leading)).
    pub rounds: usize,
    /// The best distinct hypotheses at this level's voxel, best first
    /// ([`CoarseToFine::hypotheses`](super::CoarseToFine::hypotheses) of them).
    pub hypotheses: Vec<LevelHypothesis>,
    #[serde(skip)]
    rank: Vec<usize>,
    #[serde(skip)]
    order: Vec<usize>,
}

impl CoarseLevel {
    /// A level that kept `kept` of the rotations in `order` (best first by coarse score).
    pub(super) fn new(
        voxel: f64,
        source_points: usize,
        geometry: Geometry,
        kept: usize,
        neighbour_deg: f64,
        order: Vec<usize>,
    ) -> Self {
        let mut rank = vec![0; order.len()];
        for (r, &k) in order.iter().enumerate() {
            rank[k] = r;
        }
        CoarseLevel {
            voxel,
            source_points,
            geometry,
            kept,
            neighbour_deg,
            winner_rank: 0,
            rounds: 0,
            hypotheses: Vec::new(),
            rank,
            order,
        }
    }

    /// The rotations, best first by coarse score.
    pub fn order(&self) -> &[usize] {
        &self.order
    }

    /// Rank of rotation `k` by coarse score (0 = best).
    pub fn rank_of(&self, k: usize) -> usize {
        self.rank[k]
    }
}
