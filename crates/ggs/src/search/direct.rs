//! Direct correlation of small grids: the match score of every offset summed cell by cell
//! instead of by FFT, in exact 16-bit integers.
//!
//! The match score (docs/method.md, "Exact integers") is
//!
//! `m(a) = Σ_u O_s[a − C + u]·W[u] = Σ_x O_s[x]·W[x + C − a]`, `W = 6·O_k − 1` on the kernel
//! grid and 0 outside it,
//!
//! so each occupied source cell `x` adds the kernel, reversed on every axis, to the offsets
//! `a = x − P + v` with `v ∈ [0, NR)` and `P = NR − 1 − C` (`v = NR − 1 − u`). For a sparse source (a surface:
//! `n` occupied cells of `NS³`) that is `n·NRx·NRy` additions of one reversed kernel row
//! along z, 16 offsets at a time, against `O(L³ log L)` for the transforms, whose fixed cost
//! per call dominates on the coarse level's grids (12³ to 16³). Which is cheaper is decided
//! per rotation by [`DirectKernel::cost`] (`Workspace::direct_best`).
//!
//! Exactness: every partial sum lies in `[−n, 5·n]` (each source cell adds at most 5 and at
//! least −1 to an offset), so with `n ≤ 6553` no 16-bit sum overflows and the scores are the
//! exact integers an f64 correlation rounds to. The best offset is the first in x-major C
//! order among the highest, the rule of [`super::correlator::Correlator::exact`].

use super::correlator::BestOffset;
use super::geometry::Geometry;
use super::grid_view::Real;
use super::voxel::Occupancy;

/// Offsets summed at once along z (one 256-bit register of 16-bit integers).
const LANES: usize = 16;

/// Largest number of occupied source cells whose partial sums fit `i16` (`5·n ≤ 32 767`).
pub const MAX_OCCUPIED: usize = 6553;

/// Direct correlation is chosen when it needs fewer 16-offset additions than this many per
/// nominal FLOP of the transforms ([`Geometry::flops`]). Fitted on the coarse levels of four
/// pairs on the development machine (AMD EPYC, AVX2; `benches/direct_probe.rs`), where the
/// time of direct over transforms was 0.54 at 0.026 additions a FLOP (the generated human
/// pair), 0.63 at 0.038 (lidar_koide), 0.89 at 0.057 (3dmatch_demo) and 0.95 at 0.062 (the
/// bunny pair): even near 0.066. Only the time depends on it, never the scores.
const ADDITIONS_PER_FLOP: f64 = 0.035;

/// The reversed kernel `W` laid out for direct correlation, planned for one geometry.
#[derive(Debug, Clone)]
pub struct DirectKernel {
    nr: [usize; 3],
    /// `P = NR − 1 − C` per axis: offset `a` receives `W_rev[v]` from a source cell `x`
    /// when `a = x − P + v`.
    p: [usize; 3],
    /// Row `(vx, vy)` of the reversed kernel at `(vx·NRy + vy)·row_len`: `pad` zeros, then
    /// `W_rev[vx][vy][0..NRz]`, then zeros to `row_len`; then the same rows summed over runs
    /// of 2 to [`MAX_RUN`] cells, table `L − 1` at `(L − 1)·table_len`:
    /// `R_L[q] = Σ_{d < L} W_pad[q − d]`, so that a run of `L` cells along z adds as one row.
    tables: Vec<i16>,
    pad: usize,
    row_len: usize,
    table_len: usize,
    /// Largest source grid along z the rows are padded for.
    max_nsz: usize,
}

/// Longest run of occupied cells along z added as one row (longer runs are split): runs of 1
/// to 7 cells make 96 % of the columns of the bunny pair's coarse level.
pub const MAX_RUN: usize = 8;

/// Largest size of a kernel's tables (2 MiB; the coarse levels measured take 20–150 KiB).
pub const MAX_TABLE_BYTES: usize = 2 << 20;

/// A worker's buffers for direct correlation, reused across rotations.
#[derive(Debug, Clone, Default)]
pub struct DirectScratch {
    /// Runs of occupied cells along z, `(first z, length ≤ MAX_RUN)`, column by column, and
    /// the columns: `(i, j, start, end)` into `runs`.
    runs: Vec<(u16, u16)>,
    columns: Vec<(u16, u16, u32, u32)>,
    /// Occupied cells gathered.
    cells: usize,
    /// Where each run's kernel rows start in the tables (`(L − 1)·table_len + pad + P_z − z`),
    /// in the order of `runs`.
    starts: Vec<u32>,
    /// Scores, layout `[ax][ay][chunk·16 + lane]`.
    acc: Vec<i16>,
}

