//! Euler-angle grids of the original Greedy Grid Search (`limited15`, `full15`, `limited10`, see `rotations`).
//!
//! `R(α, β, γ) = Rz(−γ)·Ry(−β)·Rx(−α) = (Rx(α)·Ry(β)·Rz(γ))ᵀ`, applied as `R·p`; angles in
//! degrees. Grid order: α outermost, then β, then γ fastest. Each angle list is in the order of
//! its values taken modulo 360° (so −90…90 runs 0, 15, …, 90, 270, …, 345), as the reference
//! files have it.

use super::trig::{cos_deg, sin_deg};
use nalgebra::Matrix3;

/// `Rx(θ)`: rotation by θ degrees about x.
pub fn rot_x(theta: f64) -> Matrix3<f64> {
    let (s, c) = (sin_deg(theta), cos_deg(theta));
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

/// `Ry(θ)`: rotation by θ degrees about y.
pub fn rot_y(theta: f64) -> Matrix3<f64> {
    let (s, c) = (sin_deg(theta), cos_deg(theta));
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}

/// `Rz(θ)`: rotation by θ degrees about z.
pub fn rot_z(theta: f64) -> Matrix3<f64> {
    let (s, c) = (sin_deg(theta), cos_deg(theta));
    Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// `R(α, β, γ) = Rz(−γ)·Ry(−β)·Rx(−α)`, angles in degrees.
pub fn euler_matrix(alpha: f64, beta: f64, gamma: f64) -> Matrix3<f64> {
    rot_z(-gamma) * rot_y(-beta) * rot_x(-alpha)
}

/// The values `lo, lo+step, …, hi` (inclusive when reached), reduced modulo 360° into
/// [0, 360) and sorted ascending, as the reference grids order them.
pub fn angle_list_mod360(lo: i32, hi: i32, step: i32) -> Vec<f64> {
    let mut v: Vec<i32> = (lo..=hi)
        .step_by(step as usize)
        .map(|a| a.rem_euclid(360))
        .collect();
    v.sort_unstable();
    v.dedup();
    v.into_iter().map(f64::from).collect()
}

/// The values `lo, lo+step, …` up to `hi` inclusive, in ascending order, not reduced.
pub fn angle_list(lo: i32, hi: i32, step: i32) -> Vec<f64> {
    (lo..=hi).step_by(step as usize).map(f64::from).collect()
}

/// One rotation of a grid with its angles (degrees).
#[derive(Debug, Clone, Copy)]
pub struct EulerRotation {
    pub alpha: f64,
    pub beta: f64,
    pub gamma: f64,
    pub matrix: Matrix3<f64>,
}

/// The full grid, α outermost, γ fastest.
pub fn euler_grid(alphas: &[f64], betas: &[f64], gammas: &[f64]) -> Vec<EulerRotation> {
    let mut out = Vec::with_capacity(alphas.len() * betas.len() * gammas.len());
    for &alpha in alphas {
        for &beta in betas {
            for &gamma in gammas {
                out.push(EulerRotation {
                    alpha,
                    beta,
                    gamma,
                    matrix: euler_matrix(alpha, beta, gamma),
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn is_transpose_of_xyz_product() {
        for (a, b, g) in [
            (15.0, -30.0, 45.0),
            (90.0, 75.0, 330.0),
            (0.0, -90.0, 270.0),
        ] {
            let m = euler_matrix(a, b, g);
            let n = (rot_x(a) * rot_y(b) * rot_z(g)).transpose();
            assert!((m - n).abs().max() < 1e-15);
            assert!((m.determinant() - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn angle_lists() {
        assert_eq!(
            angle_list_mod360(-90, 90, 15),
            vec![0., 15., 30., 45., 60., 75., 90., 270., 285., 300., 315., 330., 345.]
        );
        assert_eq!(angle_list(-90, 75, 15).len(), 12);
    }
}
