//! The registration pipeline that every front end calls (`ggs register`, `ggs bench`, Python):
//! voxel size → coarse search → polish and verification of the distinct hypotheses →
//! refinement of the chosen one.
//!
//! ```text
//! source, target ──► voxel (auto or fixed)
//!                ──► coarse search over a rotation set (search)       → K distinct hypotheses
//!                ──► for each kept hypothesis: polish (polish)         → a finer rotation
//!                                              ICP on thinned clouds and a verification score (verify)
//!                ──► the best-verified hypothesis, refined (refine): default preset on
//!                    clouds thinned to a fifth of a voxel (see [`FinalStage`])
//! ```
//!
//! Two presets ([`Preset`]):
//! - [`Preset::Default`], for clouds with no initial guess: the full-SO(3) set `hopf15-id`,
//!   the coarse-to-fine search, the polish, and the verification of every distinct hypothesis
//!   whose match score is at least half the winner's (at most 8), then GICP;
//! - [`Preset::Paper`], the configuration of the GGS paper: `limited15` (|α|, |γ| ≤ 90°),
//!   exhaustive, the single best hypothesis, GICP with the reference parameters.
//!
//! The result tells how sure it is: the chosen hypothesis's rank, the verification score of
//! the best *distinct* runner-up (another pose more than the distinct radius or 3 voxels
//! away; near-duplicates of the chosen pose agree with it and do not count), a confidence
//! `1 − runner-up score / chosen score` (without a verified runner-up: `1 −` the coarse
//! ambiguity), and `ambiguous` when two distinct poses verify within
//! [`VerifyConfig::ambiguous_ratio`] of each other.

pub mod polish;
pub mod verify;

use crate::cloud::Cloud;
use crate::coarse::{
    auto_voxel, coarse_register, round_2_digits, CoarseToFine, Hypothesis, SearchConfig,
    SearchMode, SearchResult,
};
use crate::error::{GgsError, Result};
use crate::refine::{
    refine_prepared, refine_prepared_pose, PreparedPair, RefineConfig, RefineResult,
};
use crate::rotations::{RotationSet, DEFAULT_SET};
use crate::transform::{rotation_angle_deg, Rigid};
pub use polish::PolishConfig;
use rayon::prelude::*;
use std::time::Instant;
pub use verify::{Evidence, VerifyConfig, VerifyScore};

/// Voxels along the target's longest side when the voxel size is chosen automatically.
pub const AUTO_VOXEL_CELLS: usize = 32;

/// An automatic voxel is at least this many point spacings (the median distance from a point
/// to its nearest other point, the larger of the two clouds'): a voxel finer than the spacing
/// leaves holes between the points of one surface, and the grid score then counts exact point
/// coincidences instead of overlapping surfaces. Measured on PCL's 400-point bunny scans
/// (spacing 6.2 mm, side / 32 = 4.6 mm): wrong pose at 0.74 spacings, right from 0.9 to 2.4.
pub const AUTO_VOXEL_SPACINGS: f64 = 1.5;

/// Verified poses farther apart than this many voxels in translation are distinct.
const DISTINCT_TRANSLATION_VOXELS: f64 = 3.0;
/// A hypothesis whose verification ICP has, at the check, brought it within this angle
/// (degrees) and [`SAME_POSE_VOXELS`] (where the source's centroid lands) of an earlier
/// verified pose stops there: it is on its way to the same pose.
pub const SAME_POSE_DEG: f64 = 1.0;
/// See [`SAME_POSE_DEG`].
pub const SAME_POSE_VOXELS: f64 = 0.25;

/// A verification score below this says the result is probably wrong.
const LOW_EVIDENCE: f64 = 0.1;

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

pub use crate::spacing::point_spacing;

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
/// Stopping at 1e-4 instead (the default since 2026-12-03) moves the pose by at most 0.005°
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

    /// This stage on cells of `cell_voxels` voxels; 0 is [`FinalStage::FULL`] (full
    /// resolution and the refinement's own stopping rules). The front ends' `--refine-cell`.
    pub fn with_cell_voxels(self, cell_voxels: f64) -> Result<FinalStage> {
        if !(cell_voxels.is_finite() && cell_voxels >= 0.0) {
            return Err(GgsError::param(
                "refine cell",
                format!("must be a non-negative number of voxels, got {cell_voxels}"),
            ));
        }
        Ok(if cell_voxels == 0.0 {
            FinalStage::FULL
        } else {
            FinalStage {
                cell_voxels,
                ..self
            }
        })
    }
}

