//! Rigid transforms `p ↦ R·p + t` (R in SO(3), t in the cloud's units).
//!
//! Convention everywhere in ggs: a registration result T maps source points into the target
//! frame, `p_target = T · p_source`.

use nalgebra::{Matrix3, Matrix4, Vector3};

/// A 3-D point, `[x, y, z]`, in the cloud's units (metres for every real data set here).
pub type Point = [f64; 3];

/// Serialize a [`Rigid`] as its 4×4 rows (for `#[serde(serialize_with = "...")]`).
pub fn serialize_rows<S: serde::Serializer>(t: &Rigid, s: S) -> Result<S::Ok, S::Error> {
    serde::Serialize::serialize(&t.to_rows(), s)
}

/// A rigid transform `p ↦ R·p + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rigid {
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
}

impl Default for Rigid {
    fn default() -> Self {
        Self::identity()
    }
}

impl Rigid {
    pub fn identity() -> Self {
        Rigid {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    pub fn new(rotation: Matrix3<f64>, translation: Vector3<f64>) -> Self {
        Rigid {
            rotation,
            translation,
        }
    }

    /// `R·p + t`.
    pub fn apply(&self, p: &Point) -> Point {
        let v = self.rotation * Vector3::new(p[0], p[1], p[2]) + self.translation;
        [v.x, v.y, v.z]
    }

    /// `T⁻¹ = [Rᵀ, −Rᵀ·t]`.
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Rigid {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// `self ∘ other`: apply `other` first, then `self`.
    pub fn compose(&self, other: &Rigid) -> Self {
        Rigid {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// Homogeneous 4×4 matrix.
    pub fn to_matrix4(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&self.rotation);
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }

    /// Row-major 4×4 as nested arrays (for JSON).
    pub fn to_rows(&self) -> [[f64; 4]; 4] {
        let m = self.to_matrix4();
        let mut out = [[0.0; 4]; 4];
        for (r, row) in out.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = m[(r, c)];
            }
        }
        out
    }

    /// From 16 row-major numbers. Checks the last row is `0 0 0 1` and that the 3×3 block is a
    /// rotation to within `tol` (‖RᵀR − I‖∞ and |det R − 1|).
    pub fn from_row_major(v: &[f64], tol: f64) -> Result<Self, String> {
        if v.len() != 16 {
            return Err(format!("expected 16 numbers, found {}", v.len()));
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err("the matrix has a NaN or infinite entry".into());
        }
        let bottom = [v[12], v[13], v[14], v[15]];
        if bottom
            .iter()
            .zip([0.0, 0.0, 0.0, 1.0])
            .any(|(a, b)| (a - b).abs() > tol)
        {
            return Err(format!("last row must be 0 0 0 1, found {bottom:?}"));
        }
        let r = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
        let err = (r.transpose() * r - Matrix3::identity()).abs().max();
        let det = r.determinant();
        if err > tol || (det - 1.0).abs() > tol {
            return Err(format!(
                "the 3×3 block is not a rotation (‖RᵀR − I‖ = {err:.3e}, det = {det:.6})"
            ));
        }
        Ok(Rigid::new(r, Vector3::new(v[3], v[7], v[11])))
    }

    /// Text form: four lines of four numbers, full precision (`{:.17e}` round-trips f64).
    pub fn to_text(&self) -> String {
        let mut s = String::new();
        for row in self.to_rows() {
            let line: Vec<String> = row.iter().map(|v| format_number(*v)).collect();
            s.push_str(&line.join(" "));
            s.push('\n');
        }
        s
    }
}

/// Shortest decimal text that parses back to the same f64 (Rust's `Display` guarantees it).
fn format_number(v: f64) -> String {
    if v == 0.0 {
        "0".to_string()
    } else {
        format!("{v}")
    }
}

/// Geodesic angle between two rotations in degrees:
/// `θ = degrees(arccos(clip((trace(AᵀB) − 1)/2, −1, 1)))`.
pub fn rotation_angle_deg(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let tr = (a.transpose() * b).trace();
    ((tr - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

/// `rotation_angle_deg(a, b) <= max_deg`, decided without the arc cosine where the cosine
/// of the angle, `(tr(aᵀ·b) − 1)/2` (here `Σ a_ij·b_ij`), is more than 1e-9 from
/// `cos(max_deg)`: the angle is monotone in it, and both ways of computing it agree to
/// about 1e-15. Closer than that, the answer is [`rotation_angle_deg`]'s itself. A search's
/// neighbour test runs it hundreds of thousands of times: [`WithinDeg`] computes
/// `cos(max_deg)` once for them.
pub fn rotation_within_deg(a: &Matrix3<f64>, b: &Matrix3<f64>, max_deg: f64) -> bool {
    WithinDeg::new(max_deg).holds(a, b)
}

/// The test "at most `max_deg` apart" ([`rotation_within_deg`]) with `cos(max_deg)` computed
/// once, for a test run over many pairs of rotations.
#[derive(Debug, Clone, Copy)]
pub struct WithinDeg {
    max_deg: f64,
    cos_max: f64,
}

impl WithinDeg {
    pub fn new(max_deg: f64) -> Self {
        WithinDeg {
            max_deg,
            cos_max: max_deg.to_radians().cos(),
        }
    }

    /// Whether `a` and `b` are at most the angle apart.
    #[inline]
    pub fn holds(&self, a: &Matrix3<f64>, b: &Matrix3<f64>) -> bool {
        let tr: f64 = a.iter().zip(b.iter()).map(|(x, y)| x * y).sum();
        let cos = (tr - 1.0) / 2.0;
        if cos > self.cos_max + 1e-9 {
            true
        } else if cos < self.cos_max - 1e-9 {
            false
        } else {
            rotation_angle_deg(a, b) <= self.max_deg
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;
    use proptest::prelude::*;

    proptest! {
        /// The neighbour test without the arc cosine answers as the angle does, near the
        /// bound and far from it.
        #[test]
        fn rotation_within_deg_agrees_with_the_angle(
            ax in -3.0f64..3.0, ay in -3.0f64..3.0, az in -3.0f64..3.0,
            bx in -3.0f64..3.0, by in -3.0f64..3.0, bz in -3.0f64..3.0,
            max in 0.0f64..180.0, near in proptest::bool::ANY,
        ) {
            let a = Rotation3::from_euler_angles(ax, ay, az).into_inner();
            let b = Rotation3::from_euler_angles(bx, by, bz).into_inner();
            let angle = rotation_angle_deg(&a, &b);
            // Half the cases put the bound on the angle itself (within rounding).
            let bound = if near { angle * (1.0 + 1e-13) } else { max };
            prop_assert_eq!(rotation_within_deg(&a, &b, bound), angle <= bound);
        }
    }

    fn rigid(ax: f64, ay: f64, az: f64, t: [f64; 3]) -> Rigid {
        let r = Rotation3::from_euler_angles(ax, ay, az).into_inner();
        Rigid::new(r, Vector3::new(t[0], t[1], t[2]))
    }

    proptest! {
        #[test]
        fn inverse_composes_to_identity(ax in -3.2f64..3.2, ay in -1.5f64..1.5, az in -3.2f64..3.2,
                                        tx in -10f64..10.0, ty in -10f64..10.0, tz in -10f64..10.0) {
            let t = rigid(ax, ay, az, [tx, ty, tz]);
            let i = t.compose(&t.inverse());
            prop_assert!((i.rotation - Matrix3::identity()).abs().max() < 1e-12);
            prop_assert!(i.translation.norm() < 1e-12);
            let p = [1.0, -2.0, 3.0];
            let q = t.inverse().apply(&t.apply(&p));
            prop_assert!((q[0] - p[0]).abs() < 1e-9 && (q[1] - p[1]).abs() < 1e-9 && (q[2] - p[2]).abs() < 1e-9);
        }
    }

    #[test]
    fn text_round_trip_is_exact() {
        let t = rigid(0.3, -0.2, 1.1, [0.1, 2.5e-7, -3.0]);
        let text = t.to_text();
        let nums: Vec<f64> = text
            .split_whitespace()
            .map(|s| s.parse().unwrap())
            .collect();
        let back = Rigid::from_row_major(&nums, 1e-9).unwrap();
        assert_eq!(back, t);
    }

    #[test]
    fn rejects_non_rotation() {
        let mut v = vec![0.0; 16];
        v[0] = 2.0;
        v[5] = 1.0;
        v[10] = 1.0;
        v[15] = 1.0;
        assert!(Rigid::from_row_major(&v, 1e-6).is_err());
        assert!(Rigid::from_row_major(&v[..15], 1e-6).is_err());
    }

    #[test]
    fn angle_between_rotations() {
        let a = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.0).into_inner();
        let b = Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2)
            .into_inner();
        assert!((rotation_angle_deg(&a, &b) - 90.0).abs() < 1e-12);
        assert_eq!(rotation_angle_deg(&a, &a), 0.0);
    }

    #[test]
    fn apply_compose_and_identity_have_their_matrix_meaning() {
        // Known values, not algebraic round trips (those hold for R·p − t too).
        let quarter = Rotation3::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2)
            .into_inner();
        let t = Rigid::new(quarter, Vector3::new(10.0, 20.0, 30.0));
        let q = t.apply(&[1.0, 0.0, 0.0]);
        assert!((q[0] - 10.0).abs() < 1e-12 && (q[1] - 21.0).abs() < 1e-12 && q[2] == 30.0);
        let p = [1.5, -2.0, 0.25];
        assert_eq!(Rigid::identity().apply(&p), p);
        assert_eq!(Rigid::default(), Rigid::identity());
        // compose = the product of the 4×4 matrices, applied right to left.
        let u = rigid(0.4, -0.3, 1.2, [-1.0, 0.5, 2.0]);
        let c = t.compose(&u);
        assert!(
            (c.to_matrix4() - t.to_matrix4() * u.to_matrix4())
                .abs()
                .max()
                < 1e-12
        );
        let direct = t.apply(&u.apply(&p));
        let composed = c.apply(&p);
        for k in 0..3 {
            assert!((direct[k] - composed[k]).abs() < 1e-12);
        }
    }

    #[test]
    fn from_row_major_accepts_up_to_the_tolerance_and_no_further() {
        let mut v = vec![0.0; 16];
        for k in [0, 5, 10, 15] {
            v[k] = 1.0;
        }
        // A bottom row off by exactly the tolerance is accepted, past it rejected.
        v[12] = 0.25;
        assert!(Rigid::from_row_major(&v, 0.25).is_ok());
        v[12] = 0.5;
        let e = Rigid::from_row_major(&v, 0.25).unwrap_err();
        assert!(e.contains("last row"), "{e}");
        v[12] = 0.0;
        // The same for the rotation block: ‖RᵀR − I‖ = 2s + s² for R = (1 + s)·I.
        let s = 0.125;
        for k in [0, 5, 10] {
            v[k] = 1.0 + s;
        }
        let err = 2.0 * s + s * s;
        let det = (1.0 + s) * (1.0 + s) * (1.0 + s) - 1.0;
        assert!(Rigid::from_row_major(&v, det.max(err)).is_ok());
        let e = Rigid::from_row_major(&v, err * 0.99).unwrap_err();
        assert!(e.contains("not a rotation"), "{e}");
    }

    #[test]
    fn a_reflection_is_not_a_rotation_and_angles_are_exact_off_the_axes() {
        // RᵀR = I but det = −1: only the determinant rejects it.
        let mut v = vec![0.0; 16];
        v[0] = -1.0;
        v[5] = 1.0;
        v[10] = 1.0;
        v[15] = 1.0;
        let e = Rigid::from_row_major(&v, 1e-6).unwrap_err();
        assert!(e.contains("det = -1"), "{e}");
        // 60° (cos = 1/2): an angle where (tr − 1)/2 is neither 0 nor ±1.
        let a = Rotation3::from_axis_angle(&Vector3::x_axis(), 0.0).into_inner();
        let b = Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_3)
            .into_inner();
        assert!((rotation_angle_deg(&a, &b) - 60.0).abs() < 1e-9);
    }

    #[test]
    fn a_stretch_with_unit_determinant_is_judged_by_its_orthogonality() {
        // diag(2, 1/2, 1): det = 1 exactly, ‖RᵀR − I‖∞ = 3 exactly.
        let mut v = vec![0.0; 16];
        v[0] = 2.0;
        v[5] = 0.5;
        v[10] = 1.0;
        v[15] = 1.0;
        assert!(Rigid::from_row_major(&v, 3.0).is_ok());
        let e = Rigid::from_row_major(&v, 2.9).unwrap_err();
        assert!(e.contains("not a rotation"), "{e}");
    }
}
