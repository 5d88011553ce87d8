//! The point spacing of a cloud: the median distance from a point to its nearest other point,
//! over an evenly strided sample of [`SPACING_SAMPLES`] points, exact, in time linear in the
//! cloud and with memory for the sample only (no tree over millions of points).
//!
//! Each round puts the pending sample points into a hash of cells of edge `h` (every sample
//! point into the 3×3×3 cells around its own), then passes once over the cloud: a point of a
//! cell updates the nearest distance of the sample points registered there. A sample point
//! whose nearest distance found is at most `h/2` is exact (every point within `h` of it lies
//! in those 27 cells, whatever the rounding of the cell arithmetic at a cell's boundary);
//! the others go to the next round with `h` four times larger. The first `h`
//! is the longest side / √n (a surface's spacing); once `h` exceeds the cloud's diagonal every
//! point is a candidate, so the rounds end.

use crate::cloud::{Point, PointAccess};
use crate::num::floor_i64;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

/// Sample points whose nearest-neighbour distances make the median.
pub const SPACING_SAMPLES: usize = 512;

/// Points per parallel task of the pass over the cloud (small enough that the scans of the
/// example pairs, 40 000 points, use both threads).
const CHUNK: usize = 1 << 13;

/// Median nearest-other-point distance (see the module documentation); 0 when undefined (a
/// single point, or at least half the sample on duplicated points).
pub fn point_spacing<P: PointAccess + ?Sized>(points: &P) -> f64 {
    let n = points.count();
    if n < 2 {
        return 0.0;
    }
    let b = crate::cloud::bounds_by(n, |i| points.at(i)).expect("n ≥ 2");
    let e = b.extent();
    let longest = e[0].max(e[1]).max(e[2]);
    let diagonal = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
    if longest <= 0.0 {
        return 0.0;
    }
    let step = n.div_ceil(SPACING_SAMPLES);
    let sample: Vec<usize> = (0..n).step_by(step).collect();
    let mut nearest = vec![f64::INFINITY; sample.len()];
    let mut pending: Vec<usize> = (0..sample.len()).collect();
    let mut h = longest / (n as f64).sqrt();
    while !pending.is_empty() {
        let found = nearest_within_cells(points, &sample, &pending, h);
        let mut still = Vec::new();
        for (&s, d2) in pending.iter().zip(found) {
            let d = d2.sqrt();
            if d <= 0.5 * h || h > 2.0 * diagonal {
                nearest[s] = d;
            } else {
                still.push(s);
            }
        }
        pending = still;
        h *= 4.0;
    }
    let m = nearest.len() / 2;
    nearest.select_nth_unstable_by(m, f64::total_cmp);
    let d = nearest[m];
    if d.is_finite() && d > 0.0 {
        d
    } else {
        0.0
    }
}

/// Cell of `p` for edge `h`.
#[inline]
fn cell(p: &Point, h: f64) -> [i64; 3] {
    [
        floor_i64(p[0] / h),
        floor_i64(p[1] / h),
        floor_i64(p[2] / h),
    ]
}

/// For each `pending` sample point, the smallest squared distance to another point of the
/// cloud in the 27 cells of edge `h` around its own (infinity when none).
fn nearest_within_cells<P: PointAccess + ?Sized>(
    points: &P,
    sample: &[usize],
    pending: &[usize],
    h: f64,
) -> Vec<f64> {
    let mut around: FxHashMap<[i64; 3], Vec<u32>> = FxHashMap::default();
    for (slot, &s) in pending.iter().enumerate() {
        let c = cell(&points.at(sample[s]), h);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let key = [c[0] + dx, c[1] + dy, c[2] + dz];
                    around.entry(key).or_default().push(slot as u32);
                }
            }
        }
    }
    let n = points.count();
    let none = || vec![f64::INFINITY; pending.len()];
    // Per-worker minima merged pairwise: a minimum is the same in any order, and no
    // per-chunk vector is kept.
    (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .fold(none, |mut best, ci| {
            for j in ci * CHUNK..n.min((ci + 1) * CHUNK) {
                let p = points.at(j);
                let Some(slots) = around.get(&cell(&p, h)) else {
                    continue;
                };
                for &slot in slots {
                    let i = sample[pending[slot as usize]];
                    if i == j {
                        continue;
                    }
                    let q = points.at(i);
                    let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                    let d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                    let b = &mut best[slot as usize];
                    *b = b.min(d2);
                }
            }
            best
        })
        .reduce(none, |mut a, b| {
            for (x, y) in a.iter_mut().zip(b) {
                *x = x.min(y);
            }
            a
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::grid::median_kth_distance;
    use crate::refine::neighbors::PointIndex;

    fn tree_spacing(points: &[Point]) -> f64 {
        median_kth_distance(points, &PointIndex::new(points), 2).unwrap_or(0.0)
    }

    #[test]
    fn equals_the_tree_computation_on_dense_sparse_and_mixed_clouds() {
        let mut r = crate::test_rng::uniform(31);
        // A noisy sphere shell, a sparse volume, and a dense blob with far outliers.
        let shell = crate::test_rng::noisy_sphere(&mut r, 20_000);
        let volume: Vec<Point> = (0..700).map(|_| [r() * 50.0, r() * 3.0, r()]).collect();
        let mut mixed: Vec<Point> = (0..5000)
            .map(|_| [r() * 0.01, r() * 0.01, r() * 0.01])
            .collect();
        mixed.extend((0..5000).map(|i| [1e3 + i as f64 * 7.0, r() * 1e3, -2e3]));
        for cloud in [&shell, &volume, &mixed] {
            let (a, b) = (point_spacing(cloud), tree_spacing(cloud));
            assert_eq!(a.to_bits(), b.to_bits(), "{a} {b}");
            assert!(a > 0.0);
        }
    }

    #[test]
    fn degenerate_clouds_have_no_spacing() {
        assert_eq!(point_spacing(&Vec::<Point>::new()), 0.0);
        assert_eq!(point_spacing(&[[1.0, 2.0, 3.0]]), 0.0);
        assert_eq!(point_spacing(&vec![[1.0, 2.0, 3.0]; 10]), 0.0);
        assert_eq!(point_spacing(&[[0.0; 3], [3.0, 4.0, 0.0]]), 5.0);
    }
}