/// Everything a registration needs.
#[derive(Debug, Clone)]
pub struct RegistrationConfig {
    pub voxel: VoxelSize,
    pub rotations: RotationSet,
    /// The coarse search. Its `voxel` and `threads` are set from this config's. Its `top_k`
    /// hypotheses are reported in the result; the search looks for at least
    /// [`VerifyConfig::max_hypotheses`] when verifying.
    pub search: SearchConfig,
    /// Finer rotations around each hypothesis (`None`: the grid's rotation is kept).
    pub polish: Option<PolishConfig>,
    /// Verification of the distinct hypotheses (`None`: the coarse winner is taken).
    pub verify: Option<VerifyConfig>,
    /// How the final refinement runs (resolution, stopping step).
    pub final_stage: FinalStage,
    /// Refinement of the chosen hypothesis (`None`: none). Verification
    /// runs the same estimator (GICP when this is `None`) on thinned clouds.
    pub refine: Option<RefineConfig>,
    /// Worker threads of every stage (0: one per core); the result does not depend on it.
    pub threads: usize,
}

impl RegistrationConfig {
    /// The configuration of `preset`, with an automatic voxel size.
    pub fn preset(preset: Preset) -> Self {
        let named = |n: &str| RotationSet::named(n).expect("built-in set");
        let mut search = SearchConfig::with_voxel(f64::NAN);
        match preset {
            Preset::Default => {
                search.mode = SearchMode::CoarseToFine(CoarseToFine::for_verification());
                search.top_k = VerifyConfig::default().max_hypotheses;
                RegistrationConfig {
                    voxel: VoxelSize::AUTO,
                    rotations: named(DEFAULT_SET),
                    search,
                    polish: None,
                    verify: Some(VerifyConfig::default()),
                    final_stage: FinalStage::THINNED,
                    refine: Some(RefineConfig::default()),
                    threads: 0,
                }
            }
            Preset::Paper => RegistrationConfig {
                voxel: VoxelSize::AUTO,
                rotations: named("limited15"),
                search,
                polish: None,
                verify: None,
                final_stage: FinalStage::FULL,
                refine: Some(RefineConfig::default()),
                threads: 0,
            },
        }
    }
}

impl Default for RegistrationConfig {
    fn default() -> Self {
        Self::preset(Preset::Default)
    }
}

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
    /// Rejected on a glance at a random part of the sample (`evidence.points`), whose estimate
    /// of the score lay far below the threshold (`verify::finish`).
    pub at_a_glance: bool,
    /// Refined again on finer cells because another distinct pose also survived.
    pub settled: bool,
    /// Stopped at the check on the pose of this earlier verified hypothesis (its `rank`),
    /// whose evidence it carries (within [`SAME_POSE_DEG`] and [`SAME_POSE_VOXELS`]).
    pub same_as: Option<usize>,
}

/// The level of the coarse search a hypothesis comes from.
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
}

/// Wall times of the stages, milliseconds.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct StageTimes {
    pub search_ms: f64,
    pub verify_ms: f64,
    pub refine_ms: f64,
    pub total_ms: f64,
}

