//! Local covariances and normals from the k nearest neighbours of every point (docs/refinement.md).
//!
//! For a point with neighbours `N` (itself included): mean `μ`, covariance
//! `Σ = (1/|N|)·Σ (p − μ)(p − μ)ᵀ`, eigenvectors `e₁, e₂, e₃` with eigenvalues `λ₁ ≤ λ₂ ≤ λ₃`.
//! The normal is `e₁`; the GICP covariance is the regularized plane
//! `C = e₁·ε·e₁ᵀ + e₂e₂ᵀ + e₃e₃ᵀ = V·diag(ε, 1, 1)·Vᵀ` (ε = 1e-3): always symmetric positive
//! definite, whatever the neighbourhood (repeated or collinear points give some orthonormal
//! basis, never NaN). `planarity = (λ₂ − λ₁)/λ₃` (0 for a degenerate neighbourhood).

use super::grid::{median_kth_distance, CellGrid, KnnScratch, KNN_CELL_FACTOR};
use super::neighbors::PointIndex;
use crate::cloud::Point;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rayon::prelude::*;
use std::sync::OnceLock;

/// Local frame of one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalShape {
    /// Unit normal (sign arbitrary).
    pub normal: Vector3<f64>,
    /// Regularized plane covariance `V·diag(ε, 1, 1)·Vᵀ`.
    pub covariance: Matrix3<f64>,
}

/// Eigen-decomposition with eigenvalues sorted ascending (columns of the matrix follow).
fn sorted_eigen(m: &Matrix3<f64>) -> (Vector3<f64>, Matrix3<f64>) {
    let e = SymmetricEigen::new(*m);
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| e.eigenvalues[a].total_cmp(&e.eigenvalues[b]));
    let vals = Vector3::new(
        e.eigenvalues[idx[0]],
        e.eigenvalues[idx[1]],
        e.eigenvalues[idx[2]],
    );
    let vecs = Matrix3::from_columns(&[
        e.eigenvectors.column(idx[0]).into_owned(),
        e.eigenvectors.column(idx[1]).into_owned(),
        e.eigenvectors.column(idx[2]).into_owned(),
    ]);
    (vals, vecs)
}

/// Unit eigenvector of the smallest eigenvalue of a symmetric 3×3 matrix in closed form, or
/// `None` when it is ill-determined (the two smallest eigenvalues closer than a thousandth of
/// the spread, or an isotropic matrix): the caller then uses the iterative solver.
///
/// Eigenvalues by the trigonometric formula (Smith 1961): with `m = tr(A)/3`,
/// `p = sqrt(tr((A − mI)²)/6)` and `B = (A − mI)/p`, `λ_min = m + 2p·cos(acos(det(B)/2)/3 +
/// 2π/3)`. The eigenvector is the largest cross product of two rows of `A − λ_min·I` (each
/// row is orthogonal to it).
pub fn smallest_eigenvector(a: &Matrix3<f64>) -> Option<Vector3<f64>> {
    let m = a.trace() / 3.0;
    let b = a - Matrix3::from_diagonal_element(m);
    let p = ((b * b).trace() / 6.0).sqrt();
    if !(p.is_finite() && p > 0.0) {
        return None;
    }
    let r = ((b / p).determinant() / 2.0).clamp(-1.0, 1.0);
    let phi = r.acos() / 3.0;
    let lambda = m + 2.0 * p * (phi + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let c = a - Matrix3::from_diagonal_element(lambda);
    let (r0, r1, r2) = (
        c.row(0).transpose(),
        c.row(1).transpose(),
        c.row(2).transpose(),
    );
    let mut best = r0.cross(&r1);
    for v in [r0.cross(&r2), r1.cross(&r2)] {
        if v.norm_squared() > best.norm_squared() {
            best = v;
        }
    }
    // Spread of the eigenvalues is 3p at most; the cross product's norm is about
    // (λ_mid − λ_min)·(λ_max − λ_min).
    let norm = best.norm();
    (norm > 1e-3 * (3.0 * p) * (3.0 * p)).then(|| best / norm)
}

/// Running sums of a neighbourhood: count, Σd and Σddᵀ of `d = p − anchor` (the query
/// point), which keeps the sums small and the covariance accurate far from the origin.
#[derive(Debug, Clone, Copy)]
pub struct Moments {
    anchor: Vector3<f64>,
    n: f64,
    s: Vector3<f64>,
    ss: Matrix3<f64>,
}

impl Moments {
    pub fn new(anchor: &Point) -> Self {
        Moments {
            anchor: Vector3::new(anchor[0], anchor[1], anchor[2]),
            n: 0.0,
            s: Vector3::zeros(),
            ss: Matrix3::zeros(),
        }
    }

    #[inline]
    pub fn push(&mut self, p: &Point) {
        let d = Vector3::new(p[0], p[1], p[2]) - self.anchor;
        self.n += 1.0;
        self.s += d;
        self.ss += d * d.transpose();
    }

    /// Normal = eigenvector of the smallest eigenvalue of the covariance; covariance
    /// `V·diag(ε, 1, 1)·Vᵀ = I − (1 − ε)·n·nᵀ`.
    pub fn shape(&self, epsilon: f64) -> LocalShape {
        let fallback = LocalShape {
            normal: Vector3::z(),
            covariance: Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, epsilon)),
        };
        if self.n < 3.0 {
            return fallback;
        }
        let mean = self.s / self.n;
        let cov = self.ss / self.n - mean * mean.transpose();
        if !cov.iter().all(|v| v.is_finite()) {
            return fallback;
        }
        let normal = smallest_eigenvector(&cov).unwrap_or_else(|| {
            let (_, v) = sorted_eigen(&cov);
            v.column(0).into_owned()
        });
        if !normal.iter().all(|x| x.is_finite()) || (normal.norm() - 1.0).abs() > 1e-6 {
            return fallback;
        }
        let covariance = Matrix3::identity() - (1.0 - epsilon) * normal * normal.transpose();
        LocalShape { normal, covariance }
    }
}

