//! The seam between the search and the hardware: a [`Backend`] plans a [`Correlator`] for
//! one target kernel and FFT geometry, and the correlator scores batches of rotated sources.
//!
//! The search (`grid_search_with`) only talks to these two traits: which rotations to
//! score, at which voxel, exactly or approximately. A GPU backend implements them without
//! touching the search; the CPU backend is [`CpuBackend`](super::passes::CpuBackend) (`passes.rs`).
//!
//! The contract a backend must keep, which the search's exactness rests on:
//! - [`Correlator::exact`] returns, for each rotation, the largest match score over all
//!   offsets as the exact integer it is, and the lowest offset in x-major C order that
//!   reaches it (docs/method.md, "Exact integers");
//! - [`Correlator::approx`] returns a value and a bound with
//!   `|exact best − value| ≤ error_bound` (docs/method.md, "Reduced precision");
//! - results come back in the order of the indices asked for, and do not depend on how
//!   the work was spread over threads or devices.

use super::extents::RotatedBox;
use super::geometry::Geometry;
use super::rotated::RotatableCloud;
use super::voxel::Occupancy;
use crate::error::Result;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

/// Best offset of one rotation: its match score `m` and the offset `a` (cells).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BestOffset {
    pub match_score: i64,
    pub offset: [usize; 3],
}

/// At most this many candidate offsets are kept per approximate best (on the bunny pair's
/// voxel-size level: 2 in the median, 18 at most; on the generated human pair 99 of the 395
/// rotations there have more than 24, 77 of them at most 64).
pub const MAX_CANDIDATES: usize = 64;

/// The offsets `a` whose computed output reaches `value − 2·error_bound`, in x-major C
/// order, or none when there were more than [`MAX_CANDIDATES`]. Every offset where the exact
/// best is reached is among them: with `M = max m`, `a*` the offset of `value` and `a'` one
/// where `m(a') = M`, `computed(a') ≥ m(a') − bound ≥ m(a*) − bound ≥ value − 2·bound`.
/// So the exact best is settled by computing `m` at these offsets alone
/// ([`Correlator::exact_among`]).
///
/// Stored compactly (every rotation of a pass carries one): the first offset, then each
/// offset as its difference from the first in `i8` per axis (none kept when one does not
/// fit: the candidates near a best lie within a few cells of each other).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Candidates {
    /// Offsets kept; `u8::MAX`: too many, none kept.
    len: u8,
    first: [u16; 3],
    delta: [[i8; 3]; MAX_CANDIDATES],
}

impl Candidates {
    /// No candidates kept: an exact re-scoring correlates again.
    pub const NONE: Candidates = Candidates {
        len: u8::MAX,
        first: [0; 3],
        delta: [[0; 3]; MAX_CANDIDATES],
    };

    /// `offsets` (x-major C order) when they are few enough, fit 16 bits and lie within
    /// 127 cells of the first on every axis, else [`Candidates::NONE`].
    pub fn of(offsets: impl IntoIterator<Item = [usize; 3]>) -> Candidates {
        let mut c = Candidates {
            len: 0,
            ..Candidates::NONE
        };
        for a in offsets {
            if c.len as usize == MAX_CANDIDATES {
                return Candidates::NONE;
            }
            if c.len == 0 {
                let (Ok(x), Ok(y), Ok(z)) = (a[0].try_into(), a[1].try_into(), a[2].try_into())
                else {
                    return Candidates::NONE;
                };
                c.first = [x, y, z];
            }
            let d = [0, 1, 2].map(|i| i8::try_from(a[i] as i64 - i64::from(c.first[i])));
            let [Ok(dx), Ok(dy), Ok(dz)] = d else {
                return Candidates::NONE;
            };
            c.delta[c.len as usize] = [dx, dy, dz];
            c.len += 1;
        }
        c
    }

    /// The offsets, if kept.
    pub fn offsets(&self) -> Option<impl Iterator<Item = [usize; 3]> + '_> {
        (self.len != u8::MAX).then(|| {
            self.delta[..self.len as usize]
                .iter()
                .map(|d| [0, 1, 2].map(|i| (i64::from(self.first[i]) + i64::from(d[i])) as usize))
        })
    }
}

