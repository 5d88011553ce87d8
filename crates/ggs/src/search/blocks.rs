//! The vector blocks of the voxelization: the cells of 16 points at a time, in f32 where
//! a proven bound allows it, with the exact quotient for every point near a cell boundary
//! (docs/method.md, "Voxelization").
//!
//! The cell of a point `p` under rotation rows `r`, minimum `min` and voxel `s` is, on each
//! axis, `floor((r_d · p − min_d) / s)` computed as [`voxel::cell_fast`] of
//! [`dot_row`] (the *exact quotient*: the floor of the correctly rounded f64 division). Every
//! path here marks exactly those cells.

use super::grid_view::Real;
use super::voxel;
use crate::cloud::Point;
use std::ops::Range;

/// `row · p`, the one expression used for every rotated coordinate.
#[inline(always)]
pub fn dot_row(row: &[f64; 3], p: &Point) -> f64 {
    row[0] * p[0] + row[1] * p[1] + row[2] * p[2]
}

/// Points per vectorized block (two AVX-512 registers of f64: two independent dependency
/// chains).
pub(super) const LANES: usize = 16;

/// A float the vector blocks run in (f32 or f64).
pub(super) trait BlockFloat: Real {
    /// `1.5·2^(p−1)` for `p` mantissa bits (`1.5·2^52` for f64, `1.5·2^23` for f32):
    /// `(v + ROUND) − ROUND` is `v` rounded to the nearest integer for `|v| < 2^(p−2)`.
    const ROUND: Self;
    /// The flat index `self` (a whole number in `[0, 2^(p−1))`) as u32, by its bits:
    /// adding `2^(p−1)` puts `self` in the low mantissa bits (no float-to-integer
    /// conversion, whose saturating form does not vectorize).
    fn index(self) -> u32;
}

impl BlockFloat for f64 {
    const ROUND: f64 = 6_755_399_441_055_744.0;
    /// Exact for indices below 2^32 (`mark_span` takes this path only for grids that small).
    #[inline(always)]
    fn index(self) -> u32 {
        (self + 4_503_599_627_370_496.0).to_bits() as u32
    }
}

impl BlockFloat for f32 {
    const ROUND: f32 = 12_582_912.0;
    /// Exact for indices below 2^23 ([`Blocks::single`] declines larger grids).
    #[inline(always)]
    fn index(self) -> u32 {
        (self + 8_388_608.0).to_bits() & 0x7F_FFFF
    }
}

/// One rotation's constants for the vector blocks in `F`: rows, minimum and `1/s` in `F`,
/// and the tolerance `abs[d] + rel·v` within which a cell coordinate `v` counts as near a
/// cell boundary (those points take the exact quotient).
///
/// - f64 ([`Blocks::double`]): `1e-9 + 8ε·v`, the slack of [`voxel::cell_fast`].
/// - f32 ([`Blocks::single`]): with `u = 2^−24` (f32's unit roundoff), rows `|r_i| ≤ 1`,
///   `S = |x| + |y| + |z| ≤ scale` and `v = (r·p − min)/s` the exact cell coordinate, the f32
///   value `v'` of `((r'·p') − min')·inv'` (every input rounded to f32 once) satisfies
///   `|v' − v| ≤ (9·u·scale + 4·u·|min|)/s`: the inputs' rounding `2u·S`, the three products
///   and two sums `3u·S`, the subtraction and `min`'s rounding `u·(S + 2|min|)`, the product
///   by the rounded `1/s` `2u·|v|` with `|v| ≤ (S + |min|)/s`. The tolerance is twice that
///   (`32u·(scale + |min|)/s`), so a point farther than it from every cell boundary in f32
///   has the cell of the exact quotient; the others (about 6 tolerances' worth of the
///   points: 0.1 % at 64 cells a side) take the exact path, so the occupancy is the same bit
///   for bit.
pub(super) struct Blocks<F> {
    rows: [[F; 3]; 3],
    min: [F; 3],
    inv: F,
    abs: [F; 3],
    rel: F,
}

impl Blocks<f64> {
    /// The f64 constants of rotation `r`, minimum `min` and `inv = 1/s`.
    pub(super) fn double(r: &[[f64; 3]; 3], min: &Point, inv: f64) -> Self {
        Blocks {
            rows: *r,
            min: *min,
            inv,
            abs: [1e-9; 3],
            rel: 8.0 * f64::EPSILON,
        }
    }
}

