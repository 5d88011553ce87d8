//! Each scan's ICP points prepared once for every ICP of the alignment (the pose graph's
//! edges and the joint refinement): the points in a frame at the centre of their bounding
//! box, their k-d tree, and every point's local shape (the normal and GICP covariance of its
//! `neighbors` nearest points, [`crate::refine`]).
//!
//! A local shape does not change when its scan is translated, and turns with it
//! (`n' = R·n`, `C' = R·C·Rᵀ`). So an edge's ICP takes both scans' shapes as they are, and the
//! joint refinement's target, the union of a scan's neighbours at their poses, takes each
//! neighbour's shapes turned by its pose: a point's shape always comes from its own scan's
//! surface, and no shape is computed twice.

use super::scan::Prepared;
use crate::cloud::{bounds, Point};
use crate::refine::covariance::LocalShape;
use crate::refine::prepared::PreparedCloud;
use crate::refine::{PreparedPair, RefineConfig};
use crate::transform::Rigid;
use std::sync::{Arc, OnceLock};

/// One scan's ICP points prepared (see the module documentation).
pub struct IcpCloud {
    /// Origin of the frame of `cloud`, in the scan's own frame: the centre of the ICP points'
    /// bounding box.
    pub centre: Point,
    /// The scan's ICP points less `centre`, with their shapes (`shapes`) and their tree
    /// (built when the cloud is first a target).
    pub cloud: Arc<PreparedCloud>,
    /// The local shape of each point, in point order.
    pub shapes: Arc<[LocalShape]>,
}

impl IcpCloud {
    /// Prepare `points` (a scan's ICP points in its own frame) for shapes of `neighbors`
    /// points and GICP's `epsilon`.
    pub fn new(points: &[Point], neighbors: usize, epsilon: f64) -> Self {
        let centre = bounds(points).map_or([0.0; 3], |b| b.centre());
        let local = points
            .iter()
            .map(|p| [0, 1, 2].map(|d| p[d] - centre[d]))
            .collect();
        let computing = PreparedCloud::new(local, neighbors, epsilon);
        let shapes = computing.all_shapes();
        let cloud =
            PreparedCloud::with_shapes(computing.points, shapes.clone(), neighbors, epsilon);
        IcpCloud {
            centre,
            cloud: Arc::new(cloud),
            shapes,
        }
    }

    /// The points in the frame at `frame` (in the scan's own frame), with their shapes: the
    /// source of a pair whose target lies in that frame.
    fn in_frame(&self, frame: Point) -> PreparedCloud {
        let shift = [0, 1, 2].map(|d| self.centre[d] - frame[d]);
        let points = self
            .cloud
            .points
            .iter()
            .map(|p| [0, 1, 2].map(|d| p[d] + shift[d]))
            .collect();
        let (neighbors, epsilon) = (self.cloud.neighbors(), self.cloud.epsilon());
        PreparedCloud::with_shapes(points, self.shapes.clone(), neighbors, epsilon)
    }
}

/// The scans' ICP clouds, each prepared on first use for the refinement's neighbours and ε.
pub struct IcpClouds {
    clouds: Vec<OnceLock<IcpCloud>>,
    neighbors: usize,
    epsilon: f64,
}

impl IcpClouds {
    /// None prepared yet, for `n` scans and the ICP `cfg`.
    pub fn new(n: usize, cfg: &RefineConfig) -> Self {
        IcpClouds {
            clouds: (0..n).map(|_| OnceLock::new()).collect(),
            neighbors: cfg.neighbors,
            epsilon: cfg.epsilon,
        }
    }

    /// Scan `i`'s ICP cloud, prepared from `prepared[i].icp` on first use.
    pub fn get(&self, prepared: &[Prepared], i: usize) -> &IcpCloud {
        self.clouds[i].get_or_init(|| IcpCloud::new(&prepared[i].icp, self.neighbors, self.epsilon))
    }
}

/// The pair for an ICP of `source`'s points onto `target`'s, each given in its scan's own
/// frame: the refinement finds `p_target = T · p_source` in those frames.
pub fn edge_pair(source: &IcpCloud, target: &IcpCloud) -> PreparedPair {
    let moved = source.in_frame(target.centre);
    PreparedPair::from_clouds(target.centre, Arc::new(moved), target.cloud.clone())
}

