//! Voxelization (docs/method.md, "Voxelization").
//!
//! For points already shifted so their minimum is 0 on every axis, with voxel size `s`
//! (in the clouds' units): grid dims `N_d = floor(max_d / s) + 1` and the cell of a point is
//! `floor(p_d / s)`. Occupancy only: how many points fall in a cell does not matter.

use crate::cloud::PointAccess;
use crate::error::{GgsError, Result};

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

/// A dense occupancy grid, x-major C order (z fastest).
#[derive(Debug, Clone, PartialEq)]
pub struct Occupancy {
    pub dims: [usize; 3],
    pub cells: Vec<bool>,
}

impl Occupancy {
    /// Voxelize `points` after subtracting `min` (which must be their per-axis minimum).
    pub fn from_points<P: PointAccess + ?Sized>(
        points: &P,
        min: [f64; 3],
        voxel: f64,
    ) -> Result<Occupancy> {
        let all = || (0..points.count()).map(|i| points.at(i));
        let mut max = [f64::NEG_INFINITY; 3];
        for p in all() {
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
        for p in all() {
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

    /// A grid of `dims` whose cells are occupied with probability `p` (`next`: uniform
    /// draws in [0, 1)). For tests.
    #[cfg(test)]
    pub(crate) fn random(dims: [usize; 3], p: f64, next: &mut dyn FnMut() -> f64) -> Self {
        Occupancy {
            dims,
            cells: (0..dims.iter().product::<usize>())
                .map(|_| next() < p)
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
