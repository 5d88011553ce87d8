//! Fine registration from an initial transform: point-to-point, point-to-plane and generalized
//! ICP (docs/refinement.md), with a quality report.
//!
//! Every iteration pairs each moved source point `p' = T·p` with its nearest target point `q`
//! and keeps the pair when `‖p' − q‖ ≤ d_c` (the *correspondence distance*, fixed for the
//! run). The estimator then updates `T` (see `estimators`); the loop stops when the relative
//! changes of fitness and inlier RMSE both fall below their tolerances, when the update is
//! smaller than 1e-10 rad and 1e-10 × the cloud radius, or after `max_iterations`.
//!
//! # The figures of the quality report
//! All are computed at the final transform with the same `d_c`:
//! - `fitness_source`: fraction of source points whose nearest target point is within `d_c`
//!   (Open3D's "fitness"); `fitness_target`: fraction of target points whose nearest moved
//!   source point is within `d_c`. Their minimum says how much of the smaller overlap is
//!   explained; neither is an overlap ratio of the scenes.
//! - `inliers`: the count behind `fitness_source`.
//! - `inlier_rmse`: `sqrt(mean ‖p' − q‖²)` over those inliers, in cloud units (Euclidean,
//!   whatever the estimator minimized).
//! - `information_eigenvalues`: eigenvalues (ascending) of the point-to-plane information
//!   matrix `H = (1/n)·Σ JᵢᵀJᵢ`, `Jᵢ = [((p'ᵢ × nᵢ)/ρ)ᵀ  nᵢᵀ]` over the inliers, with `nᵢ` the
//!   target normal and `ρ` the source radius, so rotation and translation are both unitless.
//!   `degenerate` is set when `λ_min / λ_max < 1e-3`: some motion (sliding along a plane or a
//!   corridor, turning a sphere) changes the residuals by less than a thousandth of the
//!   best-constrained one, and the alignment along it is not determined by the data.

pub mod evaluate;
internal_modules!(covariance, estimators, grid, neighbors, prepared);

use crate::cloud::{Cloud, Point};
use crate::error::{GgsError, Result};
use crate::transform::Rigid;
use estimators::{exp_so3, kabsch, orthonormalize, KabschSums, NormalEquations};
use grid::RadiusSearch;
use nalgebra::{Matrix3, Matrix6, SymmetricEigen, Vector3};
use neighbors::PointIndex;
pub use prepared::PreparedPair;
use rayon::prelude::*;
use std::time::Instant;

/// Unit normals of the points of a cloud, each from its `neighbors` nearest points (itself
/// included): the eigenvector of the least eigenvalue of their covariance. The sign is
/// arbitrary. Each point is computed independently, so the result does not depend on the
/// thread count.
pub fn estimate_normals(points: &[Point], neighbors: usize) -> Vec<Vector3<f64>> {
    let index = PointIndex::new(points);
    covariance::local_shapes(points, &index, neighbors, 1e-3)
        .iter()
        .map(|s| s.normal)
        .collect()
}

/// The estimator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Point-to-point, closed form (weighted Kabsch) each iteration.
    P2p,
    /// Point-to-plane, Gauss-Newton with target normals.
    P2plane,
    /// Generalized ICP (plane-to-plane), Gauss-Newton.
    Gicp,
}

impl Method {
    /// The name used on the command line and in JSON.
    pub fn name(&self) -> &'static str {
        match self {
            Method::P2p => "p2p",
            Method::P2plane => "p2plane",
            Method::Gicp => "gicp",
        }
    }

    pub fn from_name(s: &str) -> Option<Method> {
        Some(match s {
            "p2p" => Method::P2p,
            "p2plane" => Method::P2plane,
            "gicp" => Method::Gicp,
            _ => return None,
        })
    }
}

/// Robust kernel applied to the correspondence distance `e`, as IRLS weights.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum RobustKernel {
    None,
    /// `w = 1` for `e ≤ k`, else `k/e`.
    Huber(f64),
    /// `w = 1/(1 + (e/k)²)`.
    Cauchy(f64),
    /// `w = (k²/(k² + e²))²`.
    GemanMcClure(f64),
}

impl RobustKernel {
    #[inline]
    pub fn weight(&self, e: f64) -> f64 {
        match *self {
            RobustKernel::None => 1.0,
            RobustKernel::Huber(k) => {
                if e <= k {
                    1.0
                } else {
                    k / e
                }
            }
            RobustKernel::Cauchy(k) => 1.0 / (1.0 + (e / k) * (e / k)),
            RobustKernel::GemanMcClure(k) => {
                let a = k * k / (k * k + e * e);
                a * a
            }
        }
    }
}

