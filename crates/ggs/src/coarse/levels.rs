//! The coarse level of a coarse-to-fine search: every rotation ranked at a coarser voxel,
//! and the kept rotations with their grid neighbours.

use super::config::{CoarseToFine, SearchConfig};
use super::correlator::{Backend, PassControl, RotatedSources, Scores, StageTimes};
use super::extents::{geometry_for, rotated_boxes, target_kernel};
use super::register::Prepared;
use super::result::CoarseLevel;
use super::rotated::RotatableCloud;
use crate::cloud::Cloud;
use crate::error::Result;
use crate::rotations::RotationSet;
use crate::thin::cell_centroids;
use crate::transform::rotation_angle_deg;

/// Coarse level: score every rotation approximately at `s0 = factor × voxel` with the
/// source thinned to one point (the mean) per cell of `s0/4`, and rank them (best first, ties
/// to the lowest index).
pub(super) fn coarse_candidates(
    backend: &dyn Backend,
    ctl: &PassControl<'_>,
    prep: &Prepared,
    target: &Cloud,
    set: &RotationSet,
    cfg: &SearchConfig,
    c: &CoarseToFine,
) -> Result<(CoarseLevel, StageTimes)> {
    let s0 = cfg.voxel * c.factor;
    let n = prep.rows.len();
    let thinned = Cloud::new(cell_centroids(&prep.source.points, s0 / 4.0));
    let cloud = RotatableCloud::new(&thinned);
    let all: Vec<usize> = (0..n).collect();
    let boxes = rotated_boxes(ctl.pool, &cloud, &prep.rows, &all, s0)?;
    let kernel = target_kernel(target, prep.target_min, s0)?;
    let geo = geometry_for(kernel.dims, &boxes);
    let corr = backend.plan(geo, &kernel, Scores::Approximate)?;
    let src = RotatedSources {
        cloud: &cloud,
        rows: &prep.rows,
        boxes: &boxes,
        voxel: s0,
    };
    let (found, times) = corr.approx(ctl, &src, &all)?;
    let mut order = all;
    order.sort_by(|&a, &b| found[b].value.total_cmp(&found[a].value).then(a.cmp(&b)));
    let keep = ((n as f64 * c.keep_fraction).ceil() as usize)
        .max(c.keep_min)
        .clamp(1, n);
    let neighbour_deg = c.neighbour_deg.unwrap_or(set.step_deg * 1.01);
    Ok((
        CoarseLevel::new(s0, thinned.len(), geo, keep, neighbour_deg, order),
        times,
    ))
}

/// The `keep` best rotations of the coarse order and every rotation within
/// `neighbour_deg` of one of them, in increasing index order. A keep of a quarter of the set
/// or more takes the whole set.
pub(super) fn kept_with_neighbours(
    level: &CoarseLevel,
    keep: usize,
    set: &RotationSet,
) -> Vec<usize> {
    let n = level.order().len();
    if keep * 4 >= n {
        return (0..n).collect();
    }
    let kept = &level.order()[..keep];
    let mut selected = vec![false; n];
    for &k in kept {
        selected[k] = true;
    }
    for k in 0..n {
        if !selected[k]
            && kept.iter().any(|&j| {
                rotation_angle_deg(&set.matrices[j], &set.matrices[k]) <= level.neighbour_deg
            })
        {
            selected[k] = true;
        }
    }
    (0..n).filter(|&k| selected[k]).collect()
}