/// Shape of a neighbourhood given as points.
#[cfg(any(test, feature = "internals"))]
pub fn shape_of(points: &[Point], epsilon: f64) -> LocalShape {
    let mut m = Moments::new(points.first().unwrap_or(&[0.0; 3]));
    for p in points {
        m.push(p);
    }
    m.shape(epsilon)
}

/// Shapes of all points of a cloud from their `k` nearest neighbours, in parallel; each
/// point independently, so the result does not depend on the thread count. The neighbours
/// come from a [`CellGrid`] sized by [`median_kth_distance`] (exact: the k-d tree answers what the
/// grid cannot certify), or from the tree alone for clouds the grid cannot bucket.
pub fn local_shapes(
    points: &[Point],
    index: &PointIndex,
    k: usize,
    epsilon: f64,
) -> Vec<LocalShape> {
    let shape =
        |i: usize, _: &[u32], nbrs: &[Point]| neighbourhood_shape(&points[i], nbrs, epsilon);
    if let Some(r) = median_kth_distance(points, index, k) {
        if let Some(grid) = CellGrid::new(points, r * KNN_CELL_FACTOR) {
            return grid.map_knn(points, k, 1.5 * r, index, shape);
        }
    }
    points
        .par_iter()
        .map(|p| {
            let mut m = Moments::new(p);
            index.for_k_nearest(p, k, |j| m.push(&points[j]));
            m.shape(epsilon)
        })
        .collect()
}

/// Local shapes computed on first use and kept: only points near a correspondence ever pay
/// for their neighbour search (a low-overlap pair touches a fraction of each cloud, and an
/// ICP iteration's inliers, within the 0.25 quantile of the distances, are a quarter of the
/// overlap). On the k-NN grid, [`LazyShapes::ensure`] computes the shapes a batch of points
/// needs, cell by cell, gathering each cell's candidates once; a single [`LazyShapes::get`]
/// of a point not computed yet gathers its cell's candidates for it alone. Clouds the grid
/// cannot bucket fall back to one tree query per point. A shape is a pure function of the
/// cloud and the point (the grid answers one point the same whichever others of its cell are
/// asked with it), so which thread computes it first, and in which batch, does not matter.
///
/// The cache does not hold the cloud: every query passes the same `points` and `index` the
/// cache was built with.
pub struct LazyShapes {
    k: usize,
    epsilon: f64,
    /// The grid and its hint (`None`: the tree alone).
    grid: Option<(Box<CellGrid>, f64)>,
    /// Cell and position in the cell of every point (empty without a grid).
    loc: Vec<(u32, u32)>,
    /// The shapes' slots of each grid cell, allocated on the cell's first use (memory
    /// follows the part of the cloud refinement touches); without a grid, one cell of all
    /// the points.
    slots: Vec<OnceLock<Box<[OnceLock<LocalShape>]>>>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<KnnScratch> = std::cell::RefCell::new(KnnScratch::default());
}

impl LazyShapes {
    pub fn new(points: &[Point], index: &PointIndex, k: usize, epsilon: f64) -> Self {
        let grid = median_kth_distance(points, index, k)
            .and_then(|r| CellGrid::new(points, r * KNN_CELL_FACTOR).map(|g| (g, 1.5 * r)));
        let slots = match &grid {
            Some((g, _)) => (0..g.cells()).map(|_| OnceLock::new()).collect(),
            None => vec![OnceLock::from(
                (0..points.len())
                    .map(|_| OnceLock::new())
                    .collect::<Box<[_]>>(),
            )],
        };
        LazyShapes {
            k,
            epsilon,
            loc: grid.as_ref().map_or_else(Vec::new, |(g, _)| g.locations()),
            grid: grid.map(|(g, hint)| (Box::new(g), hint)),
            slots,
        }
    }

