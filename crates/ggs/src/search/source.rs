//! The source as the search sees it: its representatives when it is dense.

use crate::cloud::Cloud;
use crate::thin::cell_centroids;

/// Representatives of the source are one point per occupied cell of voxel / this (6: a
/// point lies within `√3/6 ≈ 0.29` voxel of its representative; 8 until the tenth speed
/// round, see docs/performance.md).
pub const REPRESENTATIVE_DIVISIONS: f64 = 6.0;

/// The search voxelizes representatives instead of every point when they are at least this
/// many times fewer (3: a 46 000-point human view, 100 000 points sampled on the body, has
/// 13 000 representatives at its automatic voxel; the 40 000-point bunny scans, 27 000, keep
/// their points).
pub const MIN_POINTS_PER_REPRESENTATIVE: usize = 3;

/// Representatives of a dense source for the search at voxel `s`: one point (the mean) per
/// occupied cell of edge `c = s / REPRESENTATIVE_DIVISIONS`, when that makes at least
/// [`MIN_POINTS_PER_REPRESENTATIVE`] × fewer points (`None`: the source as it is).
///
/// The search then costs what the occupied cells cost, not what the points cost (a
/// 4.8-million-point LiDAR pair: 40 s → see docs/performance.md). What it can change: every
/// point lies within `c·√3` of its representative, so under any rotation the occupancy of
/// the representatives differs from the points' only in voxels within `c·√3 ≈ 0.29 s` of a
/// face of an occupied voxel (a representative in the next voxel over, or none in a voxel
/// the points only touched). Measured: the same picks on every real pair, and on the
/// generated partial-view benchmarks the same recall or better (docs/performance.md).
pub fn representatives(source: &Cloud, s: f64) -> Option<Cloud> {
    let reps = cell_centroids(source, s / REPRESENTATIVE_DIVISIONS);
    (reps.len() * MIN_POINTS_PER_REPRESENTATIVE <= source.len()).then(|| Cloud::new(reps))
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::refine::neighbors::PointIndex;

    /// A plane of `n` × `n` points `h` apart, slightly wavy.
    pub(in crate::search) fn plane(n: usize, h: f64) -> Cloud {
        Cloud::new(
            (0..n * n)
                .map(|i| {
                    let (x, y) = ((i % n) as f64 * h, (i / n) as f64 * h);
                    [x, y, 0.1 * (3.0 * x).sin() * y]
                })
                .collect(),
        )
    }

    #[test]
    fn dense_sources_are_represented_within_the_bound_sparse_ones_as_they_are() {
        let s = 1.0;
        let dense = plane(200, 0.025);
        let reps = representatives(&dense, s).expect("44 points per cell");
        assert!(reps.len() * MIN_POINTS_PER_REPRESENTATIVE <= dense.len());
        let c = s / REPRESENTATIVE_DIVISIONS;
        let index = PointIndex::new(&reps.to_points());
        for p in &dense.to_points() {
            assert!(index.nearest(p).1.sqrt() <= c * 3f64.sqrt(), "{p:?}");
        }
        assert!(representatives(&plane(40, 0.2), s).is_none());
    }

    #[test]
    fn representatives_are_taken_from_three_points_a_cell() {
        let (s, c) = (1.0, 1.0 / REPRESENTATIVE_DIVISIONS);
        // About 4 points a cell of the plane: 3× fewer at least.
        assert!(representatives(&plane(60, c / 2.0), s).is_some());
        // About 2 points a cell: the points as they are.
        assert!(representatives(&plane(60, c / 1.4), s).is_none());
    }
}
