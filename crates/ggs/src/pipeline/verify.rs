//! Hypothesis verification: refine several distinct coarse hypotheses and keep the one that
//! explains both clouds best at one fixed distance.
//!
//! # The verification score
//! For a pose `T` and a distance `D` (the same for every hypothesis of a pair):
//!
//! `f_s = Σ_{p ∈ S} w(d_p) / |S|` with `d_p = min_q ‖T·p − q‖`, `f_t` the same over the target
//! points with the distances to the moved source, `score = (f_s + f_t) / 2`, and
//! `w(d) = 1 − d²/D²` for `d ≤ D`, 0 beyond ([`VerifyScore::Tight`], the default): a point
//! counts by how close it lies. With `w = 1` within `D` ([`VerifyScore::Fitness`]) `f_s` and
//! `f_t` are the shares of points within `D`, and a front/back flip of a partial view (the
//! whole surface within `D`, none of it close) outscores the right pose (the overlap, close):
//! on the generated low-overlap human pairs the right pose was verified but lost for about
//! one failure in six (docs/pipeline.md, "The verification score"). Weights are integers in
//! units of 2⁻²⁰ and summed as integers, so the score does not depend on the thread count.
//! [`VerifyScore::Oriented`] counts a point as `Tight` does only where its normal and its
//! nearest neighbour's face the same way (`(R·n_p)·n_q ≥ 0`; normals from 10 neighbours,
//! turned away from their cloud's centroid): not the default, since that rule orients
//! non-convex views badly (docs/pipeline.md, "Where the remaining failures come from").
//!
//! Where a cloud is a scan from its origin ([`super::free_space::origin_is_scanner`]), the
//! other cloud's points must not lie in the space it saw through: with `v` the share of the
//! summed points that do (the mean over the sides checked; [`super::free_space::RangeImage`],
//! margin `m` = `free_space_margin_voxels · s`),
//! `score = max(0, (f_s + f_t)/2 − λ · max(0, v − v₀))` (`λ` = `free_space_weight`, `v₀` =
//! `free_space_tolerance`). On scenes a turn that lays ground on ground overlaps as well as
//! the right pose and is told apart only by this (docs/pipeline.md, "Free space").
//!
//! The sums run over the source points `S` and the target points (each an evenly strided
//! sample of at most [`SAMPLE_POINTS`] points of the full cloud); the nearest neighbours `q`
//! are searched among every point of the other cloud (up to [`INDEX_POINTS`]).
//! `D = max(distance_voxels · s, spacing_factor · ρ, scan_distance_fraction · r)`, with `s`
//! the voxel size, `ρ` the target's median distance from a point to its nearest other point
//! and `r` the median range of a cloud taken as a scan (the larger of the two; 0 for no
//! scan): a fraction of the voxel, so that a pose that is only roughly right scores low, but
//! never below the point spacing, where every pose would score low, nor, on scans, below
//! the scale at which a scene's surfaces agree (vegetation, range noise, things moved between
//! scans), where a turn that lays ground on ground fits more points than the right pose. The
//! correspondence distance of each ICP run is not used: it is chosen from the run's own
//! start, so a wrong start gets a large one and a high fitness.
//!
//! # The procedure
//! Hypotheses are taken in coarse rank order. Each is polished ([`super::polish`]), refined by
//! GICP on both clouds thinned to one point per cell of `cell_voxels · s` (the
//! correspondence distance of each run is the reference's 0.25 quantile at its start) for
//! `check_iterations`, scored, and dropped if its score is below `reject_ratio` times the best
//! so far (a wrong start stops there); otherwise refined again from where it stopped (the
//! quantile, taken anew, is smaller: a schedule from a larger distance down) for
//! `max_iterations − check_iterations` more, and scored. The best score wins; ties go to
//! the better coarse rank. The part before the check depends on the hypothesis alone
//! ([`first_stage`]), so the pipeline runs it for every hypothesis side by side and takes the
//! decisions ([`finish`]) in rank order, with the same outcome.

use super::free_space::{scan_median_range, RangeImage};
use crate::cloud::{Cloud, Point};
use crate::error::{GgsError, Result};
use crate::refine::grid::RadiusSearch;
use crate::refine::{refine_prepared_pose, PreparedPair, RefineConfig, RefinedPose};
use crate::transform::Rigid;
use rayon::prelude::*;

/// At most this many points of each cloud are used to compute a verification score (the
/// sums run over them).
pub const SAMPLE_POINTS: usize = 20_000;

/// At most this many points of each cloud are searched for a sample point's nearest
/// neighbour: every point of a cloud up to this size. A sampled index would lie farther from
/// the sample points than the cloud does: at a stride of 2 the nearest neighbour of a point
/// of the right pose is up to one point spacing ρ away instead of a fraction of it, which
/// cost `w` up to 1 − ρ²/D² = 0.75 at the former D = 2ρ, and the right pose of a low-overlap
/// pair, which fits closely, lost to a flip that fits loosely (bunny_ear_back_bun270).
pub const INDEX_POINTS: usize = 400_000;

/// The subsample estimate at the check ([`finish`]) sums `⌈n/k⌉` points of each sample of `n`,
/// drawn at random (a fixed seed), with `k` the largest whole number that leaves at least this many
/// points of each side (no subsample when `k` would be 1).
pub const SUBSAMPLE_POINTS: usize = 2_000;

/// Seed of the subsample's draw ([`Verifier::subsample_evidence`]): fixed, so a run is
/// reproducible.
const SUBSAMPLE_SEED: u64 = 0x6767_735f_676c_616e;

/// A hypothesis whose subsample estimate plus this many of its standard errors
/// ([`Evidence::standard_error`]) scores below the rejection threshold (`reject_ratio × best
/// so far`) is rejected on the subsample alone.
pub const SUBSAMPLE_SIGMAS: f64 = 6.0;

