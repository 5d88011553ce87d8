//! The coarse search of Greedy Grid Search (docs/coarse-search.md): every rotation of a set, the best
//! translation of each by FFT correlation, the best (rotation, translation) overall.
//!
//! Determinism: each rotation is scored independently into its own slot and the winner is
//! chosen by a sequential scan, so the result is bit-identical whatever the thread count.
//! Ties go to the lowest rotation index, then the lowest offset in x-major C order; scores
//! are exact integers, so float noise never decides a tie.
//!
//! Precision ([`Precision::Mixed`], the default): rotations are scored in f32 with a proven
//! error bound and every rotation whose bound could reach the winner (or a top-k hypothesis,
//! or the runner-up) is re-scored in f64, so the picks are the all-f64 ones
//! (`passes::exact_best`).
//!
//! Modes: [`SearchMode::Exhaustive`] scores every rotation at the voxel size;
//! [`SearchMode::CoarseToFine`] ranks every rotation at a coarser voxel first and scores at the
//! voxel size only the best and their neighbours, in rounds that look further while the
//! winner ranks in the lower half of what was kept (docs/performance.md).

mod memory_model;
mod passes;

use crate::cloud::{Cloud, Point};
use crate::correlate::{CpuCorrelator, Geometry};
use crate::error::{GgsError, Result};
use crate::memory;
use crate::rotated::RotatableCloud;
use crate::rotations::RotationSet;
use crate::transform::{rotation_angle_deg, Rigid};
use crate::voxel::{self, Occupancy};
use memory_model::MemoryModel;
use nalgebra::{Matrix3, Vector3};
use passes::{exact_best, rescore_f64, run_pass, LevelScores, PassInput, StageTimes, Tally};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Callback told how many rotations have been scored so far.
pub type ProgressFn = Arc<dyn Fn(usize) + Send + Sync>;

/// Parameters of a coarse search.
#[derive(Clone)]
pub struct SearchConfig {
    /// Voxel edge length `s`, in the clouds' units.
    pub voxel: f64,
    /// Worker threads; 0 means one per available core.
    pub threads: usize,
    /// Number of distinct hypotheses to return (≥ 1).
    pub top_k: usize,
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
        }
    }
}

impl CoarseToFine {
    /// The default preset's: coarse voxel 4 × voxel, 1 % kept. Its candidates are checked by
    /// the verification's ICP and score, so it need not pick the exhaustive winner; measured:
    /// the same recall as [`CoarseToFine::default`] on every benchmark of the project, with a
    /// coarse level 4× and a fine level 2× cheaper (docs/performance.md).
    pub fn for_verification() -> Self {
        CoarseToFine {
            factor: 4.0,
            keep_fraction: 0.01,
            ..CoarseToFine::default()
        }
    }
}

/// Arithmetic of the correlations; both give the same picks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// f32 transforms with a proven error bound for every rotation, then f64 re-scoring of
    /// every rotation whose bound reaches the best exact score (the default; 2–3× faster).
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
            distinct_radius_deg: None,
            max_memory: None,
            progress: None,
            cancel: None,
            mode: SearchMode::Exhaustive,
            precision: Precision::Mixed,
        }
    }
}

/// Representatives of the source are one point per occupied cell of voxel / this.
pub const REPRESENTATIVE_DIVISIONS: f64 = 8.0;

/// The search voxelizes representatives instead of every point when they are at least this
/// many times fewer.
pub const MIN_POINTS_PER_REPRESENTATIVE: usize = 4;

