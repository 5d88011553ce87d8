//! One scan of a set, prepared once for every stage of the alignment: its thinned points, a
//! k-d tree over them, its point spacing and a global shape descriptor.

use crate::cloud::{Cloud, Point};
use crate::error::{GgsError, Result};
use crate::refine::neighbors::PointIndex;
use rayon::prelude::*;

/// A scan to align: its name (as the user gave it: a file name, or `scan N`) and its points.
#[derive(Debug, Clone)]
pub struct AlignScan {
    pub name: String,
    pub cloud: Cloud,
}

/// Bins of the distance histogram ([`Prepared::descriptor`]).
pub const DESCRIPTOR_BINS: usize = 32;
/// Points of the sample whose pairwise distances make the descriptor.
const DESCRIPTOR_POINTS: usize = 600;
/// A scan is thinned to one point per cell of this many point spacings before the
/// alignment's ICP runs and overlap counts (density differences between scans then matter
/// less, and a merged model holds each surface once).
pub const THIN_SPACINGS: f64 = 1.5;

/// The alignment's ICP (pose graph edges, joint refinement) runs on scans thinned to at
/// most about this many points.
pub const ICP_POINTS: usize = 4000;

/// A scan prepared for the alignment.
pub struct Prepared {
    /// Median nearest-other-point distance of the full scan.
    pub spacing: f64,
    /// The scan thinned to cells of [`THIN_SPACINGS`] × `spacing`, in its own frame.
    pub thinned: Vec<Point>,
    /// The scan thinned for ICP: one point per cell of `icp_cell`, the smallest of
    /// [`THIN_SPACINGS`] × `spacing` × 2ᵏ that leaves at most [`ICP_POINTS`] points.
    pub icp: Vec<Point>,
    pub icp_cell: f64,
    /// k-d tree over `thinned`.
    pub index: PointIndex,
    /// Longest side of the bounding box.
    pub size: f64,
    /// The least overlap distance this scan asks for: `verify_distance_range` × its median
    /// range when its points look like a scan taken from its origin
    /// ([`scan_median_range`](crate::pipeline::free_space::scan_median_range)), else 0. Far
    /// from a LiDAR's sensor its points lie metres apart, where a multiple of the median
    /// spacing (set by the dense ground near the sensor) would miss them at the right pose;
    /// the verification's distance `D` has the same floor.
    pub scan_distance: f64,
    /// The D2 shape distribution: the histogram of distances between pairs of a strided
    /// sample, over [0, `range`) in [`DESCRIPTOR_BINS`] bins, summing to 1. It does not change
    /// when the scan moves, so scans of the same part of a scene or object have near ones.
    pub descriptor: [f64; DESCRIPTOR_BINS],
}

/// Check the set (at least two scans, none empty, names unique) and prepare every scan; the
/// descriptors share one distance range, the largest bounding-box diagonal of the set.
/// `scan_distance_fraction` is the `verify_distance_range` setting ([`Prepared::scan_distance`]).
pub fn prepare_all(scans: &[AlignScan], scan_distance_fraction: f64) -> Result<Vec<Prepared>> {
    if scans.len() < 2 {
        return Err(GgsError::param(
            "scans",
            format!("alignment needs at least two scans, got {}", scans.len()),
        ));
    }
    for (i, s) in scans.iter().enumerate() {
        s.cloud.ensure_not_empty(&s.name)?;
        if let Some(j) = scans[..i].iter().position(|o| o.name == s.name) {
            return Err(GgsError::param(
                "scans",
                format!(
                    "scans {} and {} are both named {:?}; names must be unique",
                    j + 1,
                    i + 1,
                    s.name
                ),
            ));
        }
    }
    let range = scans
        .iter()
        .filter_map(|s| s.cloud.aabb())
        .map(|b| b.diagonal())
        .fold(0.0, f64::max);
    // Each scan on its own: the same result on any number of threads.
    let prepare = |s: &AlignScan| prepare(&s.cloud, range, scan_distance_fraction);
    Ok(scans.par_iter().map(prepare).collect())
}

fn prepare(cloud: &Cloud, range: f64, scan_distance_fraction: f64) -> Prepared {
    let spacing = crate::spacing::point_spacing(cloud);
    let size = cloud
        .aabb()
        .map(|b| {
            let e = b.extent();
            e[0].max(e[1]).max(e[2])
        })
        .unwrap_or(0.0);
    let cell = THIN_SPACINGS * spacing.max(size * 1e-6).max(f64::MIN_POSITIVE);
    let thinned = crate::thin::cell_centroids(cloud, cell);
    let index = PointIndex::new(&thinned);
    let descriptor = distance_histogram(&thinned, range);
    let (mut icp, mut icp_cell) = (thinned.clone(), cell);
    while icp.len() > ICP_POINTS {
        icp_cell *= 2.0;
        icp = crate::thin::cell_centroids(&thinned, icp_cell);
    }
    let sample = cloud.strided(crate::pipeline::verify::SAMPLE_POINTS);
    let scan_range = crate::pipeline::free_space::scan_median_range(&sample);
    Prepared {
        spacing,
        thinned,
        icp,
        icp_cell,
        index,
        size,
        descriptor,
        scan_distance: scan_range.map_or(0.0, |r| scan_distance_fraction * r),
    }
}

