//! Scene crops: the views of the scene presets (`scene-e/m/h`, docs/generator.md).
//!
//! A room fragment or a LiDAR scan has no outside to put cameras on, so a scene's "views" are
//! crops of its points: view k holds the points within the crop radius `r` of a centre `c_k`,
//! `I_k = { i : ‖p_i − c_k‖ ≤ r }`. The overlap of two views is then measured exactly as for
//! the mesh views, `|I_i ∩ I_j| / |I_i| × 100`, and the preset's band keeps the pairs.
//!
//! The centres spread over the scene, not over its point density (a LiDAR scan is densest at
//! its sensor): the scene is cut into cubic cells of `r / 2`, and `c_k` is the first point (in
//! file order) of a cell drawn uniformly among the occupied ones, without repetition, from the
//! stream keyed by (seed, scene name). `r` is `share ×` the diagonal of the box holding the
//! middle 96 % of the coordinates on each axis, unless the scene has its own radius.

use ggs::cloud::Point;
use ggs::rng::Rng;
use std::collections::BTreeMap;

/// A crop keeps at least this many points, else its centre is skipped.
pub const MIN_CROP_POINTS: usize = 1000;

/// How the crops of one scene are cut.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CropConfig {
    /// Crop radius as a share of the scene's extent ([`robust_diagonal`]).
    pub share: f64,
    /// Number of crop centres drawn.
    pub count: usize,
}

impl Default for CropConfig {
    fn default() -> Self {
        CropConfig {
            share: 0.4,
            count: 12,
        }
    }
}

/// The crop radius of a scene: `own` when given, else `share × the scene's extent`
/// ([`robust_diagonal`]); `None` when that is not a positive number (every point the same).
pub fn crop_radius(points: &[Point], own: Option<f64>, cfg: &CropConfig) -> Option<f64> {
    let r = own.unwrap_or_else(|| robust_diagonal(points) * cfg.share);
    (r.is_finite() && r > 0.0).then_some(r)
}

/// The diagonal of the box that holds the middle 96 % of the coordinates on each axis (from
/// the 2nd to the 98th percentile), so that a LiDAR scan's few far returns do not set the
/// size of its crops.
pub fn robust_diagonal(points: &[Point]) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let (lo, hi) = (points.len() / 50, points.len() - 1 - points.len() / 50);
    let mut sq = 0.0;
    for axis in 0..3 {
        let mut c: Vec<f64> = points.iter().map(|p| p[axis]).collect();
        c.sort_unstable_by(f64::total_cmp);
        sq += (c[hi] - c[lo]).powi(2);
    }
    sq.sqrt()
}

/// Up to `count` crop centres: first points of distinct occupied cells of size `cell`, drawn
/// uniformly from `rng`.
pub fn crop_centres(points: &[Point], cell: f64, count: usize, rng: &mut Rng) -> Vec<Point> {
    let mut first: BTreeMap<[i64; 3], usize> = BTreeMap::new();
    for (i, p) in points.iter().enumerate() {
        let key = p.map(|c| (c / cell).floor() as i64);
        first.entry(key).or_insert(i);
    }
    let mut cells: Vec<usize> = first.into_values().collect();
    let mut centres = Vec::with_capacity(count.min(cells.len()));
    // A partial Fisher–Yates shuffle: the first `count` slots are a uniform draw without
    // repetition.
    for k in 0..count.min(cells.len()) {
        let pick = k + rng.below((cells.len() - k) as u64) as usize;
        cells.swap(k, pick);
        centres.push(points[cells[k]]);
    }
    centres
}

/// Ascending indices of the points within `radius` of `centre`.
pub fn ball_crop(points: &[Point], centre: &Point, radius: f64) -> Vec<u32> {
    let r2 = radius * radius;
    (0..points.len() as u32)
        .filter(|&i| {
            let p = &points[i as usize];
            let d = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
            d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= r2
        })
        .collect()
}

