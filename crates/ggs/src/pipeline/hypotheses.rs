//! The verification of a search's hypotheses, as the pipeline runs it: which hypotheses
//! (the distinct ones at the voxel size, then the coarse level's; or the first look's few),
//! their ICP's first stage side by side, the decisions in rank order ([`verify`]), the
//! settling of contested poses, the choice and the runner-up.

use super::config::RegistrationConfig;
use super::polish;
use super::verified::{
    HypothesisLevel, Verification, VerifiedHypothesis, SAME_POSE_DEG, SAME_POSE_VOXELS,
};
use super::verify::{self, VerifyConfig};
use crate::cloud::{Cloud, Point};
use crate::error::{GgsError, Result};
use crate::refine::{refine_prepared_pose, CorrespondenceDistance, PreparedPair, RefineConfig};
use crate::search::{Hypothesis, SearchConfig, SearchResult};
use crate::transform::{rotation_angle_deg, Rigid};
use rayon::prelude::*;

/// Verified poses farther apart than this many voxels in translation are distinct.
const DISTINCT_TRANSLATION_VOXELS: f64 = 3.0;
/// `h` polished when the config asks for it, else `h` itself.
pub(super) fn maybe_polished(
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
pub(super) struct VerifyInputs<'a> {
    source: &'a Cloud,
    target: &'a Cloud,
    coarse: &'a SearchResult,
    search: &'a SearchConfig,
}

impl<'a> VerifyInputs<'a> {
    pub(super) fn new(
        source: &'a Cloud,
        target: &'a Cloud,
        coarse: &'a SearchResult,
        search: &'a SearchConfig,
    ) -> Self {
        VerifyInputs {
            source,
            target,
            coarse,
            search,
        }
    }
}

/// The verification's structures, which depend on the clouds and the voxel only: the scorer
/// and the thinned pair of its ICP with its trees and shape grids. Built while the search
/// runs (see [`super::register`]).
pub(super) struct VerifyReady {
    verifier: verify::Verifier,
    thinned: PreparedPair,
    /// The first look's screening pair: the thinned pair thinned again to the coarser cells
    /// of this many voxels, built on first use.
    screen_cell: Option<f64>,
    screening: std::sync::OnceLock<PreparedPair>,
    icp: RefineConfig,
}

impl VerifyReady {
    pub(super) fn new(
        source: &Cloud,
        target: &Cloud,
        voxel: f64,
        spacing: f64,
        v: &VerifyConfig,
        icp: RefineConfig,
        screen_cell_voxels: Option<f64>,
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
            screen_cell: screen_cell_voxels.filter(|&c| c > 0.0).map(|c| c * voxel),
            screening: std::sync::OnceLock::new(),
            icp,
        })
    }

    /// The first look's screening pair (see [`Self::screen_cell`]), if it screens.
    fn screening_pair(&self) -> Option<&PreparedPair> {
        let cell = self.screen_cell?;
        Some(self.screening.get_or_init(|| {
            let pair = self.thinned.coarsened(cell);
            prepare_pair(&pair, &self.icp);
            pair
        }))
    }
}

/// Build what every refinement of `pair` with `r` starts from (trees, shape grids, and for a
/// quantile correspondence distance the target's median k-th-neighbour distance, where its
/// search starts); each is built on first use otherwise.
pub(super) fn prepare_pair(pair: &PreparedPair, r: &RefineConfig) {
    pair.prepare(r.method == crate::refine::Method::Gicp);
    if matches!(
        r.correspondence,
        crate::refine::CorrespondenceDistance::Quantile(_)
    ) {
        pair.target.median_kth_distance();
    }
}

/// Which hypotheses a verification takes.
#[derive(Debug, Clone, Copy)]
pub(super) enum VerifyPass {
    /// The first look's: the whole verification's candidates ([`candidates`]) with at most
    /// `count` at the voxel size, then the coarse level's (the best distinct poses over the whole
    /// set at the coarser voxel), and no settling (a contested pair is not accepted anyway).
    /// Where none of those at the voxel size scores `gate` (the first look cannot accept
    /// any), the coarse level's are not verified; where one does, they are screened on the
    /// coarser cells of the ready screening pair when there is one.
    FirstLook { count: usize, gate: f64 },
    /// Every candidate ([`candidates`]), contested poses settled.
    All,
}