/// The outcome of [`register`].
#[derive(Debug, Clone, serde::Serialize)]
pub struct Registration {
    /// The final transform, `p_target = T · p_source`.
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub transform: Rigid,
    /// The chosen hypothesis's grid transform (before polish and ICP).
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub coarse_transform: Rigid,
    pub voxel: f64,
    /// How the voxel was chosen automatically (`None`: it was given).
    pub voxel_rule: Option<String>,
    /// Rank of the chosen hypothesis among the coarse search's (0: its winner).
    pub chosen_rank: usize,
    /// `1 − runner-up / chosen` verification score (or `1 −` the coarse ambiguity), in [0, 1].
    pub confidence: f64,
    /// Two distinct poses verify (or, unverified, score) about equally well.
    pub ambiguous: bool,
    /// What a user should know: ambiguity, low evidence.
    pub warnings: Vec<String>,
    pub search: SearchResult,
    pub verification: Option<Verification>,
    pub refine: Option<RefineResult>,
    /// Cell edge (cloud units) of the clouds the final refinement ran on; 0: full resolution.
    pub refine_cell: f64,
    pub timings: StageTimes,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Register `source` onto `target` with `cfg` (see the module documentation).
pub fn register(source: &Cloud, target: &Cloud, cfg: &RegistrationConfig) -> Result<Registration> {
    let (pool, _) = crate::threads::pool(cfg.threads)?;
    pool.install(|| register_in_pool(source, target, cfg))
}

/// The coarse search's configuration: the pipeline's, at the resolved voxel and thread
/// count, keeping as many hypotheses as the verification checks.
fn search_config(cfg: &RegistrationConfig, voxel: f64) -> SearchConfig {
    let mut search = cfg.search.clone();
    search.voxel = voxel;
    search.threads = cfg.threads;
    if let Some(v) = &cfg.verify {
        search.top_k = search.top_k.max(v.max_hypotheses);
    }
    search
}

/// Where the final refinement starts: the verification's choice, or (without verification)
/// the coarse winner, polished when the configuration asks. Returns that pose, the coarse
/// transform it came from and its coarse rank.
fn starting_pose(
    source: &Cloud,
    target: &Cloud,
    coarse: &SearchResult,
    verification: Option<&Verification>,
    search: &SearchConfig,
    cfg: &RegistrationConfig,
) -> Result<(Rigid, Rigid, usize)> {
    Ok(match verification {
        Some(v) => {
            let h = &v.hypotheses[v.chosen];
            (h.transform, h.coarse_transform, h.rank)
        }
        None => (
            maybe_polished(source, target, coarse.winner(), search, cfg)?.transform,
            coarse.transform(),
            0,
        ),
    })
}

fn register_in_pool(
    source: &Cloud,
    target: &Cloud,
    cfg: &RegistrationConfig,
) -> Result<Registration> {
    let t0 = Instant::now();
    source.ensure_not_empty("source")?;
    target.ensure_not_empty("target")?;
    let refine_cfg = cfg.refine.map(|r| RefineConfig {
        threads: cfg.threads,
        ..r
    });
    // The point spacing serves the voxel rule and the verification distance.
    let target_spacing = std::sync::OnceLock::new();
    let spacing_of_target = || *target_spacing.get_or_init(|| point_spacing(target));
    let (voxel, voxel_rule) = cfg.voxel.resolve(target, || {
        let (s, t) = rayon::join(|| point_spacing(source), spacing_of_target);
        s.max(t)
    })?;
    let search = search_config(cfg, voxel);
    // What the verification and the final refinement start from depends on the clouds and
    // the voxel only: it is built while the search runs, on the threads the search leaves
    // idle (the same results: every piece is a pure function of its inputs).
    let icp = refine_cfg.unwrap_or(RefineConfig {
        threads: cfg.threads,
        ..RefineConfig::default()
    });
    let (coarse, (ready, prepared_final)) = rayon::join(
        || coarse_register(source, target, &cfg.rotations, &search),
        || {
            rayon::join(
                || {
                    cfg.verify.as_ref().map(|v| {
                        VerifyReady::new(source, target, voxel, spacing_of_target(), v, icp)
                    })
                },
                // A thinned pair only: a full-resolution one (`--refine-cell 0`) of a large
                // cloud would add its size to the search's peak memory.
                || {
                    refine_cfg
                        .as_ref()
                        .filter(|_| cfg.final_stage.cell_voxels > 0.0)
                        .map(|r| final_pair(source, target, voxel, r, cfg.final_stage))
                },
            )
        },
    );
    let mut coarse = coarse?;
    let search_ms = ms(t0);
    let t_verify = Instant::now();
    let verification = match (&cfg.verify, ready) {
        (Some(v), Some(ready)) => {
            let inputs = VerifyInputs {
                source,
                target,
                coarse: &coarse,
                search: &search,
            };
            Some(verify_hypotheses(&inputs, ready?, cfg, v)?)
        }
        _ => None,
    };
    let (start, coarse_transform, chosen_rank) =
        starting_pose(source, target, &coarse, verification.as_ref(), &search, cfg)?;
    let verify_ms = ms(t_verify);
    let t_refine = Instant::now();
    let refined = match (&refine_cfg, prepared_final) {
        (Some(r), Some(pair)) => Some(refine_final(&pair?, &start, r, cfg.final_stage)?),
        (Some(r), None) => {
            let pair = final_pair(source, target, voxel, r, cfg.final_stage)?;
            Some(refine_final(&pair, &start, r, cfg.final_stage)?)
        }
        (None, _) => None,
    };
    let refine_ms = ms(t_refine);
    let (confidence, ambiguous, warnings) = assess(&coarse, verification.as_ref(), cfg);
    coarse.hypotheses.truncate(cfg.search.top_k.max(1));
    Ok(Registration {
        transform: refined.as_ref().map_or(start, |r| r.transform),
        coarse_transform,
        voxel,
        voxel_rule,
        chosen_rank,
        confidence,
        ambiguous,
        warnings,
        search: coarse,
        verification,
        refine: refined,
        refine_cell: cfg.final_stage.cell_voxels * voxel,
        timings: StageTimes {
            search_ms,
            verify_ms,
            refine_ms,
            total_ms: ms(t0),
        },
    })
}

/// The pair of the final refinement: both clouds at full resolution, or thinned to cells of
/// `stage.cell_voxels × voxel` (see [`FinalStage`]), with its trees and shape grids built.
fn final_pair(
    source: &Cloud,
    target: &Cloud,
    voxel: f64,
    r: &RefineConfig,
    stage: FinalStage,
) -> Result<PreparedPair> {
    let stage = stage.with_cell_voxels(stage.cell_voxels)?;
    let pair = if stage.cell_voxels == 0.0 {
        PreparedPair::new(source, target, r.neighbors, r.epsilon)?
    } else {
        let cell = stage.cell_voxels * voxel;
        PreparedPair::thinned(source, target, cell, r.neighbors, r.epsilon)?
    };
    prepare_pair(&pair, r);
    Ok(pair)
}

/// The final refinement of `start` on `pair` ([`final_pair`]) with `stage.min_step` and
/// `stage.max_iterations` (see [`FinalStage`]).
fn refine_final(
    pair: &PreparedPair,
    start: &Rigid,
    r: &RefineConfig,
    stage: FinalStage,
) -> Result<RefineResult> {
    let stage = stage.with_cell_voxels(stage.cell_voxels)?;
    let r = RefineConfig {
        min_rotation_step: r.min_rotation_step.max(stage.min_step),
        min_translation_step: r.min_translation_step.max(stage.min_step),
        max_iterations: r.max_iterations.min(stage.max_iterations),
        ..*r
    };
    refine_prepared(pair, start, &r)
}

/// `h` polished when the config asks for it, else `h` itself.
fn maybe_polished(
    source: &Cloud,
    target: &Cloud,
    h: &Hypothesis,
    search: &SearchConfig,
    cfg: &RegistrationConfig,
) -> Result<Hypothesis> {
    Ok(match &cfg.polish {
        Some(p) => polish::polish(source, target, h, cfg.rotations.step_deg, search, p)?.hypothesis,
        None => *h,
    })
}

/// The hypotheses to verify: the winner and every distinct one whose match score is at
/// least `margin` × the winner's, at most `max_hypotheses`; then the coarse level's
/// hypotheses (coarse-to-fine) whose pose none of those already has.
fn candidates(
    coarse: &SearchResult,
    v: &VerifyConfig,
    agree: impl Fn(&Rigid, &Rigid) -> bool,
) -> Vec<(Hypothesis, HypothesisLevel)> {
    let best = coarse.hypotheses[0].match_score;
    let n = coarse
        .hypotheses
        .iter()
        .take(v.max_hypotheses.max(1))
        .take_while(|h| best > 0 && h.match_score as f64 >= v.margin * best as f64)
        .count()
        .max(1);
    let mut out: Vec<(Hypothesis, HypothesisLevel)> = coarse.hypotheses[..n]
        .iter()
        .map(|h| (*h, HypothesisLevel::Voxel))
        .collect();
    let level = coarse.stats.coarse_level.as_ref();
    for h in level.map_or(&[][..], |l| &l.hypotheses[..]) {
        if out.iter().all(|(o, _)| !agree(&o.transform, &h.transform)) {
            let as_hypothesis = Hypothesis {
                rotation_index: h.rotation_index,
                score: h.match_score.round() as i64,
                match_score: h.match_score.round() as i64,
                offset: h.offset,
                transform: h.transform,
            };
            out.push((as_hypothesis, HypothesisLevel::Coarse));
        }
    }
    out
}

/// What the verification works on.
struct VerifyInputs<'a> {
    source: &'a Cloud,
    target: &'a Cloud,
    coarse: &'a SearchResult,
    search: &'a SearchConfig,
}