/// Representatives of a dense source for the search at voxel `s`: one point (the mean) per
/// occupied cell of edge `c = s / REPRESENTATIVE_DIVISIONS`, when that makes at least
/// [`MIN_POINTS_PER_REPRESENTATIVE`] × fewer points (`None`: the source as it is).
///
/// The search then costs what the occupied cells cost, not what the points cost (a
/// 4.8-million-point LiDAR pair: 40 s → see docs/performance.md). What it can change: every
/// point lies within `c·√3` of its representative, so under any rotation the occupancy of
/// the representatives differs from the points' only in voxels within `c·√3 ≈ 0.22 s` of a
/// face of an occupied voxel (a representative in the next voxel over, or none in a voxel
/// the points only touched). Measured: the same picks on every real pair (docs/performance.md).
pub fn representatives(source: &Cloud, s: f64) -> Option<Cloud> {
    let reps = voxel::cell_centroids(&source.points, s / REPRESENTATIVE_DIVISIONS);
    (reps.len() * MIN_POINTS_PER_REPRESENTATIVE <= source.len()).then(|| Cloud::new(reps))
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

/// One (rotation, translation) candidate.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Hypothesis {
    /// Index of the rotation in the set.
    pub rotation_index: usize,
    /// Score `Σ S_pad·K` (PV = 5, NV = PPV = −1), an exact integer.
    pub score: i64,
    /// Offset-free match score `5·n11 − n01` (docs/coarse-search.md, "Exact integers"); same argmax as `score`.
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
    /// Target voxelization and kernel spectrum (wall).
    pub target_ms: f64,
    /// Rotated source extents for all rotations (wall).
    pub extents_ms: f64,
    /// Scoring the rotations at the voxel size and selecting the winner (wall).
    pub search_ms: f64,
    /// Everything in `coarse_register` (wall).
    pub total_ms: f64,
    /// CPU time summed over workers and over both levels: voxelizing rotated sources.
    pub cpu_voxelize_ms: f64,
    /// CPU time: forward FFTs along z and y.
    pub cpu_forward_ms: f64,
    /// CPU time: FFT along x, product with the kernel spectrum, inverse along x.
    pub cpu_product_ms: f64,
    /// CPU time: inverse FFTs along y and z and the argmax.
    pub cpu_inverse_ms: f64,
    /// Coarse level of a coarse-to-fine search: thinning, its kernel and extents, scoring
    /// every rotation, ranking (wall; not included in the other fields).
    pub coarse_level_ms: f64,
    /// f64 re-scoring of the rotations whose f32 bound reached the best (wall; included in
    /// `search_ms`).
    pub rescore_ms: f64,
}

/// Result of a coarse search.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SearchResult {
    /// Best transform, `p_target = T · p_source`.
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub transform: Rigid,
    pub rotation_index: usize,
    /// Score `Σ S_pad·K` of the winner (docs/coarse-search.md).
    pub score: i64,
    /// Match score `5·n11 − n01` of the winner.
    pub match_score: i64,
    pub offset: [usize; 3],
    /// Best hypothesis whose rotation is more than `distinct_radius_deg` from the winner's.
    pub runner_up: Option<Hypothesis>,
    /// `runner_up.match_score / match_score` (when the winner's is positive): near 1, another
    /// pose explains the data about as well; near 0 or below, the answer is clear.
    pub ambiguity: Option<f64>,
    pub distinct_radius_deg: f64,
    /// The `top_k` best distinct hypotheses, best first (the first is the winner).
    pub hypotheses: Vec<Hypothesis>,
    pub voxel: f64,
    pub rotation_set: String,
    pub rotations: usize,
    pub source_points: usize,
    /// Source points the search voxelized: all, or their representatives
    /// ([`representatives`]).
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
    /// Rotations re-scored in f64 because their f32 bound reached the best (mixed precision).
    pub rescored: usize,
    /// Coarse level of a coarse-to-fine search.
    pub coarse_level: Option<CoarseLevel>,
    /// Nominal floating-point operations of all FFT correlations run (both levels and the
    /// re-scoring), in GFLOP ([`Geometry::flops`]).
    pub fft_gflop: f64,
    pub timings: Timings,
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
    /// lower half of it (1 when the coarse ranking was clear).
    pub rounds: usize,
    #[serde(skip)]
    rank: Vec<usize>,
    #[serde(skip)]
    order: Vec<usize>,
}

