//! Local covariances and normals from the k nearest neighbours of every point (SPEC §6).
//!
//! For a point with neighbours `N` (itself included): mean `μ`, covariance
//! `Σ = (1/|N|)·Σ (p − μ)(p − μ)ᵀ`, eigenvectors `e₁, e₂, e₃` with eigenvalues `λ₁ ≤ λ₂ ≤ λ₃`.
//! The normal is `e₁`; the GICP covariance is the regularized plane
//! `C = e₁·ε·e₁ᵀ + e₂e₂ᵀ + e₃e₃ᵀ = V·diag(ε, 1, 1)·Vᵀ` (ε = 1e-3): always symmetric positive
//! definite, whatever the neighbourhood (repeated or collinear points give some orthonormal
//! basis, never NaN). `planarity = (λ₂ − λ₁)/λ₃` (0 for a degenerate neighbourhood).

use super::neighbors::PointIndex;
use crate::cloud::Point;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use rayon::prelude::*;

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
        let (_, v) = sorted_eigen(&cov);
        let normal = v.column(0).into_owned();
        if !normal.iter().all(|x| x.is_finite()) || (normal.norm() - 1.0).abs() > 1e-6 {
            return fallback;
        }
        let covariance = Matrix3::identity() - (1.0 - epsilon) * normal * normal.transpose();
        LocalShape { normal, covariance }
    }
}

/// Shape of a neighbourhood given as points.
pub fn shape_of(points: &[Point], epsilon: f64) -> LocalShape {
    let mut m = Moments::new(points.first().unwrap_or(&[0.0; 3]));
    for p in points {
        m.push(p);
    }
    m.shape(epsilon)
}

/// Shapes of all points of a cloud from their `k` nearest neighbours (k-d tree), in
/// parallel; each point independently, so the result does not depend on the thread count.
pub fn local_shapes(
    points: &[Point],
    index: &PointIndex,
    k: usize,
    epsilon: f64,
) -> Vec<LocalShape> {
    points
        .par_iter()
        .map(|p| {
            let mut m = Moments::new(p);
            index.for_k_nearest(p, k, |j| m.push(&points[j]));
            m.shape(epsilon)
        })
        .collect()
}

/// Local shapes computed on first use and kept: only points that take part in a
/// correspondence ever pay for their neighbour search (a low-overlap pair touches a fraction
/// of each cloud). A shape is a pure function of the cloud and the point, so which thread
/// computes it first does not matter.
pub struct LazyShapes<'a> {
    points: &'a [Point],
    index: &'a PointIndex,
    k: usize,
    epsilon: f64,
    cache: Vec<std::sync::OnceLock<LocalShape>>,
}

impl<'a> LazyShapes<'a> {
    pub fn new(points: &'a [Point], index: &'a PointIndex, k: usize, epsilon: f64) -> Self {
        LazyShapes {
            points,
            index,
            k,
            epsilon,
            cache: (0..points.len())
                .map(|_| std::sync::OnceLock::new())
                .collect(),
        }
    }

    /// The shape of point `i`.
    #[inline]
    pub fn get(&self, i: usize) -> &LocalShape {
        self.cache[i].get_or_init(|| {
            let p = &self.points[i];
            let mut m = Moments::new(p);
            self.index
                .for_k_nearest(p, self.k, |j| m.push(&self.points[j]));
            m.shape(self.epsilon)
        })
    }

    /// How many shapes were computed so far.
    pub fn computed(&self) -> usize {
        self.cache.iter().filter(|c| c.get().is_some()).count()
    }
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
        for i in (0..200).rev() {
            assert_eq!(*lazy.get(i), eager[i]);
        }
        assert_eq!(lazy.computed(), 200);
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
