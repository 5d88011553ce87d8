//! Sparse correlation: the match score of every offset from the pairs of occupied cells,
//! where both grids are sparse (the fine level of a thin surface such as a partial view of a
//! body: a few hundred occupied cells of tens of thousands).
//!
//! With `W = 6·O_k − 1` on the kernel grid and 0 outside it (docs/method.md, "Exact
//! integers"), the score of offset `a` splits into a pair count and a box count:
//!
//! `m(a) = Σ_x O_s[x]·W[x + C − a] = 6·n₁₁(a) − n_in(a)`,
//!
//! `n₁₁(a) = #{(x, u) occupied in source and kernel : a = x + v − P}` with `v = NR − 1 − u`
//! and `P = NR − 1 − C`, and `n_in(a) = #{x occupied : a + P − NR + 1 ≤ x ≤ a + P}` (per
//! axis) the source cells that land on the kernel's box. The first costs one 16-lane addition
//! per pair of runs of occupied cells along z (a run of `L_s` source cells and one of `L_t`
//! kernel cells add a trapezoid of pair counts to `L_s + L_t − 1` consecutive offsets; at most
//! `n_s·n_k` pairs, against `n_runs·NRx·NRy` 16-offset additions for the dense rows of
//! [`super::direct`], which spend most of them on the kernel's empty cells);
//! the second is the source's occupancy summed over a box, built from one profile along z
//! per source column spread over a rectangle of offset rows by a two-dimensional difference
//! array and two prefix sums.
//!
//! Exactness: `n₁₁ ≤ min(n_s, n_k)` and `n_in ≤ n_s`, so with `6·min(n_s, n_k) ≤ 32 767` and
//! `n_s ≤ 32 767` every score is an exact 16-bit integer. The best offset is the first in
//! x-major C order among the highest, as for every other correlator.

use super::correlator::BestOffset;
use super::direct::{DirectScratch, MAX_RUN};
use super::geometry::Geometry;
use super::voxel::Occupancy;

/// Largest pair-count factor `min(n_s, n_k)` whose scores fit `i16` (`6·n ≤ 32 767`).
pub const MAX_PAIRED: usize = 5461;

/// Costs of a sparse correlation in nominal FLOPs of the transforms that take as long
/// ([`SparseKernel::cost`]), fitted on the development machine (AMD EPYC, 2 cores, the AVX2 path;
/// `benches/direct_probe.rs`, every rotation of `hopf15-id`) where the transforms took about
/// 34 ps a FLOP: 68 µs a rotation for 26 713 run pairs and 15 912 offsets (the generated
/// human pair at its voxel size; the transforms 192 µs), 412 µs for 353 160 and 24 828 (the
/// bunny pair; the transforms 284 µs), 131 µs for 85 014 and 14 007 (PCL's 400-point bunny
/// views at 6 mm; the transforms 167 µs), 7.3 µs for 2 282 and 443 (the bunny pair's coarse
/// level; direct correlation 4.1 µs). Only the time depends on them, never the scores.
pub const FLOPS_PER_RUN_PAIR: f64 = 32.0;
/// See [`FLOPS_PER_RUN_PAIR`].
pub const FLOPS_PER_OFFSET: f64 = 70.0;
/// See [`FLOPS_PER_RUN_PAIR`].
pub const FLOPS_PER_ROTATION: f64 = 88_000.0;
/// The fitted cost is raised by this factor, so that sparse correlation is chosen only where
/// it is clearly cheaper: the fit is off by 10 % or so near the break-even, and the
/// transforms' time per FLOP varies by as much from grid to grid. Measured against 1.25 on
/// PCL's bunny views with `--preset paper` (sparse for 5 016 of 6 360 rotations instead of
/// 2 569): 170 → 154 ms for the whole process, medians of 7 interleaved runs; the generated
/// human and the bunny pairs unchanged.
pub const COST_MARGIN: f64 = 1.1;

/// The occupied cells of a kernel, reversed, laid out for sparse correlation.
#[derive(Debug, Clone)]
pub struct SparseKernel {
    nr: [usize; 3],
    /// `P = NR − 1 − C` per axis.
    p: [usize; 3],
    /// The runs along z of the occupied cells as `v = NR − 1 − u`, `(v₁, first v₂, length ≤
    /// 8)`, in x-major order, and where each `v₀` starts.
    runs: Vec<[u16; 3]>,
    v0_start: Vec<u32>,
    occupied: usize,
}

