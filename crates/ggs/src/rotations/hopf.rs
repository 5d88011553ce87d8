//! The Hopf-fibration grid of Yershova et al. with 15° steps, as the reference
//! `R_Hopf_15_15_15.npy` (see `rotations`).
//!
//! ψ = 15°·a (a < 24), θ = 15°·b (b < 12), φ = 15°·c (c < 24), a outermost and c fastest;
//! quaternion `(x, y, z, w) = (cos(θ/2)cos(ψ/2), cos(θ/2)sin(ψ/2), sin(θ/2)cos(φ+ψ/2),
//! sin(θ/2)sin(φ+ψ/2))` with w the scalar part.

use nalgebra::Matrix3;

/// Rotation matrix of the unit quaternion `(x, y, z, w)`, w scalar.
pub fn quaternion_matrix(x: f64, y: f64, z: f64, w: f64) -> Matrix3<f64> {
    Matrix3::new(
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - z * w),
        2.0 * (x * z + y * w),
        2.0 * (x * y + z * w),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - x * w),
        2.0 * (x * z - y * w),
        2.0 * (y * z + x * w),
        1.0 - 2.0 * (x * x + y * y),
    )
}

/// The 24·12·24 = 6912 rotations of the grid, in reference order (duplicates included).
pub fn hopf_grid(step_deg: f64) -> Vec<Matrix3<f64>> {
    let n_psi = (360.0 / step_deg).round() as usize;
    let n_theta = (180.0 / step_deg).round() as usize;
    let n_phi = n_psi;
    let mut out = Vec::with_capacity(n_psi * n_theta * n_phi);
    for a in 0..n_psi {
        let psi = (step_deg * a as f64).to_radians();
        for b in 0..n_theta {
            let theta = (step_deg * b as f64).to_radians();
            for c in 0..n_phi {
                let phi = (step_deg * c as f64).to_radians();
                let (ct, st) = ((theta / 2.0).cos(), (theta / 2.0).sin());
                let x = ct * (psi / 2.0).cos();
                let y = ct * (psi / 2.0).sin();
                let z = st * (phi + psi / 2.0).cos();
                let w = st * (phi + psi / 2.0).sin();
                out.push(quaternion_matrix(x, y, z, w));
            }
        }
    }
    out
}
