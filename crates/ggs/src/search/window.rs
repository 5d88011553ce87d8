//! The kernel window's share of the match score, counted exactly beside the transforms.
//!
//! The match score splits as `m(a) = 6·n11(a) − W(a)` (docs/method.md, "Exact integers"),
//! where `W(a)` counts the source-occupied cells inside the kernel window at offset `a`. A
//! correlator may correlate the kernel `6·O_k − 1` over its window (the −1 inside the
//! spectrum: [`KernelWindow::InSpectrum`]) or only `6·O_k` and subtract `W(a)` counted from
//! prefix sums of the source grid ([`KernelWindow::Counted`]). The outputs are the same
//! integers; what differs is the spectrum's peak, which scales the reduced-precision error
//! bound: `|6·n_k − |K||` or more with the window inside, exactly `6·n_k` without it. On a
//! sparse target (a scene: 1 % of the window occupied) counting the window shrinks the bound
//! about 14×; on a dense one (an object filling a sixth of its box) it would not help.

/// How the −1 of the kernel's empty window cells enters a correlation's outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KernelWindow {
    /// The spectrum is that of `6·O_k − 1` over the window.
    InSpectrum,
    /// The spectrum is that of `6·O_k`; each output has `W(a)` subtracted, counted from
    /// prefix sums of the source grid.
    Counted,
}

impl KernelWindow {
    /// `Counted` when it at least halves the spectrum's peak, judged from the DC bins: the
    /// window-inside spectrum peaks at `|6·n_k − |K||` or more, the counted one at `6·n_k`.
    /// `cells` is `|K|`, `occupied` is `n_k`.
    pub fn for_kernel(cells: i64, occupied: i64) -> Self {
        if 2 * 6 * occupied <= (cells - 6 * occupied).abs() {
            KernelWindow::Counted
        } else {
            KernelWindow::InSpectrum
        }
    }
}

/// Counts of occupied source cells over boxes of one source grid, from a table of prefix
/// sums over x and y per z: `P[x][y][z]` = occupied cells `(x', y', z)` with `x' < x`,
/// `y' < y`. `W(a)` for a whole row of offsets `(ax, ay, ·)` then takes 4 reads per z and
/// a running sum.
#[derive(Debug, Clone, Default)]
pub struct WindowCounts {
    table: Vec<u32>,
    ns: [usize; 3],
    /// Per row: the window's counts per z, then their running sum (`ns_z + 1` entries).
    running: Vec<u32>,
}

impl WindowCounts {
    /// Bytes of the table for a source grid of at most `source_max` cells per axis.
    pub fn bytes(source_max: [usize; 3]) -> u128 {
        let [x, y, z] = source_max.map(|v| v as u128);
        4 * ((x + 1) * (y + 1) * z + z + 1)
    }

    /// Build the table for the grid `cell(x, y, z)` (non-zero: occupied) of `ns` cells.
    pub fn build(&mut self, ns: [usize; 3], occupied: impl Fn(usize, usize, usize) -> bool) {
        let [nx, ny, nz] = ns;
        let plane = (ny + 1) * nz;
        self.ns = ns;
        self.table.clear();
        self.table.resize((nx + 1) * plane, 0);
        self.running.resize(nz + 1, 0);
        for x in 0..nx {
            let (done, rest) = self.table.split_at_mut((x + 1) * plane);
            let (prev, next) = (&done[x * plane..], &mut rest[..plane]);
            // `column[z]`: occupied cells (x, y' ≤ y, z) of this x-plane so far.
            let column = &mut self.running[..nz];
            column.fill(0);
            for y in 0..ny {
                let at = (y + 1) * nz;
                for z in 0..nz {
                    column[z] += u32::from(occupied(x, y, z));
                    next[at + z] = prev[at + z] + column[z];
                }
            }
        }
    }

    /// `W(a)` for the offsets `(ax, ay, az)`, `az < out.len()`: the occupied source cells
    /// `x` with `x + C − a` inside the window `[0, NR)`, i.e. `x ∈ [a − C, a − C + NR)`.
    pub fn row(
        &mut self,
        ax: usize,
        ay: usize,
        center: [usize; 3],
        window: [usize; 3],
        out: &mut [u32],
    ) {
        let [nx, ny, nz] = self.ns;
        let span = |a: usize, d: usize, n: usize| {
            let lo = a.saturating_sub(center[d]).min(n);
            let hi = (a + window[d]).saturating_sub(center[d]).min(n);
            (lo, hi)
        };
        let ((x0, x1), (y0, y1)) = (span(ax, 0, nx), span(ay, 1, ny));
        if x0 == x1 || y0 == y1 {
            out.fill(0);
            return;
        }
        let at = |x: usize, y: usize| &self.table[(x * (ny + 1) + y) * nz..][..nz];
        let (p11, p01, p10, p00) = (at(x1, y1), at(x0, y1), at(x1, y0), at(x0, y0));
        // running[z] = window cells with z' < z.
        let mut sum = 0u32;
        self.running[0] = 0;
        for z in 0..nz {
            sum += p11[z] + p00[z] - p01[z] - p10[z];
            self.running[z + 1] = sum;
        }
        for (az, w) in out.iter_mut().enumerate() {
            let (lo, hi) = span(az, 2, nz);
            *w = self.running[hi] - self.running[lo];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_window_is_counted_where_it_halves_the_peak() {
        use KernelWindow::{Counted, InSpectrum};
        // A scene (1 % of the window occupied); an object filling a sixth of its box, where
        // the window inside cancels the DC; and both sides of `12·n_k = |K| − 6·n_k`.
        for (cells, want) in [(100_000, Counted), (6_000, InSpectrum), (18_000, Counted)] {
            assert_eq!(KernelWindow::for_kernel(cells, 1_000), want, "{cells}");
        }
        assert_eq!(KernelWindow::for_kernel(17_999, 1_000), InSpectrum);
    }

    #[test]
    fn counts_match_brute_force() {
        let ns = [5, 4, 6];
        let occ = |x: usize, y: usize, z: usize| (x * 7 + y * 3 + z * 5).is_multiple_of(4);
        let mut w = WindowCounts::default();
        w.build(ns, occ);
        let (center, window) = ([2, 1, 3], [4, 3, 5]);
        let mut row = vec![0; ns[2]];
        for ax in 0..ns[0] {
            for ay in 0..ns[1] {
                w.row(ax, ay, center, window, &mut row);
                for (az, &got) in row.iter().enumerate() {
                    let a = [ax, ay, az];
                    let mut want = 0;
                    for x in 0..ns[0] {
                        for y in 0..ns[1] {
                            for z in 0..ns[2] {
                                let p = [x, y, z];
                                let inside = (0..3).all(|d| {
                                    let u = (p[d] + center[d]) as i64 - a[d] as i64;
                                    (0..window[d] as i64).contains(&u)
                                });
                                want += u32::from(inside && occ(x, y, z));
                            }
                        }
                    }
                    assert_eq!(got, want, "offset {a:?}");
                }
            }
        }
    }
}
