//! The joint refinement: every placed scan refined by ICP against the others at once.
//!
//! A round refines each placed scan but the anchor, from its current pose, onto the union of
//! its neighbours in the pose graph (the scans it shares an accepted edge with) at their
//! current poses; the new poses replace the old ones together at the end of the round (a
//! Jacobi step, so the order of the scans does not matter and the scans of a round run in
//! parallel with the same result). Pairwise errors that the pose graph averaged are then
//! corrected against all the overlapping surface at once.

use super::graph::{icp_distance, Edge};
use super::icp::{union_pair, IcpClouds};
use super::scan::Prepared;
use crate::error::Result;
use crate::refine::{self, CorrespondenceDistance, RefineConfig};
use crate::transform::Rigid;
use rayon::prelude::*;

/// Rounds of the joint refinement.
pub const JOINT_ROUNDS: usize = 2;

/// The scans sharing an accepted edge with `i`, in index order.
fn neighbours(i: usize, edges: &[Edge]) -> Vec<usize> {
    let mut n: Vec<usize> = edges
        .iter()
        .filter(|e| e.accepted && (e.from == i || e.to == i))
        .map(|e| if e.from == i { e.to } else { e.from })
        .collect();
    n.sort_unstable();
    n.dedup();
    n
}

/// [`JOINT_ROUNDS`] rounds (see the module documentation); returns the new poses.
pub fn refine_jointly(
    prepared: &[Prepared],
    icp: &IcpClouds,
    poses: &[Option<Rigid>],
    edges: &[Edge],
    anchor: usize,
    refine_cfg: &RefineConfig,
) -> Result<Vec<Option<Rigid>>> {
    let mut poses = poses.to_vec();
    for _ in 0..JOINT_ROUNDS {
        let next: Vec<Option<Rigid>> = (0..poses.len())
            .into_par_iter()
            .map(|i| refine_one(prepared, icp, &poses, edges, i, anchor, refine_cfg))
            .collect::<Result<_>>()?;
        poses = next;
    }
    Ok(poses)
}

fn refine_one(
    prepared: &[Prepared],
    icp: &IcpClouds,
    poses: &[Option<Rigid>],
    edges: &[Edge],
    i: usize,
    anchor: usize,
    refine_cfg: &RefineConfig,
) -> Result<Option<Rigid>> {
    let Some(pose) = poses[i] else {
        return Ok(None);
    };
    let others = neighbours(i, edges);
    if i == anchor || others.is_empty() {
        return Ok(Some(pose));
    }
    let mut parts = Vec::with_capacity(others.len());
    let mut d: f64 = 0.0;
    for &j in &others {
        let pj = poses[j].expect("an edge joins placed scans");
        parts.push((icp.get(prepared, j), pj));
        d = d.max(icp_distance(prepared, i, j) / 2.0);
    }
    let cfg = RefineConfig {
        correspondence: CorrespondenceDistance::Fixed(d),
        ..*refine_cfg
    };
    let pair = union_pair(icp.get(prepared, i), &parts);
    Ok(Some(
        refine::refine_prepared_pose(&pair, &pose, &cfg)?.transform,
    ))
}
