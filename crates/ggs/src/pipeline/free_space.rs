//! Free space: the space a scanner at a cloud's origin saw through.
//!
//! A LiDAR scan is taken from its origin: every point `q` of the scan was seen along the ray
//! from the origin to `q`, so the space on that ray in front of `q` was empty when the scan
//! was taken. A pose that puts points of the other cloud there contradicts the scan. On
//! scenes (streets, buildings, rooms) a wrong pose that lays floor on floor and wall on wall
//! overlaps as much as the right one, and only this tells them apart: a 180° turn about the
//! vertical puts the other scan's walls in the middle of the street this scan saw through.
//!
//! # The range image
//! Directions from the origin are binned by azimuth `atan2(y, x)` and elevation
//! `asin(z / r)` in bins of [`BIN_DEG`] × [`BIN_DEG`]; each bin keeps the smallest range `r`
//! of the cloud's points in it. A point `p` (in the scan's frame, at range `r_p`) **violates**
//! the free space when `r_p < r_near − m`, where `r_near` is the smallest range kept in the
//! 3 × 3 bins around `p`'s (bins holding no point are skipped; none at all: no violation)
//! and `m` the margin, in cloud units. Taking the nearest of the neighbouring bins makes the
//! test err towards no violation: a right pose whose points fall between the scan's rings is
//! not blamed, while a wrong pose puts whole walls metres inside the seen space.
//!
//! # When the origin is the scanner
//! Nothing in most files says where the sensor was. [`origin_is_scanner`] takes a cloud's
//! origin as its scanner when the cloud surrounds it as a panoramic scan does: the origin lies
//! inside the bounding box, the points cover at least [`MIN_AZIMUTH_SHARE`] of the azimuth
//! sectors about the `z` axis, and their median range is at most [`MAX_MEDIAN_RANGE`] of the
//! box's diagonal (a scan reaches far beyond the dense ground near its sensor). An object scan
//! whose file has its origin at the object's centre or outside it (turntable scans, views of a
//! mesh, RGB-D fragments whose origin is one camera among many) fails at least one test, so
//! its verification is unchanged.

use crate::cloud::Point;

/// Angular size of a range-image bin, degrees.
pub const BIN_DEG: f64 = 1.0;
/// Azimuth sectors of [`origin_is_scanner`]'s coverage test, degrees each.
const SECTOR_DEG: f64 = 5.0;
/// Share of the azimuth sectors a panoramic scan's points cover.
pub const MIN_AZIMUTH_SHARE: f64 = 0.75;
/// A panoramic scan's median range, as a share of its bounding box's diagonal, at most.
pub const MAX_MEDIAN_RANGE: f64 = 0.2;
/// Points closer to the origin than this share of the box's diagonal are the scanner's own
/// mount or noise: they neither fill the range image nor are tested.
const NEAR_SHARE: f64 = 1e-3;

const AZIMUTH_BINS: usize = (360.0 / BIN_DEG) as usize;
const ELEVATION_BINS: usize = (180.0 / BIN_DEG) as usize;

/// Distance of `p` from the origin.
#[inline]
fn range(p: &Point) -> f64 {
    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()
}

/// Azimuth `atan2(y, x)` of `p`, degrees in `[0, 360]`.
#[inline]
fn azimuth_deg(p: &Point) -> f64 {
    p[1].atan2(p[0]).to_degrees() + 180.0
}

/// Range `r`, azimuth and elevation bins of `p` (from the origin).
#[inline]
fn direction_bin(p: &Point) -> (f64, usize, usize) {
    let r = range(p);
    let azimuth = azimuth_deg(p);
    let elevation = (p[2] / r).clamp(-1.0, 1.0).asin().to_degrees() + 90.0;
    let a = ((azimuth / BIN_DEG) as usize).min(AZIMUTH_BINS - 1);
    let e = ((elevation / BIN_DEG) as usize).min(ELEVATION_BINS - 1);
    (r, a, e)
}

/// The smallest and the largest coordinate of `points` per axis.
fn bounds(points: &[Point]) -> (Point, Point) {
    let mut min = [f64::INFINITY; 3];
    let mut max = [f64::NEG_INFINITY; 3];
    for p in points {
        for d in 0..3 {
            min[d] = min[d].min(p[d]);
            max[d] = max[d].max(p[d]);
        }
    }
    (min, max)
}

