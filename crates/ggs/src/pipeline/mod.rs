//! The registration pipeline that every front end calls (`ggs register`, `ggs bench`, Python):
//! voxel size → grid search → verification of the distinct hypotheses → refinement of the
//! chosen one.
//!
//! ```text
//! source, target ──► voxel (auto or fixed)
//!                ──► coarse level: every rotation at a coarser voxel (search)
//!                ──► first look (first_look): its best few at the voxel size, verified;
//!                    one pose clearly right → to the refinement
//!                ──► the rest of the grid search (search)           → K distinct hypotheses
//!                ──► for each kept hypothesis: [polish (polish)]
//!                                              ICP on thinned clouds and a verification score
//!                                              (verify, hypotheses)
//!                ──► the best-verified hypothesis, refined (refine): default preset on
//!                    clouds thinned to a fifth of a voxel (see [`FinalStage`])
//! ```
//!
//! Two presets ([`Preset`]):
//! - [`Preset::Default`], for clouds with no initial guess: the full-SO(3) set `hopf15-id`,
//!   the coarse-to-fine search with its first look ([`FirstLook`]), the verification of every
//!   distinct hypothesis whose match score is at least half the winner's (at most 32) and of
//!   the coarse level's 8 best distinct poses, then GICP on thinned clouds;
//! - [`Preset::Paper`], the configuration of the GGS paper: `limited15` (|α|, |γ| ≤ 90°),
//!   exhaustive, the single best hypothesis, GICP with the reference parameters.
//!
//! The result tells how sure it is: the chosen hypothesis's rank, the verification score of
//! the best *distinct* runner-up (another pose more than the distinct radius or 3 voxels
//! away; near-duplicates of the chosen pose agree with it and do not count), a confidence
//! `1 − runner-up score / chosen score` (without a verified runner-up: `1 −` the coarse
//! ambiguity), and `ambiguous` when two distinct poses verify within
//! [`VerifyConfig::ambiguous_ratio`] of each other.

mod config;
pub mod document;
pub mod first_look;
pub mod free_space;
mod hypotheses;
pub mod polish;
mod registration;
mod verified;
pub mod verify;

use crate::cloud::Cloud;
use crate::error::Result;
use crate::refine::{refine_prepared, PreparedPair, QualityReport, RefineConfig, RefineResult};
use crate::search::{CpuBackend, PreparedSearch, Search, SearchConfig, SearchMode, SearchResult};
use crate::transform::{rotation_angle_deg, Rigid};
pub use config::{
    FinalStage, Preset, RegistrationConfig, VoxelSize, AUTO_VOXEL_CELLS, AUTO_VOXEL_SPACINGS,
};
pub use document::{RefinementDocument, RegistrationDocument};
pub use first_look::{FirstLook, FirstLookReport};
use hypotheses::{
    maybe_polished, prepare_pair, verify_hypotheses, FirstStages, VerifyInputs, VerifyPass,
    VerifyReady,
};
pub use polish::PolishConfig;
pub use registration::{Registration, StageTimes};
use std::time::Instant;
pub use verified::{
    HypothesisLevel, Verification, VerifiedHypothesis, SAME_POSE_DEG, SAME_POSE_VOXELS,
};
pub use verify::{Evidence, VerifyConfig, VerifyScore};

/// A verification score below this says the result is probably wrong.
const LOW_EVIDENCE: f64 = 0.1;

/// The chosen pose is flagged when more than this many times `v₀`
/// ([`VerifyConfig::free_space_tolerance`]) of its points lie in the other scan's seen free
/// space: on the shared scene pairs the right poses leave 0.1–2.1 % there after the
/// verification's ICP, the overlap's wrong choices 4–17 %.
pub const FREE_SPACE_WARNING: f64 = 1.5;

pub use crate::spacing::point_spacing;

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Register `source` onto `target` with `cfg` (see the module documentation).
pub fn register(source: &Cloud, target: &Cloud, cfg: &RegistrationConfig) -> Result<Registration> {
    let (pool, _) = crate::threads::pool(cfg.threads)?;
    pool.install(|| register_in_pool(source, target, cfg))
}

