//! Voxelization (docs/coarse-search.md, step 1).
//!
//! For points already shifted so their minimum is 0 on every axis, with voxel size `s`
//! (in the clouds' units): grid dims `N_d = floor(max_d / s) + 1` and the cell of a point is
//! `floor(p_d / s)`. Occupancy only: how many points fall in a cell does not matter.

use crate::error::{GgsError, Result};
use rayon::prelude::*;

/// Number of cells along one axis for a shifted extent `extent ≥ 0`: `floor(extent/s) + 1`.
pub fn axis_cells(extent: f64, voxel: f64) -> usize {
    (extent / voxel).floor() as usize + 1
}

/// Grid dims for a shifted extent, with a check that the cell count stays representable.
pub fn grid_dims(extent: [f64; 3], voxel: f64) -> Result<[usize; 3]> {
    let mut dims = [0usize; 3];
    for d in 0..3 {
        let cells = (extent[d] / voxel).floor() + 1.0;
        if !(cells.is_finite() && cells < 1e7) {
            return Err(GgsError::param(
                "voxel",
                format!(
                    "voxel size {voxel} gives {cells:.3e} cells along one axis (extent {:.6}); use a larger voxel",
                    extent[d]
                ),
            ));
        }
        dims[d] = cells as usize;
    }
    Ok(dims)
}

/// Cell index of a shifted coordinate `p ≥ 0`: `floor(p/s)`.
#[inline]
pub fn cell(p: f64, voxel: f64) -> usize {
    // p ≥ 0, so truncation is floor; i64 truncation is one instruction on x86-64.
    (p / voxel) as i64 as usize
}

/// `floor(p/s)` for `p ≥ 0` given `inv = 1/s`, without a division: `p·inv` differs from the
/// correctly rounded `p/s` by at most about 2 ulps of the result, so the two floors can only
/// disagree when `p·inv` lies within `1e-9 + 8ε·(p·inv)` of an integer; then the exact
/// quotient decides. Bit-identical to [`cell`] for every input.
#[inline(always)]
pub fn cell_fast(p: f64, voxel: f64, inv: f64) -> usize {
    let y = p * inv;
    let c = y as i64;
    let f = y - c as f64;
    let tol = 1e-9 + 8.0 * f64::EPSILON * y;
    if f > tol && f < 1.0 - tol {
        c as usize
    } else {
        cell(p, voxel)
    }
}

/// One point per occupied cell of edge `cell` (cells anchored at the points' minimum): the
/// mean of the points in it, in increasing cell order (x-major), each mean summed in input
/// order. Deterministic and independent of the thread count: the points are sorted by (cell,
/// index), a total order with no ties.
pub fn cell_centroids(points: &[[f64; 3]], cell: f64) -> Vec<[f64; 3]> {
    if points.is_empty() {
        return Vec::new();
    }
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for p in points {
        for d in 0..3 {
            min[d] = min[d].min(p[d]);
            max[d] = max[d].max(p[d]);
        }
    }
    let key = |p: &[f64; 3]| -> [u64; 3] {
        std::array::from_fn(|d| ((p[d] - min[d]) / cell).floor().max(0.0) as u64)
    };
    // Cells per axis fit 21 bits almost always: one u64 key (x, y, z packed, the same order
    // as the triple) and a u32 index sort fast and small; otherwise the triple.
    let top = key(&max);
    if top.iter().all(|&k| k < 1 << 21) && points.len() <= u32::MAX as usize {
        let mut keyed: Vec<(u64, u32)> = points
            .par_iter()
            .enumerate()
            .map(|(i, p)| {
                let k = key(p);
                ((k[0] << 42) | (k[1] << 21) | k[2], i as u32)
            })
            .collect();
        keyed.par_sort_unstable();
        means_of_runs(points, &keyed, |e| (e.0, e.1 as usize))
    } else {
        let mut keyed: Vec<([u64; 3], usize)> = points
            .iter()
            .enumerate()
            .map(|(i, p)| (key(p), i))
            .collect();
        keyed.par_sort_unstable();
        means_of_runs(points, &keyed, |e| (e.0, e.1))
    }
}

/// The mean of the points of every run of equal keys in `keyed` (sorted by key, then index).
fn means_of_runs<E, K: PartialEq>(
    points: &[[f64; 3]],
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
            let p = &points[parts(e).1];
            for d in 0..3 {
                sum[d] += p[d];
            }
        }
        out.push(sum.map(|v| v / n));
        start = end;
    }
    out
}