/// The crops of one scene: the centres of the kept crops and their point indices.
#[derive(Debug, Clone, PartialEq)]
pub struct Crops {
    pub centres: Vec<Point>,
    /// The index of each kept crop's centre in the draw.
    pub ids: Vec<u32>,
    /// Ascending point indices of each kept crop.
    pub indices: Vec<Vec<u32>>,
}

/// `cfg.count` crops of `radius` around centres drawn from `rng` (see the module docs); crops
/// under [`MIN_CROP_POINTS`] are left out and keep no id.
pub fn scene_crops(points: &[Point], radius: f64, cfg: &CropConfig, rng: &mut Rng) -> Crops {
    let drawn = crop_centres(points, radius / 2.0, cfg.count, rng);
    let mut crops = Crops {
        centres: Vec::new(),
        ids: Vec::new(),
        indices: Vec::new(),
    };
    for (k, c) in drawn.iter().enumerate() {
        let crop = ball_crop(points, c, radius);
        if crop.len() >= MIN_CROP_POINTS {
            crops.centres.push(*c);
            crops.ids.push(k as u32);
            crops.indices.push(crop);
        }
    }
    crops
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat 40 × 40 grid of points, spacing 0.1, at z = 0.
    fn floor() -> Vec<Point> {
        (0..40_000)
            .map(|i| [(i % 200) as f64 * 0.02, (i / 200) as f64 * 0.02, 0.0])
            .collect()
    }

    #[test]
    fn a_crop_is_every_point_within_the_radius_in_order() {
        let pts = floor();
        let c = [2.0, 2.0, 0.0];
        let crop = ball_crop(&pts, &c, 0.5);
        assert!(crop.windows(2).all(|w| w[0] < w[1]));
        let brute = pts
            .iter()
            .filter(|p| (p[0] - 2.0).hypot(p[1] - 2.0) <= 0.5)
            .count();
        assert_eq!(crop.len(), brute);
        // π·0.5² / 0.02² ≈ 1963 points.
        assert!(crop.len() > 1900 && crop.len() < 2030, "{}", crop.len());
    }

    #[test]
    fn centres_are_distinct_cells_and_follow_the_seed() {
        let pts = floor();
        let draw = |seed| crop_centres(&pts, 0.5, 12, &mut Rng::new(seed));
        let a = draw(1);
        assert_eq!(a.len(), 12);
        let cells: std::collections::HashSet<[i64; 2]> = a
            .iter()
            .map(|p| [(p[0] / 0.5).floor() as i64, (p[1] / 0.5).floor() as i64])
            .collect();
        assert_eq!(cells.len(), 12, "one centre per cell");
        assert_eq!(a, draw(1));
        assert_ne!(a, draw(2));
        // More centres asked for than cells (4 m / 0.5 m = 8 per axis): every cell once.
        assert_eq!(crop_centres(&pts, 0.5, 1000, &mut Rng::new(3)).len(), 64);
    }

    #[test]
    fn small_crops_are_left_out_and_keep_no_id() {
        let pts = floor();
        let cfg = CropConfig::default();
        assert!(scene_crops(&pts, 0.1, &cfg, &mut Rng::new(0))
            .indices
            .is_empty());
        let r = crop_radius(&pts, None, &cfg).unwrap();
        // The 800th and 39 199th of the sorted x (and y): 0.08 and 3.9.
        let side: f64 = 3.9 - 0.08;
        assert!((r - 0.4 * side.hypot(side)).abs() < 1e-9, "{r}");
        let c = scene_crops(&pts, r, &cfg, &mut Rng::new(0));
        assert_eq!(c.ids, (0..12).collect::<Vec<u32>>());
        assert!(c.indices.iter().all(|i| i.len() >= MIN_CROP_POINTS));
        assert_eq!(crop_radius(&pts[..1], None, &cfg), None);
        assert_eq!(crop_radius(&pts, Some(2.0), &cfg), Some(2.0));
        // A far return does not stretch the crops.
        let mut far = pts.clone();
        far.push([1000.0, 1000.0, 1000.0]);
        let (d, d_far) = (robust_diagonal(&pts), robust_diagonal(&far));
        assert!((d_far - d).abs() < 0.01 * d, "{d} → {d_far}");
    }
}