impl DirectScratch {
    /// Occupied cells gathered by the last [`DirectKernel::gather`].
    pub fn cells(&self) -> usize {
        self.cells
    }

    /// The runs gathered, `(first z, length)`, column by column.
    pub(super) fn runs(&self) -> &[(u16, u16)] {
        &self.runs
    }

    /// The columns gathered, `(i, j, start, end)` into [`Self::runs`], in x-major order.
    pub(super) fn columns(&self) -> &[(u16, u16, u32, u32)] {
        &self.columns
    }
}

impl DirectKernel {
    /// The kernel of `kernel` for sources up to `geo.source_max`, or `None` when its grid is
    /// too long along z for the padding to stay small (more than 8 chunks of 16) or its
    /// tables would take more than [`MAX_TABLE_BYTES`]: a kernel that large is never cheaper
    /// to correlate directly.
    pub fn new(geo: &Geometry, kernel: &Occupancy) -> Option<DirectKernel> {
        let nr = kernel.dims;
        let max_nsz = geo.source_max[2];
        if nr[2] > 8 * LANES || max_nsz > 8 * LANES || nr[0] * nr[1] > 1 << 16 {
            return None;
        }
        let p = [0, 1, 2].map(|d| nr[d] - 1 - geo.center[d]);
        // Offset `a_z = c·16 + l` takes `v_z = a_z + P_z − z` from a source cell at z: entry
        // `pad + v_z` of its row, zero outside `[0, NR_z)`. `v_z` runs from `P_z − (NS_z − 1)`
        // to `16·chunks − 1 + P_z`, so the rows hold exactly that (small rows keep the tables
        // of runs in the first-level cache).
        let pad = max_nsz.saturating_sub(1 + p[2]);
        let row_len = pad + p[2] + max_nsz.div_ceil(LANES) * LANES;
        let table_len = nr[0] * nr[1] * row_len;
        if MAX_RUN * table_len * std::mem::size_of::<i16>() > MAX_TABLE_BYTES {
            return None;
        }
        let mut tables = vec![0i16; MAX_RUN * table_len];
        // Kernel entries past the row are never read (a source much shorter than the kernel).
        for (r, row) in tables[..table_len].chunks_exact_mut(row_len).enumerate() {
            let (vx, vy) = (r / nr[1], r % nr[1]);
            for vz in 0..nr[2].min(row_len - pad) {
                let occupied = kernel.get(nr[0] - 1 - vx, nr[1] - 1 - vy, nr[2] - 1 - vz);
                row[pad + vz] = if occupied { 5 } else { -1 };
            }
        }
        // R_L[q] = R_{L−1}[q] + W_pad[q − (L − 1)].
        for run in 2..=MAX_RUN {
            let (done, rest) = tables.split_at_mut((run - 1) * table_len);
            let (single, previous) = (&done[..table_len], &done[(run - 2) * table_len..]);
            let shifted = (0..row_len).map(|q| q.checked_sub(run - 1));
            let rows = rest[..table_len].chunks_exact_mut(row_len);
            for (r, row) in rows.enumerate() {
                for (q, from) in shifted.clone().enumerate() {
                    let w = from.map_or(0, |f| single[r * row_len + f]);
                    row[q] = previous[r * row_len + q] + w;
                }
            }
        }
        Some(DirectKernel {
            nr,
            p,
            tables,
            pad,
            row_len,
            table_len,
            max_nsz,
        })
    }

    /// The expected time of a direct correlation of `runs` runs of source cells on a grid of
    /// dims `ns`, in nominal FLOPs of the transforms ([`Geometry::flops`]) that take as long.
    pub fn cost(&self, ns: [usize; 3], runs: usize) -> f64 {
        self.additions(ns, runs) / ADDITIONS_PER_FLOP
    }

    /// Score rows a direct correlation of the cells gathered in `scratch` adds to, each once
    /// per column (an upper bound, as [`Self::additions`]).
    #[cfg(feature = "internals")]
    pub fn rows_touched(&self, scratch: &DirectScratch) -> usize {
        scratch.columns.len() * self.nr[0] * self.nr[1]
    }

    /// 16-offset additions of a direct correlation of `runs` runs of cells on a grid of dims
    /// `ns` (an upper bound: rows that fall outside the offsets are skipped).
    pub fn additions(&self, ns: [usize; 3], runs: usize) -> f64 {
        runs as f64 * (self.nr[0] * self.nr[1]) as f64 * chunks(ns[2]) as f64
    }