/// The verification's structures, which depend on the clouds and the voxel only: the scorer
/// and the thinned pair of its ICP with its trees and shape grids. Built while the search
/// runs (see [`register_in_pool`]).
struct VerifyReady {
    verifier: verify::Verifier,
    thinned: PreparedPair,
    icp: RefineConfig,
}

impl VerifyReady {
    fn new(
        source: &Cloud,
        target: &Cloud,
        voxel: f64,
        spacing: f64,
        v: &VerifyConfig,
        icp: RefineConfig,
    ) -> Result<Self> {
        let (verifier, thinned) = rayon::join(
            || verify::Verifier::new(source, target, voxel, spacing, v),
            || {
                let cell = v.cell_voxels * voxel;
                let pair = PreparedPair::thinned(source, target, cell, icp.neighbors, icp.epsilon)?;
                prepare_pair(&pair, &icp);
                Ok::<_, GgsError>(pair)
            },
        );
        Ok(VerifyReady {
            verifier,
            thinned: thinned?,
            icp,
        })
    }
}

/// Build what every refinement of `pair` with `r` starts from (trees, shape grids, and for a
/// quantile correspondence distance the target's median k-th-neighbour distance, where its
/// search starts); each is built on first use otherwise.
fn prepare_pair(pair: &PreparedPair, r: &RefineConfig) {
    pair.prepare(r.method == crate::refine::Method::Gicp);
    if matches!(
        r.correspondence,
        crate::refine::CorrespondenceDistance::Quantile(_)
    ) {
        pair.target.median_kth_distance();
    }
}