/// The ICP runs of a pair's verification passes, kept for the next pass: the first stages by
/// the hypothesis they started from (a first stage depends on its start alone:
/// [`verify::first_stage`]), and the decision on a pass's first hypothesis (nothing to beat
/// and no pose before it, so a pure function of its start too).
#[derive(Default)]
pub(super) struct FirstStages {
    done: Vec<(Rigid, Hypothesis, verify::FirstStage)>,
    leader: Option<(Rigid, verify::Checked)>,
}

impl FirstStages {
    fn get(&self, start: &Rigid) -> Option<(Hypothesis, verify::FirstStage)> {
        self.done
            .iter()
            .find(|(s, _, _)| s == start)
            .map(|(_, h, f)| (*h, f.clone()))
    }

    fn has(&self, start: &Rigid) -> bool {
        self.done.iter().any(|(s, _, _)| s == start)
    }
}

/// Two poses compared where they put the source's centroid: the translation `t` itself
/// depends on the frame's origin (1° apart about an origin 4000 km away, as in UTM
/// coordinates, is 70 km).
struct PoseGap {
    centroid: Point,
    distinct_radius_deg: f64,
    voxel: f64,
}

impl PoseGap {
    fn new(source: &Cloud, coarse: &SearchResult) -> Self {
        PoseGap {
            centroid: source.centroid().expect("non-empty"),
            distinct_radius_deg: coarse.stats.distinct_radius_deg,
            voxel: coarse.stats.voxel,
        }
    }

    /// The angle between the rotations (degrees) and the distance between where the poses
    /// put the source's centroid.
    fn gap(&self, a: &Rigid, b: &Rigid) -> (f64, f64) {
        let (pa, pb) = (a.apply(&self.centroid), b.apply(&self.centroid));
        let moved =
            ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2) + (pa[2] - pb[2]).powi(2)).sqrt();
        (rotation_angle_deg(&a.rotation, &b.rotation), moved)
    }

    /// More than the distinct radius or [`DISTINCT_TRANSLATION_VOXELS`] apart.
    fn distinct(&self, a: &Rigid, b: &Rigid) -> bool {
        let (deg, moved) = self.gap(a, b);
        deg > self.distinct_radius_deg || moved > DISTINCT_TRANSLATION_VOXELS * self.voxel
    }

    /// Within [`SAME_POSE_DEG`] and [`SAME_POSE_VOXELS`].
    fn same(&self, a: &Rigid, b: &Rigid) -> bool {
        let (deg, moved) = self.gap(a, b);
        deg <= SAME_POSE_DEG && moved <= SAME_POSE_VOXELS * self.voxel
    }
}

impl VerifyPass {
    /// The hypotheses this pass verifies, in order.
    fn candidates(
        self,
        coarse: &SearchResult,
        v: &VerifyConfig,
        poses: &PoseGap,
    ) -> Vec<(Hypothesis, HypothesisLevel)> {
        let agree = |a: &Rigid, b: &Rigid| !poses.distinct(a, b);
        match self {
            // The whole verification's rule, at most `count` at the voxel size: the coarse
            // level's poses are the alternatives that tell a clear pair from an unclear one.
            VerifyPass::FirstLook { count, .. } => {
                let first = VerifyConfig {
                    max_hypotheses: count.min(v.max_hypotheses),
                    ..*v
                };
                candidates(coarse, &first, agree)
            }
            VerifyPass::All => candidates(coarse, v, agree),
        }
    }
}