impl std::fmt::Display for RobustKernel {
    /// The form [`str::parse`] reads: `none`, `huber:K`, `cauchy:K`, `geman-mcclure:K`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RobustKernel::None => write!(f, "none"),
            RobustKernel::Huber(k) => write!(f, "huber:{k}"),
            RobustKernel::Cauchy(k) => write!(f, "cauchy:{k}"),
            RobustKernel::GemanMcClure(k) => write!(f, "geman-mcclure:{k}"),
        }
    }
}

impl std::str::FromStr for RobustKernel {
    type Err = GgsError;
    /// `none`, `huber:K`, `cauchy:K` or `geman-mcclure:K` (K > 0, cloud units).
    fn from_str(s: &str) -> Result<Self> {
        if s == "none" {
            return Ok(RobustKernel::None);
        }
        let bad = |why: String| GgsError::param("kernel", format!("'{s}': {why}"));
        let (name, k) = s
            .split_once(':')
            .ok_or_else(|| bad("expected NAME:K, e.g. huber:0.01".into()))?;
        let k: f64 = k
            .parse()
            .ok()
            .filter(|k: &f64| k.is_finite() && *k > 0.0)
            .ok_or_else(|| bad("K must be a positive number".into()))?;
        match name {
            "huber" => Ok(RobustKernel::Huber(k)),
            "cauchy" => Ok(RobustKernel::Cauchy(k)),
            "geman-mcclure" => Ok(RobustKernel::GemanMcClure(k)),
            _ => Err(bad(format!(
                "unknown kernel '{name}' (none, huber, cauchy, geman-mcclure)"
            ))),
        }
    }
}

/// How the correspondence distance `d_c` is chosen.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum CorrespondenceDistance {
    /// The `q` quantile (linear interpolation) of the source-to-target nearest-neighbour
    /// distances after the initial transform (the reference uses q = 0.25).
    Quantile(f64),
    /// A fixed distance in cloud units.
    Fixed(f64),
}

/// Parameters of a refinement.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct RefineConfig {
    pub method: Method,
    pub correspondence: CorrespondenceDistance,
    pub kernel: RobustKernel,
    /// Iteration cap (500 as the reference; converged runs stop far earlier).
    pub max_iterations: usize,
    /// Stop when `|Δfitness|/fitness` and `|Δrmse|/rmse` are both below these.
    pub relative_fitness: f64,
    pub relative_rmse: f64,
    /// Stop when an update rotates by less than this (radians) and moves by less than
    /// `min_translation_step` × the source radius.
    pub min_rotation_step: f64,
    pub min_translation_step: f64,
    /// Neighbours for normals and covariances.
    pub neighbors: usize,
    /// GICP covariance along the normal, ε.
    pub epsilon: f64,
    /// Worker threads (0 = all cores); the result does not depend on it.
    pub threads: usize,
}

/// The reference's correspondence-distance quantile: 0.25 of the nearest-neighbour distances
/// at the start.
pub const DEFAULT_DISTANCE_QUANTILE: f64 = 0.25;

impl Default for RefineConfig {
    fn default() -> Self {
        RefineConfig {
            method: Method::Gicp,
            correspondence: CorrespondenceDistance::Quantile(DEFAULT_DISTANCE_QUANTILE),
            kernel: RobustKernel::None,
            max_iterations: 500,
            relative_fitness: 1e-6,
            relative_rmse: 1e-6,
            min_rotation_step: 1e-10,
            min_translation_step: 1e-10,
            neighbors: 20,
            epsilon: 1e-3,
            threads: 0,
        }
    }
}

/// `degenerate` is set when `λ_min / λ_max` of the information matrix lies below this: a
/// motion the data barely constrains (a plane sliding, a corridor, a sphere turning).
pub const DEGENERATE_RATIO: f64 = 1e-3;

/// What the refinement achieved (see the module documentation for exact definitions).
#[derive(Debug, Clone, serde::Serialize)]
pub struct QualityReport {
    pub fitness_source: f64,
    pub fitness_target: f64,
    pub inlier_rmse: f64,
    pub inliers: usize,
    pub correspondence_distance: f64,
    pub iterations: usize,
    pub converged: bool,
    /// `relative change`, `small update`, `max iterations`, `too few correspondences`.
    pub stop_reason: String,
    pub information_eigenvalues: [f64; 6],
    pub degenerate: bool,
}

impl QualityReport {
    /// "converged" or "not converged", as the reports print it.
    pub fn convergence(&self) -> &'static str {
        if self.converged {
            "converged"
        } else {
            "not converged"
        }
    }
}