/// A worker's buffers for sparse correlation, reused across rotations: about 2 bytes an
/// offset and 4 a cell of a slab of pair counts, less than what the memory model
/// (`memory_model.rs`) counts for each worker beyond the f32 workspace it holds beside them
/// (the f64 workspace it holds instead during re-scoring).
#[derive(Debug, Clone, Default)]
pub struct SparseScratch {
    /// Each run of occupied source cells as its place in a slab of pair counts (`x₁·E₂ + x₂`
    /// of its first cell, with `E = NS + NR − 1` along y and z) times 8 plus its length − 1,
    /// in x-major order, and where each `x₀` starts; each kernel run's likewise (`v₁·E₂ +
    /// v₂`), in the kernel's order.
    places: Vec<u32>,
    x0_start: Vec<u32>,
    kernel_places: Vec<u32>,
    /// Pair counts of one slab `a₀`, `[a₁ + P₁][a₂ + P₂]` over `E₁ × E₂` (and [`LANES`]
    /// more, which a run pair at the end adds zeros to), in two copies that consecutive source
    /// runs alternate between ([`add_pairs`]); `n₁₁` is their sum.
    pairs: Vec<i16>,
    /// The box counts' difference array, then the counts, `(NS₀ + 1) × (NS₁ + 1)` rows of
    /// `NS₂`; one column's profile along z and its running sum.
    boxes: Vec<i16>,
    profile: Vec<i16>,
    running: Vec<i16>,
    /// One row of scores (`NS₂` offsets).
    row: Vec<i16>,
}

impl SparseKernel {
    /// The kernel's occupied cells for the sources of `geo`; `None` when a grid axis is too
    /// long for 16-bit cell coordinates.
    pub fn new(geo: &Geometry, kernel: &Occupancy) -> Option<SparseKernel> {
        let nr = kernel.dims;
        if nr.iter().chain(&geo.source_max).any(|&n| n >= 1 << 15) {
            return None;
        }
        let p = [0, 1, 2].map(|d| nr[d] - 1 - geo.center[d]);
        let mut runs: Vec<[u16; 3]> = Vec::new();
        let mut v0_start = vec![0u32];
        for v0 in 0..nr[0] {
            for v1 in 0..nr[1] {
                let mut open = false;
                for v2 in 0..nr[2] {
                    if !kernel.get(nr[0] - 1 - v0, nr[1] - 1 - v1, nr[2] - 1 - v2) {
                        open = false;
                    } else if open && runs.last().is_some_and(|r| (r[2] as usize) < MAX_RUN) {
                        runs.last_mut().expect("open run")[2] += 1;
                    } else {
                        runs.push([v1 as u16, v2 as u16, 1]);
                        open = true;
                    }
                }
            }
            v0_start.push(runs.len() as u32);
        }
        Some(SparseKernel {
            nr,
            p,
            runs,
            v0_start,
            occupied: kernel.occupied(),
        })
    }

    /// The expected time of a sparse correlation of `runs` runs of source cells on a grid of
    /// dims `ns`, in nominal FLOPs of the transforms ([`Geometry::flops`]) that take as long:
    /// [`FLOPS_PER_RUN_PAIR`] a pair of runs (source × kernel, an upper bound),
    /// [`FLOPS_PER_OFFSET`] an offset, [`FLOPS_PER_ROTATION`] a rotation, and a tenth more
    /// ([`COST_MARGIN`]).
    pub fn cost(&self, ns: [usize; 3], runs: usize) -> f64 {
        let offsets = (ns[0] * ns[1] * ns[2]) as f64;
        let fitted = (runs * self.runs.len()) as f64 * FLOPS_PER_RUN_PAIR
            + offsets * FLOPS_PER_OFFSET
            + FLOPS_PER_ROTATION;
        fitted * COST_MARGIN
    }

    /// Runs along z of the occupied kernel cells (at most [`MAX_RUN`] cells each).
    #[cfg(feature = "internals")]
    pub fn runs(&self) -> usize {
        self.runs.len()
    }

    /// Occupied kernel cells `n_k`.
    #[cfg(feature = "internals")]
    pub fn occupied(&self) -> usize {
        self.occupied
    }