fn rows(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [
        [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
        [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
        [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
    ]
}

/// Per-rotation min corner and grid dims of the rotated, centred source.
#[derive(Debug, Clone, Copy)]
struct RotatedBox {
    min: Point,
    dims: [usize; 3],
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Extents of the rotated cloud for the rotations `indices` (entry `k` of the result is
/// `Some` for those, `None` for the others).
fn rotated_boxes(
    pool: &rayon::ThreadPool,
    cloud: &RotatableCloud,
    rows: &[[[f64; 3]; 3]],
    indices: &[usize],
    s: f64,
) -> Result<Vec<Option<RotatedBox>>> {
    use rayon::prelude::*;
    let computed: Vec<Result<RotatedBox>> = pool.install(|| {
        indices
            .par_iter()
            .map(|&k| {
                let r = &rows[k];
                let mut lo = [0.0; 3];
                let mut hi = [0.0; 3];
                for d in 0..3 {
                    (lo[d], hi[d]) = cloud.range(&r[d]);
                }
                let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
                Ok(RotatedBox {
                    min: lo,
                    dims: voxel::grid_dims(ext, s)?,
                })
            })
            .collect()
    });
    let mut boxes = vec![None; rows.len()];
    for (&k, b) in indices.iter().zip(computed) {
        boxes[k] = Some(b?);
    }
    Ok(boxes)
}

/// FFT geometry for kernel dims `nr` and the largest of `boxes`.
fn geometry_for(nr: [usize; 3], boxes: &[Option<RotatedBox>]) -> Geometry {
    let mut ns_max = [1usize; 3];
    for b in boxes.iter().flatten() {
        for d in 0..3 {
            ns_max[d] = ns_max[d].max(b.dims[d]);
        }
    }
    Geometry::new(nr, ns_max)
}

/// Occupancy of `target` shifted by `-min`, at voxel `s`.
fn target_kernel(target: &Cloud, min: Point, s: f64) -> Result<Occupancy> {
    let shifted: Vec<Point> = target
        .points
        .iter()
        .map(|p| [p[0] - min[0], p[1] - min[1], p[2] - min[2]])
        .collect();
    Occupancy::from_points(&shifted, [0.0; 3], s)
}

/// Run the coarse search of `source` against `target` over `set`.
pub fn coarse_register(
    source: &Cloud,
    target: &Cloud,
    set: &RotationSet,
    cfg: &SearchConfig,
) -> Result<SearchResult> {
    let t_start = Instant::now();
    let s = cfg.voxel;
    if !(s.is_finite() && s > 0.0) {
        return Err(GgsError::param(
            "voxel",
            format!("must be a positive number, got {s}"),
        ));
    }
    if cfg.top_k == 0 {
        return Err(GgsError::param("top_k", "must be at least 1"));
    }
    if set.is_empty() {
        return Err(GgsError::param("rotations", "the rotation set is empty"));
    }
    if let SearchMode::CoarseToFine(c) = &cfg.mode {
        c.validate()?;
    }
    source.ensure_not_empty("source")?;
    target.ensure_not_empty("target")?;
    let threads = crate::threads::resolve(cfg.threads);
    let budget = cfg.max_memory.unwrap_or_else(memory::default_budget);

    // Target: shift to min 0, kernel dims. Source: centre on its mean.
    let tb = target.aabb().expect("non-empty");
    let m_y = tb.min;
    let nr = voxel::grid_dims(tb.extent(), s)?;
    let representatives = representatives(source, s);
    let rc = RotatableCloud::new(representatives.as_ref().unwrap_or(source));
    let c_x = rc.centroid;
    let radius = rc
        .points
        .iter()
        .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
        .fold(0.0, f64::max);
    let sizes = MemoryModel {
        target_extent: tb.extent(),
        source_radius: radius,
        threads,
        points: rc.points.len(),
    };
    let early = Geometry::new(nr, [1, 1, 1]);
    let early_bytes = sizes.bytes(&early);
    if early_bytes > budget {
        return Err(sizes.error(&early, early_bytes, budget, s));
    }
    let rot_rows: Vec<[[f64; 3]; 3]> = set.matrices.iter().map(rows).collect();
    let n_rot = set.len();
    let (pool, _) = crate::threads::pool(threads)?;
    let mut times = StageTimes::default();

    // Coarse level (coarse-to-fine only): every rotation ranked at a coarser voxel.
    let t_coarse = Instant::now();
    let mut coarse_level = match &cfg.mode {
        SearchMode::Exhaustive => None,
        SearchMode::CoarseToFine(c) => {
            let (level, st) =
                coarse_candidates(&pool, threads, &rc, target, m_y, set, &rot_rows, cfg, c)?;
            times.add(&st);
            Some(level)
        }
    };
    let coarse_level_ms = ms(t_coarse.elapsed());

    // Rounds at the voxel size: all rotations (exhaustive), or the kept ones and their
    // neighbours, with `kept` doubled while the winner ranks in the lower half of it.
    let t_kernel = Instant::now();
    let kernel = target_kernel(target, m_y, s)?;
    debug_assert_eq!(kernel.dims, nr);
    let mut target_ms = ms(t_kernel.elapsed());
    let mut extents_ms = 0.0;
    let mut boxes: Vec<Option<RotatedBox>> = vec![None; n_rot];
    let mut scored = vec![false; n_rot];
    let mut scores = LevelScores::new(n_rot);
    let mut correlators: Option<(Geometry, CpuCorrelator<f64>, Option<CpuCorrelator<f32>>)> = None;
    let mut estimate = 0;
    let mut tally = Tally {
        times,
        ..Tally::default()
    };
    let progress = match cfg.mode {
        SearchMode::Exhaustive => cfg.progress.as_deref(),
        SearchMode::CoarseToFine(_) => None,
    };
    let t_search = Instant::now();
    let no_boxes: Vec<Option<RotatedBox>> = Vec::new();
    let base_input = PassInput {
        pool: &pool,
        threads,
        cloud: &rc,
        rows: &rot_rows,
        boxes: &no_boxes,
        voxel: s,
        cancel: cfg.cancel.as_ref(),
        progress: None,
    };
    let mut keep = coarse_level.as_ref().map_or(n_rot, |l| l.kept);
    let winner = loop {
        let wanted = match &coarse_level {
            None => (0..n_rot).collect::<Vec<_>>(),
            Some(level) => kept_with_neighbours(level, keep, set),
        };
        let new: Vec<usize> = wanted.into_iter().filter(|&k| !scored[k]).collect();
        let t_ext = Instant::now();
        for (k, b) in rotated_boxes(&pool, &rc, &rot_rows, &new, s)?
            .into_iter()
            .enumerate()
        {
            if b.is_some() {
                boxes[k] = b;
            }
        }
        extents_ms += ms(t_ext.elapsed());
        // FFT lengths fit the largest source scored so far; a later round with a larger one
        // re-plans (scores do not depend on the lengths).
        let geo = geometry_for(nr, &boxes);
        if correlators.as_ref().is_none_or(|(g, _, _)| *g != geo) {
            estimate = sizes.bytes(&geo);
            if estimate > budget {
                return Err(sizes.error(&geo, estimate, budget, s));
            }
            let t = Instant::now();
            let c64 = CpuCorrelator::<f64>::new(geo, &kernel);
            let c32 = match cfg.precision {
                Precision::Mixed => Some(CpuCorrelator::<f32>::from_f64(&c64)),
                Precision::F64 => None,
            };
            correlators = Some((geo, c64, c32));
            target_ms += ms(t.elapsed());
        }
        let (_, corr64, corr32) = correlators.as_ref().expect("planned above");
        let input = PassInput {
            boxes: &boxes,
            progress,
            ..base_input
        };
        match corr32 {
            Some(c32) => {
                let (found, st) = run_pass(&input, c32, &new, |c, ws| c.approx_best(ws))?;
                tally.times.add(&st);
                for (&k, a) in new.iter().zip(found) {
                    scores.approx[k] = Some(a);
                }
            }
            None => {
                let (found, st) = run_pass(&input, corr64, &new, |c, ws| c.best_offset(ws))?;
                tally.times.add(&st);
                for (&k, b) in new.iter().zip(found) {
                    scores.exact[k] = Some(b);
                }
            }
        }
        for &k in &new {
            scored[k] = true;
        }
        let quiet = PassInput {
            progress: None,
            ..input
        };
        let w = exact_best(
            &mut scores,
            |_| true,
            |p, sc| rescore_f64(&quiet, corr64, p, sc, &mut tally),
        )?
        .expect("at least one rotation is scored");
        if let Some(level) = &mut coarse_level {
            level.rounds += 1;
            level.kept = keep;
            level.winner_rank = level.rank[w];
            // A winner deep in the kept list means the coarse ranking is not clear for this
            // pair: look twice as far.
            if level.rank[w] * 2 > keep && scored.iter().any(|&d| !d) {
                keep = (keep * 2).min(n_rot);
                continue;
            }
        }
        break w;
    };
    let (geo, corr64, _) = correlators.expect("at least one round ran");
    let quiet = PassInput {
        progress: None,
        boxes: &boxes,
        ..base_input
    };
    let mut rescore = |p: &[usize], sc: &mut LevelScores| -> Result<()> {
        rescore_f64(&quiet, &corr64, p, sc, &mut tally)
    };
    let radius = cfg.distinct_radius_deg.unwrap_or(2.0 * set.step_deg);
    let far = |chosen: &[usize], k: usize| {
        chosen
            .iter()
            .all(|&c| rotation_angle_deg(&set.matrices[c], &set.matrices[k]) > radius)
    };
    let mut chosen = vec![winner];
    while chosen.len() < cfg.top_k.max(2) {
        match exact_best(&mut scores, |k| far(&chosen, k), &mut rescore)? {
            Some(k) => chosen.push(k),
            None => break,
        }
    }
    let runner_up_index = chosen.get(1).copied();
    chosen.truncate(cfg.top_k);
    let search_ms = ms(t_search.elapsed());

    let constant = corr64.kernel_cells - 6 * corr64.kernel_occupied;
    let hypothesis = |k: usize| -> Hypothesis {
        let b = scores.exact[k].expect("selected rotations have exact scores");
        let bx = boxes[k].expect("selected rotations have extents");
        let r = set.matrices[k];
        let mut t = -(r * Vector3::from(c_x));
        for d in 0..3 {
            t[d] += -bx.min[d] + (geo.center[d] as f64 - b.offset[d] as f64) * s + m_y[d];
        }
        Hypothesis {
            rotation_index: k,
            score: constant + 6 * b.match_score,
            match_score: b.match_score,
            offset: b.offset,
            transform: Rigid::new(r, t),
        }
    };
    let runner_up = runner_up_index.map(hypothesis);
    let win = hypothesis(winner);
    let ambiguity = match runner_up {
        Some(r) if win.match_score > 0 => Some(r.match_score as f64 / win.match_score as f64),
        _ => None,
    };
    Ok(SearchResult {
        transform: win.transform,
        rotation_index: winner,
        score: win.score,
        match_score: win.match_score,
        offset: win.offset,
        runner_up,
        ambiguity,
        distinct_radius_deg: radius,
        hypotheses: chosen.into_iter().map(hypothesis).collect(),
        voxel: s,
        rotation_set: set.name.clone(),
        rotations: n_rot,
        source_points: source.len(),
        searched_points: rc.points.len(),
        target_points: target.len(),
        target_occupied: corr64.kernel_occupied as usize,
        geometry: geo,
        threads,
        memory_estimate_bytes: estimate,
        max_rounding_error: tally.times.max_rounding_error,
        mode: cfg.mode,
        precision: cfg.precision,
        scored: scored.iter().filter(|&&d| d).count(),
        rescored: tally.rescored,
        coarse_level,
        fft_gflop: tally.times.flops * 1e-9,
        timings: Timings {
            target_ms,
            extents_ms,
            search_ms,
            total_ms: ms(t_start.elapsed()),
            cpu_voxelize_ms: ms(tally.times.voxelize),
            cpu_forward_ms: ms(tally.times.forward),
            cpu_product_ms: ms(tally.times.product),
            cpu_inverse_ms: ms(tally.times.inverse),
            coarse_level_ms,
            rescore_ms: ms(tally.rescore_time),
        },
    })
}

impl CoarseToFine {
    fn validate(&self) -> Result<()> {
        if !(self.factor.is_finite() && self.factor >= 1.0) {
            return Err(GgsError::param(
                "coarse factor",
                format!("must be a number ≥ 1, got {}", self.factor),
            ));
        }
        if !(self.keep_fraction.is_finite() && (0.0..=1.0).contains(&self.keep_fraction)) {
            return Err(GgsError::param(
                "keep fraction",
                format!("must be in [0, 1], got {}", self.keep_fraction),
            ));
        }
        if let Some(d) = self.neighbour_deg {
            if !(d.is_finite() && d >= 0.0) {
                return Err(GgsError::param(
                    "neighbour angle",
                    format!("must be a non-negative number of degrees, got {d}"),
                ));
            }
        }
        Ok(())
    }
}

/// Coarse level: score every rotation in f32 at `s0 = factor × voxel` with the source thinned
/// to one point (the mean) per cell of `s0/4`, and rank them (best first, ties to the lowest
/// index).
#[allow(clippy::too_many_arguments)]
fn coarse_candidates(
    pool: &rayon::ThreadPool,
    threads: usize,
    fine: &RotatableCloud,
    target: &Cloud,
    m_y: Point,
    set: &RotationSet,
    rot_rows: &[[[f64; 3]; 3]],
    cfg: &SearchConfig,
    c: &CoarseToFine,
) -> Result<(CoarseLevel, StageTimes)> {
    let s0 = cfg.voxel * c.factor;
    let n = rot_rows.len();
    let thinned = Cloud::new(voxel::cell_centroids(&fine.points, s0 / 4.0));
    let cloud = RotatableCloud::new(&thinned);
    let all: Vec<usize> = (0..n).collect();
    let boxes = rotated_boxes(pool, &cloud, rot_rows, &all, s0)?;
    let kernel = target_kernel(target, m_y, s0)?;
    let geo = geometry_for(kernel.dims, &boxes);
    let corr = CpuCorrelator::<f32>::new(geo, &kernel);
    let input = PassInput {
        pool,
        threads,
        cloud: &cloud,
        rows: rot_rows,
        boxes: &boxes,
        voxel: s0,
        cancel: cfg.cancel.as_ref(),
        progress: cfg.progress.as_deref(),
    };
    let (found, times) = run_pass(&input, &corr, &all, |c, ws| c.approx_best(ws))?;
    let mut order = all;
    order.sort_by(|&a, &b| found[b].value.total_cmp(&found[a].value).then(a.cmp(&b)));
    let keep = ((n as f64 * c.keep_fraction).ceil() as usize)
        .max(c.keep_min)
        .clamp(1, n);
    let neighbour_deg = c.neighbour_deg.unwrap_or(set.step_deg * 1.01);
    let mut rank = vec![0; n];
    for (r, &k) in order.iter().enumerate() {
        rank[k] = r;
    }
    Ok((
        CoarseLevel {
            voxel: s0,
            source_points: thinned.len(),
            geometry: geo,
            kept: keep,
            neighbour_deg,
            winner_rank: 0,
            rounds: 0,
            rank,
            order,
        },
        times,
    ))
}

/// The `keep` best rotations of the coarse order and every rotation within
/// `neighbour_deg` of one of them, in increasing index order. A keep of a quarter of the set
/// or more takes the whole set.
fn kept_with_neighbours(level: &CoarseLevel, keep: usize, set: &RotationSet) -> Vec<usize> {
    let n = level.order.len();
    if keep * 4 >= n {
        return (0..n).collect();
    }
    let kept = &level.order[..keep];
    let mut selected = vec![false; n];
    for &k in kept {
        selected[k] = true;
    }
    for k in 0..n {
        if !selected[k]
            && kept.iter().any(|&j| {
                rotation_angle_deg(&set.matrices[j], &set.matrices[k]) <= level.neighbour_deg
            })
        {
            selected[k] = true;
        }
    }
    (0..n).filter(|&k| selected[k]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::neighbors::PointIndex;

    /// A plane of `n` × `n` points `h` apart, slightly wavy.
    fn plane(n: usize, h: f64) -> Cloud {
        Cloud::new(
            (0..n * n)
                .map(|i| {
                    let (x, y) = ((i % n) as f64 * h, (i / n) as f64 * h);
                    [x, y, 0.1 * (3.0 * x).sin() * y]
                })
                .collect(),
        )
    }

    #[test]
    fn dense_sources_are_represented_within_the_bound_sparse_ones_as_they_are() {
        let s = 1.0;
        let dense = plane(200, 0.025);
        let reps = representatives(&dense, s).expect("25 points per cell");
        assert!(reps.len() * MIN_POINTS_PER_REPRESENTATIVE <= dense.len());
        let c = s / REPRESENTATIVE_DIVISIONS;
        let index = PointIndex::new(&reps.points);
        for p in &dense.points {
            assert!(index.nearest(p).1.sqrt() <= c * 3f64.sqrt(), "{p:?}");
        }
        assert!(representatives(&plane(40, 0.2), s).is_none());
    }

    #[test]
    fn the_search_on_representatives_finds_the_rotation_of_a_dense_pair() {
        let set = RotationSet::named("limited15").unwrap();
        let source = plane(300, 0.005);
        let k = 700;
        let truth = Rigid::new(set.matrices[k], Vector3::new(0.3, -0.2, 0.1));
        let target = source.transformed(&truth);
        let cfg = SearchConfig::with_voxel(0.15);
        let r = coarse_register(&source, &target, &set, &cfg).unwrap();
        assert!(
            r.searched_points * 4 <= r.source_points,
            "{}",
            r.searched_points
        );
        assert_eq!(r.rotation_index, k);
        assert!((r.transform.translation - truth.translation).norm() < 0.15);
    }
}
