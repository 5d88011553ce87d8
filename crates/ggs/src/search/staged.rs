//! A search in steps, for a caller that may stop early: [`PreparedSearch::start`] ranks
//! every rotation at the coarse level (coarse-to-fine); [`Search::score_leading`] scores only
//! the coarse level's leading few at the voxel size and picks their distinct hypotheses;
//! [`Search::complete`] scores what the whole search scores and returns what
//! [`grid_search_with`](super::grid_search_with) returns, bit for bit: a rotation's
//! score depends on nothing but the rotation, so the ones scored first keep theirs,
//! and the picks are the exact best among the scored rotations whichever were re-scored
//! exactly on the way ([`super::selection::exact_best`]).

use super::config::{SearchConfig, SearchMode};
use super::correlator::{Backend, PassControl};
use super::extents::target_kernel;
use super::fine::{FineLevel, Picks};
use super::levels::coarse_candidates;
use super::prepared::{ms, validate, Prepared};
use super::result::{CoarseLevel, SearchResult, Timings};
use super::selection::Tally;
use crate::cloud::Cloud;
use crate::error::{GgsError, Result};
use crate::rotations::RotationSet;
use std::time::Instant;

/// A checked request with both clouds prepared (the source centred, the rotations as rows, the
/// memory budget) and the search's thread pool.
pub struct PreparedSearch<'c> {
    source: &'c Cloud,
    target: &'c Cloud,
    set: &'c RotationSet,
    cfg: &'c SearchConfig,
    pool: rayon::ThreadPool,
    threads: usize,
    prep: Prepared,
    started: Instant,
}

impl<'c> PreparedSearch<'c> {
    /// Check the request (bad voxel, empty set or clouds, bad coarse-to-fine parameters) and
    /// prepare both clouds.
    pub fn new(
        source: &'c Cloud,
        target: &'c Cloud,
        set: &'c RotationSet,
        cfg: &'c SearchConfig,
    ) -> Result<Self> {
        let started = Instant::now();
        validate(source, target, set, cfg)?;
        let threads = crate::threads::resolve(cfg.threads);
        let (pool, _) = crate::threads::pool(threads)?;
        let prep = Prepared::new(source, target, set, cfg, threads)?;
        Ok(PreparedSearch {
            source,
            target,
            set,
            cfg,
            pool,
            threads,
            prep,
            started,
        })
    }

    fn control(&self) -> PassControl<'_> {
        PassControl {
            pool: &self.pool,
            threads: self.threads,
            cancel: self.cfg.cancel.as_ref(),
            progress: None,
        }
    }

    /// The coarse level (coarse-to-fine: every rotation ranked at the coarser voxel) and the
    /// target's kernel at the voxel size.
    pub fn start<'a>(&'a self, backend: &'a dyn Backend) -> Result<Search<'a, 'c>> {
        let mut tally = Tally::default();
        let t_coarse = Instant::now();
        let coarse_level = match &self.cfg.mode {
            SearchMode::Exhaustive => None,
            SearchMode::CoarseToFine(c) => {
                let with_progress = PassControl {
                    progress: self.cfg.progress.as_deref(),
                    ..self.control()
                };
                let (level, times) = coarse_candidates(
                    backend,
                    &with_progress,
                    &self.prep,
                    self.target,
                    self.set,
                    self.cfg,
                    c,
                )?;
                tally.times.add(&times);
                Some(level)
            }
        };
        let coarse_level_ms = ms(t_coarse.elapsed());
        let t_kernel = Instant::now();
        let kernel = target_kernel(self.target, self.prep.target_min, self.cfg.voxel)?;
        let fine = FineLevel::new(&self.prep, kernel, ms(t_kernel.elapsed()));
        Ok(Search {
            inputs: self,
            backend,
            coarse_level,
            coarse_level_ms,
            fine,
            tally,
            fine_ms: 0.0,
        })
    }
}

/// A search under way: the coarse level done, the voxel size's level scored so far.
pub struct Search<'a, 'c> {
    inputs: &'a PreparedSearch<'c>,
    backend: &'a dyn Backend,
    coarse_level: Option<CoarseLevel>,
    coarse_level_ms: f64,
    fine: FineLevel<'a>,
    tally: Tally,
    /// Wall time spent at the voxel size so far, ms.
    fine_ms: f64,
}

impl Search<'_, '_> {
    /// The `count` best rotations of the coarse level scored at the voxel size (no
    /// neighbours, no further rounds) and their distinct hypotheses, as a result whose
    /// coarse level says `kept: count`. An error for an exhaustive search (no coarse level).
    pub fn score_leading(&mut self, count: usize) -> Result<SearchResult> {
        let p = self.inputs;
        let level = self.coarse_level.as_ref().ok_or_else(|| {
            GgsError::param(
                "search",
                "scoring the leading rotations needs a coarse-to-fine search",
            )
        })?;
        let t = Instant::now();
        let ctl = p.control();
        let count = count.clamp(1, level.order().len());
        let winner =
            self.fine
                .score_leading(self.backend, &ctl, p.cfg, level, count, &mut self.tally)?;
        let picks = self
            .fine
            .distinct(&ctl, p.set, p.cfg, winner, &mut self.tally)?;
        self.fine_ms += ms(t.elapsed());
        let mut level = level.clone();
        level.kept = count;
        level.winner_rank = level.rank_of(winner);
        level.rounds = 0;
        self.result(picks, Some(level))
    }

