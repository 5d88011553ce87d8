//! The centred source cloud, prepared for being rotated many times (docs/method.md,
//! "Voxelization", step 2).
//!
//! Points are grouped into spatial clusters (a grid of 8 to 32 cells a side over the cloud's
//! box) so the exact extents of `R·(X − c)` for a rotation come from a few clusters: a cluster
//! whose bound `u·centre + radius` cannot beat the best value found so far is skipped. The
//! extents are computed with the same float expression as the voxelization, so both agree
//! bit for bit. Cluster order also keeps voxel writes local. Occupancy does not depend on
//! point order (the coarse level's thinning of these points does, in the last bits of its
//! means).

#[cfg(any(test, feature = "internals"))]
pub use super::blocks::dot_row;
use super::blocks::{Coords, ExactPath, RotationBlocks};
pub use super::grid_view::GridView;
use super::grid_view::Real;
use crate::cloud::{Cloud, Point};

/// Divisions per axis of the cluster grid over the cloud's box: `∛n / 2.5` within
/// `[8, 32]`, so about `n^(2/3) / 4` clusters on a surface. The extents' cost is one
/// projection per cluster plus the points of the ten or so clusters near the extremes;
/// measured on the bunny scan (`benches/range_probe.rs`, 6360 rotations): 8 divisions best
/// at 1367 points (2.0 µs a rotation; 1.1 µs since the projections are kept between the
/// two passes, where 6 divisions give 1.0 µs but slow the voxelization 2.2 → 3.3 µs), 12–13
/// at 40 097 (8.5 µs against 12 at 8; 6.2 µs now).
fn cluster_divisions(n: usize) -> usize {
    ((n as f64).cbrt() / 2.5).clamp(8.0, 32.0) as usize
}

/// The clusters as coordinate arrays: centre (mean) `(x, y, z)[i]`, the largest distance
/// `radius[i]` of a point from it, and the points `span[i].0..span[i].1`.
#[derive(Debug, Clone, Default)]
struct Centres {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    radius: Vec<f64>,
    span: Vec<(usize, usize)>,
}

/// A centred cloud grouped into clusters.
#[derive(Debug, Clone)]
pub struct RotatableCloud {
    /// Centroid `c_x` that was subtracted.
    pub centroid: Point,
    /// `X − c_x`, grouped by cluster.
    pub points: Vec<Point>,
    /// The same points as coordinate arrays (the extents and the voxelization).
    coords: Coords,
    /// `max |x| + |y| + |z|` over the centred points: bounds every rotated coordinate.
    scale: f64,
    centres: Centres,
    /// Absolute slack added to cluster bounds to cover float rounding.
    margin: f64,
}

impl RotatableCloud {
    /// Centre `cloud` on its mean and group it. `cloud` must not be empty.
    pub fn new(cloud: &Cloud) -> Self {
        let c = cloud.centroid().expect("non-empty cloud");
        let centred: Vec<Point> = cloud
            .iter()
            .map(|p| [p[0] - c[0], p[1] - c[1], p[2] - c[2]])
            .collect();
        let b = Cloud::new(centred.clone()).aabb().expect("non-empty");
        let e = b.extent();
        let divisions = cluster_divisions(centred.len());
        let cell = (e[0].max(e[1]).max(e[2]) / divisions as f64).max(f64::MIN_POSITIVE);
        let key = |p: &Point| -> (u32, u32, u32) {
            let f = |d: usize| (((p[d] - b.min[d]) / cell) as u32).min(divisions as u32);
            (f(0), f(1), f(2))
        };
        // Each key computed once (a comparison sort calling `key` cost 9 ms on 40 000
        // points), then the indices ordered by (key, index). A key is at most 32 (6 bits) an
        // axis.
        let keys: Vec<u64> = centred
            .iter()
            .map(|p| {
                let (a, b, c) = key(p);
                (a as u64) << 12 | (b as u64) << 6 | c as u64
            })
            .collect();
        let points: Vec<Point> = crate::order::by_key(&keys)
            .into_iter()
            .map(|i| centred[i])
            .collect();
        let mut centres = Centres::default();
        let mut start = 0;
        while start < points.len() {
            let k = key(&points[start]);
            let mut end = start + 1;
            while end < points.len() && key(&points[end]) == k {
                end += 1;
            }
            let n = (end - start) as f64;
            let mut centre = [0.0; 3];
            for p in &points[start..end] {
                for d in 0..3 {
                    centre[d] += p[d] / n;
                }
            }
            let radius = points[start..end]
                .iter()
                .map(|p| {
                    ((p[0] - centre[0]).powi(2)
                        + (p[1] - centre[1]).powi(2)
                        + (p[2] - centre[2]).powi(2))
                    .sqrt()
                })
                .fold(0.0, f64::max);
            centres.x.push(centre[0]);
            centres.y.push(centre[1]);
            centres.z.push(centre[2]);
            centres.radius.push(radius);
            centres.span.push((start, end));
            start = end;
        }
        let scale = points
            .iter()
            .map(|p| p[0].abs() + p[1].abs() + p[2].abs())
            .fold(0.0, f64::max);
        RotatableCloud {
            centroid: c,
            coords: Coords::new(&points),
            points,
            centres,
            scale,
            margin: 1e-9 * (scale + 1e-300),
        }
    }