/// Result of a refinement.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RefineResult {
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub transform: Rigid,
    pub report: QualityReport,
    pub method: Method,
    /// k-d trees and local shapes.
    pub setup_ms: f64,
    pub iterate_ms: f64,
    pub total_ms: f64,
}

const CHUNK: usize = 1024;

/// `sqrt(sum_sq / n)`, 0 for no term: the RMS of `n` distances whose squares sum to `sum_sq`.
pub(crate) fn root_mean(sum_sq: f64, n: usize) -> f64 {
    if n > 0 {
        (sum_sq / n as f64).sqrt()
    } else {
        0.0
    }
}

#[inline]
fn v3(p: &Point) -> Vector3<f64> {
    Vector3::new(p[0], p[1], p[2])
}

/// Linear-interpolation quantile (`q ∈ [0, 1]`) of `values` (reordered in place): the
/// order statistics at `⌊pos⌋` and `⌈pos⌉`, `pos = q·(n − 1)`, found by selection (linear
/// time; the same values a full sort puts there).
pub fn quantile(values: &mut [f64], q: f64) -> f64 {
    let pos = q.clamp(0.0, 1.0) * (values.len() - 1) as f64;
    let lo = pos.floor() as usize;
    let hi = pos.ceil() as usize;
    let (_, &mut v_lo, above) = values.select_nth_unstable_by(lo, f64::total_cmp);
    // The next order statistic is the least of those above (if `hi` is past `lo`).
    let v_hi = if hi > lo {
        above.iter().copied().min_by(f64::total_cmp).unwrap_or(v_lo)
    } else {
        v_lo
    };
    v_lo + (v_hi - v_lo) * (pos - lo as f64)
}

/// The `q` quantile of the positive distances from each moved source point `T·p` to its
/// nearest target point (`None` when every distance is 0). Most source points of a coarse
/// alignment lie within a few point spacings of the target: those are found on a grid of
/// radius `r = QUANTILE_START·R`, with `R = start_radius` the target's median
/// k-th-neighbour distance (`None`: the tree measures every point); the others only count as
/// "farther than `r`" unless the quantile falls among them, when the points not found yet are
/// searched again within `2r`, `4r`, … (at most [`QUANTILE_ROUNDS`] times) and, if the
/// quantile still falls beyond, measured by the k-d tree. Every distance found is the exact
/// nearest-neighbour distance, so the result equals the all-tree computation.
fn nearest_distance_quantile(
    src: &[Point],
    t: &Rigid,
    tgt: &[Point],
    tindex: &PointIndex,
    start_radius: Option<f64>,
    q: f64,
) -> Option<f64> {
    let moved: Vec<Point> = src.iter().map(|p| t.apply(p)).collect();
    let mut dist = vec![f64::INFINITY; moved.len()];
    let mut pending: Vec<usize> = (0..moved.len()).collect();
    let positive_quantile = |dist: &[f64]| -> Option<f64> {
        let mut d: Vec<f64> = dist.iter().copied().filter(|&d| d > 0.0).collect();
        (!d.is_empty()).then(|| quantile(&mut d, q))
    };
    if let Some(r0) = start_radius {
        let mut r = r0 * QUANTILE_START;
        for _ in 0..QUANTILE_ROUNDS {
            let search = RadiusSearch::new(tgt, r, Some(tindex));
            let found: Vec<Option<f64>> = pending
                .par_iter()
                .map(|&i| search.nearest(&moved[i]).map(|n| n.1.sqrt()))
                .collect();
            let mut still = Vec::new();
            for (&i, d) in pending.iter().zip(found) {
                match d {
                    Some(d) => dist[i] = d,
                    None => still.push(i),
                }
            }
            pending = still;
            match positive_quantile(&dist) {
                None => return None,
                Some(v) if v.is_finite() => return Some(v),
                Some(_) => r *= 2.0,
            }
        }
    }
    let exact: Vec<f64> = pending
        .par_iter()
        .map(|&i| tindex.nearest(&moved[i]).1.sqrt())
        .collect();
    for (&i, d) in pending.iter().zip(exact) {
        dist[i] = d;
    }
    positive_quantile(&dist)
}

/// Iterations remembered to detect a settled loop: a state (fitness, RMSE) repeating within
/// this many iterations is a cycle of correspondences flipping in and out (cycles of 3
/// iterations seen on the Stanford bunny scans ran to the 500-iteration cap before).
const SETTLE_HISTORY: usize = 8;