    /// The whole search: at the voxel size, the kept rotations and their neighbours in
    /// rounds (coarse-to-fine) or every rotation (exhaustive), then the distinct hypotheses.
    pub fn complete(mut self) -> Result<SearchResult> {
        let p = self.inputs;
        let t = Instant::now();
        let ctl = p.control();
        let progress = match p.cfg.mode {
            SearchMode::Exhaustive => p.cfg.progress.as_deref(),
            SearchMode::CoarseToFine(_) => None,
        };
        let winner = self.fine.rounds(
            self.backend,
            &PassControl { progress, ..ctl },
            p.set,
            p.cfg,
            self.coarse_level.as_mut(),
            &mut self.tally,
        )?;
        let picks = self
            .fine
            .distinct(&ctl, p.set, p.cfg, winner, &mut self.tally)?;
        self.fine_ms += ms(t.elapsed());
        let level = self.coarse_level.take();
        self.result(picks, level)
    }

    fn result(&self, picks: Picks, level: Option<CoarseLevel>) -> Result<SearchResult> {
        let p = self.inputs;
        let times = &self.tally.times;
        let timings = Timings {
            target_ms: self.fine.target_ms,
            extents_ms: self.fine.extents_ms,
            search_ms: self.fine_ms,
            total_ms: 0.0,
            cpu_voxelize_ms: ms(times.voxelize),
            cpu_forward_ms: ms(times.forward),
            cpu_product_ms: ms(times.product),
            cpu_inverse_ms: ms(times.inverse),
            cpu_direct_ms: ms(times.direct),
            coarse_level_ms: self.coarse_level_ms,
            rescore_ms: ms(self.tally.rescore_time),
        };
        let mut result = self.fine.result(
            p.source,
            p.target,
            p.set,
            p.cfg,
            picks,
            level,
            &self.tally,
            timings,
        )?;
        result.timings.total_ms = ms(p.started.elapsed());
        Ok(result)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::search::config::CoarseToFine;
    use crate::search::passes::CpuBackend;
    use crate::search::source::tests::plane;
    use crate::search::{grid_search, SearchConfig};
    use crate::transform::Rigid;
    use nalgebra::Vector3;

    fn pair(set: &RotationSet) -> (Cloud, Cloud) {
        let source = plane(60, 0.02);
        let truth = Rigid::new(set.matrices[700], Vector3::new(0.3, -0.2, 0.1));
        let target = source.transformed(&truth);
        (source, target)
    }

    fn coarse_to_fine() -> SearchConfig {
        let mut cfg = SearchConfig::with_voxel(0.06);
        cfg.mode = SearchMode::CoarseToFine(CoarseToFine::for_verification());
        cfg.top_k = 8;
        cfg
    }

    #[test]
    fn the_leading_rotations_then_the_rest_is_the_whole_search_bit_for_bit() {
        let set = RotationSet::named("limited15").unwrap();
        let (source, target) = pair(&set);
        let cfg = coarse_to_fine();
        let whole = grid_search(&source, &target, &set, &cfg).unwrap();
        let prepared = PreparedSearch::new(&source, &target, &set, &cfg).unwrap();
        let mut search = prepared.start(&CpuBackend).unwrap();
        let first = search.score_leading(4).unwrap();
        let rest = search.complete().unwrap();
        assert_eq!(rest.hypotheses, whole.hypotheses);
        assert_eq!(rest.runner_up, whole.runner_up);
        assert_eq!(rest.ambiguity, whole.ambiguity);
        assert_eq!(rest.stats.scored, whole.stats.scored);
        let (a, b) = (
            rest.stats.coarse_level.unwrap(),
            whole.stats.coarse_level.unwrap(),
        );
        assert_eq!(
            (a.kept, a.rounds, a.winner_rank),
            (b.kept, b.rounds, b.winner_rank)
        );
        assert!(first.stats.scored < whole.stats.scored);
    }

    #[test]
    fn scoring_the_leading_rotations_scores_only_the_best_of_the_coarse_level() {
        let set = RotationSet::named("limited15").unwrap();
        let (source, target) = pair(&set);
        let cfg = coarse_to_fine();
        let prepared = PreparedSearch::new(&source, &target, &set, &cfg).unwrap();
        let mut search = prepared.start(&CpuBackend).unwrap();
        let first = search.score_leading(4).unwrap();
        let level = first.stats.coarse_level.as_ref().unwrap();
        assert_eq!((first.stats.scored, level.kept, level.rounds), (4, 4, 0));
        let best = &level.order()[..4];
        assert!(first
            .hypotheses
            .iter()
            .all(|h| best.contains(&h.rotation_index)));
        assert_eq!(
            level.winner_rank,
            level.rank_of(first.winner().rotation_index)
        );
    }

    #[test]
    fn an_exhaustive_search_has_no_leading_rotations() {
        let set = RotationSet::named("limited15").unwrap();
        let (source, target) = pair(&set);
        let cfg = SearchConfig::with_voxel(0.06);
        let prepared = PreparedSearch::new(&source, &target, &set, &cfg).unwrap();
        let mut search = prepared.start(&CpuBackend).unwrap();
        assert!(search.score_leading(4).is_err());
    }
}