    /// Exact `(min, max)` over points of `row · p` (for a unit `row`), bit for bit the
    /// values of [`dot_row`] over every point: a cluster is evaluated only when its bound
    /// `row · centre ± radius` can reach beyond the extremes found so far.
    pub fn range(&self, row: &[f64; 3]) -> (f64, f64) {
        self.range_with(row, &mut Vec::new())
    }

    /// [`RotatableCloud::range`] with the clusters' projections kept in `scratch` (a buffer
    /// a caller reuses across rotations: no allocation per call).
    pub fn range_with(&self, row: &[f64; 3], scratch: &mut Vec<f64>) -> (f64, f64) {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::level() >= crate::simd::Level::Avx2 {
            // SAFETY: `simd::level` reports Avx2 or wider only when the CPU has AVX2, the
            // only requirement of `range_avx2`.
            return unsafe { self.range_avx2(row, scratch) };
        }
        self.range_body(row, scratch)
    }

    /// [`RotatableCloud::range_with`] compiled for AVX2 (the projection and bound loops
    /// vectorize; no FMA contraction happens, so the values are the baseline's).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn range_avx2(&self, row: &[f64; 3], scratch: &mut Vec<f64>) -> (f64, f64) {
        self.range_body(row, scratch)
    }

    /// Two passes over the clusters. The first projects every centre (`d_i = row · c_i`,
    /// kept in `scratch`) and takes the largest and smallest, four lanes at a time; the
    /// clusters holding them seed the extremes with their points. The second reads the kept
    /// projections four at a time and evaluates a cluster only where its bound
    /// `d_i ± (radius_i·|row| + margin)` reaches the extremes found so far (tested against
    /// the values at the start of each group of four: older extremes are less extreme, so
    /// the test never skips a cluster the current ones would evaluate).
    #[inline(always)]
    fn range_body(&self, row: &[f64; 3], scratch: &mut Vec<f64>) -> (f64, f64) {
        let norm = (row[0] * row[0] + row[1] * row[1] + row[2] * row[2]).sqrt();
        let c = &self.centres;
        let n = c.x.len();
        scratch.clear();
        scratch.resize(n, 0.0);
        let (xs, ys, zs) = (&c.x[..n], &c.y[..n], &c.z[..n]);
        let mut hi4 = [f64::NEG_INFINITY; 4];
        let mut lo4 = [f64::INFINITY; 4];
        for (j, d4) in scratch.chunks_mut(4).enumerate() {
            for (l, d) in d4.iter_mut().enumerate() {
                let i = 4 * j + l;
                *d = row[0] * xs[i] + row[1] * ys[i] + row[2] * zs[i];
                hi4[l] = if *d > hi4[l] { *d } else { hi4[l] };
                lo4[l] = if *d < lo4[l] { *d } else { lo4[l] };
            }
        }
        let dmax = hi4.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b));
        let dmin = lo4.iter().fold(f64::INFINITY, |a, &b| a.min(b));
        let d = &scratch[..];
        let imax = d.iter().position(|&v| v == dmax).unwrap_or(0);
        let imin = d.iter().position(|&v| v == dmin).unwrap_or(0);
        let (mut lo, mut hi) = self.cluster_range(row, imax, f64::INFINITY, f64::NEG_INFINITY);
        if imin != imax {
            (lo, hi) = self.cluster_range(row, imin, lo, hi);
        }
        let widen = norm * (1.0 + 1e-12);
        let radius = &c.radius[..n];
        for (j, d4) in d.chunks(4).enumerate() {
            let base = 4 * j;
            let reaches = |l: usize, lo: f64, hi: f64| {
                let s = radius[base + l] * widen + self.margin;
                d4[l] + s >= hi || d4[l] - s <= lo
            };
            let mut any = false;
            for l in 0..d4.len() {
                any |= reaches(l, lo, hi);
            }
            if !any {
                continue;
            }
            for l in 0..d4.len() {
                let i = base + l;
                if i != imax && i != imin && reaches(l, lo, hi) {
                    (lo, hi) = self.cluster_range(row, i, lo, hi);
                }
            }
        }
        (lo, hi)
    }

    /// `(min, max)` of `lo`, `hi` and `row · p` over the points of cluster `i`, in four
    /// lanes over the coordinate arrays (a minimum is the same value in any order).
    #[inline(always)]
    fn cluster_range(&self, row: &[f64; 3], i: usize, lo: f64, hi: f64) -> (f64, f64) {
        let span = self.centres.span[i].0..self.centres.span[i].1;
        let (xs, ys, zs) = (
            &self.coords.xs[span.clone()],
            &self.coords.ys[span.clone()],
            &self.coords.zs[span],
        );
        let mut lo4 = [lo; 4];
        let mut hi4 = [hi; 4];
        let whole = xs.len() - xs.len() % 4;
        for j in (0..whole).step_by(4) {
            for l in 0..4 {
                let v = row[0] * xs[j + l] + row[1] * ys[j + l] + row[2] * zs[j + l];
                lo4[l] = if v < lo4[l] { v } else { lo4[l] };
                hi4[l] = if v > hi4[l] { v } else { hi4[l] };
            }
        }
        for j in whole..xs.len() {
            let v = row[0] * xs[j] + row[1] * ys[j] + row[2] * zs[j];
            lo4[0] = if v < lo4[0] { v } else { lo4[0] };
            hi4[0] = if v > hi4[0] { v } else { hi4[0] };
        }
        let lo = lo4.iter().fold(f64::INFINITY, |a, &b| a.min(b));
        let hi = hi4.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b));
        (lo, hi)
    }
}

