//! The first look: before the whole coarse-to-fine search, score only the coarse level's
//! best few rotations at the voxel size, verify their best distinct poses and then the coarse
//! level's own distinct poses, and stop there when one pose is clearly right.
//!
//! Most of a pair's time goes to scoring the kept rotations' neighbours at the voxel size
//! and to verifying a dozen or more hypotheses, which the pairs that need them need (a
//! low-overlap view whose right pose ranks low, a scene with look-alike poses). A pair whose
//! coarse level ranks the right rotation near the top does not: its first hypothesis
//! converges under ICP and explains both clouds far better than any other pose.
//!
//! The alternatives it is weighed against are the coarse level's best distinct poses
//! ([`CoarseToFine::hypotheses`](crate::search::CoarseToFine::hypotheses), 8 by default):
//! the best poses over the whole rotation set at the coarser voxel, each verified as the
//! whole verification would (they are among its candidates too).
//!
//! # The rule
//! The first look accepts its chosen pose when
//! - its verification score is at least [`FirstLook::accept_score`] (0.5: with the tight
//!   score, `w = 1 − d²/D²` averaged over both clouds, at least half of each cloud lies
//!   close to the other: a wrong pose needs most of both surfaces to coincide), and
//! - every verified pose distinct from it scores below `reject_ratio` (0.6) times it: no
//!   look-alike competes (a scene whose floor dominates, slid along the floor, scores alike
//!   at several poses).
//!
//! When none of its own poses (those at the voxel size) reaches the score threshold, the
//! first look ends there, before the coarse level's; its checks compare with at least the
//! threshold ([`super::verify::RejectionThreshold`]). Where it does not settle the pair, the search goes on
//! exactly as without the first look and the verification takes every hypothesis; the first
//! look's ICP runs on its own poses are reused where a hypothesis starts from the same pose
//! (and the first hypothesis's whole decision where both passes start from the same pose),
//! so the result is the one the whole search gives, bit for bit, and the first look costs
//! only what it verified that the whole search does not.
//!
//! # Screening the alternatives
//! The coarse level's poses are only there to be ruled out: the first look's own pose is
//! the answer. They are verified as every hypothesis is (the same ICP schedule, checks and
//! score over the full clouds) but with ICP on both clouds thinned to cells of
//! [`FirstLook::screen_cell_voxels`] (one voxel) instead of the verification's half voxel:
//! about a quarter of the points. On coarser cells a pose converges in fewer iterations
//! (the bunny pair's second hypothesis reaches the right pose within its 10 iterations
//! before the check on cells of one voxel, and scores 0.22 at the check on cells of half a
//! voxel), so a competitor is, if anything, more visible. Measured on every benchmark of the
//! project (docs/notes/performance-history.md, "Screening the first look's alternatives"):
//! the first look settled the same pairs as with the alternatives verified on the
//! verification's own cells, with the same transform but for 10 pairs whose chosen pose was
//! itself an alternative (within 0.0006°), at 11 % fewer instructions on the bunny pair. The screening's ICP runs are not
//! reused by the whole verification (its cells differ), so a pair the first look declines
//! after screening pays for the screening: a quarter of what the alternatives cost before.
//!
//! Measured before it became the default (docs/pipeline.md, "The first look"): on every
//! benchmark of the project no pair was settled on a wrong pose, and no success was lost;
//! the wrong answers' chosen poses verify at 0.29 at most, the right ones of high-overlap
//! pairs at 0.5 to 0.9.

use super::verified::Verification;
use super::verify::VerifyConfig;

/// When to stop after the first look (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FirstLook {
    /// Rotations scored at the voxel size: the best of the coarse level, no neighbours.
    pub rotations: usize,
    /// Distinct hypotheses of those verified (the best first), before the coarse level's.
    pub hypotheses: usize,
    /// The least verification score accepted.
    pub accept_score: f64,
    /// The coarse level's alternatives are screened by the verification's ICP on clouds
    /// thinned to cells of this many voxels (0: the verification's own cells); see
    /// "Screening the alternatives" in the module documentation.
    pub screen_cell_voxels: f64,
    /// Where the first look does not settle the pair, stop there anyway and report its
    /// choice, unsettled ([`FirstLookReport::accepted`] false), instead of running the whole
    /// search: a quick try for a caller that has other pairs to try first (the alignment of
    /// many scans).
    pub stop_unsettled: bool,
}