impl Blocks<f32> {
    /// The f32 constants for rotation `r`, minimum `min` and voxel `s`, or `None` when f32
    /// cannot serve: a grid of 2^23 cells or more (flat indices would not be exact in f32),
    /// coordinates of 2^21 cells or more, or a tolerance of a tenth of a cell or more.
    pub(super) fn single(
        r: &[[f64; 3]; 3],
        min: &Point,
        s: f64,
        scale: f64,
        cells: usize,
    ) -> Option<Self> {
        const U: f64 = f32::EPSILON as f64 / 2.0;
        let inv = 1.0 / s;
        let reach: [f64; 3] = std::array::from_fn(|d| (scale + min[d].abs()) * inv);
        let tol = reach.map(|x| 32.0 * U * x);
        let fits = cells < 1 << 23
            && reach.iter().all(|&x| x < (1u32 << 21) as f64)
            && tol.iter().all(|&t| t < 0.1);
        fits.then(|| Blocks {
            rows: r.map(|row| row.map(|x| x as f32)),
            min: min.map(|x| x as f32),
            inv: inv as f32,
            abs: tol.map(|t| t as f32),
            rel: 0.0,
        })
    }
}

/// What the exact path of one rotation's voxelization needs: rows `r`, minimum `min`, voxel
/// `s` and `inv = 1/s`, and the grid's strides.
pub(super) struct ExactPath<'a> {
    pub r: &'a [[f64; 3]; 3],
    pub min: &'a Point,
    pub s: f64,
    pub inv: f64,
    pub sx: usize,
    pub sy: usize,
}

impl ExactPath<'_> {
    /// The flat index of the exact quotient's cell of `p`.
    #[inline(always)]
    pub(super) fn index(&self, p: &Point) -> usize {
        let cell =
            |d: usize| voxel::cell_fast(dot_row(&self.r[d], p) - self.min[d], self.s, self.inv);
        cell(0) * self.sx + cell(1) * self.sy + cell(2)
    }
}

/// Points as coordinate arrays in f64 and in f32, padded with [`LANES`] zeros so a block
/// may start at any point.
#[derive(Debug, Clone, Default)]
pub(super) struct Coords {
    pub xs: Vec<f64>,
    pub ys: Vec<f64>,
    pub zs: Vec<f64>,
    xs32: Vec<f32>,
    ys32: Vec<f32>,
    zs32: Vec<f32>,
    /// Number of points (without the padding).
    pub len: usize,
}

impl Coords {
    pub(super) fn new(points: &[Point]) -> Self {
        let pad = |v: Vec<f64>| {
            let mut v = v;
            v.resize(points.len() + LANES, 0.0);
            v
        };
        let xs = pad(points.iter().map(|p| p[0]).collect());
        let ys = pad(points.iter().map(|p| p[1]).collect());
        let zs = pad(points.iter().map(|p| p[2]).collect());
        let narrow = |v: &[f64]| v.iter().map(|&x| x as f32).collect();
        Coords {
            xs32: narrow(&xs),
            ys32: narrow(&ys),
            zs32: narrow(&zs),
            xs,
            ys,
            zs,
            len: points.len(),
        }
    }

    /// Point `k` in f64.
    #[inline(always)]
    pub(super) fn point(&self, k: usize) -> Point {
        [self.xs[k], self.ys[k], self.zs[k]]
    }

    /// Bytes per point of these arrays.
    pub(super) const BYTES_PER_POINT: usize = 36;
}

/// One rotation's vector blocks, in f32 where [`Blocks::single`] allows it, else in f64.
pub(super) enum RotationBlocks {
    Single(Blocks<f32>),
    Double(Blocks<f64>),
}

impl RotationBlocks {
    /// The blocks for rotation `e.r`, minimum `e.min` and voxel `e.s` over points whose
    /// `|x| + |y| + |z|` is at most `scale`, into a grid of `cells` cells.
    #[inline(always)]
    pub(super) fn new(e: &ExactPath<'_>, scale: f64, cells: usize) -> Self {
        match Blocks::single(e.r, e.min, e.s, scale, cells) {
            Some(b) => RotationBlocks::Single(b),
            None => RotationBlocks::Double(Blocks::double(e.r, e.min, e.inv)),
        }
    }