/// Parameters of the verification.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct VerifyConfig {
    /// Verify every distinct hypothesis whose coarse match score is at least `margin` times
    /// the winner's (the winner always).
    pub margin: f64,
    /// At most this many hypotheses.
    pub max_hypotheses: usize,
    /// `D` is at least this many voxels.
    pub distance_voxels: f64,
    /// `D` is at least this many target point spacings.
    pub spacing_factor: f64,
    /// `D` is at least this fraction of the median range of a cloud taken as a scan from
    /// its origin (the larger of the two): a scene's surfaces are rough, noisy and partly
    /// moved at that scale, and a smaller `D` rewards laying ground on ground.
    pub scan_distance_fraction: f64,
    /// ICP of the verification runs on clouds thinned to cells of this many voxels.
    pub cell_voxels: f64,
    /// ICP iterations before a hypothesis is compared with the best so far.
    pub check_iterations: usize,
    /// ICP iterations in all, per hypothesis.
    pub max_iterations: usize,
    /// A hypothesis scoring below this fraction of the best so far at the check stops.
    pub reject_ratio: f64,
    /// Contested poses (two distinct ones scoring at least `settle_ratio` × the best) are
    /// refined again on clouds thinned to cells of this many voxels (0: never).
    pub fine_cell_voxels: f64,
    /// ICP iterations of that second refinement.
    pub fine_iterations: usize,
    /// Its fixed correspondence distance, in voxels (0: the refinement's own rule).
    pub fine_distance_voxels: f64,
    /// A hypothesis scoring at least this fraction of the best is a contender of that second
    /// refinement, stopped at its check or not.
    pub settle_ratio: f64,
    /// Two distinct poses whose scores are within this ratio make the result ambiguous.
    pub ambiguous_ratio: f64,
    /// How a point within `D` counts.
    pub score: VerifyScore,
    /// `λ`: the score loses `λ · max(0, v − v₀)` for a share `v` of points lying in the free
    /// space seen by the other cloud (a scan from its origin, [`super::free_space`]).
    pub free_space_weight: f64,
    /// `v₀`: the share of points that may lie in the other scan's free space at the right
    /// pose (moving objects, glass, vegetation, range noise) before the score loses any.
    pub free_space_tolerance: f64,
    /// The free-space margin `m` in voxels: a point violates the free space when it lies at
    /// least this far in front of the nearest surface seen in its direction.
    pub free_space_margin_voxels: f64,
    /// The least score a pose must reach to be of use to the caller (0: any). A hypothesis
    /// scoring below `reject_ratio` × the larger of this and the best so far at its check
    /// stops there, and only poses at or above `reject_ratio` × it are contested. Not a
    /// setting: [`crate::align`] sets it from the overlap a placement needs.
    pub least_score: f64,
}

/// How a point within `D` of the other cloud counts in the verification score.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VerifyScore {
    /// `w(d) = 1`: the share of points within `D` (Open3D's fitness).
    Fitness,
    /// `w(d) = 1 − d²/D²`: a point counts by how close it lies, so a small overlap that fits
    /// exactly beats a large one that fits loosely (a front/back flip of a partial view).
    Tight,
    /// `Tight`, counted only where the two points face the same way: their normals (from
    /// their nearest points, oriented away from their cloud's centroid) have a positive dot
    /// product once the source's is turned by `R`.
    Oriented,
}

impl VerifyScore {
    /// The names `--verify-score` takes.
    pub const NAMES: [&'static str; 3] = ["tight", "fitness", "oriented"];
}

impl std::str::FromStr for VerifyScore {
    type Err = crate::GgsError;
    /// `tight` or `fitness`.
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "tight" => Ok(VerifyScore::Tight),
            "fitness" => Ok(VerifyScore::Fitness),
            "oriented" => Ok(VerifyScore::Oriented),
            other => Err(crate::GgsError::param(
                "verify score",
                format!("unknown '{other}' (tight, fitness or oriented)"),
            )),
        }
    }
}

impl Default for VerifyConfig {
    fn default() -> Self {
        VerifyConfig {
            margin: 0.5,
            max_hypotheses: 32,
            distance_voxels: 0.2,
            spacing_factor: 1.5,
            scan_distance_fraction: 0.15,
            cell_voxels: 0.5,
            check_iterations: 10,
            max_iterations: 30,
            reject_ratio: 0.6,
            fine_cell_voxels: 0.25,
            fine_iterations: 50,
            fine_distance_voxels: 0.0,
            settle_ratio: 0.5,
            ambiguous_ratio: 0.9,
            score: VerifyScore::Tight,
            free_space_weight: 10.0,
            free_space_tolerance: 0.02,
            free_space_margin_voxels: 1.0,
            least_score: 0.0,
        }
    }
}

impl VerifyConfig {
    /// Every setting in its range, else an error that names it by its settings key
    /// ([`crate::Settings`]): the one check of these ranges, run by [`super::register`].
    pub fn validate(&self) -> Result<()> {
        let fraction = |name: &'static str, v: f64| {
            if v.is_finite() && (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(GgsError::param(name, format!("must be in [0, 1], got {v}")))
            }
        };
        let non_negative = |name: &'static str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(GgsError::param(
                    name,
                    format!("must be a number ≥ 0, got {v}"),
                ))
            }
        };
        if self.max_hypotheses == 0 {
            return Err(GgsError::param("max_hypotheses", "must be at least 1"));
        }
        if self.max_iterations < self.check_iterations {
            return Err(GgsError::param(
                "verify_iterations",
                format!(
                    "must be at least verify_check_iterations ({}), got {}",
                    self.check_iterations, self.max_iterations
                ),
            ));
        }
        fraction("margin", self.margin)?;
        fraction("reject_ratio", self.reject_ratio)?;
        fraction("settle_ratio", self.settle_ratio)?;
        fraction("ambiguous_ratio", self.ambiguous_ratio)?;
        fraction("free_space_tolerance", self.free_space_tolerance)?;
        for (name, v) in [
            ("verify_distance_voxels", self.distance_voxels),
            ("verify_distance_spacings", self.spacing_factor),
            ("verify_distance_range", self.scan_distance_fraction),
            ("verify_cell", self.cell_voxels),
            ("verify_fine_cell", self.fine_cell_voxels),
            ("verify_fine_distance", self.fine_distance_voxels),
            ("free_space_weight", self.free_space_weight),
            ("free_space_margin", self.free_space_margin_voxels),
        ] {
            non_negative(name, v)?;
        }
        Ok(())
    }
}

/// The verification score of one pose (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Evidence {
    /// `f_s`: share of source points within `D` of a target point.
    pub fitness_source: f64,
    /// `f_t`: share of target points within `D` of a moved source point.
    pub fitness_target: f64,
    /// `max(0, (f_s + f_t)/2 − λ·max(0, v − v₀))`: the overlap, less the free-space penalty
    /// where a cloud is a scan from its origin (`v` = `free_space_violations`).
    pub score: f64,
    /// How many source and target points the sums ran over: the samples, or the part of them
    /// drawn for the subsample estimate for a hypothesis rejected on a subsample ([`finish`]).
    pub points: [usize; 2],
    /// Share of the summed points that lie in the other scan's free space
    /// ([`super::free_space`]): the mean over the sides whose other cloud is a scan from its
    /// origin; `None` when neither is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub free_space_violations: Option<f64>,
}

