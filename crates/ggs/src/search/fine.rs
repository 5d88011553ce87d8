//! The level at the voxel size: rounds of scoring, the exact winner, the distinct
//! hypotheses, and each argmax turned into a transform.

use super::config::{Precision, SearchConfig, SearchMode};
use super::correlator::{Backend, Correlator, PassControl, Scores};
use super::extents::{geometry_for, rotated_boxes, RotatedBox};
use super::levels::kept_with_neighbours;
use super::prepared::{ms, Prepared};
use super::result::{CoarseLevel, Hypothesis, SearchResult, SearchStats, Timings};
use super::selection::{exact_best, rescore_exact, LevelScores, Tally};
use super::voxel::Occupancy;
use crate::cloud::Cloud;
use crate::error::{GgsError, Result};
use crate::rotations::RotationSet;
use crate::transform::{Rigid, WithinDeg};
use nalgebra::Vector3;
use std::time::Instant;

/// The rotations at the voxel size: their extents, scores, and the correlator planned for
/// the largest rotated source scored so far.
pub(super) struct FineLevel<'p> {
    prep: &'p Prepared,
    kernel: Occupancy,
    boxes: Vec<Option<RotatedBox>>,
    scored: Vec<bool>,
    scores: LevelScores,
    corr: Option<Box<dyn Correlator>>,
    /// Memory estimate of the current plan, in bytes.
    estimate: u64,
    pub(super) target_ms: f64,
    pub(super) extents_ms: f64,
}

/// The winner, the distinct hypotheses (winner first) and the runner-up, as rotation indices.
pub(super) struct Picks {
    chosen: Vec<usize>,
    runner_up: Option<usize>,
    radius_deg: f64,
}

impl<'p> FineLevel<'p> {
    pub(super) fn new(prep: &'p Prepared, kernel: Occupancy, target_ms: f64) -> Self {
        debug_assert_eq!(kernel.dims, prep.kernel_dims);
        let n = prep.rows.len();
        FineLevel {
            prep,
            kernel,
            boxes: vec![None; n],
            scored: vec![false; n],
            scores: LevelScores::new(n),
            corr: None,
            estimate: 0,
            target_ms,
            extents_ms: 0.0,
        }
    }

    /// Rounds at the voxel size: all rotations (exhaustive), or the kept ones and their
    /// neighbours, with `kept` doubled while the winner ranks in the lower half of it (and,
    /// with [`stop_when_winner_holds`](super::CoarseToFine::stop_when_winner_holds), only
    /// while a doubling moves the winner). Returns the winner.
    pub(super) fn rounds(
        &mut self,
        backend: &dyn Backend,
        ctl: &PassControl<'_>,
        set: &RotationSet,
        cfg: &SearchConfig,
        mut coarse: Option<&mut CoarseLevel>,
        tally: &mut Tally,
    ) -> Result<usize> {
        let n = self.prep.rows.len();
        let mut keep = coarse.as_ref().map_or(n, |l| l.kept);
        let stop_when_held = match &cfg.mode {
            SearchMode::CoarseToFine(c) => c.stop_when_winner_holds,
            SearchMode::Exhaustive => false,
        };
        let mut previous = None;
        loop {
            let wanted = match &coarse {
                None => (0..n).collect::<Vec<_>>(),
                Some(level) => kept_with_neighbours(ctl.pool, level, keep, set),
            };
            self.score_unscored(backend, ctl, cfg.precision, wanted, tally)?;
            let w = self.winner(ctl, tally)?;
            if let Some(level) = coarse.as_deref_mut() {
                level.rounds += 1;
                level.kept = keep;
                level.winner_rank = level.rank_of(w);
                // A winner deep in the kept list means the coarse ranking is not clear for
                // this pair: look twice as far.
                let held = stop_when_held && previous == Some(w);
                if level.rank_of(w) * 2 > keep && self.scored.iter().any(|&d| !d) && !held {
                    keep = (keep * 2).min(n);
                    previous = Some(w);
                    continue;
                }
            }
            return Ok(w);
        }
    }

    /// The leading rotations: the `count` best of the coarse order at the voxel size (`1 ≤ count ≤`
    /// the set's size), no neighbours, no further rounds. Returns the winner among them. A later
    /// [`Self::rounds`] scores only the rotations this did not (a rotation's score depends on
    /// nothing else), so the search's result after both is the one `rounds` alone gives.
    pub(super) fn score_leading(
        &mut self,
        backend: &dyn Backend,
        ctl: &PassControl<'_>,
        cfg: &SearchConfig,
        coarse: &CoarseLevel,
        count: usize,
        tally: &mut Tally,
    ) -> Result<usize> {
        let mut wanted = coarse.order()[..count].to_vec();
        wanted.sort_unstable();
        self.score_unscored(backend, ctl, cfg.precision, wanted, tally)?;
        self.winner(ctl, tally)
    }