fn verify_hypotheses(
    inputs: &VerifyInputs,
    ready: VerifyReady,
    cfg: &RegistrationConfig,
    v: &VerifyConfig,
) -> Result<Verification> {
    let VerifyInputs {
        source,
        target,
        coarse,
        search,
    } = *inputs;
    let voxel = coarse.stats.voxel;
    let VerifyReady {
        verifier,
        thinned,
        icp,
    } = ready;
    let cell = v.cell_voxels * voxel;
    // Translations compared where they put the source's centroid: `t` itself depends on the
    // frame's origin (1° apart about an origin 4000 km away, as in UTM coordinates, is 70 km).
    let c = source.centroid().expect("non-empty");
    // Two poses apart: the angle between their rotations (degrees) and the distance between
    // where they put the source's centroid.
    let gap = |a: &Rigid, b: &Rigid| {
        let (pa, pb) = (a.apply(&c), b.apply(&c));
        let moved =
            ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2) + (pa[2] - pb[2]).powi(2)).sqrt();
        (rotation_angle_deg(&a.rotation, &b.rotation), moved)
    };
    let distinct = |a: &Rigid, b: &Rigid| {
        let (deg, moved) = gap(a, b);
        deg > coarse.stats.distinct_radius_deg || moved > DISTINCT_TRANSLATION_VOXELS * voxel
    };
    let same_pose = |a: &Rigid, b: &Rigid| {
        let (deg, moved) = gap(a, b);
        deg <= SAME_POSE_DEG && moved <= SAME_POSE_VOXELS * voxel
    };
    let todo = candidates(coarse, v, |a, b| !distinct(a, b));
    // Every hypothesis's polish and first stage depend on its start alone: they run side by
    // side, and the decisions that depend on the hypotheses before are then taken in order.
    let firsts: Vec<(Hypothesis, verify::FirstStage)> = todo
        .par_iter()
        .map(|(h, _)| {
            let polished = maybe_polished(source, target, h, search, cfg)?;
            let first = verify::first_stage(&thinned, &polished.transform, &icp, v)?;
            Ok((polished, first))
        })
        .collect::<Result<_>>()?;
    let mut out: Vec<VerifiedHypothesis> = Vec::new();
    let mut best = 0.0f64;
    for (rank, ((h, level), (polished, first))) in todo.iter().zip(firsts).enumerate() {
        let known = |t: &Rigid| {
            out.iter()
                .find(|o| !o.rejected_early && o.same_as.is_none() && same_pose(&o.transform, t))
                .map(|o| (o.rank, o.evidence))
        };
        let c = verify::finish(first, &thinned, &verifier, &icp, v, best, &known)?;
        best = best.max(c.evidence.score);
        out.push(VerifiedHypothesis {
            rank,
            level: *level,
            rotation_index: h.rotation_index,
            match_score: h.match_score,
            polished_match_score: polished.match_score,
            coarse_transform: h.transform,
            transform: c.transform,
            evidence: c.evidence,
            iterations: c.iterations,
            rejected_early: c.rejected_early,
            at_a_glance: c.at_a_glance,
            settled: false,
            same_as: c.same_as,
        });
    }
    let finer = || {
        PreparedPair::thinned(
            source,
            target,
            v.fine_cell_voxels * voxel,
            icp.neighbors,
            icp.epsilon,
        )
    };
    settle_contested(&mut out, &verifier, finer, &icp, v, &distinct)?;
    // A hypothesis stopped on an earlier one's pose carries that one's evidence, settled or not
    // (`rank` is the position in `out`).
    for k in 0..out.len() {
        if let Some(j) = out[k].same_as {
            out[k].evidence = out[j].evidence;
        }
    }
    let chosen = best_scoring(&out, |_| true).expect("the winner is always verified");
    let runner_up = best_scoring(&out, |k| {
        distinct(&out[k].transform, &out[chosen].transform)
    });
    Ok(Verification {
        hypotheses: out,
        chosen,
        runner_up,
        distance: verifier.distance,
        cell,
        score: v.score,
    })
}