/// Scores poses of one pair at one distance `D`; built once per pair.
pub struct Verifier {
    source: Vec<Point>,
    target: Vec<Point>,
    in_source: RadiusSearch<'static>,
    in_target: RadiusSearch<'static>,
    /// The distance `D`, in cloud units.
    pub distance: f64,
    score: VerifyScore,
    /// With [`VerifyScore::Oriented`]: the normals of the source sample, the target sample,
    /// the source index and the target index points.
    normals: Option<[Vec<Normal>; 4]>,
    /// The positions in each sample the subsample estimate sums ([`Self::subsample_evidence`]);
    /// `None` when the samples are too small for one.
    subsample: Option<[Vec<u32>; 2]>,
    /// The free space seen by the target (tests the moved source points) and by the source
    /// (tests the target points moved back), where that cloud is a scan from its origin.
    free_space: [Option<RangeImage>; 2],
    /// The free-space margin `m`, cloud units.
    free_space_margin: f64,
    /// `λ` of [`VerifyConfig::free_space_weight`].
    free_space_weight: f64,
    /// `v₀` of [`VerifyConfig::free_space_tolerance`].
    free_space_tolerance: f64,
}

/// `m` of the positions `0..n`, drawn uniformly without replacement by `rng` (a partial
/// Fisher–Yates shuffle), in increasing order.
fn draw(n: usize, m: usize, rng: &mut crate::rng::Rng) -> Vec<u32> {
    let mut all: Vec<u32> = (0..n as u32).collect();
    for i in 0..m.min(n) {
        let j = i + rng.below((n - i) as u64) as usize;
        all.swap(i, j);
    }
    all.truncate(m.min(n));
    all.sort_unstable();
    all
}

/// A unit normal.
type Normal = [f32; 3];

/// Neighbours of a point that give its normal.
const NORMAL_NEIGHBORS: usize = 10;

/// The normal at each of `at`: the eigenvector of the smallest eigenvalue of the covariance
/// of its [`NORMAL_NEIGHBORS`] nearest points of `cloud` (indexed by `index`), turned to point
/// away from `centroid` (a degenerate neighbourhood gets the z axis, the fallback of
/// [`crate::refine::covariance::Moments::shape`]).
fn normals(
    at: &[Point],
    cloud: &[Point],
    index: &crate::refine::neighbors::PointIndex,
    centroid: &Point,
) -> Vec<Normal> {
    at.par_iter()
        .map(|p| {
            let mut acc = crate::refine::covariance::Moments::new(p);
            index.for_k_nearest(p, NORMAL_NEIGHBORS, |j| acc.push(&cloud[j]));
            let n = acc.shape(1e-3).normal;
            let out = (0..3).map(|d| (p[d] - centroid[d]) * n[d]).sum::<f64>();
            let s = if out < 0.0 { -1.0 } else { 1.0 };
            [(s * n[0]) as f32, (s * n[1]) as f32, (s * n[2]) as f32]
        })
        .collect()
}

/// One point's full weight: weights are integers in `[0, WEIGHT_ONE]`.
const WEIGHT_ONE: u64 = 1 << 20;

impl Verifier {
    /// Index both clouds for queries at `D` (see [`VerifyConfig`]) for voxel `voxel` and the
    /// target's point spacing `spacing`.
    pub fn new(
        source: &Cloud,
        target: &Cloud,
        voxel: f64,
        spacing: f64,
        cfg: &VerifyConfig,
    ) -> Self {
        let (source_index, target_index) =
            (source.strided(INDEX_POINTS), target.strided(INDEX_POINTS));
        let (source_sample, target_sample) =
            (source.strided(SAMPLE_POINTS), target.strided(SAMPLE_POINTS));
        let ranges = [
            scan_median_range(&target_sample),
            scan_median_range(&source_sample),
        ];
        let scan_floor =
            (ranges.iter().flatten()).fold(0.0f64, |a, &r| a.max(cfg.scan_distance_fraction * r));
        let distance = (cfg.distance_voxels * voxel)
            .max(cfg.spacing_factor * spacing)
            .max(scan_floor);
        let normals = (cfg.score == VerifyScore::Oriented).then(|| {
            let (si, ti) = (
                crate::refine::neighbors::PointIndex::new(&source_index),
                crate::refine::neighbors::PointIndex::new(&target_index),
            );
            let centroid = |c: &[Point]| crate::cloud::centroid_of(c).expect("non-empty");
            let (sc, tc) = (centroid(&source_index), centroid(&target_index));
            [
                normals(&source_sample, &source_index, &si, &sc),
                normals(&target_sample, &target_index, &ti, &tc),
                normals(&source_index, &source_index, &si, &sc),
                normals(&target_index, &target_index, &ti, &tc),
            ]
        });
        let k = (source_sample.len().min(target_sample.len()) / SUBSAMPLE_POINTS).max(1);
        let subsample = (k > 1).then(|| {
            [&source_sample, &target_sample].map(|sample| {
                let n = sample.len();
                let mut rng = crate::rng::Rng::stream(SUBSAMPLE_SEED, &[n as u64]);
                draw(n, n.div_ceil(k), &mut rng)
            })
        });
        let free_space = [
            ranges[0].map(|_| RangeImage::new(&target_index)),
            ranges[1].map(|_| RangeImage::new(&source_index)),
        ];
        Verifier {
            free_space,
            free_space_margin: cfg.free_space_margin_voxels * voxel,
            free_space_weight: cfg.free_space_weight,
            free_space_tolerance: cfg.free_space_tolerance,
            in_source: RadiusSearch::new(&source_index, distance, None),
            in_target: RadiusSearch::new(&target_index, distance, None),
            subsample,
            source: source_sample,
            target: target_sample,
            distance,
            score: cfg.score,
            normals,
        }
    }

    /// Whether normal `a` turned by `r` and normal `b` face the same way: `(r·a)·b ≥ 0`.
    #[inline]
    fn facing(r: &nalgebra::Matrix3<f64>, a: &Normal, b: &Normal) -> bool {
        let a = r * nalgebra::Vector3::new(a[0] as f64, a[1] as f64, a[2] as f64);
        let dot = a.x * b[0] as f64 + a.y * b[1] as f64 + a.z * b[2] as f64;
        dot >= 0.0
    }

    /// The weight of one point whose nearest neighbour within `D` is `hit` (squared distance),
    /// in units of `1 / WEIGHT_ONE`: an integer, so sums do not depend on the thread count.
    #[inline]
    fn weight(&self, hit: Option<(usize, f64)>) -> u64 {
        match (hit, self.score) {
            (None, _) => 0,
            (Some(_), VerifyScore::Fitness) => WEIGHT_ONE,
            (Some((_, d2)), VerifyScore::Tight | VerifyScore::Oriented) => {
                let r2 = self.distance * self.distance;
                (WEIGHT_ONE as f64 * (1.0 - d2 / r2).max(0.0)).floor() as u64
            }
        }
    }