impl RotatableCloud {
    /// Voxelize the rotated cloud: for every point `p`, mark the cell
    /// `floor((R·p − min) / s)` of `grid` with 1.
    ///
    /// `min` must be the per-axis minimum of `R·p` computed by [`RotatableCloud::range`] (the
    /// same float expression, so every coordinate is ≥ 0) and the grid must hold every cell.
    /// Bit-identical to [`voxel::cell_fast`](super::voxel::cell_fast) of [`dot_row`] per point:
    /// the points go through the vector blocks of `search::blocks` (f32 where a proven
    /// bound allows, the exact quotient near a cell boundary).
    pub fn voxelize<T: Real>(&self, r: &[[f64; 3]; 3], min: &Point, s: f64, grid: GridView<'_, T>) {
        #[cfg(target_arch = "x86_64")]
        match crate::simd::level() {
            // SAFETY: `simd::level` returns Avx512 only when the CPU has AVX-512F, the only
            // requirement of `voxelize_avx512`.
            crate::simd::Level::Avx512 => {
                return unsafe { self.voxelize_avx512::<T>(r, min, s, grid) }
            }
            // SAFETY: Avx2 only when the CPU has AVX2.
            crate::simd::Level::Avx2 => return unsafe { self.voxelize_avx2::<T>(r, min, s, grid) },
            crate::simd::Level::Scalar => {}
        }
        self.voxelize_body(r, min, s, grid)
    }