/// Radius rounds of [`nearest_distance_quantile`] before the k-d tree measures the rest.
const QUANTILE_ROUNDS: usize = 6;

/// The first round's radius, in the target's median k-th-neighbour distances `R`;
/// the rounds then double it up to `16R`. A query scans about `r²` worth of surface, and
/// from a good pose a quarter of the points lie far inside `R` (the bunny pair's final GICP:
/// the quantile is `R/7`), so starting at `R/2` makes that search 12 → 3 ms; from a coarse
/// hypothesis the quantile is about `R/3` and the round at `R/2` mostly finds it. (At `R/4`
/// the finer grid costs more to build than the search saves.) The result does not depend on
/// it.
const QUANTILE_START: f64 = 0.5;

/// Per-iteration statistics at the current pose.
#[derive(Default, Clone, Copy)]
struct Stats {
    inliers: usize,
    sq_sum: f64,
}

/// Refine `init` so that `target ≈ T·source`.
pub fn refine(
    source: &Cloud,
    target: &Cloud,
    init: &Rigid,
    cfg: &RefineConfig,
) -> Result<RefineResult> {
    let pair = PreparedPair::new(source, target, cfg.neighbors, cfg.epsilon)?;
    refine_prepared(&pair, init, cfg)
}

/// Refine `init` on a prepared pair: its trees and local shapes are built by the first call
/// and reused by the next ones (same results as [`refine`] on the pair's clouds).
/// `cfg.neighbors` and `cfg.epsilon` must be the pair's.
pub fn refine_prepared(
    pair: &PreparedPair,
    init: &Rigid,
    cfg: &RefineConfig,
) -> Result<RefineResult> {
    let mut r = with_started_run(pair, init, cfg, |started, init_l| {
        let t1 = Instant::now();
        let run = started.iterate(pair, init_l, cfg);
        let iterate_ms = t1.elapsed().as_secs_f64() * 1e3;
        let report = quality(pair, &started.tsearch, &run, started.d_c, started.radius);
        RefineResult {
            transform: run.transform,
            report,
            method: cfg.method,
            setup_ms: started.setup_ms,
            iterate_ms,
            total_ms: started.setup_ms + t1.elapsed().as_secs_f64() * 1e3,
        }
    })?;
    r.transform = pair.to_global(&r.transform);
    Ok(r)
}

/// Where a refinement ended, without its quality report (which costs another pass over
/// both clouds): what a run that is only a step of a larger procedure needs.
#[derive(Debug, Clone, Copy)]
pub struct RefinedPose {
    pub transform: Rigid,
    pub iterations: usize,
    pub converged: bool,
}

/// [`refine_prepared`]'s pose, iterations and convergence, without the quality report.
pub fn refine_prepared_pose(
    pair: &PreparedPair,
    init: &Rigid,
    cfg: &RefineConfig,
) -> Result<RefinedPose> {
    let run = with_started_run(pair, init, cfg, |started, init_l| {
        started.iterate(pair, init_l, cfg)
    })?;
    Ok(RefinedPose {
        transform: pair.to_global(&run.transform),
        iterations: run.iterations,
        converged: run.converged,
    })
}

/// `f(started run, init in the pair's frame)` on `cfg.threads`, once `cfg` is checked
/// against the pair and the run from `init` is started ([`start_run`]).
fn with_started_run<R: Send>(
    pair: &PreparedPair,
    init: &Rigid,
    cfg: &RefineConfig,
    f: impl FnOnce(&StartedRun, &Rigid) -> R + Send,
) -> Result<R> {
    check_config(pair, cfg)?;
    let init_l = pair.to_local(init);
    crate::threads::in_pool(cfg.threads, || {
        Ok(f(&start_run(pair, &init_l, cfg)?, &init_l))
    })?
}

/// The pair was prepared for the config's neighbours and ε, and the correspondence distance
/// is valid.
fn check_config(pair: &PreparedPair, cfg: &RefineConfig) -> Result<()> {
    if cfg.neighbors != pair.neighbors || cfg.epsilon != pair.epsilon {
        return Err(GgsError::param(
            "neighbors",
            format!(
                "the pair was prepared for {} neighbours and ε {}, the refinement asks for {} and {}",
                pair.neighbors, pair.epsilon, cfg.neighbors, cfg.epsilon
            ),
        ));
    }
    match cfg.correspondence {
        CorrespondenceDistance::Quantile(q) if !(0.0..=1.0).contains(&q) => Err(GgsError::param(
            "correspondence",
            format!("quantile must be in [0, 1], got {q}"),
        )),
        CorrespondenceDistance::Fixed(d) if !(d.is_finite() && d > 0.0) => Err(GgsError::param(
            "correspondence",
            format!("distance must be positive, got {d}"),
        )),
        _ => Ok(()),
    }
}