/// A dense occupancy grid, x-major C order (z fastest).
#[derive(Debug, Clone, PartialEq)]
pub struct Occupancy {
    pub dims: [usize; 3],
    pub cells: Vec<bool>,
}

impl Occupancy {
    /// Voxelize `points` after subtracting `min` (which must be their per-axis minimum).
    pub fn from_points(points: &[[f64; 3]], min: [f64; 3], voxel: f64) -> Result<Occupancy> {
        let mut max = [f64::NEG_INFINITY; 3];
        for p in points {
            for d in 0..3 {
                max[d] = max[d].max(p[d] - min[d]);
            }
        }
        let dims = grid_dims(max, voxel)?;
        let n = dims[0]
            .checked_mul(dims[1])
            .and_then(|v| v.checked_mul(dims[2]))
            .ok_or_else(|| GgsError::param("voxel", "grid too large"))?;
        let mut cells = vec![false; n];
        for p in points {
            let i = cell(p[0] - min[0], voxel);
            let j = cell(p[1] - min[1], voxel);
            let k = cell(p[2] - min[2], voxel);
            cells[(i * dims[1] + j) * dims[2] + k] = true;
        }
        Ok(Occupancy { dims, cells })
    }

    /// Number of occupied cells.
    pub fn occupied(&self) -> usize {
        self.cells.iter().filter(|&&c| c).count()
    }

    #[inline]
    pub fn get(&self, i: usize, j: usize, k: usize) -> bool {
        self.cells[(i * self.dims[1] + j) * self.dims[2] + k]
    }
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
        // Packed keys (cells per axis < 2^21), and the wide path (3e7 cells along x).
        for cell in [0.05, 0.013, 1e-7] {
            let (a, b) = (cell_centroids(&pts, cell), centroids_by_map(&pts, cell));
            assert_eq!(a.len(), b.len(), "{cell}");
            for (p, q) in a.iter().zip(&b) {
                assert_eq!(p.map(f64::to_bits), q.map(f64::to_bits), "{cell}");
            }
        }
    }

    #[test]
    fn dims_follow_floor_plus_one() {
        assert_eq!(axis_cells(0.0, 0.1), 1);
        assert_eq!(axis_cells(0.25, 0.1), 3);
        assert_eq!(axis_cells(0.3, 0.1), 3); // 0.3/0.1 = 2.9999999999999996 in f64
        assert!(grid_dims([1.0, 1.0, 1e12], 1e-3).is_err());
    }

    #[test]
    fn fast_cell_equals_division() {
        let mut uniform = crate::test_rng::uniform(12345);
        for &s in &[
            0.005,
            0.006,
            0.06,
            0.1,
            0.3,
            0.75,
            1.0,
            2.0,
            1.0 / 3.0,
            1e-7,
        ] {
            let inv = 1.0 / s;
            for k in 0..200_000u64 {
                let r = uniform();
                // Random values, and values on and next to exact multiples of s (up to 1e7
                // cells, the largest grid axis allowed).
                let base = ((k * 7919) % 10_000_000) as f64 * s;
                for p in [
                    r * 100.0 * s,
                    base,
                    f64::from_bits(base.to_bits() + 1),
                    f64::from_bits(base.to_bits().saturating_sub(1)),
                ] {
                    if p >= 0.0 {
                        assert_eq!(cell_fast(p, s, inv), cell(p, s), "p {p:e} s {s}");
                    }
                }
            }
        }
    }

    #[test]
    fn occupancy_ignores_counts() {
        let pts = [[0.0, 0.0, 0.0], [0.01, 0.0, 0.0], [0.25, 0.1, 0.0]];
        let o = Occupancy::from_points(&pts, [0.0; 3], 0.1).unwrap();
        assert_eq!(o.dims, [3, 2, 1]);
        assert_eq!(o.occupied(), 2);
        assert!(o.get(0, 0, 0) && o.get(2, 1, 0));
    }

    #[test]
    fn ten_million_cells_along_an_axis_is_refused_one_fewer_is_not() {
        assert_eq!(
            grid_dims([9_999_998.0, 0.0, 0.0], 1.0).unwrap(),
            [9_999_999, 1, 1]
        );
        let e = grid_dims([9_999_999.0, 0.0, 0.0], 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("use a larger voxel"), "{e}");
    }
}