/// The grid search's configuration: the pipeline's, at the resolved voxel and thread
/// count, keeping as many hypotheses as the verification checks.
fn search_config(cfg: &RegistrationConfig, voxel: f64) -> SearchConfig {
    let mut search = cfg.search.clone();
    search.voxel = voxel;
    search.threads = cfg.threads;
    if let Some(v) = &cfg.verify {
        search.top_k = search.top_k.max(v.max_hypotheses);
        // The verification takes no hypothesis below `margin` × the winner's match score.
        search.min_match_fraction = Some(v.margin);
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

/// Refuses out-of-range stage settings and empty clouds before any work.
fn validate(source: &Cloud, target: &Cloud, cfg: &RegistrationConfig) -> Result<()> {
    if let Some(v) = &cfg.verify {
        v.validate()?;
    }
    cfg.final_stage.validate()?;
    source.ensure_not_empty("source")?;
    target.ensure_not_empty("target")
}

fn register_in_pool(
    source: &Cloud,
    target: &Cloud,
    cfg: &RegistrationConfig,
) -> Result<Registration> {
    let t0 = Instant::now();
    validate(source, target, cfg)?;
    // The point spacing serves the voxel rule and the verification distance.
    let target_spacing = std::sync::OnceLock::new();
    let spacing_of_target = || *target_spacing.get_or_init(|| point_spacing(target));
    let (voxel, voxel_rule) = cfg.voxel.resolve(target, || {
        let (s, t) = rayon::join(|| point_spacing(source), spacing_of_target);
        s.max(t)
    })?;
    let search = search_config(cfg, voxel);
    let first_look = first_look_of(cfg, &search);
    // What the verification and the final refinement start from depends on the clouds and
    // the voxel only: it is built while the search runs, on the threads the search leaves
    // idle (the same results: every piece is a pure function of its inputs).
    let prepared = std::sync::OnceLock::new();
    let clouds = (source, target);
    let (started, (ready, prepared_final)) = rayon::join(
        || start_search(&prepared, source, target, cfg, &search, first_look.as_ref()),
        || prepare_alongside_search(clouds, voxel, &spacing_of_target, cfg, first_look),
    );
    let (running, first) = started?;
    let mut search_ms = ms(t0);
    // The first look's search ends here; completing it (below) counts as search too.
    let t_verify = Instant::now();
    let checks = Verifications {
        clouds,
        ready: ready.transpose()?,
        icp_runs: FirstStages::default(),
        search: &search,
        cfg,
    };
    let found = Hypotheses { running, checks }.found(first, first_look)?;
    let rest_ms = found.rest_ms;
    search_ms += rest_ms;
    let (first_look, verification, mut coarse) = (found.report, found.verification, found.coarse);
    let (start, coarse_transform, chosen_rank) =
        starting_pose(source, target, &coarse, verification.as_ref(), &search, cfg)?;
    let verify_ms = ms(t_verify) - rest_ms;
    let t_refine = Instant::now();
    let refined = refine_chosen(clouds, voxel, cfg, prepared_final, &start)?;
    let refine_ms = ms(t_refine);
    let (confidence, ambiguous, mut warnings) = assess(&coarse, verification.as_ref(), cfg);
    if let Some(r) = &refined {
        warnings.extend(refinement_warnings(&r.report));
    }
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
        first_look,
        verification,
        refine: refined,
        refine_cell: cfg.final_stage.cell_voxels * voxel,
        timings: StageTimes {
            search_ms,
            verify_ms,
            refine_ms,
            total_ms: ms(t0),
        },
        settings: None,
    })
}

/// What the search and the verification found; `rest_ms`: the wall time of the search after
/// the first look.
struct SearchAndVerification {
    coarse: SearchResult,
    verification: Option<Verification>,
    report: Option<FirstLookReport>,
    rest_ms: f64,
}

/// What a first look leads to.
enum Look {
    /// The pair is settled (or the look may not go on): the answer.
    Settled(Box<SearchAndVerification>),
    /// The whole search runs, with the look's report.
    GoOn(Option<FirstLookReport>),
}

/// One registration's hypotheses, owned together: the running grid search and their
/// verification.
struct Hypotheses<'a> {
    running: Search<'a, 'a>,
    checks: Verifications<'a>,
}