    /// Whether the source and the target are taken as scans from their origins, whose free
    /// space the score checks ([`super::free_space::origin_is_scanner`]).
    pub fn scanners(&self) -> [bool; 2] {
        [self.free_space[1].is_some(), self.free_space[0].is_some()]
    }

    /// The free-space margin `m`, cloud units.
    pub fn free_space_margin(&self) -> f64 {
        self.free_space_margin
    }

    /// `v`: the mean over the checked sides of the share of their summed points (`points`)
    /// that violate the other cloud's free space (`violating`); `None` when no side is checked.
    fn free_space_share(&self, violating: [u64; 2], points: [usize; 2]) -> Option<f64> {
        let checked = (0..2).filter(|&k| self.free_space[k].is_some());
        let (sum, sides) = checked.fold((0.0, 0usize), |(sum, n), k| {
            (sum + violating[k] as f64 / points[k] as f64, n + 1)
        });
        (sides > 0).then(|| sum / sides as f64)
    }

    /// The evidence for `T` (`p_target = T · p_source`).
    pub fn evidence(&self, t: &Rigid) -> Evidence {
        self.evidence_over(t, None)
    }

    /// An estimate of the evidence for `T`: the same sums over the positions drawn at random from
    /// each sample (`⌈n/k⌉` of `n`, [`SUBSAMPLE_POINTS`]), so `score` estimates the full one with
    /// [`Evidence::standard_error`] (a simple random sample: no scan pattern of the file's point
    /// order can bias it, as a stride could). `None` when the samples are too small for a
    /// subsample.
    pub fn subsample_evidence(&self, t: &Rigid) -> Option<Evidence> {
        let [s, g] = self.subsample.as_ref()?;
        Some(self.evidence_over(t, Some([s, g])))
    }

    /// The evidence for `T` over the positions `at` of each sample (all of them: `None`).
    fn evidence_over(&self, t: &Rigid, at: Option<[&[u32]; 2]>) -> Evidence {
        let inv = t.inverse();
        let facing = |i: usize, hit: Option<(usize, f64)>, side: usize| -> Option<(usize, f64)> {
            let (Some(n), Some((j, _))) = (&self.normals, hit) else {
                return hit;
            };
            let (r, a, b) = if side == 0 {
                (&t.rotation, &n[0][i], &n[3][j])
            } else {
                (&inv.rotation, &n[1][i], &n[2][j])
            };
            Self::facing(r, a, b).then_some(hit).flatten()
        };
        let summed = |points: &[Point], which: usize| at.map_or(points.len(), |a| a[which].len());
        // Σ w and the count of free-space violations over the summed points of one side's
        // sample, moved by `m` into the other cloud.
        let side = |points: &[Point], m: &Rigid, other: &RadiusSearch, which: usize| {
            let seen = self.free_space[which].as_ref();
            (0..summed(points, which))
                .into_par_iter()
                .map(|s| {
                    let i = at.map_or(s, |a| a[which][s] as usize);
                    let q = m.apply(&points[i]);
                    let w = self.weight(facing(i, other.nearest(&q), which));
                    let v = seen.is_some_and(|image| image.violates(&q, self.free_space_margin));
                    (w, v as u64)
                })
                .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
        };
        let (matched_source, violating_source) = side(&self.source, t, &self.in_target, 0);
        let (matched_target, violating_target) = side(&self.target, &inv, &self.in_source, 1);
        let points = [summed(&self.source, 0), summed(&self.target, 1)];
        let fs = matched_source as f64 / WEIGHT_ONE as f64 / points[0] as f64;
        let ft = matched_target as f64 / WEIGHT_ONE as f64 / points[1] as f64;
        let free_space_violations =
            self.free_space_share([violating_source, violating_target], points);
        let excess =
            free_space_violations.map_or(0.0, |v| (v - self.free_space_tolerance).max(0.0));
        let penalty = self.free_space_weight * excess;
        Evidence {
            fitness_source: fs,
            fitness_target: ft,
            score: (0.5 * (fs + ft) - penalty).max(0.0),
            points,
            free_space_violations,
        }
    }
}

impl Evidence {
    /// An upper bound on the standard error of `score` as an estimate of the score over all
    /// the points, for evidence summed over a part of them (`points`): each side's mean of
    /// `n` weights in `[0, 1]` with mean `μ` has a variance of at most `μ(1 − μ)/n` (floored
    /// at `1/n²`, so that an empty match is not taken as certain), and
    /// `score = (f_s + f_t)/2`: `½·√(v_s + v_t)`.
    pub fn standard_error(&self) -> f64 {
        let var = |mu: f64, n: usize| {
            let n = n.max(1) as f64;
            (mu * (1.0 - mu)).max(1.0 / n) / n
        };
        0.5 * (var(self.fitness_source, self.points[0]) + var(self.fitness_target, self.points[1]))
            .sqrt()
    }
}

/// One hypothesis after verification's ICP.
#[derive(Debug, Clone, Copy)]
pub struct Checked {
    pub transform: Rigid,
    pub evidence: Evidence,
    /// ICP iterations run.
    pub iterations: usize,
    /// Stopped at the check: its score was below `reject_ratio` × the best so far.
    pub rejected_early: bool,
    /// Rejected on its subsample estimate ([`finish`]): `evidence` is the subsample's.
    pub rejected_on_subsample: bool,
    /// Stopped at the check: its ICP had brought it onto the pose of this earlier verified
    /// hypothesis (its index), whose evidence it carries; see [`check`].
    pub same_as: Option<usize>,
}

/// The first stage of [`check`]: `check_iterations` of ICP from a start. It depends on
/// nothing but its start, so the hypotheses of a pair run it side by side ([`first_stage`]);
/// what follows depends on the hypotheses before ([`finish`]).
#[derive(Debug, Clone)]
pub struct FirstStage {
    run: RefinedPose,
}

/// ICP of the verification from `from` for `iterations` on the thinned clouds.
fn verification_run(
    thinned: &PreparedPair,
    from: &Rigid,
    refine_cfg: &RefineConfig,
    iterations: usize,
) -> Result<RefinedPose> {
    let c = RefineConfig {
        max_iterations: iterations,
        ..*refine_cfg
    };
    refine_prepared_pose(thinned, from, &c)
}