    /// Collect the runs of occupied cells along z of the source grid `cells` (cell
    /// `(i, j, k)` at `i·sx + j·sy + k`, dims `ns`; each row's cells past `ns[2]` up to the
    /// row stride `sy` are empty, as [`super::cpu::Workspace::begin`] leaves them) into
    /// `scratch`; returns how many runs there are ([`DirectScratch::cells`] counts the cells).
    pub fn gather<T: Real>(
        cells: &[T],
        strides: [usize; 2],
        ns: [usize; 3],
        scratch: &mut DirectScratch,
    ) -> usize {
        scratch.runs.clear();
        scratch.columns.clear();
        scratch.cells = 0;
        match crate::simd::level() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `simd::level` returns Avx2 or wider only when the CPU has AVX2.
            crate::simd::Level::Avx2 | crate::simd::Level::Avx512 => unsafe {
                gather_avx2(cells, strides, ns, scratch)
            },
            _ => gather_body(cells, strides, ns, scratch),
        }
        scratch.runs.len()
    }

    /// The best offset of the source gathered in `scratch` ([`Self::gather`]) on a grid of
    /// dims `ns`, or `None` when it has more than [`MAX_OCCUPIED`] cells or is too long
    /// along z for this kernel.
    pub fn best(&self, ns: [usize; 3], scratch: &mut DirectScratch) -> Option<BestOffset> {
        if scratch.cells > MAX_OCCUPIED || ns[2] > self.max_nsz {
            return None;
        }
        let width = chunks(ns[2]) * LANES;
        scratch.acc.clear();
        scratch.acc.resize(ns[0] * ns[1] * width, 0);
        // A run of L cells from z reads its kernel rows from `pad + P_z − z` on, in table L − 1.
        let first = self.pad + self.p[2];
        let table_len = self.table_len;
        scratch.starts.clear();
        scratch.starts.extend(
            (scratch.runs.iter())
                .map(|&(z, len)| ((len as usize - 1) * table_len + first - z as usize) as u32),
        );
        let sums = Sums {
            kernel: self,
            ns,
            width,
        };
        match crate::simd::level() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `simd::level` returns Avx2 or wider only when the CPU has AVX2.
            crate::simd::Level::Avx2 | crate::simd::Level::Avx512 => unsafe {
                sums.add_all_avx2(&scratch.columns, &scratch.starts, &mut scratch.acc)
            },
            _ => sums.add_all(&scratch.columns, &scratch.starts, &mut scratch.acc),
        }
        Some(first_best(&scratch.acc, ns, width))
    }
}

/// One rotation's accumulation: the kernel, the source grid's dims and the row width of the
/// scores (16-bit integers, exact whatever the vector width).
struct Sums<'a> {
    kernel: &'a DirectKernel,
    ns: [usize; 3],
    width: usize,
}

impl Sums<'_> {
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn add_all_avx2(&self, columns: &[(u16, u16, u32, u32)], starts: &[u32], acc: &mut [i16]) {
        self.add_all(columns, starts, acc)
    }

    /// Add every column's cells (their row starts `starts`) to the scores `acc`.
    #[inline(always)]
    fn add_all(&self, columns: &[(u16, u16, u32, u32)], starts: &[u32], acc: &mut [i16]) {
        for &(i, j, from, to) in columns {
            let starts = &starts[from as usize..to as usize];
            self.add_column([i as usize, j as usize], starts, acc);
        }
    }

    /// Add the reversed kernel of the cells of column `(i, j)` (their row starts `starts`) to
    /// every offset row it reaches: `a_x = i − P_x + v_x ∈ [0, NS_x)`, likewise y.
    #[inline(always)]
    fn add_column(&self, [i, j]: [usize; 2], starts: &[u32], acc: &mut [i16]) {
        let k = self.kernel;
        let [nrx, nry, _] = k.nr;
        let [px, py, _] = k.p;
        let (ns, width) = (self.ns, self.width);
        // v ≥ P − i (a ≥ 0) and v < NS + P − i (a < NS); i < NS.
        let (vy0, vy1) = (py.saturating_sub(j), nry.min(ns[1] + py - j));
        if vy0 >= vy1 {
            return;
        }
        let ay0 = j + vy0 - py;
        for vx in px.saturating_sub(i)..nrx.min(ns[0] + px - i) {
            let ax = i + vx - px;
            // Rows vy0.. of the kernel (each with the tables of runs after it) and ay0.. of
            // the scores, walked together. Plain loops: an iterator adapter's `for_each` is not
            // inlined into the AVX2 body.
            let out_rows = acc[(ax * ns[1] + ay0) * width..].chunks_exact_mut(width);
            for (vy, out) in (vy0..vy1).zip(out_rows) {
                let kernel_row = &k.tables[(vx * nry + vy) * k.row_len..];
                if width == LANES {
                    add_one_chunk(out, kernel_row, starts);
                } else {
                    add_shifted(out, kernel_row, starts);
                }
            }
        }
    }
}