/// The pair for an ICP of `source`'s points (in its scan's own frame) onto the union of
/// `parts`, each scan's points at its pose in the common frame, with its shapes turned by
/// that pose: the refinement finds the source scan's pose in the common frame.
pub fn union_pair(source: &IcpCloud, parts: &[(&IcpCloud, Rigid)]) -> PreparedPair {
    let mut points = Vec::new();
    let mut shapes = Vec::new();
    for (part, pose) in parts {
        let r = pose.rotation;
        for (p, shape) in part.cloud.points.iter().zip(part.shapes.iter()) {
            points.push(pose.apply(&[0, 1, 2].map(|d| p[d] + part.centre[d])));
            shapes.push(LocalShape {
                normal: r * shape.normal,
                covariance: r * shape.covariance * r.transpose(),
            });
        }
    }
    let centre = bounds(&points).map_or([0.0; 3], |b| b.centre());
    for p in &mut points {
        *p = [0, 1, 2].map(|d| p[d] - centre[d]);
    }
    let (neighbors, epsilon) = (source.cloud.neighbors(), source.cloud.epsilon());
    let target = PreparedCloud::with_shapes(points, shapes.into(), neighbors, epsilon);
    let moved = source.in_frame(centre);
    PreparedPair::from_clouds(centre, Arc::new(moved), Arc::new(target))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::refine::{refine_prepared_pose, CorrespondenceDistance, Method};
    use nalgebra::{Rotation3, Vector3};

    /// A wavy patch 0.5 × 0.5 of 40 × 40 jittered points (no two neighbours at equal
    /// distances), away from the origin.
    fn patch() -> Vec<Point> {
        let mut jitter = crate::test_rng::uniform(7);
        (0..1600)
            .map(|i| {
                let x = ((i % 40) as f64 + 0.3 * jitter()) * 0.0125;
                let y = ((i / 40) as f64 + 0.3 * jitter()) * 0.0125;
                [
                    x + 3.0,
                    y - 2.0,
                    0.05 * (8.0 * x).sin() * (6.0 * y).cos() + 1.0,
                ]
            })
            .collect()
    }

    /// A turn by `deg` about an axis through the patch's centre, then a shift by `t`.
    fn motion(deg: f64, t: [f64; 3]) -> Rigid {
        let axis = nalgebra::Unit::new_normalize(Vector3::new(1.0, -2.0, 0.5));
        let r = *Rotation3::from_axis_angle(&axis, deg.to_radians()).matrix();
        let c = Vector3::new(3.25, -1.75, 1.0);
        Rigid::new(r, c - r * c + Vector3::from(t))
    }

    fn icp_cfg() -> RefineConfig {
        RefineConfig {
            method: Method::Gicp,
            correspondence: CorrespondenceDistance::Fixed(0.05),
            threads: 1,
            ..RefineConfig::default()
        }
    }

    /// The patch's ICP cloud, and that of the patch moved by `m`.
    fn patch_and_moved(m: &Rigid) -> (IcpCloud, IcpCloud) {
        let points = patch();
        let moved: Vec<Point> = points.iter().map(|p| m.apply(p)).collect();
        (
            IcpCloud::new(&points, 20, 1e-3),
            IcpCloud::new(&moved, 20, 1e-3),
        )
    }

    #[test]
    fn a_scans_shapes_turn_with_it() {
        let m = motion(70.0, [0.3, -1.0, 2.0]);
        let (a, b) = patch_and_moved(&m);
        let r = m.rotation;
        for (sa, sb) in a.shapes.iter().zip(b.shapes.iter()) {
            let turned = r * sa.covariance * r.transpose();
            assert!((turned - sb.covariance).abs().max() < 1e-9);
        }
    }

    #[test]
    fn an_edge_finds_the_relative_pose_of_two_scans_in_their_own_frames() {
        // Scan b is scan a seen from another frame: p_b = m · p_a.
        let m = motion(3.0, [0.01, -0.02, 0.015]);
        let (a, b) = patch_and_moved(&m);
        let found = refine_prepared_pose(&edge_pair(&a, &b), &Rigid::identity(), &icp_cfg())
            .unwrap()
            .transform;
        let deg = crate::transform::rotation_angle_deg(&found.rotation, &m.rotation);
        let shift = (found.translation - m.translation).norm();
        assert!(deg < 1e-3 && shift < 1e-5, "{deg}°, {shift}");
    }

    #[test]
    fn a_union_of_posed_scans_places_a_scan_in_the_common_frame() {
        let points = patch();
        let (left, right): (Vec<Point>, Vec<Point>) = points.iter().partition(|p| p[0] < 3.25);
        // The common frame holds the halves at poses q and s; the source is the whole patch
        // in its own frame, whose pose in the common frame is the identity.
        let (q, s) = (
            motion(40.0, [1.0, 0.0, 0.0]),
            motion(-25.0, [0.0, 2.0, 1.0]),
        );
        let own = |pose: &Rigid, half: &[Point]| -> Vec<Point> {
            half.iter().map(|p| pose.inverse().apply(p)).collect()
        };
        let (l, r) = (own(&q, &left), own(&s, &right));
        let (l, r) = (IcpCloud::new(&l, 20, 1e-3), IcpCloud::new(&r, 20, 1e-3));
        let source = IcpCloud::new(&points, 20, 1e-3);
        let pair = union_pair(&source, &[(&l, q), (&r, s)]);
        // The union's first points are the left half's, with the shapes it has where it lies.
        let in_place = IcpCloud::new(&left, 20, 1e-3);
        for (k, shape) in in_place.shapes.iter().enumerate() {
            let turned = pair.target.shape(k).covariance;
            assert!((turned - shape.covariance).abs().max() < 1e-9, "point {k}");
        }
        let start = motion(2.0, [0.01, 0.0, -0.01]);
        let found = refine_prepared_pose(&pair, &start, &icp_cfg())
            .unwrap()
            .transform;
        let deg =
            crate::transform::rotation_angle_deg(&found.rotation, &Rigid::identity().rotation);
        let shift = found.translation.norm();
        assert!(deg < 1e-3 && shift < 1e-5, "{deg}°, {shift}");
    }
}