/// The verification's structures (built beside the search; `None` without verification)
/// and the ICP runs a first look leaves for the whole verification.
struct Verifications<'a> {
    clouds: (&'a Cloud, &'a Cloud),
    ready: Option<VerifyReady>,
    icp_runs: FirstStages,
    search: &'a SearchConfig,
    cfg: &'a RegistrationConfig,
}

impl Verifications<'_> {
    /// The verification of the hypotheses of `found` that `pass` takes (`None` without
    /// verification), reusing and keeping the ICP runs.
    fn verify(&mut self, found: &SearchResult, pass: VerifyPass) -> Result<Option<Verification>> {
        let (Some(v), Some(ready)) = (self.cfg.verify.as_ref(), self.ready.as_ref()) else {
            return Ok(None);
        };
        let inputs = VerifyInputs::new(self.clouds.0, self.clouds.1, found, self.search);
        verify_hypotheses(&inputs, ready, self.cfg, v, pass, &mut self.icp_runs).map(Some)
    }
}

impl Hypotheses<'_> {
    /// The first look's answer where it settles the pair (`first`: its search), else the
    /// whole search's and verification's.
    fn found(
        mut self,
        first: Option<SearchResult>,
        look: Option<FirstLook>,
    ) -> Result<SearchAndVerification> {
        let look = match (first, look) {
            (Some(first), Some(look)) => self.first_look(first, look)?,
            _ => Look::GoOn(None),
        };
        match look {
            Look::Settled(found) => Ok(*found),
            Look::GoOn(report) => self.complete(report),
        }
    }

    /// The first look's verification of `first` and its judgement: the whole answer when the
    /// look settles the pair (or may not go on), else its report (none without verification)
    /// for the whole search.
    fn first_look(&mut self, first: SearchResult, look: FirstLook) -> Result<Look> {
        let pass = VerifyPass::FirstLook {
            count: look.hypotheses,
            gate: look.accept_score,
        };
        let (Some(verification), Some(v)) =
            (self.checks.verify(&first, pass)?, self.checks.cfg.verify)
        else {
            return Ok(Look::GoOn(None));
        };
        let judged = look.judge(&verification, first.stats.scored, &v);
        if judged.accepted || look.stop_unsettled {
            return Ok(Look::Settled(Box::new(SearchAndVerification {
                coarse: first,
                verification: Some(verification),
                report: Some(judged),
                rest_ms: 0.0,
            })));
        }
        Ok(Look::GoOn(Some(judged)))
    }

    /// The rest of the search and the verification of every candidate.
    fn complete(mut self, report: Option<FirstLookReport>) -> Result<SearchAndVerification> {
        let t_rest = Instant::now();
        let coarse = self.running.complete()?;
        let rest_ms = ms(t_rest);
        let verification = self.checks.verify(&coarse, VerifyPass::All)?;
        Ok(SearchAndVerification {
            coarse,
            verification,
            report,
            rest_ms,
        })
    }
}

/// What the verification (with the first look's screening cells) and a thinned final
/// refinement start from, side by side (none where `cfg` has no verification or no thinned
/// refinement); `spacing` gives the target's point spacing.
fn prepare_alongside_search(
    (source, target): (&Cloud, &Cloud),
    voxel: f64,
    spacing: &(dyn Fn() -> f64 + Sync),
    cfg: &RegistrationConfig,
    look: Option<FirstLook>,
) -> (Option<Result<VerifyReady>>, Option<Result<PreparedPair>>) {
    let refine_cfg = final_refine_config(cfg);
    let icp = refine_cfg.unwrap_or(RefineConfig {
        threads: cfg.threads,
        ..RefineConfig::default()
    });
    let screen = look.map(|l| l.screen_cell_voxels);
    rayon::join(
        || {
            let v = cfg.verify.as_ref()?;
            Some(VerifyReady::new(
                source,
                target,
                voxel,
                spacing(),
                v,
                icp,
                screen,
            ))
        },
        || thinned_final_pair(source, target, voxel, refine_cfg.as_ref(), cfg),
    )
}

/// The final refinement's parameters on the pipeline's threads (`None`: no refinement).
fn final_refine_config(cfg: &RegistrationConfig) -> Option<RefineConfig> {
    cfg.refine.map(|r| RefineConfig {
        threads: cfg.threads,
        ..r
    })
}