/// Verify the hypotheses `pass` takes from `inputs.coarse` (see the module documentation).
pub(super) fn verify_hypotheses(
    inputs: &VerifyInputs,
    ready: &VerifyReady,
    cfg: &RegistrationConfig,
    v: &VerifyConfig,
    pass: VerifyPass,
    stages: &mut FirstStages,
) -> Result<Verification> {
    let poses = PoseGap::new(inputs.source, inputs.coarse);
    let todo = pass.candidates(inputs.coarse, v, &poses);
    let (own, floor) = match pass {
        // The first look decides its own poses (those at the voxel size) first; when none
        // scores the gate it settles nothing, and the coarse level's are left to the whole
        // verification.
        VerifyPass::FirstLook { gate, .. } => {
            let own = todo
                .iter()
                .take_while(|(_, level)| *level == HypothesisLevel::Voxel)
                .count();
            (own, gate.max(v.least_score))
        }
        VerifyPass::All => (todo.len(), v.least_score),
    };
    let checks = RankedChecks {
        ready,
        v,
        poses: &poses,
        floor,
    };
    let mut out = Vec::new();
    let firsts = checks.first_stages(inputs, cfg, &ready.thinned, &todo[..own], Some(stages))?;
    checks.in_order(&todo[..own], firsts, Some(stages), &ready.thinned, &mut out)?;
    if own < todo.len() && out.iter().any(|h| h.evidence.score >= floor) {
        let others = &todo[own..];
        checks.alternatives(inputs, cfg, others, stages, &mut out)?;
    }
    if matches!(pass, VerifyPass::All) {
        let finer = || {
            let cell = v.fine_cell_voxels * inputs.coarse.stats.voxel;
            let icp = &ready.icp;
            PreparedPair::thinned(
                inputs.source,
                inputs.target,
                cell,
                icp.neighbors,
                icp.epsilon,
            )
        };
        let distinct = |a: &Rigid, b: &Rigid| poses.distinct(a, b);
        let fine = settling_icp(&ready.icp, v, inputs.coarse.stats.voxel);
        settle_contested(&mut out, &ready.verifier, finer, &fine, v, &distinct)?;
    }
    // A hypothesis stopped on an earlier one's pose carries that one's evidence, settled or not
    // (`rank` is the position in `out`).
    for k in 0..out.len() {
        if let Some(j) = out[k].same_as {
            out[k].evidence = out[j].evidence;
        }
    }
    let chosen = best_scoring(&out, |_| true).expect("the winner is always verified");
    let runner_up = best_scoring(&out, |k| {
        poses.distinct(&out[k].transform, &out[chosen].transform)
    });
    Ok(Verification {
        hypotheses: out,
        chosen,
        runner_up,
        distance: ready.verifier.distance,
        cell: v.cell_voxels * inputs.coarse.stats.voxel,
        score: v.score,
        scanners: ready.verifier.scanners(),
        free_space_margin: ready.verifier.free_space_margin(),
    })
}

/// How a pass takes its decisions: on what, and against what floor.
struct RankedChecks<'r> {
    ready: &'r VerifyReady,
    v: &'r VerifyConfig,
    poses: &'r PoseGap,
    /// The least "best so far" a check compares with: the first look only looks for a pose
    /// scoring its gate, so a hypothesis below `reject_ratio` × the gate at its check is
    /// dropped there, as the whole verification drops one below `reject_ratio` × the best so
    /// far (the floor of the whole verification is [`VerifyConfig::least_score`], 0 unless
    /// the caller needs a score).
    floor: f64,
}