    /// The best offset of the source gathered in `direct` ([`super::direct::DirectKernel::gather`])
    /// on a grid of dims `ns`, or `None` (the transforms then score it) when its scores might
    /// not fit 16 bits, its places 32 bits, or it has no occupied cell.
    pub fn best(
        &self,
        ns: [usize; 3],
        direct: &DirectScratch,
        scratch: &mut SparseScratch,
    ) -> Option<BestOffset> {
        let n_s = direct.cells();
        if n_s.min(self.occupied) > MAX_PAIRED || n_s > i16::MAX as usize {
            return None;
        }
        // Places are packed with 3 bits of run length into u32.
        let [e1, e2] = self.extents(ns);
        if n_s == 0 || ns.contains(&0) || (e1 * e2 + LANES) as u64 * 8 > u64::from(u32::MAX) {
            return None;
        }
        self.place_sources(ns, direct, scratch);
        self.count_boxes(ns, direct, scratch);
        Some(self.count_pairs_and_combine(ns, scratch))
    }

    /// `E₁, E₂`: the pair counts' extents along y and z.
    fn extents(&self, ns: [usize; 3]) -> [usize; 2] {
        [ns[1] + self.nr[1] - 1, ns[2] + self.nr[2] - 1]
    }

    /// Fill `places` and `x0_start` from the runs gathered in `direct`, and `kernel_places`.
    fn place_sources(&self, ns: [usize; 3], direct: &DirectScratch, s: &mut SparseScratch) {
        let [_, e2] = self.extents(ns);
        let packed = |place: usize, len: u16| (place * 8 + len as usize - 1) as u32;
        s.kernel_places.clear();
        (s.kernel_places).extend(
            (self.runs.iter()).map(|&[v1, v2, len]| packed(v1 as usize * e2 + v2 as usize, len)),
        );
        s.places.clear();
        s.x0_start.clear();
        s.x0_start.resize(ns[0] + 1, 0);
        for &(i, j, from, to) in direct.columns() {
            let column = j as usize * e2;
            let runs = &direct.runs()[from as usize..to as usize];
            (s.places).extend(
                runs.iter()
                    .map(|&(z, len)| packed(column + z as usize, len)),
            );
            s.x0_start[i as usize + 1] = s.places.len() as u32;
        }
        // Rows with no column start where the previous one ended.
        for i in 1..=ns[0] {
            s.x0_start[i] = s.x0_start[i].max(s.x0_start[i - 1]);
        }
    }

    /// `n_in` over `NS` into `boxes` (rows of `NS₂`, row `(a₀, a₁)` at `a₀·(NS₁ + 1) + a₁`).
    fn count_boxes(&self, ns: [usize; 3], direct: &DirectScratch, s: &mut SparseScratch) {
        let (nr, p) = (self.nr, self.p);
        let (rows1, n2) = (ns[1] + 1, ns[2]);
        s.boxes.clear();
        s.boxes.resize((ns[0] + 1) * rows1 * n2, 0);
        s.profile.resize(n2, 0);
        // Offsets reached from source coordinate x: x − P ≤ a ≤ x − P + NR − 1, within NS.
        let reach = |x: usize, d: usize| {
            let lo = x.saturating_sub(p[d]);
            let hi = (x + nr[d] - 1).checked_sub(p[d]).map(|h| h.min(ns[d] - 1));
            hi.filter(|&h| lo <= h).map(|h| (lo, h + 1))
        };
        for &(i, j, from, to) in direct.columns() {
            let (Some((lo0, hi0)), Some((lo1, hi1))) = (reach(i as usize, 0), reach(j as usize, 1))
            else {
                continue;
            };
            self.column_profile(ns, &direct.runs()[from as usize..to as usize], s);
            for (r, sign) in [
                (lo0, lo1, 1i16),
                (hi0, lo1, -1),
                (lo0, hi1, -1),
                (hi0, hi1, 1),
            ]
            .map(|(a0, a1, sign)| (a0 * rows1 + a1, sign))
            {
                let row = &mut s.boxes[r * n2..][..n2];
                for (b, &q) in row.iter_mut().zip(&s.profile) {
                    *b = b.wrapping_add(sign.wrapping_mul(q));
                }
            }
        }
        // Prefix sums along x, then y (each row adds the one before it).
        for r in rows1..(ns[0] + 1) * rows1 {
            let (done, rest) = s.boxes.split_at_mut(r * n2);
            add_row(&mut rest[..n2], &done[(r - rows1) * n2..][..n2]);
        }
        for a0 in 0..=ns[0] {
            for a1 in 1..rows1 {
                let r = a0 * rows1 + a1;
                let (done, rest) = s.boxes.split_at_mut(r * n2);
                add_row(&mut rest[..n2], &done[(r - 1) * n2..][..n2]);
            }
        }
    }