/// Index of the best-scoring hypothesis among those `eligible`; ties to the better rank.
fn best_scoring(out: &[VerifiedHypothesis], eligible: impl Fn(usize) -> bool) -> Option<usize> {
    (0..out.len()).filter(|&k| eligible(k)).reduce(|a, b| {
        if out[b].evidence.score > out[a].evidence.score {
            b
        } else {
            a
        }
    })
}

/// When two distinct poses both score at least `reject_ratio` × the best, refines each
/// contender again on clouds thinned to the finer cells of `fine_cell_voxels` (built only
/// then, `finer`) for `fine_iterations`, and re-scores it: on the coarser cells a right pose
/// of a small overlap stops short (too few points where the clouds overlap) and loses to a
/// loose look-alike (docs/pipeline.md, "Settling contested poses"). A clear pair costs
/// nothing more.
fn settle_contested(
    out: &mut [VerifiedHypothesis],
    verifier: &verify::Verifier,
    finer: impl FnOnce() -> Result<PreparedPair>,
    icp: &RefineConfig,
    v: &VerifyConfig,
    distinct: &dyn Fn(&Rigid, &Rigid) -> bool,
) -> Result<()> {
    if v.fine_cell_voxels <= 0.0 || v.fine_iterations == 0 {
        return Ok(());
    }
    let best = out.iter().map(|h| h.evidence.score).fold(0.0, f64::max);
    let contenders: Vec<usize> = (0..out.len())
        .filter(|&k| {
            !out[k].rejected_early
                && out[k].same_as.is_none()
                && out[k].evidence.score >= v.reject_ratio * best
        })
        .collect();
    let contested = contenders.iter().any(|&a| {
        contenders
            .iter()
            .any(|&b| distinct(&out[a].transform, &out[b].transform))
    });
    if !contested {
        return Ok(());
    }
    let pair = finer()?;
    let c = RefineConfig {
        max_iterations: v.fine_iterations,
        ..*icp
    };
    for k in contenders {
        let r = refine_prepared_pose(&pair, &out[k].transform, &c)?;
        let h = &mut out[k];
        h.transform = r.transform;
        h.evidence = verifier.evidence(&r.transform);
        h.iterations += r.iterations;
        h.settled = true;
    }
    Ok(())
}

