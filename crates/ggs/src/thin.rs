//! Thinning: one point per occupied cell of a grid, the mean of the points in it.
//!
//! Used by the grid search (representatives of dense sources, the coarse level's source)
//! and by the refinement (ICP on thinned clouds), so it sits at the cloud layer, below both.

use crate::cloud::{Point, PointAccess};
use rayon::prelude::*;

/// One point per occupied cell of edge `cell` (cells anchored at the points' minimum): the
/// mean of the points in it, in increasing cell order (x-major), each mean summed in input
/// order. Deterministic and independent of the thread count: the points are sorted by (cell,
/// index), a total order with no ties.
pub fn cell_centroids<P: PointAccess + ?Sized>(points: &P, cell: f64) -> Vec<Point> {
    let n = points.count();
    if n == 0 {
        return Vec::new();
    }
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for p in (0..n).map(|i| points.at(i)) {
        for d in 0..3 {
            min[d] = min[d].min(p[d]);
            max[d] = max[d].max(p[d]);
        }
    }
    let key = |p: &[f64; 3]| -> [u64; 3] {
        std::array::from_fn(|d| crate::num::floor_u64((p[d] - min[d]) / cell))
    };
    // Usually the cell triple and the index fit one u64 together (x, y, z, index from the top
    // bits down: the same order as (triple, index)), 8 bytes a point; else a u64 key for
    // cells under 2^21 per axis and a u32 index; else the triple.
    let top = key(&max);
    let bits = |v: u64| 64 - v.leading_zeros();
    let [bx, by, bz] = top.map(bits);
    let bi = bits(n as u64 - 1);
    if bx + by + bz + bi <= 64 {
        let mut keyed: Vec<u64> = (0..n)
            .into_par_iter()
            .map(|i| {
                let k = key(&points.at(i));
                (((k[0] << by | k[1]) << bz | k[2]) << bi) | i as u64
            })
            .collect();
        keyed.par_sort_unstable();
        let low = (1u64 << bi) - 1;
        means_of_runs(points, &keyed, |&e| (e >> bi, (e & low) as usize))
    } else if top.iter().all(|&k| k < 1 << 21) && n <= u32::MAX as usize {
        let mut keyed: Vec<(u64, u32)> = (0..n)
            .into_par_iter()
            .map(|i| {
                let k = key(&points.at(i));
                ((k[0] << 42) | (k[1] << 21) | k[2], i as u32)
            })
            .collect();
        keyed.par_sort_unstable();
        means_of_runs(points, &keyed, |e| (e.0, e.1 as usize))
    } else {
        let mut keyed: Vec<([u64; 3], usize)> = (0..n).map(|i| (key(&points.at(i)), i)).collect();
        keyed.par_sort_unstable();
        means_of_runs(points, &keyed, |e| (e.0, e.1))
    }
}

/// The mean of the points of every run of equal keys in `keyed` (sorted by key, then index).
fn means_of_runs<P: PointAccess + ?Sized, E, K: PartialEq>(
    points: &P,
    keyed: &[E],
    parts: impl Fn(&E) -> (K, usize),
) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    let mut start = 0;
    while start < keyed.len() {
        let k = parts(&keyed[start]).0;
        let mut end = start + 1;
        while end < keyed.len() && parts(&keyed[end]).0 == k {
            end += 1;
        }
        let n = (end - start) as f64;
        let mut sum = [0.0; 3];
        for e in &keyed[start..end] {
            let p = points.at(parts(e).1);
            for d in 0..3 {
                sum[d] += p[d];
            }
        }
        out.push(sum.map(|v| v / n));
        start = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plain algorithm: a map from the cell triple to the points' sum and count.
    fn centroids_by_map(points: &[[f64; 3]], cell: f64) -> Vec<[f64; 3]> {
        let mut min = [f64::INFINITY; 3];
        for p in points {
            for d in 0..3 {
                min[d] = min[d].min(p[d]);
            }
        }
        let mut cells: std::collections::BTreeMap<[u64; 3], ([f64; 3], usize)> = Default::default();
        for p in points {
            let k = std::array::from_fn(|d| ((p[d] - min[d]) / cell).floor().max(0.0) as u64);
            let e = cells.entry(k).or_insert(([0.0; 3], 0));
            for d in 0..3 {
                e.0[d] += p[d];
            }
            e.1 += 1;
        }
        cells
            .values()
            .map(|(s, n)| s.map(|v| v / *n as f64))
            .collect()
    }

    #[test]
    fn cell_centroids_equal_the_plain_algorithm_bit_for_bit() {
        let mut r = crate::test_rng::uniform(77);
        let pts: Vec<[f64; 3]> = (0..50_000)
            .map(|_| [r() * 3.0 - 1.0, r() * 0.5, 100.0 + r() * 2.0])
            .collect();
        // Cell and index in one u64 (0.05, 0.013), a u64 key and a u32 index (1e-5: 69
        // bits in all), and the wide path (3e7 cells along x).
        for cell in [0.05, 0.013, 1e-5, 1e-7] {
            let (a, b) = (cell_centroids(&pts, cell), centroids_by_map(&pts, cell));
            assert_eq!(a.len(), b.len(), "{cell}");
            for (p, q) in a.iter().zip(&b) {
                assert_eq!(p.map(f64::to_bits), q.map(f64::to_bits), "{cell}");
            }
        }
    }
}