/// [`add_shifted`] for a row of one chunk (z ≤ 16: every coarse level measured), with
/// fixed-size arrays: half the time on the coarse levels of the human and bunny pairs.
#[inline(always)]
fn add_one_chunk(out: &mut [i16], row: &[i16], starts: &[u32]) {
    let out: &mut [i16; LANES] = out.try_into().expect("one chunk");
    let mut sum = *out;
    for &s in starts {
        let w: &[i16; LANES] = row[s as usize..][..LANES].try_into().expect("16 lanes");
        for l in 0..LANES {
            sum[l] = sum[l].wrapping_add(w[l]);
        }
    }
    *out = sum;
}

/// `out[c·16 + l] += Σ_s row[s + c·16 + l]` over the starts `s` (`row` runs on to the end of
/// the tables).
#[inline(always)]
fn add_shifted(out: &mut [i16], row: &[i16], starts: &[u32]) {
    for (c, lanes) in out.chunks_exact_mut(LANES).enumerate() {
        let row = &row[c * LANES..];
        let mut sum = [0i16; LANES];
        sum.copy_from_slice(lanes);
        for &s in starts {
            let w = &row[s as usize..s as usize + LANES];
            for l in 0..LANES {
                sum[l] = sum[l].wrapping_add(w[l]);
            }
        }
        lanes.copy_from_slice(&sum);
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn gather_avx2<T: Real>(
    cells: &[T],
    strides: [usize; 2],
    ns: [usize; 3],
    scratch: &mut DirectScratch,
) {
    gather_body(cells, strides, ns, scratch)
}

/// [`DirectKernel::gather`]: each row 32 cells at a time as a bit mask (16 at once, a
/// compare and a move-mask, where the row fits), then one entry per run: most of a surface's
/// cells are empty, and the occupied ones come in short runs.
#[inline(always)]
fn gather_body<T: Real>(
    cells: &[T],
    [sx, sy]: [usize; 2],
    ns: [usize; 3],
    scratch: &mut DirectScratch,
) {
    let short = ns[2] <= LANES && sy >= LANES;
    for i in 0..ns[0] {
        for j in 0..ns[1] {
            let start = scratch.runs.len();
            let at = i * sx + j * sy;
            if short {
                let row: &[T; LANES] = cells[at..][..LANES].try_into().expect("16 cells");
                let mask = (0..LANES).fold(0u32, |m, k| m | (u32::from(row[k] != T::zero()) << k));
                push_runs(mask, 0, scratch);
            } else {
                for (c, chunk) in cells[at..][..ns[2]].chunks(32).enumerate() {
                    let mask = (chunk.iter().enumerate())
                        .fold(0u32, |m, (k, v)| m | (u32::from(*v != T::zero()) << k));
                    push_runs(mask, c * 32, scratch);
                }
            }
            let end = scratch.runs.len();
            if end > start {
                (scratch.columns).push((i as u16, j as u16, start as u32, end as u32));
            }
        }
    }
}

/// The runs of the occupied cells `mask` (bit k: cell `z0 + k`), split at [`MAX_RUN`].
#[inline(always)]
fn push_runs(mut mask: u32, z0: usize, scratch: &mut DirectScratch) {
    scratch.cells += mask.count_ones() as usize;
    while mask != 0 {
        let z = mask.trailing_zeros();
        let len = (mask >> z).trailing_ones().min(MAX_RUN as u32);
        scratch.runs.push((z0 as u16 + z as u16, len as u16));
        mask &= !(((1u64 << len) - 1) << z) as u32;
    }
}

/// 16-offset chunks of a row of `nsz` offsets.
fn chunks(nsz: usize) -> usize {
    nsz.div_ceil(LANES)
}

/// The highest score of `acc` over the offsets `[0, NS)` and its first offset in x-major C
/// order.
fn first_best(acc: &[i16], ns: [usize; 3], width: usize) -> BestOffset {
    let mut best = i16::MIN;
    let mut offset = [0; 3];
    for ax in 0..ns[0] {
        for ay in 0..ns[1] {
            let row = &acc[(ax * ns[1] + ay) * width..][..ns[2]];
            let top = row.iter().copied().fold(i16::MIN, i16::max);
            if top > best {
                best = top;
                let az = row.iter().position(|&v| v == top).unwrap_or(0);
                offset = [ax, ay, az];
            }
        }
    }
    BestOffset {
        match_score: i64::from(best),
        offset,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::test_rng::uniform;

    /// The first best offset of `m(a)` computed straight from its definition.
    pub(crate) fn brute_best(src: &Occupancy, kernel: &Occupancy) -> BestOffset {
        let scores = crate::search::cpu::brute_force_scores(src, kernel);
        let best = scores.iter().copied().max().expect("at least one offset");
        let at = scores.iter().position(|&m| m == best).expect("the maximum");
        let [_, ny, nz] = src.dims;
        BestOffset {
            match_score: best,
            offset: [at / (ny * nz), at / nz % ny, at % nz],
        }
    }

    /// A grid of dims `dims` whose cells are occupied with probability `fill`.
    pub(crate) fn random_grid(
        dims: [usize; 3],
        fill: f64,
        next: &mut impl FnMut() -> f64,
    ) -> Occupancy {
        let cells = (0..dims.iter().product()).map(|_| next() < fill).collect();
        Occupancy { dims, cells }
    }

    /// `src` as a grid buffer with rows of `lz ≥ NS₂` cells, as a workspace holds it.
    pub(crate) fn dense(src: &Occupancy, lz: usize) -> (Vec<f32>, [usize; 2]) {
        let [nx, ny, nz] = src.dims;
        let mut cells = vec![0.0f32; nx * ny * lz];
        for i in 0..nx {
            for j in 0..ny {
                for k in 0..nz {
                    if src.get(i, j, k) {
                        cells[(i * ny + j) * lz + k] = 1.0;
                    }
                }
            }
        }
        (cells, [ny * lz, lz])
    }

    #[test]
    fn direct_scores_equal_the_definition_ties_included() {
        let mut next = uniform(20261204);
        for round in 0..60 {
            let mut dim = |lo: usize, hi: usize| lo + (next() * (hi - lo + 1) as f64) as usize;
            // Every fourth kernel much longer along z than its sources.
            let nr = [dim(1, 9), dim(1, 9), dim(1, [20, 20, 20, 60][round % 4])];
            let ns = [dim(1, 10), dim(1, 10), dim(1, [36, 36, 36, 6][round % 4])];
            // Sparse and dense fills; a few all-empty sources (every score 0 or less).
            let fill = [0.0, 0.05, 0.3, 0.9][round % 4];
            let kernel = random_grid(nr, 0.4, &mut next);
            let src = random_grid(ns, fill, &mut next);
            let geo = Geometry::new(nr, [ns[0], ns[1], ns[2] + round % 3]);
            let direct = DirectKernel::new(&geo, &kernel).expect("small kernel");
            let (cells, strides) = dense(&src, ns[2] + 5);
            let mut scratch = DirectScratch::default();
            let runs = DirectKernel::gather(&cells, strides, ns, &mut scratch);
            assert_eq!(scratch.cells(), src.occupied());
            assert!(runs <= scratch.cells() && (runs == 0) == (scratch.cells() == 0));
            let got = direct.best(ns, &mut scratch).expect("few cells");
            assert_eq!(got, brute_best(&src, &kernel), "round {round}");
        }
    }

    #[test]
    fn too_many_cells_or_too_long_a_source_is_declined() {
        let kernel = Occupancy {
            dims: [2, 2, 2],
            cells: vec![true; 8],
        };
        let geo = Geometry::new([2, 2, 2], [200, 40, 40]);
        let direct = DirectKernel::new(&geo, &kernel).expect("small kernel");
        let ns = [200, 40, 40];
        let cells = vec![1.0f32; 200 * 40 * 40];
        let mut scratch = DirectScratch::default();
        // 8 000 columns of 40 cells, each 5 runs of 8.
        let runs = DirectKernel::gather(&cells, [1600, 40], ns, &mut scratch);
        assert_eq!((runs, scratch.cells()), (40_000, 320_000));
        assert!(direct.best(ns, &mut scratch).is_none());
        let long = Geometry::new([2, 2, 2], [4, 4, 200]);
        assert!(DirectKernel::new(&long, &kernel).is_none());
        let wide = Occupancy {
            dims: [100, 100, 8],
            cells: vec![true; 80_000],
        };
        let big = Geometry::new(wide.dims, [100, 100, 16]);
        assert!(DirectKernel::new(&big, &wide).is_none());
    }
}