/// The final refinement of `start` (`None` without one), on the pair prepared beside the
/// search when there is one.
fn refine_chosen(
    (source, target): (&Cloud, &Cloud),
    voxel: f64,
    cfg: &RegistrationConfig,
    prepared: Option<Result<PreparedPair>>,
    start: &Rigid,
) -> Result<Option<RefineResult>> {
    let Some(r) = final_refine_config(cfg) else {
        return Ok(None);
    };
    let pair =
        prepared.unwrap_or_else(|| final_pair(source, target, voxel, &r, cfg.final_stage))?;
    Ok(Some(refine_final(&pair, start, &r, cfg.final_stage)?))
}

/// The first look of `cfg`, where it applies: a coarse-to-fine search whose hypotheses are
/// verified.
fn first_look_of(cfg: &RegistrationConfig, search: &SearchConfig) -> Option<FirstLook> {
    let staged = matches!(search.mode, SearchMode::CoarseToFine(_)) && cfg.verify.is_some();
    cfg.first_look.filter(|_| staged)
}

/// The search prepared (kept in `slot`, which outlives it) and its coarse level ranked, with
/// the first look's result when `look` asks for one.
fn start_search<'a>(
    slot: &'a std::sync::OnceLock<PreparedSearch<'a>>,
    source: &'a Cloud,
    target: &'a Cloud,
    cfg: &'a RegistrationConfig,
    search: &'a SearchConfig,
    look: Option<&FirstLook>,
) -> Result<(Search<'a, 'a>, Option<SearchResult>)> {
    let made = PreparedSearch::new(source, target, &cfg.rotations, search)?;
    let prepared = slot.get_or_init(|| made);
    let mut running = prepared.start(&CpuBackend)?;
    let first = look
        .map(|l| running.score_leading(l.rotations))
        .transpose()?;
    Ok((running, first))
}

