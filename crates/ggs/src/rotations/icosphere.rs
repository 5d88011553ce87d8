//! Icosphere vertices and the axis-angle rotation set of Exhaustive Grid Search (`ico162-s10`, see `rotations`).

use super::trig::{cos_deg, sin_deg};
use nalgebra::{Matrix3, Vector3};
use std::collections::HashMap;

/// Unit vertices of an icosahedron subdivided `levels` times (each edge split at its midpoint,
/// new vertices pushed to the unit sphere): 12, 42, 162, 642, … vertices. The order is
/// deterministic: the 12 icosahedron vertices, then new vertices in the order the faces
/// create them.
pub fn icosphere(levels: u32) -> Vec<Vector3<f64>> {
    let (vertices, _) = icosphere_mesh(levels);
    vertices
}

/// The regular icosahedron: vertices `(±1, ±φ, 0), (0, ±1, ±φ), (±φ, 0, ±1)` (not normalised,
/// length √(1 + φ²)) and its 20 faces, counter-clockwise from outside, in the usual order.
pub fn icosahedron() -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let p = (1.0 + 5f64.sqrt()) / 2.0;
    let vertices = vec![
        [-1.0, p, 0.0],
        [1.0, p, 0.0],
        [-1.0, -p, 0.0],
        [1.0, -p, 0.0],
        [0.0, -1.0, p],
        [0.0, 1.0, p],
        [0.0, -1.0, -p],
        [0.0, 1.0, -p],
        [p, 0.0, -1.0],
        [p, 0.0, 1.0],
        [-p, 0.0, -1.0],
        [-p, 0.0, 1.0],
    ];
    let faces = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    (vertices, faces)
}

/// Vertices and triangles of the subdivided icosahedron.
pub fn icosphere_mesh(levels: u32) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>) {
    let (raw, mut faces) = icosahedron();
    let mut v: Vec<Vector3<f64>> = raw
        .iter()
        .map(|a| Vector3::new(a[0], a[1], a[2]).normalize())
        .collect();
    for _ in 0..levels {
        let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
        let mut next = Vec::with_capacity(faces.len() * 4);
        for f in &faces {
            let mut m = [0usize; 3];
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                m[k] = *mid.entry(key).or_insert_with(|| {
                    v.push(((v[a] + v[b]) / 2.0).normalize());
                    v.len() - 1
                });
            }
            next.push([f[0], m[0], m[2]]);
            next.push([f[1], m[1], m[0]]);
            next.push([f[2], m[2], m[1]]);
            next.push([m[0], m[1], m[2]]);
        }
        faces = next;
    }
    (v, faces)
}

/// Rotation by `angle_deg` about the unit `axis` (Rodrigues).
pub fn axis_angle(axis: &Vector3<f64>, angle_deg: f64) -> Matrix3<f64> {
    let (s, c) = (sin_deg(angle_deg), cos_deg(angle_deg));
    let k = axis.cross_matrix();
    Matrix3::identity() + k * s + k * k * (1.0 - c)
}

/// Identity, then for each icosphere vertex (in order) the rotations by `step`, `2·step`, …,
/// `360° − step` about it. Not deduplicated: antipodal vertices repeat every rotation.
pub fn axis_angle_set(levels: u32, step_deg: u32) -> Vec<Matrix3<f64>> {
    let mut out = vec![Matrix3::identity()];
    for axis in icosphere(levels) {
        for k in (step_deg..360).step_by(step_deg as usize) {
            out.push(axis_angle(&axis, k as f64));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_counts() {
        assert_eq!(icosphere(0).len(), 12);
        assert_eq!(icosphere(1).len(), 42);
        assert_eq!(icosphere(2).len(), 162);
        for v in icosphere(2) {
            assert!((v.norm() - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn antipodes_present() {
        let v = icosphere(2);
        for a in &v {
            assert!(v.iter().any(|b| (a + b).norm() < 1e-12));
        }
    }

    #[test]
    fn rodrigues_is_rotation() {
        let axis = Vector3::new(1.0, 2.0, 3.0).normalize();
        let r = axis_angle(&axis, 40.0);
        assert!((r.transpose() * r - Matrix3::identity()).abs().max() < 1e-15);
        assert!((r * axis - axis).norm() < 1e-15);
        let ang = crate::transform::rotation_angle_deg(&Matrix3::identity(), &r);
        assert!((ang - 40.0).abs() < 1e-9);
    }
}
