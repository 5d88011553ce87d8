//! Duplicate removal for rotation sets. Both rules keep the first occurrence, so the order of
//! the survivors is the order of the input.

use nalgebra::Matrix3;

/// Indices of the rotations kept when every rotation within `tol_deg` (geodesic angle) of an
/// earlier kept one is dropped. `tol_deg` must be ≥ 0.
///
/// Uses the chordal form, stable for tiny angles: `‖A − B‖_F = 2√2·sin(θ/2)`, so
/// `angle(A, B) ≤ tol ⇔ ‖A − B‖_F ≤ 2√2·sin(tol/2)` (plus 1e-13 for float noise).
pub fn dedup_geodesic(rotations: &[Matrix3<f64>], tol_deg: f64) -> Vec<usize> {
    let max_sq = (2.0 * 2f64.sqrt() * (tol_deg.to_radians() / 2.0).sin() + 1e-13).powi(2);
    let mut kept: Vec<usize> = Vec::new();
    for (i, r) in rotations.iter().enumerate() {
        let duplicate = kept
            .iter()
            .any(|&j| (rotations[j] - r).norm_squared() <= max_sq);
        if !duplicate {
            kept.push(i);
        }
    }
    kept
}

/// Indices kept by the element-wise rule of the reference files: a rotation is a duplicate of
/// an earlier kept one `K` when every entry satisfies `|r − k| ≤ 1e-16 + 1e-16·|k|`.
///
/// With matrices from [`super::euler::euler_matrix`] this reproduces
/// `R_limited_15_15_15_removed_duplicates.npy` (1886 rows) and
/// `R_15_15_15_removed_duplicates.npy` (6364 rows) row for row: the few gimbal-lock rows whose
/// entries carry `sin²45° + cos²45° = 1 + 2⁻⁵²` survive there as they did in the original.
pub fn dedup_reference(rotations: &[Matrix3<f64>]) -> Vec<usize> {
    let mut kept: Vec<usize> = Vec::new();
    for (i, r) in rotations.iter().enumerate() {
        let duplicate = kept.iter().any(|&j| {
            let k = &rotations[j];
            r.iter()
                .zip(k.iter())
                .all(|(a, b)| (a - b).abs() <= 1e-16 + 1e-16 * b.abs())
        });
        if !duplicate {
            kept.push(i);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rotations::euler::euler_matrix;

    #[test]
    fn geodesic_dedup_of_gimbal_lock() {
        // At β = −90° only α − γ matters.
        let m = vec![
            euler_matrix(0.0, -90.0, 0.0),
            euler_matrix(30.0, -90.0, 30.0),
            euler_matrix(30.0, -90.0, 0.0),
        ];
        assert_eq!(dedup_geodesic(&m, 1e-6), vec![0, 2]);
    }

    #[test]
    fn tolerance_groups_close_rotations() {
        let m = vec![
            euler_matrix(0.0, 0.0, 0.0),
            euler_matrix(0.0, 0.0, 4.0),
            euler_matrix(0.0, 0.0, 6.0),
        ];
        assert_eq!(dedup_geodesic(&m, 5.0), vec![0, 2]);
        assert_eq!(dedup_geodesic(&m, 0.0), vec![0, 1, 2]);
    }
}