impl RankedChecks<'_> {
    /// Every hypothesis's polish and first stage on `pair` depend on its start alone: they run
    /// side by side, or come from an earlier pass (`stages`, which keeps the new ones; `None`:
    /// neither taken nor kept, for a pair other than the verification's).
    fn first_stages(
        &self,
        inputs: &VerifyInputs,
        cfg: &RegistrationConfig,
        pair: &PreparedPair,
        todo: &[(Hypothesis, HypothesisLevel)],
        stages: Option<&mut FirstStages>,
    ) -> Result<Vec<(Hypothesis, verify::FirstStage)>> {
        let (icp, v) = (&self.ready.icp, self.v);
        let kept = stages.as_deref();
        let firsts: Vec<(Hypothesis, verify::FirstStage)> = todo
            .par_iter()
            .map(|(h, _)| match kept.and_then(|k| k.get(&h.transform)) {
                Some(done) => Ok(done),
                None => {
                    let VerifyInputs {
                        source,
                        target,
                        search,
                        ..
                    } = *inputs;
                    let polished = maybe_polished(source, target, h, search, cfg)?;
                    let first = verify::first_stage(pair, &polished.transform, icp, v)?;
                    Ok((polished, first))
                }
            })
            .collect::<Result<_>>()?;
        if let Some(stages) = stages {
            for ((h, _), (polished, first)) in todo.iter().zip(&firsts) {
                if !stages.has(&h.transform) {
                    stages.done.push((h.transform, *polished, first.clone()));
                }
            }
        }
        Ok(firsts)
    }

    /// The first look's alternatives (the coarse level's poses), after its own: screened on
    /// the coarser cells (neither kept for nor taken from the whole verification, whose ICP
    /// runs on the finer ones), or on the verification's own cells where there is no
    /// screening pair.
    fn alternatives(
        &self,
        inputs: &VerifyInputs,
        cfg: &RegistrationConfig,
        others: &[(Hypothesis, HypothesisLevel)],
        stages: &mut FirstStages,
        out: &mut Vec<VerifiedHypothesis>,
    ) -> Result<()> {
        let ready = self.ready;
        match ready.screening_pair() {
            Some(screening) => {
                let firsts = self.first_stages(inputs, cfg, screening, others, None)?;
                self.in_order(others, firsts, None, screening, out)
            }
            None => {
                let firsts =
                    self.first_stages(inputs, cfg, &ready.thinned, others, Some(stages))?;
                self.in_order(others, firsts, Some(stages), &ready.thinned, out)
            }
        }
    }

    /// The decisions that depend on the hypotheses before ([`verify::finish`]), in order,
    /// appended to `out` (those decided before). A pass's first is taken from `stages` when an
    /// earlier pass decided the same start first and did not drop it at its check (its decision
    /// is then the one a pass with no floor takes). The ICP runs on `pair`: the
    /// verification's, with `stages`, or the first look's screening pair, without.
    fn in_order(
        &self,
        todo: &[(Hypothesis, HypothesisLevel)],
        firsts: Vec<(Hypothesis, verify::FirstStage)>,
        mut stages: Option<&mut FirstStages>,
        pair: &PreparedPair,
        out: &mut Vec<VerifiedHypothesis>,
    ) -> Result<()> {
        let (ready, v, poses) = (self.ready, self.v, self.poses);
        let mut best = out.iter().map(|h| h.evidence.score).fold(0.0f64, f64::max);
        for ((h, level), (polished, first)) in todo.iter().zip(firsts) {
            let rank = out.len();
            let known = |t: &Rigid| {
                out.iter()
                    .find(|o| {
                        !o.rejected_early && o.same_as.is_none() && poses.same(&o.transform, t)
                    })
                    .map(|o| (o.rank, o.evidence))
            };
            let (verifier, icp) = (&ready.verifier, &ready.icp);
            let leader = stages
                .as_deref()
                .and_then(|s| s.leader)
                .filter(|(start, _)| rank == 0 && *start == h.transform);
            let threshold = verify::RejectionThreshold {
                best,
                floor: self.floor,
            };
            let c = match leader {
                Some((_, c)) => c,
                None => verify::finish(first, pair, verifier, icp, v, threshold, &known)?,
            };
            if let Some(stages) = stages.as_deref_mut().filter(|_| rank == 0) {
                if !c.rejected_early {
                    stages.leader = Some((h.transform, c));
                }
            }
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
                rejected_on_subsample: c.rejected_on_subsample,
                settled: false,
                same_as: c.same_as,
                screened: stages.is_none(),
            });
        }
        Ok(())
    }
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

/// The ICP of the settling: the verification's (`icp`), for `fine_iterations`, with the
/// fixed correspondence distance `fine_distance_voxels` × `voxel` where that is set (0 by
/// default). From a right pose a few degrees off at 10–30 % overlap, the quantile distance of
/// the start takes in parts that do not overlap and can hold the pose short; a distance under
/// a voxel pulls only the parts that already nearly meet (docs/pipeline.md, step 3, has what it
/// gains and costs).
fn settling_icp(icp: &RefineConfig, v: &VerifyConfig, voxel: f64) -> RefineConfig {
    let correspondence = if v.fine_distance_voxels > 0.0 {
        CorrespondenceDistance::Fixed(v.fine_distance_voxels * voxel)
    } else {
        icp.correspondence
    };
    RefineConfig {
        max_iterations: v.fine_iterations,
        correspondence,
        ..*icp
    }
}