/// The correspondence distance of a run from `t` (`None`: every source point already sits on
/// a target point, nothing to refine).
fn correspondence_distance(pair: &PreparedPair, t: &Rigid, cfg: &RefineConfig) -> Option<f64> {
    match cfg.correspondence {
        CorrespondenceDistance::Fixed(d) => Some(d),
        // Quantile of the positive distances: points that already coincide (duplicated
        // scans, tiny clouds) must not drive d_c to 0.
        CorrespondenceDistance::Quantile(q) => nearest_distance_quantile(
            &pair.source.points,
            t,
            &pair.target.points,
            pair.target.index(),
            pair.target.median_kth_distance(),
            q,
        ),
    }
}

/// A refinement ready to iterate: the correspondence distance `d_c` of its start (`None`:
/// every source point already sits on a target point), the target indexed for it, and the
/// source's radius about its centroid (the translation step's unit).
struct StartedRun<'a> {
    /// Time to start it (trees, shapes, `d_c`, the index), in ms.
    setup_ms: f64,
    d_c: f64,
    exact: bool,
    tsearch: RadiusSearch<'a>,
    radius: f64,
}

/// Trees, local shapes and the correspondence distance of a run from `init` (pair frame).
fn start_run<'a>(
    pair: &'a PreparedPair,
    init: &Rigid,
    cfg: &RefineConfig,
) -> Result<StartedRun<'a>> {
    let t0 = Instant::now();
    pair.prepare(cfg.method == Method::Gicp);
    tracing::debug!(
        ms = t0.elapsed().as_secs_f64() * 1e3,
        "trees and shape grids"
    );
    let src = &pair.source.points;
    let centroid = crate::cloud::centroid_of(src).expect("non-empty");
    let radius = src
        .iter()
        .map(|p| (v3(p) - v3(&centroid)).norm())
        .fold(0.0, f64::max)
        .max(1e-12);
    let d_c = correspondence_distance(pair, init, cfg);
    tracing::debug!(
        ms = t0.elapsed().as_secs_f64() * 1e3,
        "correspondence distance"
    );
    let exact = d_c.is_none();
    let d_c = d_c.unwrap_or(f64::MIN_POSITIVE);
    if !(d_c.is_finite() && d_c > 0.0) {
        return Err(GgsError::param(
            "correspondence",
            format!("correspondence distance is {d_c}: the clouds coincide or are degenerate; pass a fixed distance"),
        ));
    }
    let tsearch = RadiusSearch::new(&pair.target.points, d_c, Some(pair.target.index()));
    Ok(StartedRun {
        setup_ms: t0.elapsed().as_secs_f64() * 1e3,
        d_c,
        exact,
        tsearch,
        radius,
    })
}

impl StartedRun<'_> {
    /// The ICP loop from `init` (see [`iterate`]), or no iteration when the start is exact.
    fn iterate(&self, pair: &PreparedPair, init: &Rigid, cfg: &RefineConfig) -> Run {
        if self.exact {
            return Run {
                transform: *init,
                iterations: 0,
                converged: true,
                stop_reason: "exact overlap".into(),
            };
        }
        iterate(pair, &self.tsearch, init, self.radius, cfg)
    }
}

/// Where the iterations ended.
struct Run {
    transform: Rigid,
    iterations: usize,
    converged: bool,
    stop_reason: String,
}

/// The correspondence sums of every source point at `t`: inlier statistics, and the
/// estimator's (normal equations, or Kabsch sums for point-to-point). Accumulated in fixed
/// chunks summed in order, so independent of the thread count.
///
/// `hints[i]` is source point `i`'s correspondence at the previous iteration ([`NO_HINT`]:
/// none); the search starts from it ([`RadiusSearch::nearest_near`], the same answer) and
/// it is replaced by this iteration's.
fn accumulate(
    pair: &PreparedPair,
    tsearch: &RadiusSearch,
    t: &Rigid,
    cfg: &RefineConfig,
    hints: &mut [u32],
) -> (Stats, NormalEquations, KabschSums) {
    let parts: Vec<(Stats, NormalEquations, KabschSums)> = pair
        .source
        .points
        .par_chunks(CHUNK)
        .zip(hints.par_chunks_mut(CHUNK))
        .enumerate()
        .map(|(ci, (chunk, hint))| {
            // The chunk's correspondences first, then the local shapes they need in one
            // batch per cloud (each grid cell's candidates gathered once), then the sums.
            let found = correspondences(pair, tsearch, t, ci * CHUNK, chunk, hint);
            if cfg.method == Method::Gicp {
                pair.source.ensure_shapes(found.iter().map(|f| f.source));
            }
            if cfg.method != Method::P2p {
                pair.target.ensure_shapes(found.iter().map(|f| f.target));
            }
            chunk_sums(pair, t, cfg, &found)
        })
        .collect();
    let mut st = Stats::default();
    let mut ne = NormalEquations::default();
    let mut ks = KabschSums::default();
    for (s, n, k) in &parts {
        st.inliers += s.inliers;
        st.sq_sum += s.sq_sum;
        ne.add(n);
        ks.add(k);
    }
    (st, ne, ks)
}

