//! The exact selection that makes reduced precision safe, and the distinct hypotheses.
//!
//! A rotation scored approximately has an interval `[value − bound, value + bound]` that
//! holds its exact best match score. The best eligible rotation is found by re-scoring
//! exactly every rotation whose interval reaches the best exact score known (or the best
//! lower end), until none is left: a rotation never re-scored has an exact score strictly
//! below the winner's, so the pick (ties to the lowest index) is the one an all-exact search
//! makes (docs/method.md, "Reduced precision").

use super::correlator::{
    ApproxBest, BestOffset, Candidates, Correlator, PassControl, Rescored, RotatedSources,
    PassTimes,
};
use crate::error::Result;
use std::time::{Duration, Instant};

/// Work counters of a search: stage times, and the exact re-scoring.
#[derive(Debug, Default)]
pub struct Tally {
    pub times: PassTimes,
    pub rescored: usize,
    pub rescore_time: Duration,
}

/// Re-score the rotations `pending` exactly against the floor `at_least`: into
/// `scores.exact`, or `scores.below` for those shown to stay below it.
pub fn rescore_exact(
    corr: &dyn Correlator,
    ctl: &PassControl<'_>,
    src: &RotatedSources<'_>,
    pending: &[usize],
    at_least: f64,
    scores: &mut LevelScores,
    tally: &mut Tally,
) -> Result<()> {
    let t = Instant::now();
    let candidates: Vec<Candidates> = pending
        .iter()
        .map(|&k| scores.approx[k].map_or(Candidates::NONE, |a| a.candidates))
        .collect();
    let (found, st) = corr.exact_among(ctl, src, pending, &candidates, at_least)?;
    tally.times.add(&st);
    for (&k, r) in pending.iter().zip(found) {
        match r {
            Rescored::Exact(b) => scores.exact[k] = Some(b),
            Rescored::Below(m) => scores.below[k] = Some(m),
            Rescored::TooMany => {
                return Err(crate::error::GgsError::param(
                    "rotations",
                    "an exact re-scoring was left unsettled",
                ))
            }
        }
    }
    tally.rescored += pending.len();
    tally.rescore_time += t.elapsed();
    Ok(())
}

/// Per-rotation scores of one resolution level: approximate, exact, or both; and for a
/// rotation re-scored against a floor it stayed below, the largest its exact best can be.
pub struct LevelScores {
    pub approx: Vec<Option<ApproxBest>>,
    pub exact: Vec<Option<BestOffset>>,
    pub below: Vec<Option<i64>>,
}

impl LevelScores {
    pub fn new(n: usize) -> Self {
        LevelScores {
            approx: vec![None; n],
            exact: vec![None; n],
            below: vec![None; n],
        }
    }

    /// The largest the exact best of unsettled rotation `k` can be.
    fn upper(&self, k: usize) -> Option<f64> {
        let a = self.approx[k]?;
        Some(match self.below[k] {
            Some(m) => a.upper().min(m as f64),
            None => a.upper(),
        })
    }

    fn scored(&self, k: usize) -> bool {
        self.approx[k].is_some() || self.exact[k].is_some()
    }
}

