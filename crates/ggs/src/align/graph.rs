//! The pose graph: an edge for every pair of placed scans that overlap, measured by ICP
//! between the two scans, checked against the placements, and one optimization of all poses
//! over the accepted edges.
//!
//! Edge `(i, j)` measures `Z_ij ≈ P_i⁻¹ · P_j` (scan `j` in scan `i`'s frame) by GICP of `j`'s
//! thinned points onto `i`'s, started from the placements' `P_i⁻¹ · P_j`. The placements
//! went through other scans (the models `i` and `j` were registered onto), so an edge whose
//! ICP moves away from that start by more than [`EDGE_MAX_DEG`] or [`EDGE_MAX_SHIFT`]
//! overlap distances closes a cycle that does not close: it is rejected, as is an edge whose
//! overlap after ICP is under [`EDGE_MIN_OVERLAP`]. The accepted edges then enter
//!
//! `min Σ_edges ρ(‖log(Z_ij⁻¹ · P_i⁻¹ · P_j)‖²_Σ) + Σ_scans ‖log(P̂_i⁻¹ · P_i)‖²_Σ₀`
//!
//! over the poses `P_i` of SE(3), with the anchor held by a tight prior and every other scan
//! by a loose prior at its placement `P̂_i` (which keeps the problem well posed and changes the
//! result by about `Σ/Σ₀ = 10⁻⁴` of an edge's pull), `ρ` Huber's kernel, solved by
//! Levenberg-Marquardt in fact.rs (factrs: factor graphs on Lie groups, sparse Cholesky by
//! faer, single-threaded, so the result does not depend on the thread count).

use super::icp::{edge_pair, IcpClouds};
use super::overlap::{overlap_distance, overlap_share, OVERLAP_SAMPLE};
use super::scan::Prepared;
use crate::error::Result;
use crate::refine::{self, CorrespondenceDistance, RefineConfig};
use crate::transform::Rigid;
use factrs::assign_symbols;
use factrs::core::{BetweenResidual, Graph, Huber, LevenMarquardt, PriorResidual, Values, SE3};
use factrs::noise::GaussianNoise;
use factrs::traits::Optimizer;
use factrs::variables::MatrixLieGroup;
use nalgebra::{Matrix4, Vector3};
use rayon::prelude::*;
use serde::Serialize;

assign_symbols!(X: SE3);

/// Scans whose overlap (sampled, before ICP) is under this share get no edge.
pub const EDGE_MIN_OVERLAP: f64 = 0.1;
/// Each scan keeps the edges of its this many largest overlaps (an edge kept by either end
/// is measured), so the graph has at most `EDGE_NEIGHBOURS · N` edges.
pub const EDGE_NEIGHBOURS: usize = 5;
/// Points sampled for the overlap test of a candidate edge.
const EDGE_SAMPLE: usize = 600;
/// An edge's ICP may turn the placements' relative pose by at most this many degrees.
pub const EDGE_MAX_DEG: f64 = 2.0;
/// … and move it by at most this many overlap distances.
pub const EDGE_MAX_SHIFT: f64 = 2.0;
/// An edge contradicts a placement when its scans overlap by at least this share after ICP
/// and ICP turns their relative pose by at least [`CONTRADICTION_DEG`]: scans that share
/// this much pin their relative rotation, so from right placements ICP turns it by a
/// fraction of a degree. One of the two is then probably placed wrong (a near-symmetric
/// object fits turned, and the scans placed onto it follow it). Measured on the bunny sets
/// and 13 human-view sets: edges of 30 % or more between rightly placed scans turn by 0.57°
/// at most; those between a turned scan and a right one by 0.9–3.9°.
pub const CONTRADICTION_OVERLAP: f64 = 0.3;
/// See [`CONTRADICTION_OVERLAP`]; degrees.
pub const CONTRADICTION_DEG: f64 = 1.0;
/// Standard deviation of an edge's rotation (radians) in the optimization; the translation's
/// is the pair's overlap distance.
const EDGE_SIGMA_ROTATION: f64 = 0.005;
/// A placement prior is this many times looser than an edge.
const PRIOR_LOOSENESS: f64 = 100.0;