/// A source point within the correspondence distance of a target point.
struct Correspondence {
    source: usize,
    target: usize,
    /// Squared distance.
    dd: f64,
    /// The source point moved by the current transform.
    moved: Vector3<f64>,
}

/// The correspondences of the source points `first..first + chunk.len()` at `t`, in order,
/// with their hints updated (see [`accumulate`]).
fn correspondences(
    pair: &PreparedPair,
    tsearch: &RadiusSearch,
    t: &Rigid,
    first: usize,
    chunk: &[Point],
    hint: &mut [u32],
) -> Vec<Correspondence> {
    let tgt = &pair.target.points;
    let mut found = Vec::new();
    for (k, p) in chunk.iter().enumerate() {
        let pm = t.rotation * v3(p) + t.translation;
        let near = (hint[k] != NO_HINT).then(|| &tgt[hint[k] as usize]);
        let nearest = tsearch.nearest_near(&[pm.x, pm.y, pm.z], near);
        hint[k] = nearest.map_or(NO_HINT, |(j, _)| u32::try_from(j).unwrap_or(NO_HINT));
        if let Some((j, dd)) = nearest {
            found.push(Correspondence {
                source: first + k,
                target: j,
                dd,
                moved: pm,
            });
        }
    }
    found
}

/// The sums of one chunk's correspondences, in order.
fn chunk_sums(
    pair: &PreparedPair,
    t: &Rigid,
    cfg: &RefineConfig,
    found: &[Correspondence],
) -> (Stats, NormalEquations, KabschSums) {
    let r = t.rotation;
    let mut st = Stats::default();
    let mut ne = NormalEquations::default();
    let mut ks = KabschSums::default();
    for c in found {
        let (pm, dd) = (c.moved, c.dd);
        st.inliers += 1;
        st.sq_sum += dd;
        let q = v3(&pair.target.points[c.target]);
        match cfg.method {
            Method::P2p => ks.push(&pm, &q, cfg.kernel.weight(dd.sqrt())),
            Method::P2plane => {
                let n = &pair.target.shape(c.target).normal;
                let res = n.dot(&(pm - q)).abs();
                ne.add_point_to_plane(&pm, &q, n, cfg.kernel.weight(res));
            }
            Method::Gicp => {
                let cs = &pair.source.shape(c.source).covariance;
                let m = pair.target.shape(c.target).covariance + r * cs * r.transpose();
                let m = m.try_inverse().unwrap_or_else(Matrix3::identity);
                ne.add_gicp(&pm, &q, &m, cfg.kernel.weight(dd.sqrt()));
            }
        }
    }
    (st, ne, ks)
}

/// No correspondence at the previous iteration (see [`accumulate`]).
const NO_HINT: u32 = u32::MAX;

