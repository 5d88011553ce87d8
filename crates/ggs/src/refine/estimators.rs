//! One linearized step of each estimator, accumulated over correspondences.
//!
//! Pose update: `T ← [Exp(ω) | v] ∘ T` with `ξ = (ω, v)` (rotation vector in radians, then
//! translation in cloud units) and Jacobian of a moved point `p' = T·p`:
//! `∂p'/∂ξ = [−[p']ₓ  I]`.
//! - point-to-plane: `r = nᵀ(p' − q)`, `J = [(p' × n)ᵀ  nᵀ]`;
//! - generalized ICP: `d = p' − q`, `M = (C_q + R·C_p·Rᵀ)⁻¹`, cost `dᵀMd`, `J = [−[p']ₓ  I]`;
//! - point-to-point: closed form (weighted Kabsch), see [`kabsch`].

use nalgebra::{Matrix3, Matrix3x6, Matrix6, Rotation3, Vector3, Vector6};

/// Normal equations `H·ξ = −b` with the cost they came from.
#[derive(Debug, Clone, Copy)]
pub struct NormalEquations {
    pub h: Matrix6<f64>,
    pub b: Vector6<f64>,
    pub cost: f64,
}

impl Default for NormalEquations {
    fn default() -> Self {
        NormalEquations {
            h: Matrix6::zeros(),
            b: Vector6::zeros(),
            cost: 0.0,
        }
    }
}

impl NormalEquations {
    pub fn add(&mut self, o: &NormalEquations) {
        self.h += o.h;
        self.b += o.b;
        self.cost += o.cost;
    }

    /// Point-to-plane term with weight `w`.
    #[inline]
    pub fn add_point_to_plane(
        &mut self,
        p: &Vector3<f64>,
        q: &Vector3<f64>,
        n: &Vector3<f64>,
        w: f64,
    ) {
        let r = n.dot(&(p - q));
        let a = p.cross(n);
        let j = Vector6::new(a.x, a.y, a.z, n.x, n.y, n.z);
        self.h += w * j * j.transpose();
        self.b += w * r * j;
        self.cost += w * r * r;
    }

    /// Generalized-ICP term with information `m = (C_q + R·C_p·Rᵀ)⁻¹` and weight `w`.
    #[inline]
    pub fn add_gicp(&mut self, p: &Vector3<f64>, q: &Vector3<f64>, m: &Matrix3<f64>, w: f64) {
        let d = p - q;
        let jac = jacobian(p);
        let jt_m = jac.transpose() * m;
        self.h += w * jt_m * jac;
        self.b += w * jt_m * d;
        self.cost += w * d.dot(&(m * d));
    }

    /// Solve `H·ξ = −b`: Cholesky, with a tiny Levenberg damping where `H` is singular
    /// (a degenerate geometry leaves the unconstrained directions unchanged).
    pub fn solve(&self) -> Option<Vector6<f64>> {
        if let Some(c) = self.h.cholesky() {
            return Some(-c.solve(&self.b));
        }
        let scale = (0..6)
            .map(|i| self.h[(i, i)].abs())
            .fold(0.0, f64::max)
            .max(1e-300);
        let damped = self.h + Matrix6::identity() * (1e-9 * scale);
        damped.cholesky().map(|c| -c.solve(&self.b))
    }
}

/// `∂(T·p)/∂ξ` at the moved point `p`: `[−[p]ₓ  I]`.
#[inline]
pub fn jacobian(p: &Vector3<f64>) -> Matrix3x6<f64> {
    let mut j = Matrix3x6::zeros();
    let s = -p.cross_matrix();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&s);
    j.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&Matrix3::identity());
    j
}

/// `Exp(ω)` (Rodrigues, exact on SO(3)).
pub fn exp_so3(omega: &Vector3<f64>) -> Matrix3<f64> {
    Rotation3::new(*omega).into_inner()
}

/// Angle of a rotation in radians, accurate for tiny angles:
/// `atan2(‖vee(R − Rᵀ)‖/2, (trace R − 1)/2)`.
pub fn rotation_angle_rad(r: &Matrix3<f64>) -> f64 {
    let v = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    (v.norm() / 2.0).atan2((r.trace() - 1.0) / 2.0)
}

/// Nearest rotation to `m` (SVD, determinant fixed to +1): keeps a pose exactly on SO(3).
pub fn orthonormalize(m: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = m.svd(true, true);
    let (u, vt) = (svd.u.expect("u"), svd.v_t.expect("v_t"));
    let mut r = u * vt;
    if r.determinant() < 0.0 {
        let mut u2 = u;
        u2.column_mut(2).neg_mut();
        r = u2 * vt;
    }
    r
}