/// An exact re-scoring of one rotation against a floor ([`Correlator::exact_among`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rescored {
    /// The exact best offset.
    Exact(BestOffset),
    /// The exact best match score is at most this (below the floor asked for).
    Below(i64),
    /// Not settled without a full exact correlation (too many offsets to count).
    TooMany,
}

/// Approximate best of one rotation from a reduced-precision correlation: the largest
/// computed output and a bound on how far the exact best match score can be from it,
/// `|max_a m(a) − value| ≤ error_bound`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ApproxBest {
    pub value: f64,
    pub error_bound: f64,
    /// Offset of `value` (the exact best may sit elsewhere when several are close).
    pub offset: [usize; 3],
    /// Where the exact best can be.
    pub candidates: Candidates,
}

impl ApproxBest {
    /// Smallest possible exact best match score.
    pub fn lower(&self) -> f64 {
        self.value - self.error_bound
    }
    /// Largest possible exact best match score.
    pub fn upper(&self) -> f64 {
        self.value + self.error_bound
    }
}

impl From<BestOffset> for ApproxBest {
    /// An exact score as an interval of width 0.
    fn from(b: BestOffset) -> Self {
        ApproxBest {
            value: b.match_score as f64,
            error_bound: 0.0,
            offset: b.offset,
            candidates: Candidates::of([b.offset]),
        }
    }
}

/// Exact scores as intervals of width 0, for a correlator with no approximate path.
pub fn as_intervals((exact, times): (Vec<BestOffset>, PassTimes)) -> (Vec<ApproxBest>, PassTimes) {
    (exact.into_iter().map(ApproxBest::from).collect(), times)
}

/// Which scores a correlator is planned for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scores {
    /// Approximate only: the ranking of a coarse level.
    Approximate,
    /// Approximate first, exact for the rotations the bound cannot settle.
    Mixed,
    /// Exact only.
    Exact,
}

/// Work done by a pass, summed over workers: CPU time per stage, the exactness check and
/// the nominal FLOPs. A backend that cannot split its time reports what it has.
#[derive(Debug, Clone, Copy, Default)]
pub struct PassTimes {
    pub voxelize: Duration,
    pub forward: Duration,
    pub product: Duration,
    pub inverse: Duration,
    /// Direct correlation of small grids (gathering their cells included).
    pub direct: Duration,
    /// Largest distance of an exact-path output from its integer.
    pub max_rounding_error: f64,
    /// Nominal FFT floating-point operations ([`Geometry::flops`]).
    pub flops: f64,
}

impl PassTimes {
    pub fn add(&mut self, o: &PassTimes) {
        self.voxelize += o.voxelize;
        self.forward += o.forward;
        self.product += o.product;
        self.inverse += o.inverse;
        self.direct += o.direct;
        self.max_rounding_error = self.max_rounding_error.max(o.max_rounding_error);
        self.flops += o.flops;
    }
}

/// The rotated copies of the source a pass scores: rotation `k` is the centred `cloud`
/// rotated by `rows[k]`, shifted so that `boxes[k].min` is the origin, voxelized at `voxel`.
#[derive(Clone, Copy)]
pub struct RotatedSources<'a> {
    pub cloud: &'a RotatableCloud,
    pub rows: &'a [[[f64; 3]; 3]],
    /// Extents per rotation index (entries not asked for are not read).
    pub boxes: &'a [Option<RotatedBox>],
    pub voxel: f64,
}

/// How a pass runs: the threads it may use, when it stops, whom it tells.
#[derive(Clone, Copy)]
pub struct PassControl<'a> {
    pub pool: &'a rayon::ThreadPool,
    pub threads: usize,
    /// Set from another thread to stop ([`GgsError::Cancelled`](crate::GgsError::Cancelled)).
    pub cancel: Option<&'a Arc<AtomicBool>>,
    /// Told the number of rotations scored so far, after each.
    pub progress: Option<&'a (dyn Fn(usize) + Send + Sync)>,
}

