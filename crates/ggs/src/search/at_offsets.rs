//! Exact match scores at chosen offsets, counted from the definition: the exact re-scoring
//! of a rotation that a reduced-precision correlation could not settle.
//!
//! `m(a) = Σ 5·[O_k(u)] − [¬O_k(u)]` over the occupied source cells `x` whose
//! `u = x + C − a` falls in the kernel window (docs/method.md, "Exact integers"), one pass
//! over the source's occupied cells per offset. The offsets come from the f32 correlation and
//! its proven bound: every offset where the exact best can be is kept, so the counts settle
//! the best as an f64 correlation would, at a fraction of its cost while the offsets are few.

use super::correlator::{BestOffset, Rescored, MAX_CANDIDATES};
use super::cpu::{CpuCorrelator, Real, Workspace};
use super::voxel::Occupancy;

/// At most this many offsets are counted for one rotation; beyond it the count would cost
/// more than an f64 correlation on any plan (see [`counted_offsets_cap`]).
const MAX_COUNTED: usize = 16_384;

/// `m(a)` at offset `a` for the source cells `cells`: kernel window `kernel`, centre `c`.
fn match_at(cells: &[[usize; 3]], kernel: &Occupancy, c: [usize; 3], a: [usize; 3]) -> i64 {
    let nr = kernel.dims;
    let mut m = 0i64;
    for x in cells {
        // u = x + C − a, inside the kernel box.
        let u = [0, 1, 2].map(|d| (x[d] + c[d]).wrapping_sub(a[d]));
        if u[0] < nr[0] && u[1] < nr[1] && u[2] < nr[2] {
            m += if kernel.get(u[0], u[1], u[2]) { 5 } else { -1 };
        }
    }
    m
}

/// The largest `m(a)` over `offsets` (x-major C order), ties to the first; `None` for none.
fn best_at(
    cells: &[[usize; 3]],
    kernel: &Occupancy,
    c: [usize; 3],
    offsets: impl Iterator<Item = [usize; 3]>,
) -> Option<BestOffset> {
    let mut best: Option<BestOffset> = None;
    for a in offsets {
        let m = match_at(cells, kernel, c, a);
        if best.is_none_or(|b| m > b.match_score) {
            best = Some(BestOffset {
                match_score: m,
                offset: a,
            });
        }
    }
    best
}

/// How many offsets are worth counting for a source of `cells` occupied cells: about as many
/// as make the counts cost what an f64 correlation of `flops` nominal operations does (a
/// kernel read per cell and offset against ~8 f64 operations per nanosecond).
fn counted_offsets_cap(flops: f64, cells: usize) -> usize {
    let cap = flops / (8.0 * cells.max(1) as f64);
    (cap as usize).clamp(MAX_CANDIDATES, MAX_COUNTED)
}

impl<T: Real> CpuCorrelator<T> {
    /// The exact best among `candidates` (x-major C order) of the source grid in `ws` (not yet
    /// transformed); ties to the first. Equal to [`CpuCorrelator::best_offset`] when
    /// `candidates` hold every offset reaching the best (see
    /// [`Candidates`](super::correlator::Candidates)).
    pub fn exact_among(
        &self,
        ws: &Workspace<T>,
        kernel: &Occupancy,
        candidates: impl Iterator<Item = [usize; 3]>,
    ) -> BestOffset {
        let mut cells = Vec::new();
        ws.occupied_cells(&mut cells);
        best_at(&cells, kernel, self.geometry().center, candidates).unwrap_or(BestOffset {
            match_score: i64::MIN,
            offset: [0; 3],
        })
    }

    /// The exact best of the source grid in `ws` (not yet transformed) if it reaches
    /// `at_least`, else a proof that it does not: correlate in `T`, keep the offsets whose
    /// outputs reach `t − bound` with `t = max(at_least, best − bound)`
    /// (the scan's near offsets), and count `m` there. With `M` the exact best, every
    /// offset reaching `M` is kept when `M ≥ t`; so a count reaching `t` is `M` (and its first
    /// offset the exact argmax), and a count below `t` shows `M < t`, which happens only when
    /// `t = at_least`: then `M ≤ ⌈at_least⌉ − 1`. [`Rescored::TooMany`] when more offsets reach
    /// than are worth counting.
    pub fn exact_above(
        &self,
        ws: &mut Workspace<T>,
        kernel: &Occupancy,
        at_least: f64,
    ) -> Rescored {
        let mut cells = Vec::new();
        ws.occupied_cells(&mut cells);
        let cap = counted_offsets_cap(self.geometry().flops(ws.ns()), cells.len());
        self.stage_forward(ws);
        self.stage_product(ws);
        let bound = self.error_bound(ws.occupied_estimate());
        let scan = self.scan_near(ws, bound, at_least, cap);
        if !scan.complete || bound.is_nan() || scan.best.is_nan() {
            return Rescored::TooMany;
        }
        let t = at_least.max(scan.best - bound);
        let offsets = ws.near_offsets();
        let center = self.geometry().center;
        match best_at(&cells, kernel, center, offsets) {
            Some(b) if b.match_score as f64 >= t => Rescored::Exact(b),
            // `M < t = at_least` (an integer below it).
            _ => Rescored::Below(at_least.ceil() as i64 - 1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::search::cpu::{brute_force_scores, Geometry, KernelWindow};

    /// Against every floor, `exact_above` gives the exact best (value and first offset) when
    /// it reaches the floor, and otherwise a true upper bound below the floor; with either
    /// window, on dense and sparse grids.
    #[test]
    fn exact_above_settles_the_best_or_shows_it_below_the_floor() {
        let mut next = crate::test_rng::uniform(31);
        let mut below = 0;
        for case in 0..16 {
            let n = 6 + case;
            let p = if case % 2 == 0 { 0.3 } else { 0.03 };
            let k = Occupancy::random([n + 3, n, n + 1], p, &mut next);
            let src = Occupancy::random([n, n - 2, n + 2], 0.2, &mut next);
            let scores = brute_force_scores(&src, &k);
            let max = *scores.iter().max().unwrap();
            let first = scores.iter().position(|&m| m == max).unwrap();
            let [_, sy, sz] = src.dims;
            let want = BestOffset {
                match_score: max,
                offset: [first / (sy * sz), first / sz % sy, first % sz],
            };
            let geo = Geometry::new(k.dims, src.dims);
            let window = [KernelWindow::InSpectrum, KernelWindow::Counted][case % 2];
            let c = CpuCorrelator::<f32>::with_window(geo, &k, window);
            let mut ws = c.workspace();
            for floor in [
                f64::NEG_INFINITY,
                max as f64 - 3.5,
                max as f64,
                max as f64 + 0.5,
            ] {
                ws.load(&src);
                match c.exact_above(&mut ws, &k, floor) {
                    Rescored::Exact(b) => assert_eq!(b, want, "case {case}, floor {floor}"),
                    Rescored::Below(m) => {
                        assert!(max < floor.ceil() as i64, "case {case}: {max} ≥ {floor}");
                        assert!(max <= m && (m as f64) < floor, "case {case}: {m}");
                        below += 1;
                    }
                    Rescored::TooMany => panic!("case {case}: too many offsets"),
                }
            }
        }
        assert!(below >= 8, "only {below} floors shown unreached");
    }
}