    /// One column's `n_in` along z: `profile[a₂] = #{x₂ occupied : a₂ + P₂ − NR₂ + 1 ≤ x₂ ≤
    /// a₂ + P₂}`, the difference of two slices of the column's running count shifted by
    /// `NR₂` (`running[u]`: its cells below `u − NR₂`; zero below, the total above).
    fn column_profile(&self, ns: [usize; 3], runs: &[(u16, u16)], s: &mut SparseScratch) {
        let n2 = ns[2];
        let (nr2, p2) = (self.nr[2], self.p[2]);
        let len = n2 + nr2 + p2 + 1;
        s.running.clear();
        s.running.resize(len, 0);
        for &(z, run) in runs {
            s.running[nr2 + z as usize + 1..][..run as usize].fill(1);
        }
        // A sum carried in a register, not through memory; past the column, the total.
        let mut below = 0i16;
        for r in &mut s.running[nr2 + 1..=nr2 + n2] {
            below += *r;
            *r = below;
        }
        s.running[nr2 + n2 + 1..].fill(below);
        let (hi, lo) = (&s.running[p2 + 1 + nr2..][..n2], &s.running[p2 + 1..][..n2]);
        for ((out, &h), &l) in s.profile.iter_mut().zip(hi).zip(lo) {
            *out = h - l;
        }
    }

