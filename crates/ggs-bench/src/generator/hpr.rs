//! Hidden point removal (Katz, Tal, Basri 2007).
//!
//! With the camera at the origin (`v = p − camera`), every point is flipped about a sphere of
//! radius R: `v' = v + 2(R − ‖v‖)·v/‖v‖`. A point is visible when its flipped image is a
//! vertex of the convex hull of all flipped points and the camera. R sets how much of a
//! surface's concavity counts as occluding; the FAUST-partial protocol takes R = 1000 × the scan's bounding-box
//! diagonal.

use super::hull::convex_hull;
use ggs::cloud::{bounds, Point};

/// The flip radius of the FAUST-partial protocol: `factor` × the bounding-box diagonal of `points`.
pub fn flip_radius(points: &[Point], factor: f64) -> f64 {
    bounds(points).map_or(0.0, |b| {
        let d = [
            b.max[0] - b.min[0],
            b.max[1] - b.min[1],
            b.max[2] - b.min[2],
        ];
        factor * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    })
}

/// What hidden point removal found.
#[derive(Debug, Clone)]
pub struct Visible {
    /// Indices of the visible points, ascending.
    pub indices: Vec<u32>,
    /// Hull eyes skipped for rounding trouble (see [`super::hull::Hull::skipped`]).
    pub skipped: usize,
}

/// The points of `points` visible from `camera`, with flip radius `radius` (which must
/// exceed every point's distance to the camera). A point at the camera is not visible.
pub fn visible_points(points: &[Point], camera: &Point, radius: f64) -> Result<Visible, String> {
    let mut flipped = Vec::with_capacity(points.len() + 1);
    let mut index = Vec::with_capacity(points.len());
    for (i, p) in points.iter().enumerate() {
        let v = [p[0] - camera[0], p[1] - camera[1], p[2] - camera[2]];
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if n == 0.0 {
            continue;
        }
        if n >= radius {
            return Err(format!(
                "the flip radius {radius} does not exceed the distance {n} of point {i} to the camera"
            ));
        }
        let s = 1.0 + 2.0 * (radius - n) / n;
        flipped.push([v[0] * s, v[1] * s, v[2] * s]);
        index.push(i as u32);
    }
    flipped.push([0.0; 3]);
    let hull = convex_hull(&flipped).map_err(|e| e.to_string())?;
    let camera_slot = (flipped.len() - 1) as u32;
    Ok(Visible {
        indices: hull
            .vertices
            .iter()
            .filter(|&&k| k != camera_slot)
            .map(|&k| index[k as usize])
            .collect(),
        skipped: hull.skipped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ggs::test_rng::uniform;

    fn sphere(n: usize, seed: u64) -> Vec<Point> {
        let mut r = uniform(seed);
        (0..n)
            .map(|_| {
                let z = 2.0 * r() - 1.0;
                let phi = std::f64::consts::TAU * r();
                let s = (1.0 - z * z).sqrt();
                [s * phi.cos(), s * phi.sin(), z]
            })
            .collect()
    }

    #[test]
    fn sphere_from_outside_keeps_the_facing_cap() {
        // From distance d the visible cap of a unit sphere is the points with
        // p·ĉ > 1/d (the tangent cone): here d = 3, so z > 1/3. HPR is approximate: with a
        // large R the flipped surface is so curved that a few points just past the
        // silhouette, or on the far side behind a gap between samples, stick out too.
        let pts = sphere(50_000, 1);
        let cam = [0.0, 0.0, 3.0];
        let vis = visible_points(&pts, &cam, flip_radius(&pts, 1000.0)).unwrap();
        assert_eq!(vis.skipped, 0);
        let visible: std::collections::HashSet<u32> = vis.indices.iter().copied().collect();
        let mut wrong = 0;
        for (i, p) in pts.iter().enumerate() {
            let in_cap = p[2] > 1.0 / 3.0;
            // Points very near the silhouette may go either way.
            if (p[2] - 1.0 / 3.0).abs() > 0.02 && in_cap != visible.contains(&(i as u32)) {
                wrong += 1;
            }
        }
        assert!(wrong <= 250, "{wrong} points misclassified");
        let cap = pts.iter().filter(|p| p[2] > 1.0 / 3.0).count();
        assert!((vis.indices.len() as f64 / cap as f64 - 1.0).abs() < 0.05);
    }

    #[test]
    fn points_behind_an_occluding_plane_are_removed() {
        // A square plate at z = 1 in front of a larger one at z = 0, camera at z = 3 above
        // the centre: the far plate's points in the near plate's shadow are hidden.
        let mut r = uniform(2);
        let mut pts = vec![];
        for _ in 0..4000 {
            pts.push([r() - 0.5, r() - 0.5, 1.0]);
        }
        for _ in 0..8000 {
            pts.push([4.0 * r() - 2.0, 4.0 * r() - 2.0, 0.0]);
        }
        let cam = [0.0, 0.0, 3.0];
        let vis = visible_points(&pts, &cam, flip_radius(&pts, 1000.0)).unwrap();
        let visible: std::collections::HashSet<u32> = vis.indices.iter().copied().collect();
        // The shadow of the near plate on z = 0 is the square |x|, |y| < 0.75.
        let mut hidden_ok = 0;
        let mut shadowed = 0;
        for (i, p) in pts.iter().enumerate().skip(4000) {
            if p[0].abs() < 0.7 && p[1].abs() < 0.7 {
                shadowed += 1;
                if !visible.contains(&(i as u32)) {
                    hidden_ok += 1;
                }
            }
        }
        assert!(
            hidden_ok as f64 >= 0.995 * shadowed as f64,
            "{} of {shadowed} shadowed points seen",
            shadowed - hidden_ok
        );
        // Nearly all of the near plate is seen.
        let near_seen = (0..4000u32).filter(|i| visible.contains(i)).count();
        assert!(near_seen as f64 > 0.97 * 4000.0, "{near_seen}");
        // Most of the far plate outside the shadow is seen too.
        let far_free: Vec<usize> = (4000..pts.len())
            .filter(|&i| pts[i][0].abs() > 0.85 || pts[i][1].abs() > 0.85)
            .collect();
        let seen = far_free
            .iter()
            .filter(|&&i| visible.contains(&(i as u32)))
            .count();
        assert!(
            seen as f64 > 0.9 * far_free.len() as f64,
            "{seen}/{}",
            far_free.len()
        );
    }

    #[test]
    fn too_small_radius_is_an_error() {
        let pts = sphere(100, 3);
        assert!(visible_points(&pts, &[0.0, 0.0, 3.0], 2.0).is_err());
    }
}