    /// [`RotatableCloud::voxelize`] compiled for AVX-512 (8 f64 lanes; 3.3× faster than the
    /// SSE2 baseline on the bunny pair). No FMA contraction happens (Rust never fuses
    /// `a·b + c` by itself), so results are bit-identical to the baseline.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn voxelize_avx512<T: Real>(
        &self,
        r: &[[f64; 3]; 3],
        min: &Point,
        s: f64,
        grid: GridView<'_, T>,
    ) {
        self.voxelize_body(r, min, s, grid)
    }

    /// [`RotatableCloud::voxelize`] compiled for AVX2 (4 f64 lanes).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn voxelize_avx2<T: Real>(
        &self,
        r: &[[f64; 3]; 3],
        min: &Point,
        s: f64,
        grid: GridView<'_, T>,
    ) {
        self.voxelize_body(r, min, s, grid)
    }

    #[inline(always)]
    fn voxelize_body<T: Real>(
        &self,
        r: &[[f64; 3]; 3],
        min: &Point,
        s: f64,
        grid: GridView<'_, T>,
    ) {
        let GridView { cells, sx, sy } = grid;
        let exact = ExactPath {
            r,
            min,
            s,
            inv: 1.0 / s,
            sx,
            sy,
        };
        let blocks = RotationBlocks::new(&exact, self.scale, cells.len());
        blocks.mark_span(&self.coords, 0..self.coords.len, &exact, cells);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::search::blocks::Blocks;
    use crate::rotations::RotationSet;

    fn lcg_cloud(n: usize, seed: u64) -> Cloud {
        let mut next = crate::test_rng::uniform(seed);
        Cloud::new(
            (0..n)
                .map(|_| [next() * 3.0 - 1.0, next() * 0.5, next() * 2.0 + 7.0])
                .collect(),
        )
    }

    #[test]
    fn range_equals_brute_force_bitwise() {
        let cloud = lcg_cloud(5000, 7);
        let rc = RotatableCloud::new(&cloud);
        let set = RotationSet::named("limited15").unwrap();
        for m in set.matrices.iter().step_by(17) {
            for d in 0..3 {
                let row = [m[(d, 0)], m[(d, 1)], m[(d, 2)]];
                let mut lo = f64::INFINITY;
                let mut hi = f64::NEG_INFINITY;
                for p in &rc.points {
                    let v = dot_row(&row, p);
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
                assert_eq!(rc.range(&row), (lo, hi));
            }
        }
    }

    /// Voxelize `rc` by each rotation of `matrices` with `path` and compare every cell with
    /// the exact quotient.
    fn check_against_exact_quotient(
        rc: &RotatableCloud,
        s: f64,
        matrices: &[nalgebra::Matrix3<f64>],
        path: impl Fn(&[[f64; 3]; 3], &Point, GridView<'_, f32>),
    ) {
        for m in matrices {
            let r: [[f64; 3]; 3] = std::array::from_fn(|d| [m[(d, 0)], m[(d, 1)], m[(d, 2)]]);
            let ranges: [(f64, f64); 3] = std::array::from_fn(|d| rc.range(&r[d]));
            let min = ranges.map(|x| x.0);
            let dims: [usize; 3] =
                std::array::from_fn(|d| super::super::voxel::cell(ranges[d].1 - min[d], s) + 1);
            let mut cells = vec![0.0f32; dims.iter().product()];
            let (sx, sy) = (dims[1] * dims[2], dims[2]);
            let view = GridView {
                cells: &mut cells,
                sx,
                sy,
            };
            path(&r, &min, view);
            let mut want = vec![0.0f32; cells.len()];
            for p in &rc.points {
                let c = |d: usize| super::super::voxel::cell(dot_row(&r[d], p) - min[d], s);
                want[c(0) * sx + c(1) * sy + c(2)] = 1.0;
            }
            assert_eq!(cells, want);
        }
    }

    /// Random points and points on cell boundaries (the identity and axis flips put them
    /// exactly on a boundary, where only the exact quotient decides), with some rotations.
    fn boundary_cloud(s: f64) -> (RotatableCloud, Vec<nalgebra::Matrix3<f64>>) {
        let mut pts = lcg_cloud(3001, 5).iter().collect::<Vec<_>>();
        pts.extend((0..40).map(|i| [i as f64 * s, (i % 7) as f64 * s, 7.0 + (i % 5) as f64 * s]));
        let rc = RotatableCloud::new(&Cloud::new(pts));
        let set = RotationSet::named("limited15").unwrap();
        let mut matrices: Vec<_> = set.matrices.iter().step_by(97).copied().collect();
        matrices.push(nalgebra::Matrix3::identity());
        matrices.push(nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(
            -1.0, 1.0, -1.0,
        )));
        (rc, matrices)
    }

    #[test]
    fn voxelize_marks_the_cells_of_the_exact_quotient() {
        let s = 0.125;
        let (rc, matrices) = boundary_cloud(s);
        check_against_exact_quotient(&rc, s, &matrices, |r, min, g| rc.voxelize(r, min, s, g));
    }

    fn exact_path<'a>(
        r: &'a [[f64; 3]; 3],
        min: &'a Point,
        s: f64,
        g: &GridView<'_, f32>,
    ) -> ExactPath<'a> {
        ExactPath {
            r,
            min,
            s,
            inv: 1.0 / s,
            sx: g.sx,
            sy: g.sy,
        }
    }

    #[test]
    fn both_precisions_mark_the_cells_of_the_exact_quotient() {
        // At 1/64 the grid has about 200 × 40 × 130 cells: many points fall within f32's
        // tolerance of a boundary somewhere, so the exact fallback runs often.
        for s in [0.125, 1.0 / 64.0] {
            let (rc, matrices) = boundary_cloud(s);
            let n = rc.coords.len;
            check_against_exact_quotient(&rc, s, &matrices, |r, min, g| {
                let e = exact_path(r, min, s, &g);
                let b = RotationBlocks::Double(Blocks::double(r, min, e.inv));
                b.mark_span(&rc.coords, 0..n, &e, g.cells)
            });
            check_against_exact_quotient(&rc, s, &matrices, |r, min, g| {
                let e = exact_path(r, min, s, &g);
                let b = Blocks::single(r, min, s, rc.scale, g.cells.len())
                    .expect("small enough for f32");
                RotationBlocks::Single(b).mark_span(&rc.coords, 0..n, &e, g.cells)
            });
        }
    }

    #[test]
    fn single_point() {
        let rc = RotatableCloud::new(&Cloud::new(vec![[1.0, 2.0, 3.0]]));
        assert_eq!(rc.range(&[1.0, 0.0, 0.0]), (0.0, 0.0));
        assert_eq!(rc.points.len(), 1);
    }
}