/// The D2 histogram of `points` over [0, `range`) (see [`Prepared::descriptor`]).
fn distance_histogram(points: &[Point], range: f64) -> [f64; DESCRIPTOR_BINS] {
    let step = points.len().div_ceil(DESCRIPTOR_POINTS).max(1);
    let sample: Vec<&Point> = points.iter().step_by(step).collect();
    let mut h = [0.0; DESCRIPTOR_BINS];
    let scale = DESCRIPTOR_BINS as f64 / range.max(f64::MIN_POSITIVE);
    for (i, a) in sample.iter().enumerate() {
        for b in &sample[i + 1..] {
            let d = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            h[((d * scale) as usize).min(DESCRIPTOR_BINS - 1)] += 1.0;
        }
    }
    let total: f64 = h.iter().sum();
    if total > 0.0 {
        h.iter_mut().for_each(|v| *v /= total);
    }
    h
}

/// `½ Σ |a − b|`: the total-variation distance of two descriptors, in [0, 1].
pub fn descriptor_distance(a: &[f64; DESCRIPTOR_BINS], b: &[f64; DESCRIPTOR_BINS]) -> f64 {
    0.5 * a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f64>()
}

/// The scan whose descriptor is nearest to all the others' (least sum of distances; ties
/// by index): the placements start there, so that a scan unlike the set does not.
pub fn medoid(prepared: &[Prepared]) -> usize {
    let total = |i: usize| -> f64 {
        prepared
            .iter()
            .map(|q| descriptor_distance(&prepared[i].descriptor, &q.descriptor))
            .sum()
    };
    (0..prepared.len())
        .map(|i| (total(i), i))
        .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        .map_or(0, |(_, i)| i)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transform::Rigid;

    fn cube_corners(scale: f64) -> Cloud {
        let mut pts = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                pts.push([i as f64 * scale, j as f64 * scale, 0.0]);
                pts.push([i as f64 * scale, 0.0, j as f64 * scale]);
            }
        }
        Cloud::new(pts)
    }

    #[test]
    fn the_descriptor_does_not_see_a_rigid_motion_and_sees_a_scale() {
        let a = cube_corners(0.01);
        let m = Rigid::new(
            *nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0).matrix(),
            nalgebra::Vector3::new(1.0, -2.0, 0.5),
        );
        let scans = [
            AlignScan {
                name: "a".into(),
                cloud: a.clone(),
            },
            AlignScan {
                name: "moved".into(),
                cloud: a.transformed(&m),
            },
            AlignScan {
                name: "bigger".into(),
                cloud: cube_corners(0.02),
            },
        ];
        let p = prepare_all(&scans, 0.15).unwrap();
        let same = descriptor_distance(&p[0].descriptor, &p[1].descriptor);
        let other = descriptor_distance(&p[0].descriptor, &p[2].descriptor);
        // Thinning on axis-aligned cells and the strided sample differ slightly once moved.
        assert!(same < 0.1, "{same}");
        assert!(other > 0.3, "{other}");
    }

    /// A LiDAR-like scan about its origin: ground rings 1–10.5 m out, as many points on each
    /// (dense near the sensor), and a sparser wall 20 m out.
    fn yard() -> Cloud {
        let mut points = Vec::new();
        for k in 0..3600 {
            let (r, a) = (
                1.0 + 0.5 * (k / 180) as f64,
                (k % 180) as f64 * 2f64.to_radians(),
            );
            points.push([r * a.cos(), r * a.sin(), -1.5]);
            if k % 4 == 0 {
                let z = (k % 7) as f64 * 0.5;
                points.push([20.0 * (a + 0.01).cos(), 20.0 * (a + 0.01).sin(), z]);
            }
        }
        Cloud::new(points)
    }

    #[test]
    fn a_scan_from_its_origin_asks_for_an_overlap_distance_at_its_range_scale() {
        let scans = [
            AlignScan {
                name: "yard".into(),
                cloud: yard(),
            },
            AlignScan {
                name: "cube".into(),
                cloud: cube_corners(0.05),
            },
        ];
        let p = prepare_all(&scans, 0.15).unwrap();
        // The median range is about 7 m (on the ground rings), so the distance about 1 m.
        assert!(p[0].scan_distance > 0.15 * 6.0, "{}", p[0].scan_distance);
        let spacings = crate::align::overlap::OVERLAP_SPACINGS * p[0].spacing;
        assert!(p[0].scan_distance > 2.0 * spacings, "{spacings}");
        assert_eq!(
            p[1].scan_distance, 0.0,
            "an object is no scan from its origin"
        );
        let d = crate::align::overlap::overlap_distance(&p, 0, 1);
        assert_eq!(d, p[0].scan_distance);
        assert_eq!(
            crate::align::overlap::overlap_distance(&p, 1, 1),
            crate::align::overlap::OVERLAP_SPACINGS * p[1].spacing
        );
    }

    #[test]
    fn a_set_is_refused_with_what_is_wrong() {
        let one = [AlignScan {
            name: "a".into(),
            cloud: cube_corners(0.01),
        }];
        let e = prepare_all(&one, 0.15).err().unwrap().to_string();
        assert!(e.contains("at least two scans"), "{e}");
        let twice = [one[0].clone(), one[0].clone()];
        let e = prepare_all(&twice, 0.15).err().unwrap().to_string();
        assert!(e.contains("both named \"a\""), "{e}");
        let empty = [
            one[0].clone(),
            AlignScan {
                name: "e.ply".into(),
                cloud: Cloud::new(vec![]),
            },
        ];
        let e = prepare_all(&empty, 0.15).err().unwrap().to_string();
        assert!(e.contains("e.ply"), "{e}");
    }
}
