//! Scoring passes over a list of rotations, and the exact selection that makes reduced
//! precision safe.
//!
//! A pass voxelizes each rotated source into a worker's workspace and correlates it. Work is
//! handed out by an atomic counter and every result lands in the slot of its rotation, so a
//! pass gives the same results whatever the thread count.
//!
//! Selection ([`exact_best`]): a rotation scored in f32 has an interval
//! `[value − bound, value + bound]` that holds its exact best match score. The best eligible
//! rotation is found by re-scoring in f64 every rotation whose interval reaches the best exact
//! score known (or the best lower end), until none is left: a rotation never re-scored has an
//! exact score strictly below the winner's, so the pick (ties to the lowest index) is the one
//! an all-f64 search makes.

use super::RotatedBox;
use crate::correlate::{ApproxBest, BestOffset, CpuCorrelator, Real, Workspace};
use crate::error::{GgsError, Result};
use crate::rotated::RotatableCloud;
use rayon::ThreadPool;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// CPU time of a pass per stage, summed over workers.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct StageTimes {
    pub voxelize: Duration,
    pub forward: Duration,
    pub product: Duration,
    pub inverse: Duration,
    /// Largest distance of an f64 output from its integer.
    pub max_rounding_error: f64,
    /// Nominal FFT floating-point operations ([`Geometry::flops`](crate::correlate::Geometry::flops)).
    pub flops: f64,
}

impl StageTimes {
    pub fn add(&mut self, o: &StageTimes) {
        self.voxelize += o.voxelize;
        self.forward += o.forward;
        self.product += o.product;
        self.inverse += o.inverse;
        self.max_rounding_error = self.max_rounding_error.max(o.max_rounding_error);
        self.flops += o.flops;
    }
}

/// What a pass needs besides the correlator: the rotated source and where to stop.
pub(super) struct PassInput<'a> {
    pub pool: &'a ThreadPool,
    pub threads: usize,
    pub cloud: &'a RotatableCloud,
    pub rows: &'a [[[f64; 3]; 3]],
    /// Extents per rotation index (entries outside `indices` are not read).
    pub boxes: &'a [Option<RotatedBox>],
    pub voxel: f64,
    pub cancel: Option<&'a Arc<AtomicBool>>,
    pub progress: Option<&'a (dyn Fn(usize) + Send + Sync)>,
}

/// Score the rotations `indices` with `score` (one call per rotation, in a worker's
/// workspace holding that rotation's source grid). Results are in the order of `indices`.
pub(super) fn run_pass<T: Real, R: Send + Copy>(
    input: &PassInput<'_>,
    corr: &CpuCorrelator<T>,
    indices: &[usize],
    score: impl Fn(&CpuCorrelator<T>, &mut Workspace<T>) -> R + Sync,
) -> Result<(Vec<R>, StageTimes)> {
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let slots: Mutex<Vec<Option<R>>> = Mutex::new(vec![None; indices.len()]);
    let stats: Mutex<StageTimes> = Mutex::new(StageTimes::default());
    let cancelled = AtomicBool::new(false);
    let s = input.voxel;
    let workers = input.threads.min(indices.len()).max(1);
    input.pool.scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|_| {
                let mut ws = corr.workspace();
                let mut t_vox = Duration::ZERO;
                let mut flops = 0.0;
                let mut local: Vec<(usize, R)> = Vec::new();
                loop {
                    if input.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                        cancelled.store(true, Ordering::Relaxed);
                        break;
                    }
                    let slot = next.fetch_add(1, Ordering::Relaxed);
                    if slot >= indices.len() {
                        break;
                    }
                    let k = indices[slot];
                    let tv = Instant::now();
                    let b = input.boxes[k].expect("extents computed for every scored rotation");
                    ws.begin(b.dims);
                    input
                        .cloud
                        .voxelize(&input.rows[k], &b.min, s, ws.grid_mut());
                    t_vox += tv.elapsed();
                    flops += corr.geometry().flops(b.dims);
                    local.push((slot, score(corr, &mut ws)));
                    let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                    if let Some(p) = input.progress {
                        p(n);
                    }
                }
                let mut sl = slots
                    .lock()
                    .expect("no worker panics while holding the lock");
                for (slot, r) in local {
                    sl[slot] = Some(r);
                }
                let mut st = stats
                    .lock()
                    .expect("no worker panics while holding the lock");
                st.add(&StageTimes {
                    voxelize: t_vox,
                    forward: ws.t_forward,
                    product: ws.t_product,
                    inverse: ws.t_inverse,
                    max_rounding_error: ws.max_rounding_error,
                    flops,
                });
            });
        }
    });
    if cancelled.load(Ordering::Relaxed) {
        return Err(GgsError::Cancelled);
    }
    let results = slots
        .into_inner()
        .expect("workers finished")
        .into_iter()
        .map(|r| r.expect("every rotation scored"))
        .collect();
    Ok((results, stats.into_inner().expect("workers finished")))
}