/// The ICP loop from `init` at the correspondence distance of `tsearch` (see the module
/// documentation for the stopping rules).
fn iterate(
    pair: &PreparedPair,
    tsearch: &RadiusSearch,
    init: &Rigid,
    radius: f64,
    cfg: &RefineConfig,
) -> Run {
    let n_source = pair.source.points.len();
    let min_pairs = if cfg.method == Method::P2p { 3 } else { 6 };
    // (fitness, rmse) of the last SETTLE_HISTORY iterations: a repeat of any means the loop
    // has settled (a cycle, where a few correspondences flip in and out, counts too).
    let mut history: Vec<(f64, f64)> = Vec::with_capacity(SETTLE_HISTORY);
    let mut run = Run {
        transform: *init,
        iterations: 0,
        converged: false,
        stop_reason: "max iterations".into(),
    };
    let stop = |run: &mut Run, converged: bool, why: &str| {
        run.converged = converged;
        run.stop_reason = why.into();
    };
    let mut hints = vec![NO_HINT; n_source];
    for _ in 0..cfg.max_iterations {
        let t = run.transform;
        let (st, ne, ks) = accumulate(pair, tsearch, &t, cfg, &mut hints);
        if st.inliers < min_pairs {
            stop(&mut run, false, "too few correspondences");
            break;
        }
        let fitness = st.inliers as f64 / n_source as f64;
        let rmse = (st.sq_sum / st.inliers as f64).sqrt();
        let settled = history.iter().any(|&(pf, pr)| {
            (fitness - pf).abs() / fitness.max(1e-300) < cfg.relative_fitness
                && (rmse - pr).abs() / rmse.max(1e-300) < cfg.relative_rmse
        });
        if settled {
            stop(&mut run, true, "relative change");
            break;
        }
        if history.len() == SETTLE_HISTORY {
            history.remove(0);
        }
        history.push((fitness, rmse));
        run.iterations += 1;
        let update = match cfg.method {
            Method::P2p => kabsch(&ks).ok_or("too few correspondences"),
            _ => ne
                .solve()
                .map(|xi| {
                    let w = Vector3::new(xi[0], xi[1], xi[2]);
                    (exp_so3(&w), Vector3::new(xi[3], xi[4], xi[5]))
                })
                .ok_or("singular system"),
        };
        let (dr, dt) = match update {
            Ok(u) => u,
            Err(why) => {
                stop(&mut run, false, why);
                break;
            }
        };
        let rotation = orthonormalize(&(dr * t.rotation));
        run.transform = Rigid::new(rotation, dr * t.translation + dt);
        let step_rad = estimators::rotation_angle_rad(&dr);
        tracing::debug!(
            iteration = run.iterations,
            fitness,
            rmse,
            step_rad,
            step_t = dt.norm(),
            "refine"
        );
        if step_rad < cfg.min_rotation_step && dt.norm() < cfg.min_translation_step * radius {
            stop(&mut run, true, "small update");
            break;
        }
    }
    run
}