    /// Extents, plan and scores of the rotations of `wanted` not scored yet.
    fn score_unscored(
        &mut self,
        backend: &dyn Backend,
        ctl: &PassControl<'_>,
        precision: Precision,
        wanted: Vec<usize>,
        tally: &mut Tally,
    ) -> Result<()> {
        let new: Vec<usize> = wanted.into_iter().filter(|&k| !self.scored[k]).collect();
        self.extend_boxes(ctl, &new)?;
        self.plan(backend, precision)?;
        self.score(ctl, precision, &new, tally)
    }

    /// The best scored rotation by exact score.
    fn winner(&mut self, ctl: &PassControl<'_>, tally: &mut Tally) -> Result<usize> {
        let quiet = PassControl {
            progress: None,
            ..*ctl
        };
        self.exact_best(&quiet, |_| true, f64::NEG_INFINITY, tally)?
            .ok_or_else(|| GgsError::param("rotations", "no rotation was scored"))
    }

    /// Exact extents of the rotations `new`.
    fn extend_boxes(&mut self, ctl: &PassControl<'_>, new: &[usize]) -> Result<()> {
        let t = Instant::now();
        let p = self.prep;
        let found = rotated_boxes(ctl.pool, &p.source, &p.rows, new, p.voxel)?;
        for (k, b) in found.into_iter().enumerate() {
            if b.is_some() {
                self.boxes[k] = b;
            }
        }
        self.extents_ms += ms(t.elapsed());
        Ok(())
    }

    /// FFT lengths fit the largest source scored so far; a later round with a larger one
    /// re-plans (scores do not depend on the lengths).
    fn plan(&mut self, backend: &dyn Backend, precision: Precision) -> Result<()> {
        let geo = geometry_for(self.prep.kernel_dims, &self.boxes);
        if self.corr.as_ref().is_some_and(|c| *c.geometry() == geo) {
            return Ok(());
        }
        let p = self.prep;
        self.estimate = p.sizes.bytes(&geo);
        if self.estimate > p.budget {
            return Err(p.sizes.error(&geo, self.estimate, p.budget, p.voxel));
        }
        let t = Instant::now();
        let scores = match precision {
            Precision::Mixed => Scores::Mixed,
            Precision::F64 => Scores::Exact,
        };
        self.corr = Some(backend.plan(geo, &self.kernel, scores)?);
        self.target_ms += ms(t.elapsed());
        Ok(())
    }

    fn correlator(&self) -> Result<&dyn Correlator> {
        self.corr
            .as_deref()
            .ok_or_else(|| GgsError::param("rotations", "no rotation was scored"))
    }

    /// Scores the rotations `new`: approximately (mixed precision) or exactly.
    fn score(
        &mut self,
        ctl: &PassControl<'_>,
        precision: Precision,
        new: &[usize],
        tally: &mut Tally,
    ) -> Result<()> {
        let corr = self.correlator()?;
        let src = self.prep.sources(&self.boxes);
        match precision {
            Precision::Mixed => {
                let (found, st) = corr.approx(ctl, &src, new)?;
                tally.times.add(&st);
                for (&k, a) in new.iter().zip(found) {
                    self.scores.approx[k] = Some(a);
                }
            }
            Precision::F64 => {
                let (found, st) = corr.exact(ctl, &src, new)?;
                tally.times.add(&st);
                for (&k, b) in new.iter().zip(found) {
                    self.scores.exact[k] = Some(b);
                }
            }
        }
        for &k in new {
            self.scored[k] = true;
        }
        Ok(())
    }

    /// The best eligible scored rotation by exact score, if it reaches `at_least`
    /// ([`exact_best`]).
    fn exact_best(
        &mut self,
        ctl: &PassControl<'_>,
        eligible: impl Fn(usize) -> bool,
        at_least: f64,
        tally: &mut Tally,
    ) -> Result<Option<usize>> {
        let corr = self
            .corr
            .as_deref()
            .ok_or_else(|| GgsError::param("rotations", "no rotation was scored"))?;
        let src = self.prep.sources(&self.boxes);
        exact_best(&mut self.scores, eligible, at_least, |p, floor, sc| {
            rescore_exact(corr, ctl, &src, p, floor, sc, tally)
        })
    }