/// The final refinement's pair when it is thinned (built beside the search): a
/// full-resolution one (`--refine-cell 0`) of a large cloud would add its size to the
/// search's peak memory, so it is built after.
fn thinned_final_pair(
    source: &Cloud,
    target: &Cloud,
    voxel: f64,
    refine: Option<&RefineConfig>,
    cfg: &RegistrationConfig,
) -> Option<Result<PreparedPair>> {
    refine
        .filter(|_| cfg.final_stage.cell_voxels > 0.0)
        .map(|r| final_pair(source, target, voxel, r, cfg.final_stage))
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
    let r = RefineConfig {
        min_rotation_step: r.min_rotation_step.max(stage.min_step),
        min_translation_step: r.min_translation_step.max(stage.min_step),
        max_iterations: r.max_iterations.min(stage.max_iterations),
        ..*r
    };
    refine_prepared(pair, start, &r)
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
        warnings.extend(low_evidence(&chosen.evidence, v.distance));
        let tolerance = FREE_SPACE_WARNING * cfg.verify.unwrap_or_default().free_space_tolerance;
        if let Some(share) = chosen.evidence.free_space_violations.filter(|&s| s > tolerance) {
            warnings.push(format!(
                "free space: {:.1} % of the points lie more than {:.3} in front of what the other scan saw from its origin; the result is probably wrong",
                100.0 * share,
                v.free_space_margin
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

/// The low-evidence warning of a chosen pose, if its evidence is below [`LOW_EVIDENCE`]: its
/// overlap `(f_s + f_t)/2` (the share of points within `distance` of the other cloud), or
/// its score, the overlap less the free-space penalty `λ·max(0, v − v₀)`. A pose that only
/// won because every other one put more of its points in the other scan's seen free space
/// (all scoring 0) has a high confidence but a score near 0: it says so.
fn low_evidence(e: &Evidence, distance: f64) -> Option<String> {
    let overlap = 0.5 * (e.fitness_source + e.fitness_target);
    if overlap < LOW_EVIDENCE {
        Some(format!(
            "low evidence: only {:.0} % of the points lie within {distance:.3} of the other cloud after alignment; the result is probably wrong",
            100.0 * overlap,
        ))
    } else if e.score < LOW_EVIDENCE {
        Some(format!(
            "low evidence: {:.0} % of the points lie within {distance:.3} of the other cloud after alignment, but {:.1} % lie in the other scan's seen free space, which leaves a verification score of {:.3}, below {LOW_EVIDENCE}; the result is probably wrong",
            100.0 * overlap,
            100.0 * e.free_space_violations.unwrap_or(0.0),
            e.score,
        ))
    } else {
        None
    }
}

/// What the final refinement says against its own pose: a degenerate information matrix
/// (`λ_min / λ_max` below [`crate::refine::DEGENERATE_RATIO`]: the overlap leaves a motion
/// free, and the pose may be off along it) and a refinement that stopped without converging.
fn refinement_warnings(report: &QualityReport) -> Vec<String> {
    let mut warnings = Vec::new();
    if report.degenerate {
        let [low, .., high] = report.information_eigenvalues;
        warnings.push(format!(
            "weakly constrained: the overlap barely pins the pose in one direction (information eigenvalues λ_min / λ_max = {:.1e}, below {:.0e}); the result may be off along it (a plane sliding, a turn about a symmetry axis)",
            low / high,
            crate::refine::DEGENERATE_RATIO
        ));
    }
    if !report.converged {
        warnings.push(format!(
            "not converged: the final refinement stopped after {} iterations ({}); the result may be off",
            report.iterations, report.stop_reason
        ));
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;

    fn evidence(fitness: [f64; 2], free_space: Option<f64>, cfg: &VerifyConfig) -> Evidence {
        let overlap = 0.5 * (fitness[0] + fitness[1]);
        let excess = free_space.map_or(0.0, |v| (v - cfg.free_space_tolerance).max(0.0));
        Evidence {
            fitness_source: fitness[0],
            fitness_target: fitness[1],
            score: (overlap - cfg.free_space_weight * excess).max(0.0),
            points: [1000, 1000],
            free_space_violations: free_space,
        }
    }

    #[test]
    fn low_evidence_counts_the_free_space_penalty() {
        let cfg = VerifyConfig::default();
        let d = 0.5;
        // Little overlap: flagged, free space or not.
        let thin = low_evidence(&evidence([0.05, 0.1], None, &cfg), d).unwrap();
        assert!(thin.contains("only 8 %"), "{thin}");
        // Enough overlap and no scan: not flagged.
        assert_eq!(low_evidence(&evidence([0.14, 0.23], None, &cfg), d), None);
        // The same overlap with 2.9 % in the seen free space (under the free-space warning's
        // 3 %): the penalty leaves 0.095, flagged.
        let seen = evidence([0.14, 0.23], Some(0.029), &cfg);
        assert!(
            seen.score < LOW_EVIDENCE && seen.score > 0.09,
            "{}",
            seen.score
        );
        let w = low_evidence(&seen, d).unwrap();
        assert!(
            w.contains("2.9 % lie in the other scan's seen free space"),
            "{w}"
        );
        // Within the tolerance the score is the overlap: not flagged.
        assert_eq!(
            low_evidence(&evidence([0.14, 0.23], Some(0.015), &cfg), d),
            None
        );
    }

    fn quality(eigenvalues: [f64; 6], converged: bool) -> QualityReport {
        QualityReport {
            fitness_source: 0.5,
            fitness_target: 0.5,
            inlier_rmse: 0.01,
            inliers: 1000,
            correspondence_distance: 0.05,
            iterations: if converged { 4 } else { 100 },
            converged,
            stop_reason: if converged {
                "small update"
            } else {
                "max iterations"
            }
            .into(),
            information_eigenvalues: eigenvalues,
            degenerate: eigenvalues[0] < crate::refine::DEGENERATE_RATIO * eigenvalues[5],
        }
    }

    #[test]
    fn a_degenerate_or_unconverged_refinement_warns() {
        let well = [0.01, 0.02, 0.03, 0.04, 0.05, 0.06];
        assert!(refinement_warnings(&quality(well, true)).is_empty());
        let sliding = [1e-6, 0.02, 0.03, 0.04, 0.05, 0.06];
        let w = refinement_warnings(&quality(sliding, true));
        assert_eq!(w.len(), 1);
        assert!(
            w[0].starts_with("weakly constrained:") && w[0].contains("1.7e-5"),
            "{w:?}"
        );
        let w = refinement_warnings(&quality(well, false));
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("100 iterations (max iterations)"), "{w:?}");
        assert_eq!(refinement_warnings(&quality(sliding, false)).len(), 2);
    }

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