/// One edge of the pose graph.
#[derive(Debug, Clone, Serialize)]
pub struct Edge {
    /// Scan `i` of `Z_ij`.
    pub from: usize,
    /// Scan `j` of `Z_ij`.
    pub to: usize,
    /// `Z_ij`: `p_i = Z_ij · p_j`.
    #[serde(serialize_with = "crate::transform::serialize_rows")]
    pub relative: Rigid,
    /// Share of scan `j`'s points within the overlap distance of scan `i` after ICP.
    pub overlap: f64,
    /// How far ICP moved the placements' relative pose, degrees and cloud units.
    pub moved_deg: f64,
    pub moved_distance: f64,
    pub accepted: bool,
    pub reason: Option<String>,
}

/// The correspondence distance of the alignment's ICP between scans `i` and `j`: twice
/// their overlap distance, and at least their ICP cells.
pub fn icp_distance(prepared: &[Prepared], i: usize, j: usize) -> f64 {
    (2.0 * overlap_distance(prepared, i, j))
        .max(prepared[i].icp_cell)
        .max(prepared[j].icp_cell)
}

/// Measure an edge for every pair of placed scans that overlap (see the module
/// documentation), in pair order.
pub fn measure_edges(
    prepared: &[Prepared],
    icp: &IcpClouds,
    poses: &[Option<Rigid>],
    refine_cfg: &RefineConfig,
) -> Result<Vec<Edge>> {
    let placed: Vec<usize> = (0..poses.len()).filter(|&i| poses[i].is_some()).collect();
    let pairs: Vec<(usize, usize)> = placed
        .iter()
        .enumerate()
        .flat_map(|(a, &i)| placed[a + 1..].iter().map(move |&j| (i, j)))
        .collect();
    let candidates: Vec<(usize, usize, f64)> = pairs
        .par_iter()
        .map(|&(i, j)| {
            let (pi, pj) = (poses[i].unwrap(), poses[j].unwrap());
            let share = overlap_share(prepared, j, &pj, &[i], &[pi], EDGE_SAMPLE)
                .max(overlap_share(prepared, i, &pi, &[j], &[pj], EDGE_SAMPLE));
            (i, j, share)
        })
        .filter(|c| c.2 >= EDGE_MIN_OVERLAP)
        .collect();
    let pairs = strongest_per_scan(&candidates, poses.len());
    pairs
        .par_iter()
        .map(|&(i, j)| measure_edge(prepared, icp, poses, i, j, refine_cfg))
        .collect()
}

/// The candidate pairs `(i, j, overlap)` that are among the [`EDGE_NEIGHBOURS`] largest
/// overlaps of `i` or of `j` (ties by index), in pair order.
fn strongest_per_scan(candidates: &[(usize, usize, f64)], n: usize) -> Vec<(usize, usize)> {
    let mut keep = vec![false; candidates.len()];
    for scan in 0..n {
        let mut mine: Vec<usize> = (0..candidates.len())
            .filter(|&c| candidates[c].0 == scan || candidates[c].1 == scan)
            .collect();
        mine.sort_by(|&a, &b| candidates[b].2.total_cmp(&candidates[a].2).then(a.cmp(&b)));
        for &c in mine.iter().take(EDGE_NEIGHBOURS) {
            keep[c] = true;
        }
    }
    (0..candidates.len())
        .filter(|&c| keep[c])
        .map(|c| (candidates[c].0, candidates[c].1))
        .collect()
}

impl Edge {
    /// Whether the edge contradicts the placements of its scans ([`CONTRADICTION_OVERLAP`]),
    /// accepted or not.
    pub fn contradicts(&self) -> bool {
        self.overlap >= CONTRADICTION_OVERLAP && self.moved_deg >= CONTRADICTION_DEG
    }
}