/// Confidence, the ambiguity flag and the warnings of a result.
fn assess(
    coarse: &SearchResult,
    verification: Option<&Verification>,
    cfg: &RegistrationConfig,
) -> (f64, bool, Vec<String>) {
    let ambiguous_ratio = cfg.verify.unwrap_or_default().ambiguous_ratio;
    let mut warnings = Vec::new();
    let verified_ratio = verification.and_then(|v| {
        let chosen = &v.hypotheses[v.chosen];
        let best = chosen.evidence.score;
        if best < LOW_EVIDENCE {
            warnings.push(format!(
                "low evidence: only {:.0} % of the points lie within {:.3} of the other cloud after alignment; the result is probably wrong",
                100.0 * best,
                v.distance
            ));
        }
        v.runner_up.map(|k| {
            let r = &v.hypotheses[k];
            let ratio = if best > 0.0 { r.evidence.score / best } else { 1.0 };
            if ratio >= ambiguous_ratio {
                warnings.push(format!(
                    "ambiguous: coarse hypothesis {} (a pose {:.0}° away) verifies at {:.3} against {:.3} for the chosen one; the data may be symmetric or the overlap too small to decide",
                    r.rank + 1,
                    rotation_angle_deg(&r.transform.rotation, &chosen.transform.rotation),
                    r.evidence.score,
                    best
                ));
            }
            ratio
        })
    });
    let ratio = verified_ratio.unwrap_or_else(|| {
        let a = coarse.ambiguity.unwrap_or(0.0).clamp(0.0, 1.0);
        if verification.is_none() && a >= ambiguous_ratio {
            warnings.push(format!(
                "ambiguous: a rotation more than {:.0}° from the winner scores {:.0} % of its match score",
                coarse.stats.distinct_radius_deg,
                100.0 * a
            ));
        }
        a
    });
    let ratio = ratio.clamp(0.0, 1.0);
    (1.0 - ratio, ratio >= ambiguous_ratio, warnings)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square `side` × `side` sampled on an `n` × `n` grid (spacing `side / (n − 1)`).
    fn square(n: usize, side: f64) -> Cloud {
        let h = side / (n - 1) as f64;
        Cloud::new(
            (0..n * n)
                .map(|i| [(i % n) as f64 * h, (i / n) as f64 * h, 0.0])
                .collect(),
        )
    }

    fn spacing(c: &Cloud) -> f64 {
        point_spacing(c)
    }

    #[test]
    fn the_automatic_voxel_is_the_extent_rule_unless_the_points_are_sparser() {
        let dense = square(101, 1.0);
        assert!((spacing(&dense) - 0.01).abs() < 1e-6, "f32 storage");
        let (v, rule) = VoxelSize::AUTO.resolve(&dense, || 0.01).unwrap();
        assert_eq!(v, 0.031);
        assert!(rule.unwrap().contains("longest side / 32"));
        let sparse = square(21, 1.0);
        assert!((spacing(&sparse) - 0.05).abs() < 1e-6);
        // 1.5 × 0.05 > 1/32.
        let (v, rule) = VoxelSize::AUTO.resolve(&dense, || 0.05).unwrap();
        assert!((v - 0.075).abs() < 1e-12, "{v}");
        assert!(rule.unwrap().contains("point spacing 0.05"));
        let fixed = VoxelSize::Fixed(0.2).resolve(&sparse, || panic!("not needed"));
        assert_eq!(fixed.unwrap(), (0.2, None));
        assert!(VoxelSize::Fixed(-1.0).resolve(&sparse, || 0.0).is_err());
    }

    #[test]
    fn the_sparser_cloud_sets_the_automatic_voxel_whichever_it_is() {
        let (dense, sparse) = (square(101, 1.0), square(21, 1.0));
        let auto = |s: &Cloud, t: &Cloud| {
            let cfg = RegistrationConfig {
                verify: None,
                refine: None,
                ..RegistrationConfig::default()
            };
            register(s, t, &cfg).unwrap().voxel
        };
        assert!((auto(&dense, &sparse) - 0.075).abs() < 1e-12);
        assert!((auto(&sparse, &dense) - 0.075).abs() < 1e-12);
        assert_eq!(auto(&dense, &dense), 0.031);
    }
}
