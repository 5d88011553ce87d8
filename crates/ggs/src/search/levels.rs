//! The coarse level of a coarse-to-fine search: every rotation ranked at a coarser voxel,
//! and the kept rotations with their grid neighbours.

use super::config::{CoarseToFine, SearchConfig};
use super::correlator::{ApproxBest, Backend, PassControl, RotatedSources, Scores, PassTimes};
use super::extents::{geometry_for, rotated_boxes, target_kernel, RotatedBox};
use super::prepared::Prepared;
use super::result::{CoarseLevel, LevelHypothesis};
use super::rotated::RotatableCloud;
use crate::cloud::{Cloud, Point};
use crate::error::Result;
use crate::rotations::RotationSet;
use crate::thin::cell_centroids;
use crate::transform::{Rigid, WithinDeg};
use nalgebra::Vector3;

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
) -> Result<(CoarseLevel, PassTimes)> {
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
    let radius = cfg.distinct_radius_deg.unwrap_or(2.0 * set.step_deg);
    // `prep.source` is centred on `c_x` already: the thinned copy's centroid is relative to it.
    let cx = prep.source.centroid;
    let frame = LevelFrame {
        centroid: [0, 1, 2].map(|d| cx[d] + cloud.centroid[d]),
        target_min: prep.target_min,
        center: geo.center,
        voxel: s0,
    };
    let picks = distinct_in_order(&order, c.hypotheses, radius, set);
    let mut level = CoarseLevel::new(s0, thinned.len(), geo, keep, neighbour_deg, order);
    level.hypotheses = picks
        .into_iter()
        .filter_map(|k| Some(frame.hypothesis(set, k, &found[k], boxes[k].as_ref()?)))
        .collect();
    Ok((level, times))
}

/// The first `count` rotations of `order` more than `radius_deg` from every earlier pick.
fn distinct_in_order(
    order: &[usize],
    count: usize,
    radius_deg: f64,
    set: &RotationSet,
) -> Vec<usize> {
    let mut picks: Vec<usize> = Vec::with_capacity(count);
    let within = WithinDeg::new(radius_deg);
    for &k in order {
        if picks.len() >= count {
            break;
        }
        let far = |&j: &usize| !within.holds(&set.matrices[j], &set.matrices[k]);
        if picks.iter().all(far) {
            picks.push(k);
        }
    }
    picks
}

/// What turns an offset of the coarse level into a transform.
struct LevelFrame {
    /// Centroid of the thinned source the level rotated, in the source's frame.
    centroid: Point,
    target_min: Point,
    /// Kernel centre `C` of the level's geometry, cells.
    center: [usize; 3],
    voxel: f64,
}

impl LevelFrame {
    /// `t = −R·c_x − min + (C − a)·s₀ + m_y`, as at the voxel size (docs/method.md).
    fn hypothesis(
        &self,
        set: &RotationSet,
        k: usize,
        best: &ApproxBest,
        bx: &RotatedBox,
    ) -> LevelHypothesis {
        let r = set.matrices[k];
        let mut t = -(r * Vector3::from(self.centroid));
        for d in 0..3 {
            t[d] += -bx.min[d]
                + (self.center[d] as f64 - best.offset[d] as f64) * self.voxel
                + self.target_min[d];
        }
        LevelHypothesis {
            rotation_index: k,
            match_score: best.value,
            error_bound: best.error_bound,
            offset: best.offset,
            transform: Rigid::new(r, t),
        }
    }
}

/// The `keep` best rotations of the coarse order and every rotation within
/// `neighbour_deg` of one of them, in increasing index order. A keep of a quarter of the set
/// or more takes the whole set. The rotations are tested in parallel on `pool` (each on its
/// own), so the list does not depend on the thread count.
pub(super) fn kept_with_neighbours(
    pool: &rayon::ThreadPool,
    level: &CoarseLevel,
    keep: usize,
    set: &RotationSet,
) -> Vec<usize> {
    use rayon::prelude::*;
    let n = level.order().len();
    if keep * 4 >= n {
        return (0..n).collect();
    }
    let kept = &level.order()[..keep];
    let mut is_kept = vec![false; n];
    for &k in kept {
        is_kept[k] = true;
    }
    let within = WithinDeg::new(level.neighbour_deg);
    let selected: Vec<bool> = pool.install(|| {
        (0..n)
            .into_par_iter()
            .map(|k| {
                is_kept[k]
                    || kept
                        .iter()
                        .any(|&j| within.holds(&set.matrices[j], &set.matrices[k]))
            })
            .collect()
    });
    (0..n).filter(|&k| selected[k]).collect()
}