/// Refine `start` for `cfg.check_iterations` on the thinned clouds.
pub fn first_stage(
    thinned: &PreparedPair,
    start: &Rigid,
    refine_cfg: &RefineConfig,
    cfg: &VerifyConfig,
) -> Result<FirstStage> {
    let run = verification_run(thinned, start, refine_cfg, cfg.check_iterations)?;
    Ok(FirstStage { run })
}

/// Refine `start` on the thinned clouds and score it, stopping early when it scores below
/// `reject_ratio × best_so_far` at the check, or when `known` says that the pose reached by
/// then is that of an earlier verified hypothesis (index and evidence): the rest of its ICP
/// would converge where that one did, so it carries that one's evidence and, scoring no
/// higher, is never chosen over it. On the bunny pair three of eleven hypotheses end on the
/// winner's pose. The same as [`first_stage`] then [`finish`].
pub fn check(
    thinned: &PreparedPair,
    verifier: &Verifier,
    start: &Rigid,
    refine_cfg: &RefineConfig,
    cfg: &VerifyConfig,
    best_so_far: f64,
    known: &dyn Fn(&Rigid) -> Option<(usize, Evidence)>,
) -> Result<Checked> {
    let first = first_stage(thinned, start, refine_cfg, cfg)?;
    let rejection = RejectionThreshold {
        best: best_so_far,
        floor: 0.0,
    };
    finish(first, thinned, verifier, refine_cfg, cfg, rejection, known)
}

/// What a hypothesis is checked against: `reject_ratio` × the larger of the best score so
/// far and a floor. The floor (the first look's accept score; 0 in the whole verification)
/// drops a hypothesis that cannot be accepted, but only on a subsample while there is no best
/// score yet: the full score at the check is then not worth its cost, since the second run's
/// score replaces it.
#[derive(Debug, Clone, Copy)]
pub struct RejectionThreshold {
    pub best: f64,
    pub floor: f64,
}

/// The rest of [`check`] after its first stage: the decision at the check and, for a
/// hypothesis that goes on, its second run.
///
/// The decision first estimates the evidence: a fixed random part of each sample
/// ([`Verifier::subsample_evidence`]; no subsample when the samples are too small, nor when there
/// is nothing to reject against). A hypothesis whose subsample estimate, raised by
/// [`SUBSAMPLE_SIGMAS`] standard errors, still scores below `reject_ratio` × the
/// [`RejectionThreshold`] is rejected with the subsample estimate as its evidence (`points` says
/// so), without the full sums. The estimate is the mean of the same per-point weights over a part
/// of the same points drawn at random. Measured on the 4167 checks of the generated FP-O-H and
/// FP-O-M pairs (50 000 points, seed 2022), the full score lay within 3.4 of the subsample's
/// standard errors (mean 0.62, 99 % within 2.0), so six leave a wide margin; 2772 of the 3278
/// rejections were taken on a subsample, none that the full score would have kept. Every other
/// hypothesis is scored in full and decided as before.
pub fn finish(
    first: FirstStage,
    thinned: &PreparedPair,
    verifier: &Verifier,
    refine_cfg: &RefineConfig,
    cfg: &VerifyConfig,
    rejection: RejectionThreshold,
    known: &dyn Fn(&Rigid) -> Option<(usize, Evidence)>,
) -> Result<Checked> {
    let FirstStage { run: first } = first;
    let mut iterations = first.iterations;
    if let Some((k, evidence)) = known(&first.transform) {
        return Ok(Checked {
            transform: first.transform,
            evidence,
            iterations,
            rejected_early: false,
            rejected_on_subsample: false,
            same_as: Some(k),
        });
    }
    let threshold = cfg.reject_ratio * rejection.best.max(rejection.floor);
    let goes_on = more_iterations(&first, cfg);
    let subsample_rejection = (threshold > 0.0)
        .then(|| verifier.subsample_evidence(&first.transform))
        .flatten()
        .filter(|g| g.score + SUBSAMPLE_SIGMAS * g.standard_error() < threshold);
    // With no score to beat (the first hypothesis: a score is never below 0) and a second run
    // to come, the score at the check would decide nothing and be replaced: skipped, unless
    // a subsample estimate already put it below the floor.
    let nothing_to_decide = rejection.best <= 0.0 && goes_on && subsample_rejection.is_none();
    if !nothing_to_decide {
        let evidence = subsample_rejection.unwrap_or_else(|| verifier.evidence(&first.transform));
        let rejected = evidence.score < threshold;
        if rejected || !goes_on {
            return Ok(Checked {
                transform: first.transform,
                evidence,
                iterations,
                rejected_early: rejected,
                rejected_on_subsample: subsample_rejection.is_some(),
                same_as: None,
            });
        }
    }
    let rest = cfg.max_iterations - cfg.check_iterations;
    let second = verification_run(thinned, &first.transform, refine_cfg, rest)?;
    iterations += second.iterations;
    Ok(Checked {
        transform: second.transform,
        evidence: verifier.evidence(&second.transform),
        iterations,
        rejected_early: false,
        rejected_on_subsample: false,
        same_as: None,
    })
}

