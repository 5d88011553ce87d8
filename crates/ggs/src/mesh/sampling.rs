//! Seeded uniform sampling of a triangle mesh's surface.
//!
//! A triangle is chosen with probability proportional to its area (binary search in the
//! cumulative areas), then a point uniform in it: with r₁, r₂ uniform in [0, 1),
//! `p = (1 − √r₁)·a + √r₁·(1 − r₂)·b + √r₁·r₂·c` (Osada et al. 2002).

use super::Mesh;
use crate::cloud::Point;
use crate::rng::Rng;

/// Total surface area of the mesh, in squared mesh units.
pub fn surface_area(mesh: &Mesh) -> f64 {
    mesh.triangles.iter().map(|t| triangle_area(mesh, t)).sum()
}

fn triangle_area(mesh: &Mesh, t: &[u32; 3]) -> f64 {
    let [a, b, c] = t.map(|i| mesh.vertices[i as usize]);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

/// The number of samples that gives a mean spacing of about `spacing`: `⌈area / spacing²⌉`.
pub fn count_for_spacing(mesh: &Mesh, spacing: f64) -> usize {
    (surface_area(mesh) / (spacing * spacing)).ceil() as usize
}

/// `count` points uniform on the surface, from `seed`. Errors if the mesh has no triangle
/// of positive area.
pub fn sample_surface(mesh: &Mesh, count: usize, seed: u64) -> Result<Vec<Point>, String> {
    let mut cumulative = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for t in &mesh.triangles {
        total += triangle_area(mesh, t);
        cumulative.push(total);
    }
    if !(total > 0.0 && total.is_finite()) {
        return Err(format!(
            "the mesh has no surface to sample ({} triangles, total area {total})",
            mesh.triangles.len()
        ));
    }
    let mut rng = Rng::stream(seed, &[0x005a_4d50_4c45]);
    let mut out = Vec::with_capacity(count);
    for _ in 0..count {
        let u = rng.uniform() * total;
        let k = cumulative
            .partition_point(|&c| c <= u)
            .min(cumulative.len() - 1);
        let [a, b, c] = mesh.triangles[k].map(|i| mesh.vertices[i as usize]);
        let s = rng.uniform().sqrt();
        let r2 = rng.uniform();
        let (wa, wb, wc) = (1.0 - s, s * (1.0 - r2), s * r2);
        out.push([
            wa * a[0] + wb * b[0] + wc * c[0],
            wa * a[1] + wb * b[1] + wc * c[1],
            wa * a[2] + wb * b[2] + wc * c[2],
        ]);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_and_far_triangle() -> Mesh {
        // Unit square (area 1) in z = 0 and a triangle of area 3 in z = 5.
        Mesh {
            vertices: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 5.0],
                [3.0, 0.0, 5.0],
                [0.0, 2.0, 5.0],
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]],
            triangle_group: vec![0; 3],
            groups: vec![String::new()],
        }
    }

    #[test]
    fn area_weighted_and_on_the_surface() {
        let m = square_and_far_triangle();
        assert!((surface_area(&m) - 4.0).abs() < 1e-12);
        let pts = sample_surface(&m, 40_000, 9).unwrap();
        let high = pts.iter().filter(|p| (p[2] - 5.0).abs() < 1e-9).count();
        assert!((high as f64 / 40_000.0 - 0.75).abs() < 0.01, "{high}");
        for p in &pts {
            if p[2].abs() < 1e-9 {
                assert!((0.0..=1.0).contains(&p[0]) && (0.0..=1.0).contains(&p[1]));
            } else {
                assert!((p[2] - 5.0).abs() < 1e-9);
                assert!(p[0] >= 0.0 && p[1] >= 0.0 && p[0] / 3.0 + p[1] / 2.0 <= 1.0 + 1e-12);
            }
        }
        // Uniform within the square: each quadrant gets a quarter of its points.
        let low: Vec<_> = pts.iter().filter(|p| p[2].abs() < 1e-9).collect();
        let q = low.iter().filter(|p| p[0] < 0.5 && p[1] < 0.5).count();
        assert!((q as f64 / low.len() as f64 - 0.25).abs() < 0.015);
    }

    #[test]
    fn seeded() {
        let m = square_and_far_triangle();
        assert_eq!(
            sample_surface(&m, 100, 1).unwrap(),
            sample_surface(&m, 100, 1).unwrap()
        );
        assert_ne!(
            sample_surface(&m, 100, 1).unwrap(),
            sample_surface(&m, 100, 2).unwrap()
        );
        assert_eq!(count_for_spacing(&m, 0.01), 40_000);
    }

    #[test]
    fn empty_mesh_is_an_error() {
        assert!(sample_surface(&Mesh::default(), 10, 0).is_err());
    }
}