impl Default for FirstLook {
    fn default() -> Self {
        FirstLook {
            rotations: 16,
            hypotheses: 4,
            accept_score: 0.5,
            screen_cell_voxels: 1.0,
            stop_unsettled: false,
        }
    }
}

/// What the first look did, for the report.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FirstLookReport {
    /// Rotations it scored at the voxel size.
    pub rotations: usize,
    /// Hypotheses it verified.
    pub verified: usize,
    /// Verification score of its chosen pose.
    pub score: f64,
    /// Best score of a pose distinct from the chosen one, if any was verified.
    pub runner_up_score: Option<f64>,
    /// The least score it accepts ([`FirstLook::accept_score`]).
    pub accept_score: f64,
    /// The pose was taken and the search stopped there.
    pub accepted: bool,
}

impl FirstLook {
    /// Whether `v`, the verification of the hypotheses of the first look's `rotations`
    /// (those it scored), settles the pair (see the module documentation), with the report
    /// either way.
    pub fn judge(&self, v: &Verification, rotations: usize, cfg: &VerifyConfig) -> FirstLookReport {
        let score = v.hypotheses[v.chosen].evidence.score;
        let runner_up_score = v.runner_up.map(|k| v.hypotheses[k].evidence.score);
        let clear = runner_up_score.is_none_or(|r| r < cfg.reject_ratio * score);
        FirstLookReport {
            rotations,
            verified: v.hypotheses.len(),
            score,
            runner_up_score,
            accept_score: self.accept_score,
            accepted: score >= self.accept_score && clear,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{VerifiedHypothesis, VerifyScore};
    use crate::transform::Rigid;

    /// A verification of hypotheses scoring `scores`, the first chosen, the best of the rest
    /// the distinct runner-up.
    fn verification(scores: &[f64]) -> Verification {
        let hypotheses: Vec<VerifiedHypothesis> = scores
            .iter()
            .enumerate()
            .map(|(rank, &score)| VerifiedHypothesis::scoring(rank, Rigid::identity(), score))
            .collect();
        let runner_up = (1..scores.len()).reduce(|a, b| if scores[b] > scores[a] { b } else { a });
        Verification {
            hypotheses,
            chosen: 0,
            runner_up,
            distance: 0.1,
            cell: 0.5,
            score: VerifyScore::Tight,
            scanners: [false, false],
            free_space_margin: 0.5,
        }
    }

    fn judged(scores: &[f64]) -> FirstLookReport {
        let v = verification(scores);
        FirstLook::default().judge(&v, 16, &VerifyConfig::default())
    }

    #[test]
    fn a_high_score_with_no_close_rival_is_taken() {
        let r = judged(&[0.78, 0.2, 0.07]);
        assert!(r.accepted);
        assert_eq!((r.rotations, r.verified), (16, 3));
        assert_eq!(r.runner_up_score, Some(0.2));
        assert!(judged(&[0.5]).accepted, "alone, at the threshold");
    }

    #[test]
    fn a_score_below_the_threshold_is_not_taken() {
        assert!(!judged(&[0.49, 0.1]).accepted);
        assert!(!judged(&[0.3]).accepted);
    }

    #[test]
    fn a_rival_at_the_reject_ratio_or_above_is_not_taken() {
        // 0.6 × 0.8 = 0.48: a rival at 0.5 would survive the verification's check.
        assert!(!judged(&[0.8, 0.5]).accepted);
        assert!(!judged(&[0.8, 0.2, 0.7]).accepted);
        assert!(judged(&[0.8, 0.47]).accepted);
    }
}