/// Weighted sums for the closed-form point-to-point step.
#[derive(Debug, Clone, Copy)]
pub struct KabschSums {
    pub w: f64,
    pub p: Vector3<f64>,
    pub q: Vector3<f64>,
    pub pq: Matrix3<f64>,
}

impl Default for KabschSums {
    fn default() -> Self {
        KabschSums {
            w: 0.0,
            p: Vector3::zeros(),
            q: Vector3::zeros(),
            pq: Matrix3::zeros(),
        }
    }
}

impl KabschSums {
    #[inline]
    pub fn push(&mut self, p: &Vector3<f64>, q: &Vector3<f64>, w: f64) {
        self.w += w;
        self.p += w * p;
        self.q += w * q;
        self.pq += w * p * q.transpose();
    }

    pub fn add(&mut self, o: &KabschSums) {
        self.w += o.w;
        self.p += o.p;
        self.q += o.q;
        self.pq += o.pq;
    }
}

/// Weighted Kabsch: the rigid `(R, t)` minimizing `Σ w·‖R·p + t − q‖²`.
pub fn kabsch(s: &KabschSums) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    if s.w <= 0.0 {
        return None;
    }
    let mp = s.p / s.w;
    let mq = s.q / s.w;
    // Σ w (p − mp)(q − mq)ᵀ
    let cross = s.pq - s.w * mp * mq.transpose();
    let svd = cross.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut d = Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = vt.transpose() * d * u.transpose();
    Some((r, mq - r * mp))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kabsch_recovers_a_motion() {
        let r = exp_so3(&Vector3::new(0.3, -0.2, 0.5));
        let t = Vector3::new(0.1, 2.0, -1.0);
        let mut s = KabschSums::default();
        for i in 0..20 {
            let p = Vector3::new((i as f64).sin(), (i as f64 * 0.7).cos(), i as f64 * 0.1);
            s.push(&p, &(r * p + t), 1.0);
        }
        let (re, te) = kabsch(&s).unwrap();
        assert!((re - r).abs().max() < 1e-12);
        assert!((te - t).norm() < 1e-12);
    }

    #[test]
    fn tiny_angles_are_exact() {
        for a in [1e-12, 1e-8, 1e-3, 1.0, 3.0] {
            let r = exp_so3(&Vector3::new(0.0, a, 0.0));
            assert!(
                (rotation_angle_rad(&r) - a).abs() < 1e-15 + 1e-12 * a,
                "{a}"
            );
        }
    }

    #[test]
    fn orthonormalize_projects_to_so3() {
        let r = exp_so3(&Vector3::new(1.0, 0.5, -0.3));
        let noisy = r + Matrix3::new(1e-4, 0.0, 2e-4, 0.0, -1e-4, 0.0, 3e-4, 0.0, 0.0);
        let o = orthonormalize(&noisy);
        assert!((o.transpose() * o - Matrix3::identity()).abs().max() < 1e-14);
        assert!((o.determinant() - 1.0).abs() < 1e-14);
        assert!((o - r).abs().max() < 1e-3);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let p = Vector3::new(0.3, -1.2, 2.0);
        let j = jacobian(&p);
        let h = 1e-7;
        for k in 0..6 {
            let mut xi = Vector6::zeros();
            xi[k] = h;
            let w = Vector3::new(xi[0], xi[1], xi[2]);
            let v = Vector3::new(xi[3], xi[4], xi[5]);
            let moved = exp_so3(&w) * p + v;
            let fd = (moved - p) / h;
            assert!((fd - j.column(k)).norm() < 1e-6);
        }
    }

    /// `(p, q, n)`: a point, its match and the match's normal.
    type Correspondence = (Vector3<f64>, Vector3<f64>, Vector3<f64>);

    /// Points on three planes with their normals (so point-to-plane constrains all six
    /// directions), and the same points moved by a tiny motion `(ω, v)`.
    fn tiny_motion_problem() -> (Vec<Correspondence>, Vector6<f64>) {
        let xi = Vector6::new(2e-5, -3e-5, 1e-5, 4e-5, -1e-5, 2.5e-5);
        let r = exp_so3(&Vector3::new(xi[0], xi[1], xi[2]));
        let t = Vector3::new(xi[3], xi[4], xi[5]);
        let mut out = Vec::new();
        for k in 0..60 {
            let (a, b) = ((k % 6) as f64 * 0.1 - 0.25, (k / 6) as f64 * 0.07 - 0.3);
            let (p, n) = match k % 3 {
                0 => (Vector3::new(a, b, 0.4), Vector3::z()),
                1 => (Vector3::new(0.3, a, b), Vector3::x()),
                _ => (Vector3::new(b, -0.2, a), Vector3::y()),
            };
            out.push((p, r * p + t, r * n));
        }
        (out, xi)
    }

    #[test]
    fn one_point_to_plane_step_recovers_a_tiny_motion_and_sums_add() {
        let (corr, xi) = tiny_motion_problem();
        let (mut all, mut first, mut second) = Default::default();
        for (k, (p, q, n)) in corr.iter().enumerate() {
            let w = if k % 2 == 0 { 0.5 } else { 2.0 };
            NormalEquations::add_point_to_plane(&mut all, p, q, n, w);
            let half: &mut NormalEquations = if k < 30 { &mut first } else { &mut second };
            half.add_point_to_plane(p, q, n, w);
        }
        let step = all.solve().expect("six constrained directions");
        // Linearized at the identity: exact up to second order in |ξ| (≈ 1e-9 here).
        assert!((step - xi).norm() < 1e-3 * xi.norm(), "{step} vs {xi}");
        first.add(&second);
        assert!((first.h - all.h).norm() < 1e-12 && (first.b - all.b).norm() < 1e-15);
        assert!((first.cost - all.cost).abs() < 1e-20 && all.cost > 0.0);
    }

    #[test]
    fn one_term_is_its_formula() {
        // Point-to-plane: J = nᵀ·∂p'/∂ξ, H = w JJᵀ, b = w r J, cost = w r².
        let (p, q) = (Vector3::new(0.3, -0.2, 0.5), Vector3::new(0.1, 0.25, 0.45));
        let n = Vector3::new(1.0, 2.0, 2.0) / 3.0;
        let w = 0.7;
        let mut e = NormalEquations::default();
        e.add_point_to_plane(&p, &q, &n, w);
        let j: Vector6<f64> = (n.transpose() * jacobian(&p)).transpose();
        let r = n.dot(&p) - n.dot(&q);
        assert!((e.h - j * j.transpose() * w).norm() < 1e-14);
        assert!((e.b - j * (w * r)).norm() < 1e-14);
        assert!((e.cost - w * r * r).abs() < 1e-15);
        // GICP: d = p − q, H = w JᵀMJ, b = w JᵀMd, cost = w dᵀMd.
        let m = Matrix3::new(2.0, 0.1, 0.0, 0.1, 1.0, 0.2, 0.0, 0.2, 3.0);
        let mut g = NormalEquations::default();
        g.add_gicp(&p, &q, &m, w);
        let jac = jacobian(&p);
        let d = Vector3::new(p.x - q.x, p.y - q.y, p.z - q.z);
        assert!((g.h - jac.transpose() * (m * jac) * w).norm() < 1e-13);
        assert!((g.b - jac.transpose() * (m * d) * w).norm() < 1e-14);
        assert!((g.cost - w * (d.transpose() * m * d)[0]).abs() < 1e-15);
    }

    #[test]
    fn a_gicp_step_recovers_a_tiny_motion() {
        let (corr, xi) = tiny_motion_problem();
        let m = Matrix3::new(2.0, 0.1, 0.0, 0.1, 1.0, 0.2, 0.0, 0.2, 3.0);
        let mut e = NormalEquations::default();
        for (p, q, _) in &corr {
            e.add_gicp(p, q, &m, 1.5);
        }
        let step = e.solve().unwrap();
        assert!((step - xi).norm() < 1e-3 * xi.norm(), "{step} vs {xi}");
    }

    #[test]
    fn a_degenerate_system_is_solved_in_its_constrained_directions() {
        // One plane z = 0 moved along z: only v_z, ω_x and ω_y are constrained; Cholesky fails
        // and the damped solve keeps the others at zero.
        let mut e = NormalEquations::default();
        for k in 0..50 {
            let p = Vector3::new((k % 7) as f64 * 0.1, (k / 7) as f64 * 0.1, 0.0);
            let q = p + Vector3::new(0.0, 0.0, 1e-4);
            e.add_point_to_plane(&p, &q, &Vector3::z(), 1.0);
        }
        assert!(e.h.cholesky().is_none());
        let step = e.solve().expect("damped");
        assert!((step[5] - 1e-4).abs() < 1e-8, "{step}");
        for i in [0, 1, 2, 3, 4] {
            assert!(step[i].abs() < 1e-8, "{i}: {step}");
        }
    }

    #[test]
    fn rotation_angles_about_each_axis() {
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            for angle in [1e-7, 0.3, 2.5] {
                let r = exp_so3(&(axis * angle));
                assert!((rotation_angle_rad(&r) - angle).abs() < 1e-12 * angle.max(1.0));
            }
        }
    }
}