/// The quality report at the run's final transform (see the module documentation).
fn quality(
    pair: &PreparedPair,
    tsearch: &RadiusSearch,
    run: &Run,
    d_c: f64,
    radius: f64,
) -> QualityReport {
    let (src, tgt, t) = (&pair.source.points, &pair.target.points, &run.transform);
    let moved: Vec<Point> = src.iter().map(|p| t.apply(p)).collect();
    let parts: Vec<(usize, f64, Matrix6<f64>)> = moved
        .par_chunks(CHUNK)
        .map(|chunk| {
            let found: Vec<(&Point, usize, f64)> = chunk
                .iter()
                .filter_map(|p| tsearch.nearest(p).map(|(j, dd)| (p, j, dd)))
                .collect();
            // The target normals of the chunk in one batch (see `accumulate`).
            pair.target.ensure_shapes(found.iter().map(|f| f.1));
            let mut sq = 0.0;
            let mut h = Matrix6::zeros();
            for &(p, j, dd) in &found {
                sq += dd;
                let n = pair.target.shape(j).normal;
                let a = v3(p).cross(&n) / radius;
                let jv = nalgebra::Vector6::new(a.x, a.y, a.z, n.x, n.y, n.z);
                h += jv * jv.transpose();
            }
            (found.len(), sq, h)
        })
        .collect();
    let (mut inliers, mut sq, mut h) = (0usize, 0.0, Matrix6::zeros());
    for (n, s, m) in &parts {
        inliers += n;
        sq += s;
        h += m;
    }
    let msearch = RadiusSearch::new(&moved, d_c, None);
    let target_in: usize = tgt
        .par_chunks(CHUNK)
        .map(|c| c.iter().filter(|q| msearch.nearest(q).is_some()).count())
        .collect::<Vec<_>>()
        .iter()
        .sum();
    let mut eig = [0.0; 6];
    let mut degenerate = true;
    if inliers > 0 {
        h /= inliers as f64;
        let e = SymmetricEigen::new(h).eigenvalues;
        let mut v: Vec<f64> = e.iter().copied().collect();
        v.sort_by(f64::total_cmp);
        eig.copy_from_slice(&v);
        // NaN eigenvalues count as degenerate.
        degenerate =
            eig[0].partial_cmp(&(DEGENERATE_RATIO * eig[5])) != Some(std::cmp::Ordering::Greater);
    }
    QualityReport {
        fitness_source: inliers as f64 / src.len() as f64,
        fitness_target: target_in as f64 / tgt.len() as f64,
        inlier_rmse: root_mean(sq, inliers),
        inliers,
        correspondence_distance: d_c,
        iterations: run.iterations,
        converged: run.converged,
        stop_reason: run.stop_reason.clone(),
        information_eigenvalues: eig,
        degenerate,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A jittered 8×8×8 grid of unit spacing.
    fn grid_cloud(seed: u64) -> Cloud {
        let mut next = crate::test_rng::uniform(seed);
        let cells = (0..512usize).map(|n| [n / 64, n / 8 % 8, n % 8]);
        Cloud::new(cells.map(|c| c.map(|i| i as f64 + 0.2 * next())).collect())
    }

    /// One point-to-point iteration with the true pairs is the Kabsch solution.
    #[test]
    fn one_point_to_point_step_equals_kabsch() {
        let source = grid_cloud(9);
        let truth = Rigid::new(
            exp_so3(&Vector3::new(0.004, 0.002, -0.003)),
            Vector3::new(0.01, -0.02, 0.015),
        );
        let target = source.transformed(&truth);
        // Spacing 1, motion ≪ 0.5: nearest neighbours are the true pairs.
        let mut sums = KabschSums::default();
        for (p, q) in source.to_points().iter().zip(&target.to_points()) {
            sums.push(&Vector3::from(*p), &Vector3::from(*q), 1.0);
        }
        let (r, t) = kabsch(&sums).unwrap();
        let cfg = RefineConfig {
            method: Method::P2p,
            correspondence: CorrespondenceDistance::Fixed(0.5),
            max_iterations: 1,
            ..RefineConfig::default()
        };
        let out = refine(&source, &target, &Rigid::identity(), &cfg).unwrap();
        assert!((out.transform.rotation - r).abs().max() < 1e-12);
        assert!((out.transform.translation - t).norm() < 1e-12);
        // The clouds hold f32 offsets (see `Cloud`): each coordinate of this 8-unit grid is
        // off by at most 8 · 2⁻²⁴ ≈ 5e-7, so the exact motion is recovered to about that.
        let (rre, rte) = (
            crate::metrics::rre(&out.transform, &truth),
            crate::metrics::rte(&out.transform, &truth),
        );
        assert!(rre < 1e-4 && rte < 2e-6, "{rre} {rte}");
    }

    /// Selection gives the values a full sort puts at `⌊pos⌋` and `⌈pos⌉`, ties included.
    #[test]
    fn quantile_by_selection_equals_the_sorted_one() {
        let mut next = crate::test_rng::uniform(11);
        for n in [1usize, 2, 3, 10, 101, 1000] {
            // Coarse values (many ties) and fine ones.
            for ties in [true, false] {
                let values: Vec<f64> = (0..n)
                    .map(|_| if ties { (next() * 5.0).floor() } else { next() })
                    .collect();
                let mut sorted = values.clone();
                sorted.sort_by(f64::total_cmp);
                for q in [0.0, 0.1, 0.25, 0.5, 0.77, 1.0] {
                    let pos = q * (n - 1) as f64;
                    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
                    let want = sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64);
                    let got = quantile(&mut values.clone(), q);
                    assert_eq!(got.to_bits(), want.to_bits(), "n {n} q {q} ties {ties}");
                }
            }
        }
    }

    /// The grid rounds (R/4, R/2, …) and the tree give exactly the all-tree quantile, whether the
    /// quantile falls near (first round), farther out (a later round) or beyond every round.
    #[test]
    fn distance_quantile_equals_the_all_tree_computation() {
        let mut next = crate::test_rng::uniform(9);
        let tgt: Vec<Point> = (0..3000).map(|_| [next(), next(), 0.2 * next()]).collect();
        let tindex = PointIndex::new(&tgt);
        for (shift, q) in [
            (0.0, 0.25),
            (0.05, 0.25),
            (0.3, 0.5),
            (0.3, 0.9),
            (3.0, 0.25),
            (3.0, 0.9),
            (0.02, 0.9),
        ] {
            let src: Vec<Point> = (0..2000)
                .map(|i| {
                    let far = if i % 3 == 0 { shift } else { 0.0 };
                    [next() + far, next(), 0.2 * next() + 0.01]
                })
                .collect();
            let t = Rigid::identity();
            let mut all: Vec<f64> = src
                .iter()
                .map(|p| tindex.nearest(p).1.sqrt())
                .filter(|&d| d > 0.0)
                .collect();
            let expected = quantile(&mut all, q);
            let r0 = grid::median_kth_distance(&tgt, &tindex, 20);
            let got = nearest_distance_quantile(&src, &t, &tgt, &tindex, r0, q).unwrap();
            assert_eq!(got.to_bits(), expected.to_bits(), "shift {shift} q {q}");
        }
    }
}