fn measure_edge(
    prepared: &[Prepared],
    icp: &IcpClouds,
    poses: &[Option<Rigid>],
    i: usize,
    j: usize,
    refine_cfg: &RefineConfig,
) -> Result<Edge> {
    let (pi, pj) = (poses[i].unwrap(), poses[j].unwrap());
    let start = pi.inverse().compose(&pj);
    let d = overlap_distance(prepared, i, j);
    let cfg = RefineConfig {
        correspondence: CorrespondenceDistance::Fixed(icp_distance(prepared, i, j)),
        ..*refine_cfg
    };
    let pair = edge_pair(icp.get(prepared, j), icp.get(prepared, i));
    let z = refine::refine_prepared_pose(&pair, &start, &cfg)?.transform;
    let overlap = overlap_share(prepared, j, &z, &[i], &[Rigid::identity()], OVERLAP_SAMPLE);
    let moved_deg = crate::transform::rotation_angle_deg(&z.rotation, &start.rotation);
    let moved_distance = (z.translation - start.translation).norm();
    let reason = if overlap < EDGE_MIN_OVERLAP {
        Some(format!("{:.0} % overlap after ICP", overlap * 100.0))
    } else if moved_deg > EDGE_MAX_DEG || moved_distance > EDGE_MAX_SHIFT * d {
        Some(format!(
            "ICP moved the placements' relative pose by {moved_deg:.2}° and {moved_distance:.3}: the cycle does not close"
        ))
    } else {
        None
    };
    Ok(Edge {
        from: i,
        to: j,
        relative: z,
        overlap,
        moved_deg,
        moved_distance,
        accepted: reason.is_none(),
        reason,
    })
}

fn to_se3(t: &Rigid) -> SE3 {
    SE3::from_matrix(t.to_matrix4().as_view())
}

fn from_se3(x: &SE3) -> Rigid {
    let m: Matrix4<f64> = x.to_matrix();
    Rigid::new(
        m.fixed_view::<3, 3>(0, 0).into_owned(),
        Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
    )
}