    /// The winner and the best rotations more than the distinct radius from every better
    /// pick, up to `top_k` (and at least 2, for the runner-up), those after the runner-up
    /// only while they reach [`SearchConfig::min_match_fraction`] of the winner.
    pub(super) fn distinct(
        &mut self,
        ctl: &PassControl<'_>,
        set: &RotationSet,
        cfg: &SearchConfig,
        winner: usize,
        tally: &mut Tally,
    ) -> Result<Picks> {
        let radius = cfg.distinct_radius_deg.unwrap_or(2.0 * set.step_deg);
        let mut chosen = vec![winner];
        let within = WithinDeg::new(radius);
        let win = self.scores.exact[winner].map_or(0, |b| b.match_score);
        let least = cfg.min_match_fraction.map_or(f64::NEG_INFINITY, |f| {
            if win > 0 {
                f * win as f64
            } else {
                f64::INFINITY
            }
        });
        while chosen.len() < cfg.top_k.max(2) {
            let far = |k: usize| {
                chosen
                    .iter()
                    .all(|&c| !within.holds(&set.matrices[c], &set.matrices[k]))
            };
            let at_least = if chosen.len() < 2 {
                f64::NEG_INFINITY
            } else {
                least
            };
            match self.exact_best(ctl, far, at_least, tally)? {
                Some(k) => chosen.push(k),
                None => break,
            }
        }
        let runner_up = chosen.get(1).copied();
        chosen.truncate(cfg.top_k);
        Ok(Picks {
            chosen,
            runner_up,
            radius_deg: radius,
        })
    }

    /// Rotation `k`'s exact argmax as a transform: with `c_x` the source centroid, `min` the
    /// rotated box's min corner, `C` the kernel centre, `a` the offset and `m_y` the
    /// target's min corner, `t = −R·c_x − min + (C − a)·s + m_y` (docs/method.md).
    fn hypothesis(&self, set: &RotationSet, k: usize) -> Result<Hypothesis> {
        let missing = || GgsError::param("rotations", "a selected rotation was not scored");
        let b = self.scores.exact[k].ok_or_else(missing)?;
        let bx = self.boxes[k].ok_or_else(missing)?;
        let corr = self.correlator()?;
        let geo = corr.geometry();
        let (s, m_y) = (self.prep.voxel, self.prep.target_min);
        let r = set.matrices[k];
        let mut t = -(r * Vector3::from(self.prep.source.centroid));
        for d in 0..3 {
            t[d] += -bx.min[d] + (geo.center[d] as f64 - b.offset[d] as f64) * s + m_y[d];
        }
        let constant = corr.kernel_cells() - 6 * corr.kernel_occupied();
        Ok(Hypothesis {
            rotation_index: k,
            score: constant + 6 * b.match_score,
            match_score: b.match_score,
            offset: b.offset,
            transform: Rigid::new(r, t),
        })
    }

    /// The search's result from its picks.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn result(
        &self,
        source: &Cloud,
        target: &Cloud,
        set: &RotationSet,
        cfg: &SearchConfig,
        picks: Picks,
        coarse_level: Option<CoarseLevel>,
        tally: &Tally,
        timings: Timings,
    ) -> Result<SearchResult> {
        let corr = self.correlator()?;
        let hypotheses = picks
            .chosen
            .iter()
            .map(|&k| self.hypothesis(set, k))
            .collect::<Result<Vec<_>>>()?;
        let runner_up = picks
            .runner_up
            .map(|k| self.hypothesis(set, k))
            .transpose()?;
        let win = hypotheses[0];
        let ambiguity = match runner_up {
            Some(r) if win.match_score > 0 => Some(r.match_score as f64 / win.match_score as f64),
            _ => None,
        };
        let stats = SearchStats {
            distinct_radius_deg: picks.radius_deg,
            voxel: self.prep.voxel,
            rotation_set: set.name.clone(),
            rotations: set.len(),
            source_points: source.len(),
            searched_points: self.prep.source.points.len(),
            target_points: target.len(),
            target_occupied: corr.kernel_occupied() as usize,
            geometry: *corr.geometry(),
            threads: self.prep.sizes.threads,
            memory_estimate_bytes: self.estimate,
            max_rounding_error: tally.times.max_rounding_error,
            mode: cfg.mode,
            precision: cfg.precision,
            scored: self.scored.iter().filter(|&&d| d).count(),
            rescored: tally.rescored,
            coarse_level,
            fft_gflop: tally.times.flops * 1e-9,
        };
        Ok(SearchResult {
            hypotheses,
            runner_up,
            ambiguity,
            stats,
            timings,
        })
    }
}
