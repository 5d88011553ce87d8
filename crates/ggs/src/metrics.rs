//! Registration error metrics (docs/benchmarks.md).
//!
//! - `RRE = degrees(arccos(clip((trace(R_estᵀ·R_gt) − 1)/2, −1, 1)))`, in degrees;
//! - `RTE = ‖t_gt − t_est‖₂`, in the clouds' units;
//! - success: `RRE < τ_r` and `RTE < τ_t` (strict).

use crate::transform::{rotation_angle_deg, Rigid};

/// Relative rotation error in degrees.
pub fn rre(estimate: &Rigid, truth: &Rigid) -> f64 {
    rotation_angle_deg(&estimate.rotation, &truth.rotation)
}

/// Relative translation error, in the units of the clouds.
pub fn rte(estimate: &Rigid, truth: &Rigid) -> f64 {
    (truth.translation - estimate.translation).norm()
}

/// Strict success test: RRE < τ_r and RTE < τ_t.
pub fn is_success(rre_deg: f64, rte: f64, max_rre_deg: f64, max_rte: f64) -> bool {
    rre_deg < max_rre_deg && rte < max_rte
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3, Vector3};

    #[test]
    fn identity_has_zero_error() {
        let i = Rigid::identity();
        assert_eq!(rre(&i, &i), 0.0);
        assert_eq!(rte(&i, &i), 0.0);
    }

    #[test]
    fn quarter_turn_is_90_degrees() {
        let r = Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2);
        let a = Rigid::new(r.into_inner(), Vector3::new(3.0, 4.0, 0.0));
        let e = rre(&a, &Rigid::identity());
        assert!((e - 90.0).abs() < 1e-12);
        assert_eq!(rte(&a, &Rigid::identity()), 5.0);
    }

    #[test]
    fn errors_are_between_the_two_poses_not_from_the_origin() {
        // Both poses away from the identity (a test against the identity cannot tell
        // t_gt − t_est from t_gt + t_est, nor R_estᵀR_gt from R_est).
        let rot = |deg: f64| {
            Rotation3::from_axis_angle(&Vector3::z_axis(), deg.to_radians()).into_inner()
        };
        let est = Rigid::new(rot(100.0), Vector3::new(1.0, 2.0, 3.0));
        let truth = Rigid::new(rot(130.0), Vector3::new(4.0, 6.0, 3.0));
        assert_eq!(rte(&est, &truth), 5.0);
        assert!((rre(&est, &truth) - 30.0).abs() < 1e-9);
        assert!((rre(&truth, &est) - 30.0).abs() < 1e-9);
    }

    #[test]
    fn clip_keeps_acos_defined() {
        // A matrix slightly "larger" than a rotation would push the cosine past 1.
        let a = Rigid::new(Matrix3::identity() * (1.0 + 1e-12), Vector3::zeros());
        assert_eq!(rre(&a, &Rigid::identity()), 0.0);
        let b = Rigid::new(-Matrix3::identity() * (1.0 + 1e-12), Vector3::zeros());
        // trace = −3 (1+ε) → cos < −1 → clipped to exactly 180°.
        assert_eq!(rre(&b, &Rigid::identity()), 180.0);
    }

    #[test]
    fn success_is_strict() {
        assert!(is_success(0.9, 0.1, 1.0, 0.2));
        assert!(!is_success(1.0, 0.1, 1.0, 0.2));
        assert!(!is_success(0.5, 0.2, 1.0, 0.2));
    }
}
