//! Camera positions on an icosphere around a scan (docs/generator.md).
//!
//! The scan is put in its *floor frame*: translated so that its bounding-box minimum is the
//! origin, so the plane `up = 0` is the floor. Cameras are icosphere vertices scaled to
//! `radius` around a centre, the ones on or below the floor dropped, and optionally only the
//! first K kept. Camera positions are given in the floor frame, as in the FPv1 names
//! (`viewpoint0-[-0.41 2.43 0.08]`).

use ggs::cloud::{bounds, Point};

/// Unit icosphere vertices in the order of the FAUST-partial generator, so that "the first K
/// above-floor vertices" names the same cameras: the 12 icosahedron vertices
/// `(±1, ±φ, 0), (0, ±1, ±φ), (±φ, 0, ±1)` in the usual order, then, face by face, the
/// midpoints of the edges (v₀v₁), (v₀v₂), (v₁v₂) that are not yet split. As in that
/// generator, a midpoint is taken between the stored vertices (the 12 originals are stored
/// unnormalised, at length √(1+φ²)) and pushed to the unit sphere; every vertex is normalised
/// at the end. 0 → 12, 1 → 42, 2 → 162 vertices.
pub fn fpv1_icosphere(levels: u32) -> Vec<[f64; 3]> {
    let (mut v, mut faces) = ggs::rotations::icosphere::icosahedron();
    for _ in 0..levels {
        let mut split = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(faces.len() * 4);
        for f in &faces {
            let mut m = [0usize; 3];
            for (k, (a, b)) in [(f[0], f[1]), (f[0], f[2]), (f[1], f[2])]
                .into_iter()
                .enumerate()
            {
                m[k] = *split.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let mid = [
                        (v[a][0] + v[b][0]) / 2.0,
                        (v[a][1] + v[b][1]) / 2.0,
                        (v[a][2] + v[b][2]) / 2.0,
                    ];
                    v.push(unit(mid));
                    v.len() - 1
                });
            }
            next.push([f[0], m[0], m[1]]);
            next.push([m[0], f[1], m[2]]);
            next.push([m[1], m[2], f[2]]);
            next.push([m[1], m[0], m[2]]);
        }
        faces = next;
    }
    v.into_iter().map(unit).collect()
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// Where the icosphere is centred.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Centre {
    /// The mean of the scan's points (its centre of mass, for a uniformly sampled surface):
    /// what the paper describes.
    Centroid,
    /// The origin of the scan's own coordinates: what the published FPv1 used.
    Origin,
}

/// How cameras are placed.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewConfig {
    /// Icosphere subdivisions: 0 → 12, 1 → 42, 2 → 162 vertices.
    pub subdivisions: u32,
    /// Icosphere radius, in the scan's units after scaling (1.5 m by default).
    pub radius: f64,
    pub centre: Centre,
    /// The up axis: 0 = x, 1 = y, 2 = z.
    pub up: usize,
    /// Keep only the first K above-floor vertices.
    pub first: Option<usize>,
    /// Explicit camera positions in the floor frame, instead of the icosphere.
    pub cameras: Option<Vec<Point>>,
}

impl Default for ViewConfig {
    /// The published FPv1 layout: the first 12 above-floor vertices of the 42-vertex sphere,
    /// radius 1.5 m, y up, centred on the centroid.
    fn default() -> Self {
        ViewConfig {
            subdivisions: 1,
            radius: 1.5,
            centre: Centre::Centroid,
            up: 1,
            first: Some(12),
            cameras: None,
        }
    }
}

/// The offset from scan coordinates to the floor frame: `p_floor = p + offset` (minus the
/// bounding-box minimum).
pub fn floor_offset(points: &[Point]) -> Point {
    let b = bounds(points).map(|b| b.min).unwrap_or([0.0; 3]);
    [-b[0], -b[1], -b[2]]
}

/// Camera positions in the floor frame of `points`.
pub fn cameras(points: &[Point], cfg: &ViewConfig) -> Vec<Point> {
    if let Some(c) = &cfg.cameras {
        return c.clone();
    }
    let off = floor_offset(points);
    let centre = match cfg.centre {
        Centre::Origin => off,
        Centre::Centroid => {
            let n = points.len().max(1) as f64;
            let s = points
                .iter()
                .fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]]);
            [s[0] / n + off[0], s[1] / n + off[1], s[2] / n + off[2]]
        }
    };
    let mut out: Vec<Point> = fpv1_icosphere(cfg.subdivisions)
        .into_iter()
        .map(|u| {
            [
                centre[0] + cfg.radius * u[0],
                centre[1] + cfg.radius * u[1],
                centre[2] + cfg.radius * u[2],
            ]
        })
        .filter(|c| c[cfg.up] > 0.0)
        .collect();
    if let Some(k) = cfg.first {
        out.truncate(k);
    }
    out
}

/// Parse an FPv1 viewpoint name `viewpoint<k>-[x y z]` into its index and camera position.
pub fn parse_fpv1_viewpoint(name: &str) -> Option<(u32, Point)> {
    let rest = name.trim().strip_prefix("viewpoint")?;
    let (k, pos) = rest.split_once('-')?;
    let inner = pos.trim().strip_prefix('[')?.strip_suffix(']')?;
    let nums: Vec<f64> = inner
        .split_whitespace()
        .map(|t| t.parse().ok())
        .collect::<Option<_>>()?;
    if nums.len() != 3 || nums.iter().any(|x: &f64| !x.is_finite()) {
        return None;
    }
    Some((k.parse().ok()?, [nums[0], nums[1], nums[2]]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_unit_length() {
        assert_eq!(fpv1_icosphere(0).len(), 12);
        assert_eq!(fpv1_icosphere(1).len(), 42);
        assert_eq!(fpv1_icosphere(2).len(), 162);
        for v in fpv1_icosphere(2) {
            assert!(((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn parses_published_names() {
        let (k, p) =
            parse_fpv1_viewpoint("viewpoint4-[ 0.37363312  0.36927494 -1.19770686]").unwrap();
        assert_eq!(k, 4);
        assert_eq!(p, [0.37363312, 0.36927494, -1.19770686]);
        assert_eq!(
            parse_fpv1_viewpoint("viewpoint11-[-0.08989238  2.3713971   0.82826935]")
                .unwrap()
                .0,
            11
        );
        assert!(parse_fpv1_viewpoint("viewpoint4-[0.3 0.3]").is_none());
        assert!(parse_fpv1_viewpoint("view4-[0.3 0.3 0.3]").is_none());
        assert!(parse_fpv1_viewpoint("viewpoint4-[0.3 nan 0.3]").is_none());
    }

    #[test]
    fn floor_filter_and_first_k() {
        // A 1.8 m tall column: centroid 0.9 m above the floor, so the sphere's lowest
        // vertices (y = −1.28·… below the centre) fall under the floor.
        let pts: Vec<Point> = (0..=180).map(|i| [0.0, i as f64 / 100.0, 0.0]).collect();
        let cfg = ViewConfig {
            first: None,
            ..ViewConfig::default()
        };
        let all = cameras(&pts, &cfg);
        assert!(all.len() < 42 && all.iter().all(|c| c[1] > 0.0));
        let first = cameras(&pts, &ViewConfig::default());
        assert_eq!(first.len(), 12);
        assert_eq!(&all[..12], &first[..]);
    }
}