/// The length of the diagonal of the box from `min` to `max`.
fn diagonal(min: Point, max: Point) -> f64 {
    (0..3)
        .map(|d| (max[d] - min[d]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// Whether `points` (in their file's frame) look like a panoramic scan taken from the origin
/// (see the module documentation).
pub fn origin_is_scanner(points: &[Point]) -> bool {
    scan_median_range(points).is_some()
}

/// The median distance of `points` from the origin when they are a scan taken from it
/// ([`origin_is_scanner`]), else `None`.
pub fn scan_median_range(points: &[Point]) -> Option<f64> {
    if points.len() < 100 {
        return None;
    }
    let (min, max) = bounds(points);
    if (0..3).any(|d| !(min[d] < 0.0 && max[d] > 0.0)) {
        return None;
    }
    let diagonal = diagonal(min, max);
    let sectors = (360.0 / SECTOR_DEG) as usize;
    let mut covered = vec![false; sectors];
    for p in points {
        covered[((azimuth_deg(p) / SECTOR_DEG) as usize).min(sectors - 1)] = true;
    }
    let mut ranges: Vec<f64> = points.iter().map(range).collect();
    let share = covered.iter().filter(|&&c| c).count() as f64 / sectors as f64;
    let mid = ranges.len() / 2;
    let median = *ranges.select_nth_unstable_by(mid, f64::total_cmp).1;
    (share >= MIN_AZIMUTH_SHARE && median <= MAX_MEDIAN_RANGE * diagonal).then_some(median)
}

/// The smallest range seen in each direction bin of a scan taken from its origin.
#[derive(Debug, Clone)]
pub struct RangeImage {
    /// Row-major `[elevation][azimuth]`; infinite where no point fell.
    nearest: Vec<f64>,
    /// Ranges below this are not used (see [`NEAR_SHARE`]).
    near: f64,
}

impl RangeImage {
    /// The range image of `points`, a scan taken from the origin.
    pub fn new(points: &[Point]) -> Self {
        let (min, max) = bounds(points);
        let near = NEAR_SHARE * diagonal(min, max);
        let mut nearest = vec![f64::INFINITY; AZIMUTH_BINS * ELEVATION_BINS];
        for p in points {
            let (r, a, e) = direction_bin(p);
            if r > near {
                let cell = &mut nearest[e * AZIMUTH_BINS + a];
                *cell = cell.min(r);
            }
        }
        RangeImage { nearest, near }
    }

    /// Whether `p` (in the scan's frame) lies in the seen free space by more than `margin`.
    pub fn violates(&self, p: &Point, margin: f64) -> bool {
        let (r, a, e) = direction_bin(p);
        if r <= self.near {
            return false;
        }
        let mut nearest = f64::INFINITY;
        for de in [-1i64, 0, 1] {
            let row = e as i64 + de;
            if !(0..ELEVATION_BINS as i64).contains(&row) {
                continue;
            }
            for da in [AZIMUTH_BINS - 1, 0, 1] {
                let col = (a + da) % AZIMUTH_BINS;
                nearest = nearest.min(self.nearest[row as usize * AZIMUTH_BINS + col]);
            }
        }
        nearest.is_finite() && r + margin < nearest
    }
}

/// A simulated panoramic scan from the origin, for tests: rays every 0.5° of azimuth and 1°
/// of elevation from −60° to `top_deg`, as a spinning LiDAR samples, each ending at the range
/// `first_hit` gives for its unit direction (the first surface it meets).
#[cfg(test)]
pub(crate) fn simulated_scan(top_deg: i32, first_hit: impl Fn(&Point) -> f64) -> Vec<Point> {
    let mut pts = Vec::new();
    for i in 0..720 {
        let a = (i as f64 * 0.5).to_radians();
        for e in -60..=top_deg {
            let e = (e as f64).to_radians();
            let d = [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()];
            let t = first_hit(&d);
            pts.push([t * d[0], t * d[1], t * d[2]]);
        }
    }
    pts
}

/// The range along unit direction `d` to the ground `depth` below the origin (infinite for
/// a ray that does not go down).
#[cfg(test)]
pub(crate) fn to_ground(d: &Point, depth: f64) -> f64 {
    if d[2] < 0.0 {
        -depth / d[2]
    } else {
        f64::INFINITY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A panoramic scan of a ground plane 2 m below the scanner and a ring of walls 10 m away.
    fn room() -> Vec<Point> {
        simulated_scan(5, |d| (10.0 / d[0].hypot(d[1])).min(to_ground(d, 2.0)))
    }

    #[test]
    fn a_panoramic_scan_has_its_scanner_at_the_origin() {
        assert!(origin_is_scanner(&room()));
    }

    #[test]
    fn a_cloud_beside_the_origin_or_around_it_tightly_is_no_scan() {
        let shifted: Vec<Point> = room().iter().map(|p| [p[0] + 25.0, p[1], p[2]]).collect();
        assert!(!origin_is_scanner(&shifted));
        // A sphere around the origin: surrounded, but every point at the median range.
        let sphere: Vec<Point> = (0..2000)
            .map(|i| {
                let z = -1.0 + (i as f64 + 0.5) / 1000.0;
                let a = i as f64 * 2.399_963;
                let s = (1.0 - z * z).sqrt();
                [s * a.cos(), s * a.sin(), z]
            })
            .collect();
        assert!(!origin_is_scanner(&sphere));
    }

    #[test]
    fn points_inside_the_seen_space_violate_and_points_on_or_behind_it_do_not() {
        let scan = room();
        let image = RangeImage::new(&scan);
        assert!(image.violates(&[5.0, 0.0, 0.0], 0.5));
        assert!(!image.violates(&[9.8, 0.0, 0.0], 0.5));
        assert!(!image.violates(&[12.0, 0.0, 0.0], 0.5));
        // Straight up nothing was seen: no violation.
        assert!(!image.violates(&[0.0, 0.0, 5.0], 0.5));
        // Every point of the scan is consistent with its own free space.
        assert!(scan.iter().all(|p| !image.violates(p, 0.0)));
    }
}
