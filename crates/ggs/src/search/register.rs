//! One grid search, step by step: check the request, prepare both clouds, rank at the
//! coarse level (coarse-to-fine), score at the voxel in rounds, select the distinct
//! hypotheses, and turn each argmax into a transform (docs/method.md, "From an argmax to a
//! transform").

use super::config::SearchConfig;
use super::correlator::Backend;
use super::passes::CpuBackend;
use super::result::SearchResult;
use super::staged::PreparedSearch;
use crate::cloud::Cloud;
use crate::error::Result;
use crate::rotations::RotationSet;

/// Run the grid search of `source` against `target` over `set` on the CPU.
pub fn grid_search(
    source: &Cloud,
    target: &Cloud,
    set: &RotationSet,
    cfg: &SearchConfig,
) -> Result<SearchResult> {
    grid_search_with(&CpuBackend, source, target, set, cfg)
}

/// Run the grid search on the correlators of `backend`. The picks depend on the backend
/// only through its scores, which the [`Correlator`](super::Correlator) contract fixes: every backend that
/// keeps it returns the same result.
pub fn grid_search_with(
    backend: &dyn Backend,
    source: &Cloud,
    target: &Cloud,
    set: &RotationSet,
    cfg: &SearchConfig,
) -> Result<SearchResult> {
    PreparedSearch::new(source, target, set, cfg)?
        .start(backend)?
        .complete()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::search::source::tests::plane;
    use crate::transform::Rigid;
    use nalgebra::Vector3;

    #[test]
    fn the_search_on_representatives_finds_the_rotation_of_a_dense_pair() {
        let set = RotationSet::named("limited15").unwrap();
        let source = plane(300, 0.005);
        let k = 700;
        let truth = Rigid::new(set.matrices[k], Vector3::new(0.3, -0.2, 0.1));
        let target = source.transformed(&truth);
        let cfg = SearchConfig::with_voxel(0.15);
        let r = grid_search(&source, &target, &set, &cfg).unwrap();
        assert!(
            r.stats.searched_points * 4 <= r.stats.source_points,
            "{}",
            r.stats.searched_points
        );
        assert_eq!(r.winner().rotation_index, k);
        assert!((r.transform().translation - truth.translation).norm() < 0.15);
    }
}