    /// The best of `m = 6·n₁₁ − n_in` over `NS` (the first in x-major order among the highest,
    /// taken row by row as the rows are made), one slab `a₀` at a time: `n₁₁` adds one
    /// per pair of a kernel cell and a source cell with `x₀ + v₀ − P₀ = a₀`, into counts that
    /// extend past `NS` along y and z (`E₁ × E₂`, so no pair is tested, and small enough to
    /// stay in the first-level cache), a pair of runs at a time ([`TRAPEZOIDS`]).
    fn count_pairs_and_combine(&self, ns: [usize; 3], s: &mut SparseScratch) -> BestOffset {
        match crate::simd::level() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `simd::level` returns Avx2 or wider only when the CPU has AVX2.
            crate::simd::Level::Avx2 | crate::simd::Level::Avx512 => unsafe {
                self.pairs_and_combine_avx2(ns, s)
            },
            _ => self.pairs_and_combine::<false>(ns, s),
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn pairs_and_combine_avx2(&self, ns: [usize; 3], s: &mut SparseScratch) -> BestOffset {
        self.pairs_and_combine::<true>(ns, s)
    }

    /// [`Self::count_pairs_and_combine`]; `AVX2` only where the CPU has it.
    #[inline(always)]
    fn pairs_and_combine<const AVX2: bool>(
        &self,
        ns: [usize; 3],
        s: &mut SparseScratch,
    ) -> BestOffset {
        let [e1, e2] = self.extents(ns);
        let (rows1, n2) = (ns[1] + 1, ns[2]);
        s.row.resize(n2, 0);
        let (mut best, mut offset) = (i16::MIN, [0; 3]);
        for a0 in 0..ns[0] {
            s.pairs.clear();
            s.pairs.resize(2 * (e1 * e2 + LANES), 0);
            // v₀ = a₀ + P₀ − x₀ for x₀ ∈ [0, NS₀), within [0, NR₀).
            let v_lo = (a0 + self.p[0]).saturating_sub(ns[0] - 1);
            let v_hi = (a0 + self.p[0] + 1).min(self.nr[0]);
            for v0 in v_lo..v_hi {
                let x0 = a0 + self.p[0] - v0;
                let sources = &s.places[s.x0_start[x0] as usize..s.x0_start[x0 + 1] as usize];
                let kernel =
                    &s.kernel_places[self.v0_start[v0] as usize..self.v0_start[v0 + 1] as usize];
                add_pairs::<AVX2>(&mut s.pairs, sources, kernel);
            }
            let (even, odd) = s.pairs.split_at(e1 * e2 + LANES);
            for a1 in 0..ns[1] {
                let at = (a1 + self.p[1]) * e2 + self.p[2];
                let (even, odd) = (&even[at..][..n2], &odd[at..][..n2]);
                let boxes = &s.boxes[(a0 * rows1 + a1) * n2..][..n2];
                for (((o, &e), &d), &b) in s.row.iter_mut().zip(even).zip(odd).zip(boxes) {
                    *o = e.wrapping_add(d).wrapping_mul(6).wrapping_sub(b);
                }
                let top = s.row.iter().copied().fold(i16::MIN, i16::max);
                if top > best {
                    best = top;
                    let a2 = s.row.iter().position(|&v| v == top).unwrap_or(0);
                    offset = [a0, a1, a2];
                }
            }
        }
        BestOffset {
            match_score: i64::from(best),
            offset,
        }
    }
}

/// Lanes of one addition of a run pair: runs of up to 8 cells meet at up to 15 offsets.
const LANES: usize = 16;

// Run lengths are packed in 3 bits.
const _: () = assert!(MAX_RUN == 8);

/// `TRAPEZOIDS[(L_s − 1)·8 + L_t − 1][d]`: the pairs of a run of `L_s` source cells and one
/// of `L_t` kernel cells whose places sum to the runs' first places plus `d`.
static TRAPEZOIDS: [[i16; LANES]; 64] = trapezoids();

const fn trapezoids() -> [[i16; LANES]; 64] {
    let mut t = [[0i16; LANES]; 64];
    let mut i = 0;
    while i < 64 {
        let (ls, lt) = (i / 8 + 1, i % 8 + 1);
        let mut a = 0;
        while a < ls {
            let mut b = 0;
            while b < lt {
                t[i][a + b] += 1;
                b += 1;
            }
            a += 1;
        }
        i += 1;
    }
    t
}

/// `pairs[q + k + d] += TRAPEZOIDS[…][d]` for every source run and kernel run (places and
/// lengths packed as in [`SparseScratch`]); `AVX2` (one 256-bit load, add and store a run
/// pair) only where the CPU has it. Consecutive source runs add to the two halves of `pairs`
/// in turn: two runs of one column add to overlapping lanes, and a load that overlaps the
/// store just before it only in part waits for that store (store forwarding fails), which
/// made the bunny's voxel-size level 506 → 412 µs a rotation, its coarse level 15 → 7 µs.
#[inline(always)]
fn add_pairs<const AVX2: bool>(pairs: &mut [i16], sources: &[u32], kernel: &[u32]) {
    let half = pairs.len() / 2;
    for &k in kernel {
        let (place, lt) = ((k >> 3) as usize, (k & 7) as usize);
        for (i, &q) in sources.iter().enumerate() {
            let t = &TRAPEZOIDS[((q & 7) as usize) << 3 | lt];
            let at = (q >> 3) as usize + place + (i & 1) * half;
            let out: &mut [i16; LANES] = (&mut pairs[at..at + LANES]).try_into().expect("lanes");
            #[cfg(target_arch = "x86_64")]
            if AVX2 {
                // SAFETY: `AVX2` is true only in `pairs_and_combine_avx2`, which runs where the
                // CPU has AVX2.
                unsafe { add_lanes_avx2(out, t) };
                continue;
            }
            for l in 0..LANES {
                out[l] = out[l].wrapping_add(t[l]);
            }
        }
    }
}

/// `out += t`, lane by lane, in one 256-bit load, add and store.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn add_lanes_avx2(out: &mut [i16; LANES], t: &[i16; LANES]) {
    use std::arch::x86_64::{__m256i, _mm256_add_epi16, _mm256_loadu_si256, _mm256_storeu_si256};
    // SAFETY: `out` and `t` each hold 16 `i16` (32 bytes), read and written unaligned; `out`
    // is borrowed mutably, so nothing else refers to it.
    unsafe {
        let sum = _mm256_add_epi16(
            _mm256_loadu_si256(out.as_ptr() as *const __m256i),
            _mm256_loadu_si256(t.as_ptr() as *const __m256i),
        );
        _mm256_storeu_si256(out.as_mut_ptr() as *mut __m256i, sum);
    }
}