    /// The slot of point `i`'s shape.
    #[inline]
    fn slot(&self, i: usize) -> &OnceLock<LocalShape> {
        match &self.grid {
            Some((grid, _)) => {
                let (cell, off) = self.loc[i];
                let cell = cell as usize;
                let slots = self.slots[cell]
                    .get_or_init(|| (0..grid.cell_len(cell)).map(|_| OnceLock::new()).collect());
                &slots[off as usize]
            }
            None => &self.slots[0].get().expect("allocated when built")[i],
        }
    }

    /// The shape of point `i` of `points` (the cloud and tree the cache was built for).
    #[inline]
    pub fn get(&self, points: &[Point], index: &PointIndex, i: usize) -> &LocalShape {
        self.slot(i).get_or_init(|| match &self.grid {
            Some(_) => {
                let (cell, off) = self.loc[i];
                let mut out = Vec::with_capacity(1);
                self.cell_shapes(points, index, cell as usize, &[off as usize], &mut out);
                out[0].1
            }
            None => {
                let p = &points[i];
                let mut m = Moments::new(p);
                index.for_k_nearest(p, self.k, |j| m.push(&points[j]));
                m.shape(self.epsilon)
            }
        })
    }

    /// Compute the shapes of the points `needed` not computed yet (duplicates allowed),
    /// gathering the candidates of each grid cell once for all of them.
    pub fn ensure(
        &self,
        points: &[Point],
        index: &PointIndex,
        needed: impl IntoIterator<Item = usize>,
    ) {
        if self.grid.is_none() {
            for i in needed {
                self.get(points, index, i);
            }
            return;
        }
        let mut todo: Vec<(u32, u32)> = needed
            .into_iter()
            .filter(|&i| self.slot(i).get().is_none())
            .map(|i| self.loc[i])
            .collect();
        todo.sort_unstable();
        todo.dedup();
        let mut out = Vec::new();
        let mut offsets = Vec::new();
        for group in todo.chunk_by(|a, b| a.0 == b.0) {
            offsets.clear();
            offsets.extend(group.iter().map(|&(_, off)| off as usize));
            out.clear();
            self.cell_shapes(points, index, group[0].0 as usize, &offsets, &mut out);
            for &(i, shape) in &out {
                // Another thread may have computed it meanwhile: the same value.
                let _ = self.slot(i).set(shape);
            }
        }
    }

    /// The shapes of the points at `offsets` of grid cell `cell`, with their indices.
    fn cell_shapes(
        &self,
        points: &[Point],
        index: &PointIndex,
        cell: usize,
        offsets: &[usize],
        out: &mut Vec<(usize, LocalShape)>,
    ) {
        let (grid, hint) = self.grid.as_ref().expect("a grid");
        let epsilon = self.epsilon;
        SCRATCH.with(|scratch| {
            grid.cell_knn_at(
                cell,
                offsets.iter().copied(),
                points,
                self.k,
                *hint,
                index,
                &mut scratch.borrow_mut(),
                out,
                |i, _, nbrs| (i, neighbourhood_shape(&points[i], nbrs, epsilon)),
            )
        });
    }

    /// How many shapes were computed so far.
    #[cfg(any(test, feature = "internals"))]
    pub fn computed(&self) -> usize {
        self.slots
            .iter()
            .filter_map(OnceLock::get)
            .map(|cell| cell.iter().filter(|c| c.get().is_some()).count())
            .sum()
    }
}