/// Whether a second run can change anything: the first hit its cap, and iterations remain.
fn more_iterations(first: &RefinedPose, cfg: &VerifyConfig) -> bool {
    !first.converged && cfg.max_iterations > cfg.check_iterations
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Vector3};

    fn plane(n: usize) -> Cloud {
        Cloud::new(
            (0..n * n)
                .map(|i| [(i % n) as f64 * 0.01, (i / n) as f64 * 0.01, 0.0])
                .collect(),
        )
    }

    /// A panoramic scan from the origin of a 40 × 16 m walled yard, the ground 2 m below the
    /// scanner.
    fn yard() -> Cloud {
        use crate::pipeline::free_space::{simulated_scan, to_ground};
        let wall = |half: f64, c: f64| half / c.abs().max(1e-12);
        Cloud::new(simulated_scan(10, |d| {
            wall(20.0, d[0]).min(wall(8.0, d[1])).min(to_ground(d, 2.0))
        }))
    }

    #[test]
    fn a_turn_that_puts_walls_in_the_seen_yard_loses_its_score() {
        let scan = yard();
        let turn = Rigid::new(
            *nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), 90f64.to_radians()).matrix(),
            Vector3::zeros(),
        );
        let blind = VerifyConfig {
            free_space_weight: 0.0,
            ..VerifyConfig::default()
        };
        let (with, without) = (
            Verifier::new(&scan, &scan, 0.5, 0.5, &VerifyConfig::default()),
            Verifier::new(&scan, &scan, 0.5, 0.5, &blind),
        );
        assert_eq!(with.scanners(), [true, true]);
        let right = with.evidence(&Rigid::identity());
        assert_eq!(right.free_space_violations, Some(0.0));
        assert_eq!(right.score, 1.0);
        // Laid ground on ground, the turn overlaps well; its short walls stand 8 m from the
        // scanner, inside the 20 m the scan saw along x.
        let overlap_only = without.evidence(&turn);
        assert!(overlap_only.score > 0.5, "{overlap_only:?}");
        let wrong = with.evidence(&turn);
        let v = wrong.free_space_violations.unwrap();
        assert!(v > 0.1, "{wrong:?}");
        let expected = overlap_only.score - 10.0 * (v - 0.02);
        assert!((wrong.score - expected.max(0.0)).abs() < 1e-12, "{wrong:?}");
        assert!(wrong.score < 0.5 * right.score, "{wrong:?}");
    }

    #[test]
    fn every_setting_out_of_range_is_refused_by_name() {
        assert!(VerifyConfig::default().validate().is_ok());
        let d = VerifyConfig::default;
        let bad: [(VerifyConfig, &str); 8] = [
            (VerifyConfig { margin: 3.0, ..d() }, "margin"),
            (
                VerifyConfig {
                    margin: f64::NAN,
                    ..d()
                },
                "margin",
            ),
            (
                VerifyConfig {
                    max_hypotheses: 0,
                    ..d()
                },
                "max_hypotheses",
            ),
            (
                VerifyConfig {
                    reject_ratio: -0.1,
                    ..d()
                },
                "reject_ratio",
            ),
            (
                VerifyConfig {
                    scan_distance_fraction: -1.0,
                    ..d()
                },
                "verify_distance_range",
            ),
            (
                VerifyConfig {
                    free_space_weight: f64::INFINITY,
                    ..d()
                },
                "free_space_weight",
            ),
            (
                VerifyConfig {
                    settle_ratio: 1.5,
                    ..d()
                },
                "settle_ratio",
            ),
            (
                VerifyConfig {
                    fine_distance_voxels: -0.5,
                    ..d()
                },
                "verify_fine_distance",
            ),
        ];
        for (cfg, name) in bad {
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.contains(&format!("invalid parameter {name}:")), "{e}");
        }
    }

    #[test]
    fn on_scans_d_is_at_least_a_fraction_of_their_median_range() {
        let scan = yard();
        let sample = scan.strided(SAMPLE_POINTS);
        let r = crate::pipeline::free_space::scan_median_range(&sample).unwrap();
        // The yard's median range is several metres: far above 0.2 voxel and the spacing.
        assert!(r > 4.0, "{r}");
        let v = Verifier::new(&scan, &scan, 0.5, 0.01, &VerifyConfig::default());
        assert!(
            (v.distance - 0.15 * r).abs() < 1e-12,
            "{} against {r}",
            v.distance
        );
        let off = VerifyConfig {
            scan_distance_fraction: 0.0,
            ..VerifyConfig::default()
        };
        let v = Verifier::new(&scan, &scan, 0.5, 0.01, &off);
        assert!((v.distance - 0.1).abs() < 1e-12, "{}", v.distance);
    }

    #[test]
    fn clouds_that_are_no_scans_from_their_origin_score_as_before() {
        let c = plane(50);
        let v = Verifier::new(&c, &c, 0.05, 0.01, &VerifyConfig::default());
        assert_eq!(v.scanners(), [false, false]);
        assert_eq!(v.evidence(&Rigid::identity()).free_space_violations, None);
    }

    #[test]
    fn the_right_pose_scores_one_and_a_shift_beyond_d_scores_less() {
        let c = plane(50);
        let v = Verifier::new(&c, &c, 0.05, 0.01, &VerifyConfig::default());
        assert!((v.distance - 0.015).abs() < 1e-12, "{}", v.distance);
        let e = v.evidence(&Rigid::identity());
        assert_eq!(e.score, 1.0);
        let shifted = Rigid::new(Matrix3::identity(), Vector3::new(0.25, 0.0, 0.0));
        let e = v.evidence(&shifted);
        // After a shift of 0.25, 26 or 27 of the 50 columns lie within D = 0.015 of the other plane.
        assert!((e.fitness_source - 0.53).abs() < 0.03, "{e:?}");
        assert!((e.fitness_target - 0.53).abs() < 0.03, "{e:?}");
        let lifted = Rigid::new(Matrix3::identity(), Vector3::new(0.0, 0.0, 0.016));
        assert_eq!(v.evidence(&lifted).score, 0.0);
    }

    #[test]
    fn a_tight_point_counts_by_its_distance_a_fitness_point_by_being_within_d() {
        let c = plane(30);
        let lifted = Rigid::new(Matrix3::identity(), Vector3::new(0.0, 0.0, 0.01));
        let score = |score| {
            let cfg = VerifyConfig {
                score,
                spacing_factor: 2.0,
                ..VerifyConfig::default()
            };
            let v = Verifier::new(&c, &c, 0.05, 0.01, &cfg);
            assert!((v.distance - 0.02).abs() < 1e-12);
            v.evidence(&lifted)
        };
        // Every point is D/2 from the other plane: 1 − (1/2)² = 0.75 each, or 1 each.
        let tight = score(VerifyScore::Tight);
        assert!((tight.score - 0.75).abs() < 1e-5, "{tight:?}");
        assert!((tight.fitness_source - tight.fitness_target).abs() < 1e-5);
        assert_eq!(score(VerifyScore::Fitness).score, 1.0);
        assert_eq!(
            "fitness".parse::<VerifyScore>().unwrap(),
            VerifyScore::Fitness
        );
        assert!("close".parse::<VerifyScore>().is_err());
    }

    #[test]
    fn the_distance_follows_the_spacing_of_sparse_clouds() {
        let c = plane(20);
        let cfg = VerifyConfig::default();
        let v = Verifier::new(&c, &c, 0.01, 0.01, &cfg);
        assert!((v.distance - 1.5 * 0.01).abs() < 1e-12, "{}", v.distance);
    }

    /// A bumpy, asymmetric height field (so ICP has a unique answer that takes a few
    /// iterations), and the same surface moved by 4° and a few centimetres.
    fn bumpy_pair() -> (Cloud, Cloud, Rigid) {
        let n = 40;
        let target = Cloud::new(
            (0..n * n)
                .map(|i| {
                    let (x, y) = ((i % n) as f64 / n as f64, (i / n) as f64 / n as f64);
                    [
                        x,
                        y,
                        0.1 * (3.0 * x).sin() * (2.0 * y + 0.5).cos() + 0.05 * x * y,
                    ]
                })
                .collect(),
        );
        let a = 4f64.to_radians();
        let r = Matrix3::new(a.cos(), -a.sin(), 0.0, a.sin(), a.cos(), 0.0, 0.0, 0.0, 1.0);
        let truth = Rigid::new(r, Vector3::new(0.02, -0.01, 0.005));
        (target.transformed(&truth.inverse()), target, truth)
    }

    /// `check` from the identity with `check_iterations` / `max_iterations`, against
    /// `best_so_far`.
    fn run_check(
        check_iterations: usize,
        max_iterations: usize,
        reject: f64,
        best: f64,
    ) -> Checked {
        let (source, target, _) = bumpy_pair();
        let cfg = VerifyConfig {
            check_iterations,
            max_iterations,
            reject_ratio: reject,
            ..VerifyConfig::default()
        };
        let verifier = Verifier::new(&source, &target, 0.05, 0.025, &cfg);
        let icp = RefineConfig::default();
        let pair = PreparedPair::new(&source, &target, icp.neighbors, icp.epsilon).unwrap();
        check(
            &pair,
            &verifier,
            &Rigid::identity(),
            &icp,
            &cfg,
            best,
            &|_| None,
        )
        .unwrap()
    }

    #[test]
    fn a_hypothesis_on_a_known_pose_stops_at_the_check_with_its_evidence() {
        let (source, target, _) = bumpy_pair();
        let cfg = VerifyConfig {
            check_iterations: 2,
            ..VerifyConfig::default()
        };
        let verifier = Verifier::new(&source, &target, 0.05, 0.025, &cfg);
        let icp = RefineConfig::default();
        let pair = PreparedPair::new(&source, &target, icp.neighbors, icp.epsilon).unwrap();
        let known = Evidence {
            fitness_source: 0.25,
            fitness_target: 0.75,
            score: 0.5,
            points: [100, 100],
            free_space_violations: None,
        };
        let start = Rigid::identity();
        let c = check(&pair, &verifier, &start, &icp, &cfg, 0.0, &|_| {
            Some((3, known))
        })
        .unwrap();
        assert_eq!(c.same_as, Some(3));
        assert_eq!(c.evidence, known);
        assert_eq!(c.iterations, 2);
        assert!(!c.rejected_early);
        // Told nothing, it runs on and scores itself.
        let c = check(&pair, &verifier, &start, &icp, &cfg, 0.0, &|_| None).unwrap();
        assert_eq!(c.same_as, None);
        assert!(c.iterations > 2 && c.evidence.score > 0.9, "{c:?}");
    }

    #[test]
    fn check_runs_the_second_stage_up_to_the_total_cap() {
        // One iteration at the check, then the rest of a 3-iteration cap: not enough to
        // converge from 4° away, so exactly 3 run in all.
        let c = run_check(1, 3, 0.6, 0.0);
        assert_eq!(c.iterations, 3);
        assert!(!c.rejected_early);
        // Enough iterations: the right pose, scored as the verifier scores it.
        let (source, target, truth) = bumpy_pair();
        let c = run_check(2, 60, 0.6, 0.0);
        assert!(c.iterations > 2 && c.iterations < 60, "{}", c.iterations);
        assert!(crate::metrics::rre(&c.transform, &truth) < 0.01);
        let v = Verifier::new(&source, &target, 0.05, 0.025, &VerifyConfig::default());
        assert_eq!(c.evidence, v.evidence(&c.transform));
        // Converged at the check: no second stage.
        let converged = run_check(60, 80, 0.6, 0.0);
        assert!(converged.iterations < 60);
        assert_eq!(converged.iterations, run_check(60, 60, 0.6, 0.0).iterations);
    }

    #[test]
    fn check_rejects_below_the_ratio_of_the_best_and_not_at_it() {
        // The check's score (≤ 1) against reject_ratio × best_so_far.
        let first = run_check(1, 30, 0.6, 0.0);
        assert!(!first.rejected_early && first.iterations > 1);
        let s = run_check(1, 1, 0.6, 0.0).evidence.score;
        // (The quotient below needs s > 0.6 to differ from the product.)
        assert!(s > 0.6, "{s}");
        // Exactly at the threshold: kept; just above it: rejected after the check.
        assert!(!run_check(1, 30, 0.5, 2.0 * s).rejected_early);
        let r = run_check(1, 30, 0.5, 2.0 * s * 1.01);
        assert!(r.rejected_early && r.iterations == 1);
        // The threshold is a product: 0.6 × 1.7 s = 1.02 s rejects, 0.6 × 1.5 s = 0.9 s keeps
        // (a sum 0.6 + 1.5 s would reject, a quotient 0.6 / 1.7 s would keep).
        assert!(run_check(1, 30, 0.6, 1.7 * s).rejected_early);
        assert!(!run_check(1, 30, 0.6, 1.5 * s).rejected_early);
    }

    #[test]
    fn a_subsample_draws_a_part_of_each_sample_and_estimates_the_full_score() {
        // 90 × 90 = 8100 points: a subsample of ⌈8100 / 4⌉ = 2025 of them (≥ SUBSAMPLE_POINTS).
        let c = plane(90);
        let v = Verifier::new(&c, &c, 0.05, 0.01, &VerifyConfig::default());
        let small = Verifier::new(&plane(60), &c, 0.05, 0.01, &VerifyConfig::default());
        let shifted = Rigid::new(Matrix3::identity(), Vector3::new(0.3, 0.0, 0.004));
        assert_eq!(small.subsample_evidence(&shifted), None);
        let full = v.evidence(&shifted);
        assert_eq!(full.points, [8100, 8100]);
        let estimate = v.subsample_evidence(&shifted).unwrap();
        assert_eq!(estimate.points, [2025, 2025]);
        assert_ne!(estimate, full);
        assert_eq!(
            v.subsample_evidence(&shifted),
            Some(estimate),
            "the draw is fixed"
        );
        let se = estimate.standard_error();
        assert!(
            se > 0.0 && (estimate.score - full.score).abs() < 3.0 * se,
            "{estimate:?} {full:?}"
        );
        let drawn = v.subsample.as_ref().unwrap();
        for d in drawn {
            assert!(d.windows(2).all(|w| w[0] < w[1]) && *d.last().unwrap() < 8100);
        }
    }

    #[test]
    fn a_scan_pattern_in_the_point_order_does_not_bias_the_subsample() {
        // Every 4th source point (in file order) lies 1 m off the plane, as a scan pattern
        // would: the full score counts 3 of 4 source points. A stride of 4 would sum
        // the lifted ones only; the random draw estimates the score within its errors.
        let c = plane(90);
        let mut lifted: Vec<Point> = c.iter().collect();
        for p in lifted.iter_mut().step_by(4) {
            p[2] = 1.0;
        }
        let source = Cloud::new(lifted);
        let v = Verifier::new(&source, &c, 0.05, 0.01, &VerifyConfig::default());
        let t = Rigid::identity();
        let full = v.evidence(&t);
        assert!((full.fitness_source - 0.75).abs() < 1e-9, "{full:?}");
        let estimate = v.subsample_evidence(&t).unwrap();
        let se = estimate.standard_error();
        assert!(
            (estimate.score - full.score).abs() < 3.0 * se,
            "{estimate:?} {full:?}"
        );
        let stride: Vec<u32> = (0..8100).step_by(4).collect();
        let strided = v.evidence_over(&t, Some([&stride, &stride]));
        assert!(
            (strided.score - full.score).abs() > 6.0 * strided.standard_error(),
            "{strided:?} {full:?}"
        );
    }

    #[test]
    fn the_standard_error_bounds_a_mean_of_weights_in_0_1() {
        let e = |fs: f64, ft: f64, n: usize| Evidence {
            fitness_source: fs,
            fitness_target: ft,
            score: 0.5 * (fs + ft),
            points: [n, n],
            free_space_violations: None,
        };
        // ½·√(2 · 0.25 / 100) = 0.0354.
        assert!((e(0.5, 0.5, 100).standard_error() - 0.5 * (0.005f64).sqrt()).abs() < 1e-12);
        // No match at all is still uncertain by 1/n per side.
        assert!((e(0.0, 0.0, 100).standard_error() - 0.5 * (2e-4f64).sqrt()).abs() < 1e-12);
        assert!(e(0.3, 0.2, 10_000).standard_error() < e(0.3, 0.2, 100).standard_error());
    }

    #[test]
    fn a_clear_loser_is_rejected_on_a_subsample_a_close_one_is_scored_in_full() {
        let c = plane(90);
        let cfg = VerifyConfig {
            check_iterations: 0,
            max_iterations: 0,
            ..VerifyConfig::default()
        };
        let v = Verifier::new(&c, &c, 0.05, 0.01, &cfg);
        let icp = RefineConfig::default();
        let pair = PreparedPair::new(&c, &c, icp.neighbors, icp.epsilon).unwrap();
        // Half the plane overlaps: the score is about 0.5.
        let shifted = Rigid::new(Matrix3::identity(), Vector3::new(0.45, 0.0, 0.0));
        let full = v.evidence(&shifted);
        let decide = |best: f64| check(&pair, &v, &shifted, &icp, &cfg, best, &|_| None).unwrap();
        // A threshold just below its score: the subsample cannot settle it; scored in full, kept.
        let close = decide(full.score / 0.6 * 0.95);
        assert!(
            !close.rejected_early && !close.rejected_on_subsample,
            "{close:?}"
        );
        assert_eq!(close.evidence, full);
        // Against a threshold twice its score: rejected on the subsample, which says so.
        let clear = decide(2.0 * full.score / 0.6);
        assert!(
            clear.rejected_early && clear.rejected_on_subsample,
            "{clear:?}"
        );
        assert_eq!(clear.evidence.points, [2025, 2025]);
        // Just above its own score: rejected, on the full evidence.
        let just = decide(full.score / 0.6 * 1.001);
        assert!(
            just.rejected_early && !just.rejected_on_subsample,
            "{just:?}"
        );
        assert_eq!(just.evidence, full);
    }

    #[test]
    fn every_point_is_searched_not_only_the_sample() {
        // 202 × 202 = 40 804 points: the sample is every other point, which on a grid of an
        // even width is every other column. Shifted by one column (one spacing ρ = 0.01), each
        // sample point lands exactly on a target point that is not in the sample: a sampled
        // index would find it one ρ away (w = 1 − ρ²/D² = 0.56 at D = 1.5ρ).
        let c = plane(202);
        let v = Verifier::new(&c, &c, 0.05, 0.01, &VerifyConfig::default());
        let shifted = Rigid::new(Matrix3::identity(), Vector3::new(0.01, 0.0, 0.0));
        let e = v.evidence(&shifted);
        // Only the last column of each cloud has no partner.
        assert!(e.fitness_source > 0.99 && e.fitness_target > 0.99, "{e:?}");
    }
}

