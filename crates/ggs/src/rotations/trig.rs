//! Sine and cosine of angles given in whole degrees, with exact values where they exist.
//!
//! `sin_deg(θ)` reduces θ to the first quadrant and evaluates `sin` below 45° and
//! `cos(90° − θ)` above it, with the exact values 0, ½, √½ and 1 at 0°, 30°, 45° and 90°.
//! So `sin_deg(θ)` and `cos_deg(90° − θ)` are bitwise equal, `sin_deg(180°) = 0` exactly, and
//! matrices built from these values reproduce the reference rotation sets of the original
//! code, including which gimbal-lock rows its duplicate removal kept.

/// `sin(θ)` for θ in degrees.
pub fn sin_deg(theta: f64) -> f64 {
    let mut d = theta.rem_euclid(360.0);
    let mut sign = 1.0;
    if d >= 180.0 {
        d -= 180.0;
        sign = -1.0;
    }
    if d > 90.0 {
        d = 180.0 - d;
    }
    let v = if d == 0.0 {
        0.0
    } else if d == 30.0 {
        0.5
    } else if d == 45.0 {
        std::f64::consts::FRAC_1_SQRT_2
    } else if d == 90.0 {
        1.0
    } else if d < 45.0 {
        d.to_radians().sin()
    } else {
        (90.0 - d).to_radians().cos()
    };
    sign * v
}

/// `cos(θ)` for θ in degrees: `sin_deg(θ + 90°)`.
pub fn cos_deg(theta: f64) -> f64 {
    sin_deg(theta + 90.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_values() {
        assert_eq!(sin_deg(0.0), 0.0);
        assert_eq!(sin_deg(180.0), 0.0);
        assert_eq!(sin_deg(-90.0), -1.0);
        assert_eq!(cos_deg(90.0), 0.0);
        assert_eq!(cos_deg(60.0), 0.5);
        assert_eq!(sin_deg(45.0), cos_deg(45.0));
        assert_eq!(sin_deg(75.0), cos_deg(15.0));
    }

    #[test]
    fn agrees_with_libm() {
        for k in -720..=720 {
            let d = k as f64 * 0.5;
            assert!((sin_deg(d) - d.to_radians().sin()).abs() < 1e-15, "{d}");
            assert!((cos_deg(d) - d.to_radians().cos()).abs() < 1e-15, "{d}");
        }
    }
}
