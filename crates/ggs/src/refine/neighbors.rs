//! Nearest-neighbour search: an immutable k-d tree (kiddo) built once per cloud.

use crate::cloud::Point;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;

/// Leaf bucket size of the tree (points scanned linearly at a leaf).
const BUCKET: usize = 16;
use std::num::NonZero;

/// A point set with its k-d tree.
pub struct PointIndex {
    tree: ImmutableKdTree<f64, u32, 3, BUCKET>,
    len: usize,
}

impl PointIndex {
    /// Build the tree (`points` must not be empty).
    pub fn new(points: &[Point]) -> Self {
        PointIndex {
            tree: ImmutableKdTree::new_from_slice(points),
            len: points.len(),
        }
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Index of the nearest point and the squared distance to it.
    #[inline]
    pub fn nearest(&self, q: &Point) -> (usize, f64) {
        let n = self.tree.nearest_one::<SquaredEuclidean>(q);
        (n.item as usize, n.distance)
    }

    /// The nearest point within squared distance `max_d2` (inclusive), if any. Cheaper than
    /// [`Self::nearest`] for points far from the set: the search stops at the radius.
    #[inline]
    pub fn nearest_within(&self, q: &Point, max_d2: f64) -> Option<(usize, f64)> {
        let one = NonZero::new(1).expect("1 ≥ 1");
        self.tree
            .nearest_n_within::<SquaredEuclidean>(q, max_d2, one, false)
            .first()
            .map(|n| (n.item as usize, n.distance))
    }

    /// Call `f` with the index of each of the `k` nearest points (one allocation, inside kiddo).
    #[inline]
    pub fn for_k_nearest(&self, q: &Point, k: usize, mut f: impl FnMut(usize)) {
        let k = NonZero::new(k.min(self.len).max(1)).expect("k ≥ 1");
        // Unsorted results (a heap inside kiddo) are cheaper than its sorted insertion; the
        // callers only sum over the set, in tree order, which is deterministic.
        for n in self
            .tree
            .nearest_n_within::<SquaredEuclidean>(q, f64::INFINITY, k, false)
        {
            f(n.item as usize);
        }
    }

    /// Distance (not squared) to the `k`-th nearest point (the last one if the set is
    /// smaller); the query point itself counts when it belongs to the set.
    pub fn kth_distance(&self, q: &Point, k: usize) -> f64 {
        let k = NonZero::new(k.min(self.len).max(1)).expect("k ≥ 1");
        self.tree
            .nearest_n::<SquaredEuclidean>(q, k)
            .last()
            .map_or(f64::INFINITY, |n| n.distance.sqrt())
    }

    /// Indices of the `k` nearest points (fewer if the set is smaller), nearest first.
    pub fn k_nearest(&self, q: &Point, k: usize) -> Vec<usize> {
        let k = NonZero::new(k.min(self.len).max(1)).expect("k ≥ 1");
        self.tree
            .nearest_n::<SquaredEuclidean>(q, k)
            .into_iter()
            .map(|n| n.item as usize)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_and_knn() {
        let pts = vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 2.0, 0.0],
            [5.0, 5.0, 5.0],
        ];
        let idx = PointIndex::new(&pts);
        assert_eq!(idx.nearest(&[0.9, 0.1, 0.0]).0, 1);
        assert_eq!(
            idx.nearest_within(&[0.9, 0.1, 0.0], 0.03).map(|n| n.0),
            Some(1)
        );
        assert_eq!(idx.nearest_within(&[0.9, 0.1, 0.0], 0.01), None);
        assert_eq!(
            idx.nearest_within(&[0.0, 0.0, 3.0], 9.0).map(|n| n.0),
            Some(0)
        );
        assert!((idx.nearest(&[0.0, 0.0, 3.0]).1 - 9.0).abs() < 1e-12);
        assert_eq!(idx.k_nearest(&[0.0, 0.0, 0.0], 3), vec![0, 1, 2]);
        assert_eq!(idx.k_nearest(&[0.0, 0.0, 0.0], 10).len(), 4);
    }
}