    /// Mark the cells of points `span` of `c` (block by block; the last block's lanes past
    /// the span are computed and ignored).
    #[inline(always)]
    pub(super) fn mark_span<T: Real>(
        &self,
        c: &Coords,
        span: Range<usize>,
        e: &ExactPath<'_>,
        grid: &mut [T],
    ) {
        // The blocks form flat indices as u32 ([`BlockFloat::index`]): larger grids take
        // the exact path point by point.
        if grid.len() > u32::MAX as usize {
            for k in span {
                grid[e.index(&c.point(k))] = T::one();
            }
            return;
        }
        let mut i = span.start;
        while i < span.end {
            let valid = LANES.min(span.end - i);
            match self {
                RotationBlocks::Single(b) => {
                    mark_block(b, [&c.xs32, &c.ys32, &c.zs32], c, i, valid, e, grid)
                }
                RotationBlocks::Double(b) => {
                    mark_block(b, [&c.xs, &c.ys, &c.zs], c, i, valid, e, grid)
                }
            }
            i += LANES;
        }
    }
}

/// Mark the cells of the first `valid` points of the block `i..i + LANES` of `xyz` (the
/// coordinates of `c` in `F`): the cell of the block arithmetic for each lane clear of a
/// boundary, the exact quotient's for each lane near one.
///
/// The floor is `round(v) − [round(v) > v]` (exact for `0 ≤ v < 2^(p−2)`) and the flat index
/// is formed in `F` (exact below 2^23 in f32, 2^32 in f64), one axis at a time over the
/// block, so the arithmetic stays in vector registers.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn mark_block<T: Real, F: BlockFloat>(
    b: &Blocks<F>,
    xyz: [&[F]; 3],
    c: &Coords,
    i: usize,
    valid: usize,
    e: &ExactPath<'_>,
    grid: &mut [T],
) {
    let to_f = |x: usize| F::from(x).expect("a stride is a finite float");
    let (fsx, fsy) = (to_f(e.sx), to_f(e.sy));
    let [xs, ys, zs] = xyz.map(|a| &a[i..i + LANES]);
    let mut flat = [F::zero(); LANES];
    // Lane masks as u32, not bool: they stay in vector registers across the three axes.
    let mut near = [0u32; LANES];
    for (d, scale) in [(0, fsx), (1, fsy), (2, F::one())] {
        let (row, m, abs) = (&b.rows[d], b.min[d], b.abs[d]);
        for l in 0..LANES {
            let dot = row[0] * xs[l] + row[1] * ys[l] + row[2] * zs[l];
            let v = (dot - m) * b.inv;
            let nearest = (v + F::ROUND) - F::ROUND;
            let floor = if nearest > v {
                nearest - F::one()
            } else {
                nearest
            };
            let f = v - floor;
            let tol = abs + b.rel * v;
            near[l] |= u32::from(!(f > tol && f < F::one() - tol));
            flat[l] = flat[l] + floor * scale;
        }
    }
    let index = flat.map(F::index);
    if valid == LANES && near.iter().fold(0, |a, &b| a | b) == 0 {
        for &v in &index {
            grid[v as usize] = T::one();
        }
        return;
    }
    for l in 0..valid {
        if near[l] != 0 {
            grid[e.index(&c.point(i + l))] = T::one();
        } else {
            grid[index[l] as usize] = T::one();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_precision_declines_what_f32_cannot_hold() {
        let r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let min = [-1.0; 3];
        assert!(Blocks::single(&r, &min, 0.01, 1.0, 1000).is_some());
        // A grid of 2^23 cells: flat indices would not be exact.
        assert!(Blocks::single(&r, &min, 0.01, 1.0, 1 << 23).is_none());
        assert!(Blocks::single(&r, &min, 0.01, 1.0, (1 << 23) - 1).is_some());
        // 2^21 cells from the origin: the tolerance would be too wide, the rounding trick
        // out of range.
        assert!(Blocks::single(&r, &min, 1e-6, 3.0, 1000).is_none());
        let t = Blocks::single(&r, &min, 0.01, 1.0, 1000).unwrap();
        // 32·2^−24·(1 + 1)/0.01 = 3.8e-4 cells.
        assert!((t.abs[0] as f64 - 32.0 * 2.0 / 0.01 / 16_777_216.0).abs() < 1e-9);
    }

    #[test]
    fn coords_are_padded_for_a_block_at_any_point() {
        let c = Coords::new(&[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(c.len, 2);
        assert_eq!(c.xs.len(), 2 + LANES);
        assert_eq!(c.point(1), [4.0, 5.0, 6.0]);
    }
}