/// Work counters of a search: stage times, and the f64 re-scoring.
#[derive(Debug, Default)]
pub(super) struct Tally {
    pub times: StageTimes,
    pub rescored: usize,
    pub rescore_time: Duration,
}

/// Re-score the rotations `pending` in f64 (exact integers) into `scores.exact`.
pub(super) fn rescore_f64(
    input: &PassInput<'_>,
    corr: &CpuCorrelator<f64>,
    pending: &[usize],
    scores: &mut LevelScores,
    tally: &mut Tally,
) -> Result<()> {
    let t = Instant::now();
    let (found, st) = run_pass(input, corr, pending, |c, ws| c.best_offset(ws))?;
    tally.times.add(&st);
    for (&k, b) in pending.iter().zip(found) {
        scores.exact[k] = Some(b);
    }
    tally.rescored += pending.len();
    tally.rescore_time += t.elapsed();
    Ok(())
}

/// Per-rotation scores of one resolution level: approximate, exact, or both.
pub(super) struct LevelScores {
    pub approx: Vec<Option<ApproxBest>>,
    pub exact: Vec<Option<BestOffset>>,
}

impl LevelScores {
    pub fn new(n: usize) -> Self {
        LevelScores {
            approx: vec![None; n],
            exact: vec![None; n],
        }
    }

    fn scored(&self, k: usize) -> bool {
        self.approx[k].is_some() || self.exact[k].is_some()
    }
}

/// The eligible rotation with the highest exact match score (ties to the lowest index),
/// re-scoring in f64 (`rescore`) only the rotations whose approximate interval reaches it.
/// `None` when no scored rotation is eligible.
pub(super) fn exact_best(
    scores: &mut LevelScores,
    eligible: impl Fn(usize) -> bool,
    mut rescore: impl FnMut(&[usize], &mut LevelScores) -> Result<()>,
) -> Result<Option<usize>> {
    let n = scores.exact.len();
    let candidates: Vec<usize> = (0..n)
        .filter(|&k| scores.scored(k) && eligible(k))
        .collect();
    loop {
        let mut best: Option<(i64, usize)> = None;
        let mut floor = f64::NEG_INFINITY;
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
                scores.approx[k].is_some_and(|a| a.upper() >= floor || a.upper().is_nan())
            })
            .collect();
        if pending.is_empty() {
            return Ok(best.map(|(_, k)| k));
        }
        rescore(&pending, scores)?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::correlate::{ApproxBest, BestOffset};

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
        })
    }

    /// `exact_best` with a re-scoring that reveals `truth[k]` and records what it was asked.
    fn best(
        scores: &mut LevelScores,
        eligible: impl Fn(usize) -> bool,
        truth: &[i64],
    ) -> (Option<usize>, Vec<usize>) {
        let mut asked = Vec::new();
        let got = exact_best(scores, eligible, |pending, s| {
            for &k in pending {
                s.exact[k] = exact(truth[k]);
                asked.push(k);
            }
            Ok(())
        })
        .unwrap();
        (got, asked)
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

    #[test]
    fn stage_times_add_up() {
        let ms = Duration::from_millis;
        let mut a = StageTimes {
            voxelize: ms(1),
            forward: ms(2),
            product: ms(3),
            inverse: ms(4),
            max_rounding_error: 1e-9,
            flops: 10.0,
        };
        a.add(&StageTimes {
            voxelize: ms(10),
            forward: ms(20),
            product: ms(30),
            inverse: ms(40),
            max_rounding_error: 1e-12,
            flops: 5.0,
        });
        assert_eq!(
            (a.voxelize, a.forward, a.product, a.inverse),
            (ms(11), ms(22), ms(33), ms(44))
        );
        assert_eq!((a.max_rounding_error, a.flops), (1e-9, 15.0));
    }
}
