//! How much of one scan lies on others: the alignment's measure of overlap.

use super::scan::Prepared;
use crate::transform::Rigid;
use rayon::prelude::*;

/// The overlap distance, in point spacings of the coarser of the two clouds compared: a
/// point is in the overlap when a point of the other cloud lies this close.
pub const OVERLAP_SPACINGS: f64 = 3.0;
/// Points of a scan sampled to measure an overlap that decides a placement or is reported.
pub const OVERLAP_SAMPLE: usize = 4000;

/// Overlap distance of scans `i` and `j`: [`OVERLAP_SPACINGS`] spacings of the coarser, and
/// at least the larger [`Prepared::scan_distance`] of the two.
pub fn overlap_distance(prepared: &[Prepared], i: usize, j: usize) -> f64 {
    let (a, b) = (&prepared[i], &prepared[j]);
    (OVERLAP_SPACINGS * a.spacing.max(b.spacing)).max(a.scan_distance.max(b.scan_distance))
}

/// Share of scan `u`'s thinned points (a strided sample of at most `sample`), moved by
/// `pose`, that lie within the overlap distance ([`overlap_distance`]) of one of the scans
/// `others` moved by `poses`.
pub fn overlap_share(
    prepared: &[Prepared],
    u: usize,
    pose: &Rigid,
    others: &[usize],
    poses: &[Rigid],
    sample: usize,
) -> f64 {
    let pts = &prepared[u].thinned;
    if pts.is_empty() || others.is_empty() {
        return 0.0;
    }
    let to_other: Vec<(&Prepared, Rigid, f64)> = others
        .iter()
        .zip(poses)
        .map(|(&q, pq)| {
            let d = overlap_distance(prepared, u, q);
            (&prepared[q], pq.inverse().compose(pose), d * d)
        })
        .collect();
    let step = pts.len().div_ceil(sample.max(1)).max(1);
    let n = pts.len().div_ceil(step);
    // A count of hits: the same on any number of threads.
    let near: usize = (0..n)
        .into_par_iter()
        .filter(|&k| {
            let p = &pts[k * step];
            to_other
                .iter()
                .any(|(q, m, d2)| q.index.nearest_within(&m.apply(p), *d2).is_some())
        })
        .count();
    near as f64 / n as f64
}