/// Shape of the neighbourhood `nbrs` of point `p` (moments anchored at `p`).
fn neighbourhood_shape(p: &Point, nbrs: &[Point], epsilon: f64) -> LocalShape {
    let mut m = Moments::new(p);
    for q in nbrs {
        m.push(q);
    }
    m.shape(epsilon)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_points_have_the_plane_normal() {
        // A tilted plane z = 0.3x − 0.2y.
        let mut pts = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                let (x, y) = (i as f64 * 0.1, j as f64 * 0.1);
                pts.push([x, y, 0.3 * x - 0.2 * y]);
            }
        }
        let shapes = local_shapes(&pts, &PointIndex::new(&pts), 20, 1e-3);
        let expected = Vector3::new(-0.3, 0.2, 1.0).normalize();
        for s in &shapes {
            assert!((s.normal.dot(&expected).abs() - 1.0).abs() < 1e-9);
            // Along the normal the covariance is ε, in the plane 1.
            assert!((s.normal.dot(&(s.covariance * s.normal)) - 1e-3).abs() < 1e-9);
            let t = s.normal.cross(&Vector3::x()).normalize();
            assert!((t.dot(&(s.covariance * t)) - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn lazy_shapes_equal_eager_ones() {
        let pts: Vec<Point> = (0..200)
            .map(|i| {
                let t = i as f64 * 0.1;
                [t.sin(), t.cos(), 0.01 * t]
            })
            .collect();
        let idx = PointIndex::new(&pts);
        let eager = local_shapes(&pts, &idx, 20, 1e-3);
        let lazy = LazyShapes::new(&pts, &idx, 20, 1e-3);
        assert_eq!(lazy.computed(), 0);
        // The same neighbours (tree or grid), summed in a different order.
        for i in (0..200).rev() {
            let (a, b) = (lazy.get(&pts, &idx, i), &eager[i]);
            assert!((a.normal.dot(&b.normal).abs() - 1.0).abs() < 1e-12, "{i}");
            assert!((a.covariance - b.covariance).amax() < 1e-12, "{i}");
        }
        assert_eq!(lazy.computed(), 200);
    }

    /// A shape is the same bit for bit whether computed alone, in a batch of some points of
    /// its cell, or with the whole cell by the eager k-NN map.
    #[test]
    fn batched_shapes_equal_single_and_eager_ones() {
        let mut next = crate::test_rng::uniform(17);
        let pts: Vec<Point> = (0..3000)
            .map(|_| {
                let (u, v) = (next(), next());
                [u, v, 0.1 * (6.0 * u).sin() + 0.002 * next()]
            })
            .collect();
        let idx = PointIndex::new(&pts);
        let eager = local_shapes(&pts, &idx, 20, 1e-3);
        let single = LazyShapes::new(&pts, &idx, 20, 1e-3);
        let batched = LazyShapes::new(&pts, &idx, 20, 1e-3);
        assert!(batched.grid.is_some(), "the test must exercise the grid");
        // Every third point, with repeats, in two batches.
        let needed: Vec<usize> = (0..3000).step_by(3).chain((0..600).step_by(7)).collect();
        batched.ensure(&pts, &idx, needed[..500].iter().copied());
        batched.ensure(&pts, &idx, needed.iter().copied());
        let mut unique = needed.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(batched.computed(), unique.len());
        for &i in &needed {
            let (a, b) = (batched.get(&pts, &idx, i), single.get(&pts, &idx, i));
            assert_eq!(a, b, "{i}");
            assert_eq!(a, &eager[i], "{i}");
        }
        assert_eq!(batched.computed(), unique.len(), "ensure computed them all");
    }

    #[test]
    fn closed_form_normal_matches_the_iterative_solver() {
        let mut uniform = crate::test_rng::uniform(99);
        let mut r = || uniform() - 0.5;
        let mut checked = 0;
        for _ in 0..2000 {
            // Random rotation of a random diagonal (spreads from isotropic to flat).
            let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
                r(),
                r(),
                r(),
                r(),
            ));
            let scale = 10f64.powf(6.0 * r());
            let d = Vector3::new(r().abs() * 1e-2, r().abs() + 0.01, r().abs() + 0.5) * scale;
            let rm = q.to_rotation_matrix().into_inner();
            let a = rm * Matrix3::from_diagonal(&d) * rm.transpose();
            let (_, v) = sorted_eigen(&a);
            if let Some(n) = smallest_eigenvector(&a) {
                assert!((n.dot(&v.column(0)).abs() - 1.0).abs() < 1e-9, "{a}");
                checked += 1;
            }
        }
        assert!(checked > 1900, "{checked}");
        // Isotropic and double-smallest matrices defer to the iterative solver.
        assert!(smallest_eigenvector(&Matrix3::identity()).is_none());
        assert!(
            smallest_eigenvector(&Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 2.0))).is_none()
        );
        assert!(smallest_eigenvector(&Matrix3::zeros()).is_none());
    }

    #[test]
    fn degenerate_neighbourhoods_never_nan() {
        for pts in [
            vec![[1.0, 1.0, 1.0]; 25],                                  // repeated
            (0..25).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect(), // collinear
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],                     // too few
        ] {
            let s = shape_of(&pts, 1e-3);
            assert!(s.normal.iter().all(|v| v.is_finite()));
            assert!((s.normal.norm() - 1.0).abs() < 1e-9);
            assert!(s.covariance.iter().all(|v| v.is_finite()));
            let e = SymmetricEigen::new(s.covariance).eigenvalues;
            assert!(e.iter().all(|&v| v > 0.0), "{e:?}");
        }
    }
}