/// The poses that best agree with the accepted edges (see the module documentation); scans
/// that are not placed stay unplaced. `None` where the optimization failed.
pub fn optimize_poses(
    prepared: &[Prepared],
    poses: &[Option<Rigid>],
    edges: &[Edge],
    anchor: usize,
) -> Option<Vec<Option<Rigid>>> {
    let mut graph = Graph::new();
    let mut values = Values::new();
    for (i, pose) in poses.iter().enumerate() {
        let Some(pose) = pose else { continue };
        values.insert(X(i as u32), to_se3(pose));
        let d = overlap_distance(prepared, i, i).max(f64::MIN_POSITIVE);
        let (sr, st) = if i == anchor {
            (1e-6, 1e-6 * d)
        } else {
            (EDGE_SIGMA_ROTATION * PRIOR_LOOSENESS, d * PRIOR_LOOSENESS)
        };
        let factor =
            factrs::containers::FactorBuilder::new1(PriorResidual::new(to_se3(pose)), X(i as u32))
                .noise(GaussianNoise::<6>::from_split_sigma(sr, st))
                .build();
        graph.add_factor(factor);
    }
    for e in edges.iter().filter(|e| e.accepted) {
        let d = overlap_distance(prepared, e.from, e.to);
        let factor = factrs::containers::FactorBuilder::new2(
            BetweenResidual::new(to_se3(&e.relative)),
            X(e.from as u32),
            X(e.to as u32),
        )
        .noise(GaussianNoise::<6>::from_split_sigma(EDGE_SIGMA_ROTATION, d))
        .robust(Huber::default())
        .build();
        graph.add_factor(factor);
    }
    // fact.rs panics where a factorization fails; with a prior on every pose the system is
    // positive definite, so that would be a defect: the placements are then kept and the
    // caller says so.
    let solved = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let mut opt: LevenMarquardt = LevenMarquardt::new_default(graph);
        match opt.optimize(values) {
            Ok(v) | Err(factrs::optimizers::OptError::MaxIterations(v)) => Some(v),
            Err(_) => None,
        }
    }));
    let Ok(Some(solved)) = solved else {
        return None;
    };
    let mut out: Vec<Option<Rigid>> = (0..poses.len())
        .map(|i| poses[i].and_then(|_| solved.get::<_, SE3>(X(i as u32)).map(from_se3)))
        .collect();
    // The anchor's tight prior holds it to about 1e-13; it is the frame, so exactly.
    out[anchor] = poses[anchor];
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::align::scan::{prepare_all, AlignScan};
    use nalgebra::Rotation3;

    fn motion(rx: f64, ry: f64, rz: f64, t: [f64; 3]) -> Rigid {
        let r = *Rotation3::from_euler_angles(rx, ry, rz).matrix();
        Rigid::new(r, Vector3::new(t[0], t[1], t[2]))
    }

    /// Three small scans (their points only set the spacing the noise models use).
    fn prepared() -> Vec<Prepared> {
        let cloud = |k: f64| {
            let pts = (0..200)
                .map(|i| [i as f64 * 0.01, k * 0.01, (i % 7) as f64 * 0.01])
                .collect();
            crate::cloud::Cloud::new(pts)
        };
        let scans: Vec<AlignScan> = (0..3)
            .map(|k| AlignScan {
                name: format!("s{k}"),
                cloud: cloud(k as f64),
            })
            .collect();
        prepare_all(&scans, 0.15).unwrap()
    }

    fn edge(from: usize, to: usize, relative: Rigid, accepted: bool) -> Edge {
        Edge {
            from,
            to,
            relative,
            overlap: 0.5,
            moved_deg: 0.0,
            moved_distance: 0.0,
            accepted,
            reason: None,
        }
    }

    #[test]
    fn each_scan_keeps_its_strongest_edges() {
        let mut candidates = Vec::new();
        for j in 1..=8 {
            candidates.push((0, j, j as f64 / 10.0));
        }
        let kept = strongest_per_scan(&candidates, 9);
        // Every scan 1..=8 has one edge only, so each keeps it.
        assert_eq!(kept.len(), 8);
        let mut two = candidates.clone();
        two.push((1, 2, 0.05));
        assert!(strongest_per_scan(&two, 9).contains(&(1, 2)));
    }

    #[test]
    fn the_optimized_poses_agree_with_the_accepted_edges_and_ignore_the_rejected() {
        let p = prepared();
        let truth = [
            Rigid::identity(),
            motion(0.1, 0.2, -0.3, [0.1, 0.0, 0.02]),
            motion(-0.2, 0.1, 0.4, [0.0, 0.05, 0.1]),
        ];
        let rel = |i: usize, j: usize| truth[i].inverse().compose(&truth[j]);
        // Scan 2's placement is off by 1°; the edges say where it is.
        let placed = [
            Some(truth[0]),
            Some(truth[1]),
            Some(motion(0.0, 0.0, 0.0175, [0.0; 3]).compose(&truth[2])),
        ];
        let wrong = motion(1.0, 0.0, 0.0, [0.3, 0.0, 0.0]);
        let edges = [
            edge(0, 1, rel(0, 1), true),
            edge(0, 2, rel(0, 2), true),
            edge(1, 2, rel(1, 2), true),
            edge(1, 2, wrong, false),
        ];
        let out = optimize_poses(&p, &placed, &edges, 0).unwrap();
        for (o, t) in out.iter().zip(&truth) {
            let o = o.unwrap();
            assert!(crate::transform::rotation_angle_deg(&o.rotation, &t.rotation) < 0.01);
            assert!((o.translation - t.translation).norm() < 1e-4);
        }
        assert_eq!(out[0].unwrap(), placed[0].unwrap(), "the anchor stays");
        let unplaced =
            optimize_poses(&p, &[Some(truth[0]), None, Some(truth[2])], &edges[1..2], 0).unwrap();
        assert!(unplaced[1].is_none());
    }
}