/// A planned correlation against one target kernel at one geometry.
pub trait Correlator: Send + Sync {
    /// The geometry it was planned for (every source grid fits `source_max`).
    fn geometry(&self) -> &Geometry;
    /// Cells of the kernel grid, `|K|`.
    fn kernel_cells(&self) -> i64;
    /// Occupied kernel cells, `n_k`.
    fn kernel_occupied(&self) -> i64;
    /// Exact best offsets of the rotations `indices`, in their order.
    fn exact(
        &self,
        ctl: &PassControl<'_>,
        src: &RotatedSources<'_>,
        indices: &[usize],
    ) -> Result<(Vec<BestOffset>, PassTimes)>;
    /// Exact re-scoring of the rotations `indices` where it matters against a floor: the exact
    /// best of `indices[i]` when it reaches `at_least`, else [`Rescored::Below`] or the exact
    /// best. `candidates[i]` are the candidates of its approximate best: a backend may then
    /// count the match score at those offsets alone. The default correlates exactly again.
    /// Never [`Rescored::TooMany`].
    fn exact_among(
        &self,
        ctl: &PassControl<'_>,
        src: &RotatedSources<'_>,
        indices: &[usize],
        candidates: &[Candidates],
        at_least: f64,
    ) -> Result<(Vec<Rescored>, PassTimes)> {
        debug_assert_eq!(indices.len(), candidates.len());
        let _ = at_least;
        let (found, times) = self.exact(ctl, src, indices)?;
        Ok((found.into_iter().map(Rescored::Exact).collect(), times))
    }
    /// Approximate bests with proven bounds, in the order of `indices`. The default is the
    /// exact scores as intervals of width 0, for a backend with no faster approximate path.
    fn approx(
        &self,
        ctl: &PassControl<'_>,
        src: &RotatedSources<'_>,
        indices: &[usize],
    ) -> Result<(Vec<ApproxBest>, PassTimes)> {
        Ok(as_intervals(self.exact(ctl, src, indices)?))
    }
}

/// Makes correlators: the one thing the search needs to know about the hardware.
pub trait Backend: Sync {
    /// Plans a correlator for `kernel` (dims `geo.kernel_dims`) with the scores `scores`.
    fn plan(
        &self,
        geo: Geometry,
        kernel: &Occupancy,
        scores: Scores,
    ) -> Result<Box<dyn Correlator>>;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kept(c: &Candidates) -> Option<Vec<[usize; 3]>> {
        c.offsets().map(|it| it.collect())
    }

    #[test]
    fn candidates_keep_their_offsets_or_none() {
        let near = vec![[300, 7, 0], [300, 8, 2], [301, 0, 127], [427, 134, 1]];
        assert_eq!(kept(&Candidates::of(near.clone())), Some(near));
        assert_eq!(kept(&Candidates::of([])), Some(vec![]));
        // Too many, too far from the first, or beyond 16 bits: none kept.
        let many = (0..=MAX_CANDIDATES).map(|i| [i / 8, i % 8, 0]);
        assert_eq!(Candidates::of(many), Candidates::NONE);
        assert_eq!(
            kept(&Candidates::of((0..MAX_CANDIDATES).map(|i| [
                i / 8,
                i % 8,
                0
            ])))
            .map(|v| v.len()),
            Some(MAX_CANDIDATES)
        );
        assert_eq!(Candidates::of([[5, 5, 5], [5, 5, 133]]), Candidates::NONE);
        assert_eq!(Candidates::of([[5, 5, 130], [5, 6, 1]]), Candidates::NONE);
        assert_eq!(Candidates::of([[70_000, 0, 0]]), Candidates::NONE);
        assert_eq!(
            kept(&Candidates::of([[5, 5, 130], [5, 6, 2]])),
            Some(vec![[5, 5, 130], [5, 6, 2]])
        );
        assert!(Candidates::NONE.offsets().is_none());
    }
}