/// The eligible rotation with the highest exact match score (ties to the lowest index),
/// re-scoring exactly (`rescore(pending, floor, scores)`) only the rotations whose
/// approximate interval reaches the floor: each is settled or shown to stay below the floor.
/// `None` when no scored rotation is eligible, or none reaches `at_least` (the floor starts
/// there, so a rotation that could only score below it is never re-scored).
pub fn exact_best(
    scores: &mut LevelScores,
    eligible: impl Fn(usize) -> bool,
    at_least: f64,
    mut rescore: impl FnMut(&[usize], f64, &mut LevelScores) -> Result<()>,
) -> Result<Option<usize>> {
    let n = scores.exact.len();
    let candidates: Vec<usize> = (0..n)
        .filter(|&k| scores.scored(k) && eligible(k))
        .collect();
    loop {
        let mut best: Option<(i64, usize)> = None;
        let mut floor = at_least;
        for &k in &candidates {
            match (&scores.exact[k], &scores.approx[k]) {
                (Some(e), _) => {
                    if best.is_none_or(|(m, _)| e.match_score > m) {
                        best = Some((e.match_score, k));
                    }
                }
                (None, Some(a)) => floor = floor.max(a.lower()),
                (None, None) => {}
            }
        }
        if let Some((m, _)) = best {
            floor = floor.max(m as f64);
        }
        let pending: Vec<usize> = candidates
            .iter()
            .copied()
            .filter(|&k| scores.exact[k].is_none())
            .filter(|&k| {
                // A NaN bound (never expected) counts as reaching: re-score it.
                scores.upper(k).is_some_and(|u| u >= floor || u.is_nan())
            })
            .collect();
        if pending.is_empty() {
            return Ok(best.filter(|&(m, _)| m as f64 >= at_least).map(|(_, k)| k));
        }
        rescore(&pending, floor, scores)?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::search::correlator::{ApproxBest, BestOffset};

    fn exact(m: i64) -> Option<BestOffset> {
        Some(BestOffset {
            match_score: m,
            offset: [m as usize, 0, 0],
        })
    }

    fn approx(value: f64, bound: f64) -> Option<ApproxBest> {
        Some(ApproxBest {
            value,
            error_bound: bound,
            offset: [0; 3],
            candidates: Candidates::NONE,
        })
    }

    /// `exact_best` with a re-scoring that reveals `truth[k]` and records what it was asked.
    fn best(
        scores: &mut LevelScores,
        eligible: impl Fn(usize) -> bool,
        truth: &[i64],
    ) -> (Option<usize>, Vec<usize>) {
        best_against_floor(scores, eligible, truth, false)
    }

    /// [`best`], with a re-scoring that, when `floors`, only shows a rotation below the floor
    /// to be so (as [`Rescored::Below`]).
    fn best_against_floor(
        scores: &mut LevelScores,
        eligible: impl Fn(usize) -> bool,
        truth: &[i64],
        floors: bool,
    ) -> (Option<usize>, Vec<usize>) {
        let mut asked = Vec::new();
        let got = exact_best(scores, eligible, f64::NEG_INFINITY, |pending, floor, s| {
            for &k in pending {
                if floors && (truth[k] as f64) < floor {
                    s.below[k] = Some(floor.ceil() as i64 - 1);
                } else {
                    s.exact[k] = exact(truth[k]);
                }
                asked.push(k);
            }
            Ok(())
        })
        .unwrap();
        (got, asked)
    }

    #[test]
    fn below_the_least_score_nothing_is_rescored_or_returned() {
        // Rotation 0 is exact at 10, rotation 1 could reach 12, rotation 2 only 9.5.
        let mut s = LevelScores::new(3);
        s.exact[0] = exact(10);
        s.approx[1] = approx(11.0, 1.0);
        s.approx[2] = approx(9.0, 0.5);
        let mut asked = Vec::new();
        let got = exact_best(
            &mut s,
            |k| k != 0,
            10.0,
            |pending, _, sc| {
                for &k in pending {
                    sc.exact[k] = exact(9);
                }
                asked.extend_from_slice(pending);
                Ok(())
            },
        )
        .unwrap();
        // Rotation 1 is asked (truly 9); rotation 2 cannot reach 10; so none is returned.
        assert_eq!((got, asked), (None, vec![1]));
        let mut s = LevelScores::new(2);
        s.exact = vec![exact(7), exact(12)];
        let got = exact_best(&mut s, |_| true, 13.0, |_, _, _| Ok(())).unwrap();
        assert_eq!(got, None, "the best, 12, is below 13");
        let got = exact_best(&mut s, |_| true, 12.0, |_, _, _| Ok(())).unwrap();
        assert_eq!(got, Some(1));
    }

    #[test]
    fn a_rotation_shown_below_the_floor_is_asked_again_only_under_a_lower_floor() {
        // Rotation 0 is exact at 10. Rotation 1 might reach 12 but is truly 8: shown below
        // 10, it is not exact, and the winner is 0. Then with 0 not eligible the floor drops
        // to rotation 2's lower end (7.5) and rotation 1 is asked again: exact at 8, it wins.
        let mut s = LevelScores::new(3);
        s.exact[0] = exact(10);
        s.approx[1] = approx(9.0, 3.0);
        s.approx[2] = approx(8.0, 0.5);
        let truth = [10, 8, 8];
        let (got, asked) = best_against_floor(&mut s, |_| true, &truth, true);
        assert_eq!((got, asked), (Some(0), vec![1]));
        assert_eq!((s.exact[1], s.below[1]), (None, Some(9)));
        let (got, mut asked) = best_against_floor(&mut s, |k| k != 0, &truth, true);
        asked.sort();
        assert_eq!((got, asked), (Some(1), vec![1, 2]));
    }

    #[test]
    fn the_highest_exact_score_wins_and_ties_go_to_the_lowest_index() {
        let mut s = LevelScores::new(5);
        s.exact = vec![exact(3), exact(7), None, exact(7), exact(5)];
        let (got, asked) = best(&mut s, |_| true, &[0; 5]);
        assert_eq!(got, Some(1), "the first of the two 7s");
        assert!(asked.is_empty());
        // Not eligible, or not scored at all: never chosen.
        let mut s = LevelScores::new(4);
        s.exact = vec![exact(9), None, exact(4), exact(2)];
        let (got, _) = best(&mut s, |k| k != 0, &[0; 4]);
        assert_eq!(got, Some(2));
        let mut s = LevelScores::new(3);
        let (got, asked) = best(&mut s, |_| true, &[0; 3]);
        assert_eq!((got, asked), (None, vec![]));
    }

    #[test]
    fn only_intervals_that_reach_the_best_are_rescored() {
        // Rotation 0 is exact at 10; rotation 1 is at least 11, which sets the floor. Rotation
        // 1 may reach 12 (re-scored: truly 11, the winner); rotation 2 reaches at most 9
        // (never re-scored); rotation 3 reaches exactly the floor (re-scored: truly 11, a tie
        // lost to the lower index); rotation 4 is not eligible.
        let mut s = LevelScores::new(5);
        s.exact[0] = exact(10);
        s.approx[1] = approx(11.5, 0.5);
        s.approx[2] = approx(8.5, 0.5);
        s.approx[3] = approx(10.5, 0.5);
        s.approx[4] = approx(20.0, 1.0);
        let (got, mut asked) = best(&mut s, |k| k != 4, &[10, 11, 9, 11, 30]);
        asked.sort();
        assert_eq!(got, Some(1));
        assert_eq!(asked, vec![1, 3]);
        assert!(s.exact[2].is_none() && s.exact[4].is_none());
        // A lower bound above every exact score forces its re-scoring too.
        let mut s = LevelScores::new(2);
        s.exact[0] = exact(10);
        s.approx[1] = approx(14.0, 1.0);
        let (got, asked) = best(&mut s, |_| true, &[10, 13]);
        assert_eq!((got, asked), (Some(1), vec![1]));
    }
}