/// When two distinct poses both score at least `settle_ratio` × the best (or ×
/// [`VerifyConfig::least_score`] when that is more), refines each such contender again on
/// clouds thinned to the finer cells of `fine_cell_voxels` (built only then, `finer`) by the
/// ICP `fine` ([`settling_icp`]), and re-scores it: on the coarser cells a right pose of a
/// small overlap stops short (too few points where the clouds overlap) and loses to a loose
/// look-alike (docs/pipeline.md, "Coarse-level hypotheses and contested poses"). A
/// hypothesis stopped at its check is a contender too: at 10–30 % overlap the right pose,
/// still turning there, often scores half the best (a flip's large loose overlap) and would
/// have passed had its ICP gone on. A clear pair costs nothing more.
fn settle_contested(
    out: &mut [VerifiedHypothesis],
    verifier: &verify::Verifier,
    finer: impl FnOnce() -> Result<PreparedPair>,
    fine: &RefineConfig,
    v: &VerifyConfig,
    distinct: &dyn Fn(&Rigid, &Rigid) -> bool,
) -> Result<()> {
    if v.fine_cell_voxels <= 0.0 || v.fine_iterations == 0 {
        return Ok(());
    }
    let Some(contenders) = contested(out, v, distinct) else {
        return Ok(());
    };
    let pair = finer()?;
    // The contenders' ICP runs side by side on the registration's threads (each result is
    // a pure function of its start), then are recorded in index order.
    let settled = contenders
        .par_iter()
        .map(|&k| {
            let r = refine_prepared_pose(&pair, &out[k].transform, fine)?;
            Ok((k, r, verifier.evidence(&r.transform)))
        })
        .collect::<Result<Vec<_>>>()?;
    for (k, r, evidence) in settled {
        let h = &mut out[k];
        h.transform = r.transform;
        h.evidence = evidence;
        h.iterations += r.iterations;
        h.settled = true;
    }
    Ok(())
}

/// The contenders of [`settle_contested`] (indices, increasing), or `None` when the pair is
/// not contested: every hypothesis not stopped on another's pose that scores at least
/// `settle_ratio` × the best (or × `least_score` when that is more), when two of them are
/// `distinct` poses.
fn contested(
    out: &[VerifiedHypothesis],
    v: &VerifyConfig,
    distinct: &dyn Fn(&Rigid, &Rigid) -> bool,
) -> Option<Vec<usize>> {
    let best = out
        .iter()
        .map(|h| h.evidence.score)
        .fold(v.least_score, f64::max);
    let contenders: Vec<usize> = (0..out.len())
        .filter(|&k| out[k].same_as.is_none() && out[k].evidence.score >= v.settle_ratio * best)
        .collect();
    let two_poses = contenders.iter().any(|&a| {
        contenders
            .iter()
            .any(|&b| distinct(&out[a].transform, &out[b].transform))
    });
    two_poses.then_some(contenders)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    /// A verified hypothesis at a shift of `x` along x, scoring `score`.
    fn verified(rank: usize, x: f64, score: f64, rejected_early: bool) -> VerifiedHypothesis {
        let t = Rigid {
            rotation: nalgebra::Matrix3::identity(),
            translation: Vector3::new(x, 0.0, 0.0),
        };
        VerifiedHypothesis {
            rejected_early,
            ..VerifiedHypothesis::scoring(rank, t, score)
        }
    }

    /// Poses more than 1 apart along x are distinct.
    fn apart(a: &Rigid, b: &Rigid) -> bool {
        (a.translation - b.translation).norm() > 1.0
    }

    #[test]
    fn the_settling_fixes_its_distance_in_voxels_only_when_asked() {
        let icp = RefineConfig::default();
        let mut v = VerifyConfig::default();
        let own = settling_icp(&icp, &v, 0.06);
        assert_eq!(own.correspondence, icp.correspondence);
        assert_eq!(own.max_iterations, v.fine_iterations);
        v.fine_distance_voxels = 0.75;
        let fixed = settling_icp(&icp, &v, 0.06);
        assert_eq!(
            fixed.correspondence,
            CorrespondenceDistance::Fixed(0.75 * 0.06)
        );
    }

    #[test]
    fn a_pose_stopped_at_its_check_with_half_the_best_score_contests_the_best() {
        let v = VerifyConfig::default();
        let mut out = vec![
            verified(0, 0.0, 0.20, false),
            verified(1, 5.0, 0.11, true),
            verified(2, 9.0, 0.09, true),
        ];
        assert_eq!(contested(&out, &v, &apart), Some(vec![0, 1]));
        // Below `settle_ratio` × the best, it does not.
        out[1].evidence.score = 0.09;
        assert_eq!(contested(&out, &v, &apart), None);
        // Nor one stopped on the best's pose, nor a second hypothesis on the same pose.
        out[1].evidence.score = 0.15;
        out[1].same_as = Some(0);
        assert_eq!(contested(&out, &v, &apart), None);
        out[1].same_as = None;
        out[1].transform = out[0].transform;
        assert_eq!(contested(&out, &v, &apart), None);
    }
}