#[cfg(test)]
mod oriented_tests {
    use super::*;

    /// Points of the unit sphere's cap `z ≥ 0.6` on a Fibonacci spiral: its normals, turned
    /// away from the cap's own centroid, point outwards.
    fn cap(n: usize) -> Vec<Point> {
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|i| {
                let z = 1.0 - 0.4 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let a = golden * i as f64;
                [r * a.cos(), r * a.sin(), z]
            })
            .collect()
    }

    fn evidence(source: &[Point], target: &[Point], score: VerifyScore) -> Evidence {
        let cfg = VerifyConfig {
            score,
            ..VerifyConfig::default()
        };
        let (s, t) = (Cloud::new(source.to_vec()), Cloud::new(target.to_vec()));
        Verifier::new(&s, &t, 0.1, 0.01, &cfg).evidence(&Rigid::identity())
    }

    #[test]
    fn oriented_counts_points_that_face_the_same_way_only() {
        let c = cap(4000);
        // The same cap: every point faces the same way, the oriented score is the tight one.
        let tight = evidence(&c, &c, VerifyScore::Tight);
        let oriented = evidence(&c, &c, VerifyScore::Oriented);
        assert_eq!(tight.score, 1.0);
        assert_eq!(oriented.score, tight.score);
        // A heavy cluster far out on the target's convex side moves its centroid there: the
        // target's cap normals turn inwards, opposite to the source's. The tight score still
        // counts the cap (positions coincide); the oriented one counts none of it.
        let mut with_cluster = c.clone();
        with_cluster.extend((0..8000).map(|i| {
            [
                0.001 * (i % 20) as f64,
                0.001 * (i / 20 % 20) as f64,
                5.0 + 0.001 * (i / 400) as f64,
            ]
        }));
        let tight = evidence(&c, &with_cluster, VerifyScore::Tight);
        let oriented = evidence(&c, &with_cluster, VerifyScore::Oriented);
        assert!(tight.fitness_source > 0.99, "{tight:?}");
        assert!(oriented.fitness_source < 0.01, "{oriented:?}");
    }

    #[test]
    fn the_score_names_parse() {
        for name in VerifyScore::NAMES {
            let s: VerifyScore = name.parse().unwrap();
            assert_eq!(serde_json::to_value(s).unwrap(), name);
        }
        assert!("normals".parse::<VerifyScore>().is_err());
    }
}