/// `row += before`, wrapping (the sums are exact modulo 2¹⁶ and the results fit).
fn add_row(row: &mut [i16], before: &[i16]) {
    for (r, &b) in row.iter_mut().zip(before) {
        *r = r.wrapping_add(b);
    }
}

#[cfg(test)]
mod tests {
    use super::super::direct::tests::{brute_best, dense, random_grid};
    use super::super::direct::DirectKernel;
    use super::*;
    use crate::test_rng::uniform;

    #[test]
    fn sparse_scores_equal_the_definition_ties_included() {
        let mut next = uniform(20261205);
        for round in 0..80 {
            let mut dim = |lo: usize, hi: usize| lo + (next() * (hi - lo + 1) as f64) as usize;
            // Kernels longer and shorter than their sources on every axis.
            let nr = [dim(1, 12), dim(1, 12), dim(1, [20, 20, 60, 3][round % 4])];
            let ns = [dim(1, 12), dim(1, 12), dim(1, [36, 6, 36, 40][round % 4])];
            let fill = [0.02, 0.1, 0.4, 0.9][round % 4];
            let kernel = random_grid(nr, [0.05, 0.4, 0.9, 0.2][round % 4], &mut next);
            let src = random_grid(ns, fill, &mut next);
            let geo = Geometry::new(nr, [ns[0] + round % 2, ns[1], ns[2] + round % 3]);
            let sparse = SparseKernel::new(&geo, &kernel).expect("small grids");
            let (cells, strides) = dense(&src, ns[2] + 5);
            let mut direct = DirectScratch::default();
            DirectKernel::gather(&cells, strides, ns, &mut direct);
            let got = sparse.best(ns, &direct, &mut SparseScratch::default());
            if src.occupied() == 0 {
                assert!(got.is_none());
                continue;
            }
            assert_eq!(got, Some(brute_best(&src, &kernel)), "round {round}");
        }
    }

    /// The portable body of the pair counts gives the same best as the one the CPU runs.
    #[test]
    fn the_portable_body_gives_the_same_best() {
        let mut next = uniform(20261206);
        for round in 0..20 {
            let mut dim = |lo: usize, hi: usize| lo + (next() * (hi - lo + 1) as f64) as usize;
            let nr = [dim(1, 12), dim(1, 12), dim(1, 30)];
            let ns = [dim(1, 12), dim(1, 12), dim(1, 40)];
            let kernel = random_grid(nr, 0.3, &mut next);
            let src = random_grid(ns, [0.05, 0.3][round % 2], &mut next);
            let sparse = SparseKernel::new(&Geometry::new(nr, ns), &kernel).expect("small grids");
            let (cells, strides) = dense(&src, ns[2] + 3);
            let mut direct = DirectScratch::default();
            DirectKernel::gather(&cells, strides, ns, &mut direct);
            let mut s = SparseScratch::default();
            sparse.place_sources(ns, &direct, &mut s);
            sparse.count_boxes(ns, &direct, &mut s);
            let dispatched = sparse.count_pairs_and_combine(ns, &mut s);
            let portable = sparse.pairs_and_combine::<false>(ns, &mut s);
            assert_eq!(portable, dispatched, "round {round}");
        }
    }

    #[test]
    fn scores_that_might_overflow_16_bits_are_declined() {
        let kernel = Occupancy {
            dims: [80, 80, 1],
            cells: vec![true; 6400],
        };
        let geo = Geometry::new(kernel.dims, [80, 80, 1]);
        let sparse = SparseKernel::new(&geo, &kernel).expect("small grids");
        let ns = [80, 80, 1];
        let cells = vec![1.0f32; 6400];
        let mut direct = DirectScratch::default();
        DirectKernel::gather(&cells, [80, 1], ns, &mut direct);
        assert!(sparse
            .best(ns, &direct, &mut SparseScratch::default())
            .is_none());
        // 5 461 cells each still fit.
        let few = [70, 78, 1];
        let cells = vec![1.0f32; 70 * 78];
        DirectKernel::gather(&cells, [78, 1], few, &mut direct);
        assert_eq!(direct.cells(), 5460);
        assert!(sparse
            .best(few, &direct, &mut SparseScratch::default())
            .is_some());
    }
}
