//! FFT cross-correlation of a source occupancy grid with the target kernel (SPEC §2 step 4).
//!
//! With PV = 5 and NV = PPV = −1 the score of SPEC §4 splits into a constant and an exact
//! integer *match score*
//!
//! `m(a) = Σ_u O_s[a − C + u] · (6·O_k[u] − 1) = 6·n11(a) − W(a) = 5·n11(a) − n01(a)`,
//!
//! where `O_s`, `O_k` are the 0/1 occupancies of source and kernel, `C = ceil(NR/2) − 1`,
//! `n11` counts kernel-occupied cells over source-occupied cells and `W` the source-occupied
//! cells inside the kernel window. The SPEC score is `|K| − 6·n_k + 6·m(a)` with `|K|` the
//! kernel's cell count and `n_k` its occupied cells. ggs computes `m` for every offset
//! `a ∈ [0, NS)` by one circular correlation of length `L_d ≥ NS_d + floor(NR_d/2)` per axis
//! (no wrap-around reaches a valid offset: padding with −1 contributes to the constant only,
//! so the source needs no explicit padding), rounds it to the integer it equals (the f64
//! error is below 1e-9 here), and picks the best offset in x-major C order.
//!
//! Transforms: r2c along z (only the rows the source occupies), complex along y (only the
//! x-planes the source occupies), complex along x, product with the conjugate kernel
//! spectrum, inverse along x, inverse along y (only the x-planes of valid offsets), c2r along
//! z (only the rows of valid offsets). Lengths are 2·3·5·7-smooth, z even.

use crate::voxel::Occupancy;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;
use std::time::{Duration, Instant};

type C64 = Complex<f64>;

/// `true` if `n` has no prime factor above 7.
pub fn is_7_smooth(mut n: usize) -> bool {
    if n == 0 {
        return false;
    }
    for p in [2, 3, 5, 7] {
        while n % p == 0 {
            n /= p;
        }
    }
    n == 1
}

/// Smallest 2·3·5·7-smooth length ≥ `min` (and even when `even`).
pub fn fast_len(min: usize, even: bool) -> usize {
    let mut n = min.max(1);
    loop {
        if is_7_smooth(n) && (!even || n % 2 == 0) {
            return n;
        }
        n += 1;
    }
}

/// x-planes transformed along y in one batch.
const X_BLOCK: usize = 8;

/// Round to the nearest integer (ties to even) for |v| < 2^51, without a libm call:
/// adding and subtracting 1.5·2^52 leaves no fraction bits.
#[inline(always)]
fn round_small(v: f64) -> f64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    (v + MAGIC) - MAGIC
}

/// Sizes of one correlation problem, all in cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Geometry {
    /// Kernel (target) grid dims NR.
    pub kernel_dims: [usize; 3],
    /// Central kernel voxel C = ceil(NR/2) − 1 (0-based).
    pub center: [usize; 3],
    /// Largest source grid dims NS over all rotations.
    pub source_max: [usize; 3],
    /// FFT lengths L ≥ NS_max + floor(NR/2), 7-smooth, z even.
    pub fft_len: [usize; 3],
}

impl Geometry {
    pub fn new(kernel_dims: [usize; 3], source_max: [usize; 3]) -> Self {
        let mut center = [0; 3];
        let mut fft_len = [0; 3];
        for d in 0..3 {
            center[d] = kernel_dims[d].div_ceil(2) - 1;
            let need = source_max[d].max(kernel_dims[d]) + kernel_dims[d] / 2;
            fft_len[d] = fast_len(need, d == 2);
        }
        Geometry {
            kernel_dims,
            center,
            source_max,
            fft_len,
        }
    }

    /// Complex bins along z of the real transform: `L_z/2 + 1`.
    pub fn kz(&self) -> usize {
        self.fft_len[2] / 2 + 1
    }

    /// Bytes of the kernel spectrum (shared by all workers), saturating at `u64::MAX`.
    pub fn kernel_bytes(&self) -> u64 {
        saturate(self.fft_len[0] as u128 * self.fft_len[1] as u128 * self.kz() as u128 * 16)
    }

    /// Bytes of one worker's buffers, saturating at `u64::MAX`.
    pub fn workspace_bytes(&self) -> u64 {
        let [lx, ly, lz] = self.fft_len.map(|v| v as u128);
        let kz = self.kz() as u128;
        let ax = self.source_max[0].max(self.kernel_dims[0]) as u128;
        let ay = self.source_max[1].max(self.kernel_dims[1]) as u128;
        let real = ax * ay * lz * 8;
        let zspec = ax * ay * kz * 16;
        let grid = ly * kz * lx * 16;
        let slab = X_BLOCK as u128 * kz * ly * 16;
        saturate(real + zspec + grid + slab + 4 * (lx + ly + lz) * 16)
    }
}

/// `v` as u64, or `u64::MAX` when it does not fit.
fn saturate(v: u128) -> u64 {
    u64::try_from(v).unwrap_or(u64::MAX)
}

/// CPU correlator: FFT plans and the conjugate kernel spectrum of one target, shared by all
/// workers (it is `Sync`); each worker brings its own [`Workspace`].
pub struct CpuCorrelator {
    geo: Geometry,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    fft_y: Arc<dyn Fft<f64>>,
    ifft_y: Arc<dyn Fft<f64>>,
    fft_x: Arc<dyn Fft<f64>>,
    ifft_x: Arc<dyn Fft<f64>>,
    /// conj(FFT(6·O_k − 1)) / (Lx·Ly·Lz), layout [y][kz][x].
    kernel: Vec<C64>,
    scratch_len: usize,
    /// Cells of the kernel grid, |K|.
    pub kernel_cells: i64,
    /// Occupied kernel cells, n_k.
    pub kernel_occupied: i64,
}

/// Per-worker buffers, allocated once and reused for every rotation.
pub struct Workspace {
    /// Source occupancy, layout [x < ax][y < ay][z < Lz].
    real: Vec<f64>,
    ay: usize,
    zspec: Vec<C64>,
    grid: Vec<C64>,
    slab: Vec<C64>,
    zrow: Vec<C64>,
    rrow: Vec<f64>,
    scratch: Vec<C64>,
    ns: [usize; 3],
    /// Time spent in the forward transforms (z, y).
    pub t_forward: Duration,
    /// Time spent along x: forward, product with the kernel, inverse.
    pub t_product: Duration,
    /// Time spent in the inverse transforms (y, z) and the argmax.
    pub t_inverse: Duration,
    /// Largest |v − round(v)| seen: how far the FFT output was from the exact integers.
    pub max_rounding_error: f64,
}

impl Workspace {
    /// Start a new source grid of dims `ns` (each ≤ the geometry's `source_max`): clears the
    /// region it will occupy.
    pub fn begin(&mut self, ns: [usize; 3]) {
        let lz = self.rrow.len();
        for x in 0..ns[0] {
            let start = x * self.ay * lz;
            self.real[start..start + ns[1] * lz].fill(0.0);
        }
        self.ns = ns;
    }

    /// The grid buffer with its strides `(buffer, sy, sx)`: cell (i, j, k) is
    /// `buffer[i·sx + j·sy + k]`; write 1.0 to mark it occupied (the fast path for
    /// voxelizing many points).
    #[inline]
    pub fn grid_mut(&mut self) -> (&mut [f64], usize, usize) {
        let lz = self.rrow.len();
        (&mut self.real[..], lz, self.ay * lz)
    }

    /// Mark cell (i, j, k) of the current source grid as occupied.
    #[inline]
    pub fn set(&mut self, i: usize, j: usize, k: usize) {
        let lz = self.rrow.len();
        self.real[(i * self.ay + j) * lz + k] = 1.0;
    }
}

/// Best offset of one rotation: its match score `m` and the offset `a` (cells).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BestOffset {
    pub match_score: i64,
    pub offset: [usize; 3],
}

impl CpuCorrelator {
    /// Plan the transforms for `geo` and compute the kernel spectrum of `kernel`
    /// (whose dims must equal `geo.kernel_dims`).
    pub fn new(geo: Geometry, kernel: &Occupancy) -> Self {
        assert_eq!(kernel.dims, geo.kernel_dims);
        let [lx, ly, lz] = geo.fft_len;
        let mut rp = RealFftPlanner::<f64>::new();
        let r2c = rp.plan_fft_forward(lz);
        let c2r = rp.plan_fft_inverse(lz);
        let mut cp = FftPlanner::<f64>::new();
        let fft_y = cp.plan_fft_forward(ly);
        let ifft_y = cp.plan_fft_inverse(ly);
        let fft_x = cp.plan_fft_forward(lx);
        let ifft_x = cp.plan_fft_inverse(lx);
        let scratch_len = [
            r2c.get_scratch_len(),
            c2r.get_scratch_len(),
            fft_y.get_inplace_scratch_len(),
            ifft_y.get_inplace_scratch_len(),
            fft_x.get_inplace_scratch_len(),
            ifft_x.get_inplace_scratch_len(),
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        let kernel_occupied = kernel.occupied() as i64;
        let kernel_cells = kernel.cells.len() as i64;
        let mut me = CpuCorrelator {
            geo,
            r2c,
            c2r,
            fft_y,
            ifft_y,
            fft_x,
            ifft_x,
            kernel: Vec::new(),
            scratch_len,
            kernel_cells,
            kernel_occupied,
        };
        let mut ws = me.workspace();
        ws.begin(geo.kernel_dims);
        let [nx, ny, nz] = geo.kernel_dims;
        for i in 0..nx {
            for j in 0..ny {
                for k in 0..nz {
                    let v = if kernel.get(i, j, k) { 5.0 } else { -1.0 };
                    ws.real[(i * ws.ay + j) * lz + k] = v;
                }
            }
        }
        me.forward_zy(&mut ws);
        let scale = 1.0 / (lx * ly * lz) as f64;
        let kz = geo.kz();
        for y in 0..ly {
            let block = &mut ws.grid[y * kz * lx..(y + 1) * kz * lx];
            me.fft_x.process_with_scratch(block, &mut ws.scratch);
        }
        me.kernel = ws.grid.iter().map(|c| c.conj() * scale).collect();
        me
    }

    pub fn geometry(&self) -> &Geometry {
        &self.geo
    }

    /// Fresh buffers for one worker.
    pub fn workspace(&self) -> Workspace {
        let [lx, ly, lz] = self.geo.fft_len;
        let kz = self.geo.kz();
        let ax = self.geo.source_max[0].max(self.geo.kernel_dims[0]);
        let ay = self.geo.source_max[1].max(self.geo.kernel_dims[1]);
        Workspace {
            real: vec![0.0; ax * ay * lz],
            ay,
            zspec: vec![C64::default(); ax * ay * kz],
            grid: vec![C64::default(); ly * kz * lx],
            slab: vec![C64::default(); X_BLOCK * kz * ly],
            zrow: vec![C64::default(); kz],
            rrow: vec![0.0; lz],
            scratch: vec![C64::default(); self.scratch_len],
            ns: [0; 3],
            t_forward: Duration::ZERO,
            t_product: Duration::ZERO,
            t_inverse: Duration::ZERO,
            max_rounding_error: 0.0,
        }
    }

    /// r2c along z and FFT along y of the workspace's current grid into `ws.grid`
    /// (layout [y][kz][x]; columns x ≥ NS_x are zero).
    fn forward_zy(&self, ws: &mut Workspace) {
        let [lx, ly, lz] = self.geo.fft_len;
        let kz = self.geo.kz();
        let [nsx, nsy, _] = ws.ns;
        let ay = ws.ay;
        for x in 0..nsx {
            for y in 0..nsy {
                let r = (x * ay + y) * lz;
                let c = (x * ay + y) * kz;
                self.r2c
                    .process_with_scratch(
                        &mut ws.real[r..r + lz],
                        &mut ws.zspec[c..c + kz],
                        &mut ws.scratch,
                    )
                    .expect("r2c lengths match the plan");
            }
        }
        for line in ws.grid.chunks_exact_mut(lx) {
            line[nsx..].fill(C64::default());
        }
        // Blocks of X_BLOCK x-planes: one batched FFT call, and the scatter into the grid
        // writes X_BLOCK neighbouring x values at a time.
        let mut x0 = 0;
        while x0 < nsx {
            let nb = X_BLOCK.min(nsx - x0);
            for b in 0..nb {
                let x = x0 + b;
                for k in 0..kz {
                    let dst = &mut ws.slab[(b * kz + k) * ly..(b * kz + k + 1) * ly];
                    for y in 0..nsy {
                        dst[y] = ws.zspec[(x * ay + y) * kz + k];
                    }
                    dst[nsy..].fill(C64::default());
                }
            }
            self.fft_y
                .process_with_scratch(&mut ws.slab[..nb * kz * ly], &mut ws.scratch);
            for y in 0..ly {
                for k in 0..kz {
                    let base = (y * kz + k) * lx + x0;
                    for b in 0..nb {
                        ws.grid[base + b] = ws.slab[(b * kz + k) * ly + y];
                    }
                }
            }
            x0 += nb;
        }
    }

    /// Correlate the workspace's grid with the kernel and return the best offset: the largest
    /// match score, ties to the lowest offset in x-major C order.
    pub fn best_offset(&self, ws: &mut Workspace) -> BestOffset {
        let mut best = BestOffset {
            match_score: i64::MIN,
            offset: [0; 3],
        };
        self.correlate(ws, |m, a| {
            if m > best.match_score {
                best = BestOffset {
                    match_score: m,
                    offset: a,
                };
            }
        });
        best
    }

    /// Every match score `m(a)`, in x-major C order over `a ∈ [0, NS)` (for tests and tools).
    pub fn all_scores(&self, ws: &mut Workspace) -> Vec<i64> {
        let mut out = Vec::with_capacity(ws.ns.iter().product());
        self.correlate(ws, |m, _| out.push(m));
        out
    }

    fn correlate(&self, ws: &mut Workspace, mut visit: impl FnMut(i64, [usize; 3])) {
        let [lx, ly, lz] = self.geo.fft_len;
        let kz = self.geo.kz();
        let [cx, cy, cz] = self.geo.center;
        let [nsx, nsy, nsz] = ws.ns;
        let t0 = Instant::now();
        self.forward_zy(ws);
        let t1 = Instant::now();
        for y in 0..ly {
            let range = y * kz * lx..(y + 1) * kz * lx;
            let block = &mut ws.grid[range.clone()];
            self.fft_x.process_with_scratch(block, &mut ws.scratch);
            for (g, k) in block.iter_mut().zip(&self.kernel[range]) {
                *g *= *k;
            }
            self.ifft_x.process_with_scratch(block, &mut ws.scratch);
        }
        let t2 = Instant::now();
        let mut max_err = ws.max_rounding_error;
        let mut a0 = 0;
        while a0 < nsx {
            let nb = X_BLOCK.min(nsx - a0);
            let jx = |b: usize| (a0 + b + lx - cx) % lx;
            for y in 0..ly {
                for k in 0..kz {
                    let base = (y * kz + k) * lx;
                    for b in 0..nb {
                        ws.slab[(b * kz + k) * ly + y] = ws.grid[base + jx(b)];
                    }
                }
            }
            self.ifft_y
                .process_with_scratch(&mut ws.slab[..nb * kz * ly], &mut ws.scratch);
            for b in 0..nb {
                let ax = a0 + b;
                for ay in 0..nsy {
                    let jy = (ay + ly - cy) % ly;
                    for k in 0..kz {
                        ws.zrow[k] = ws.slab[(b * kz + k) * ly + jy];
                    }
                    // The result is real: DC and Nyquist bins have no imaginary part.
                    ws.zrow[0].im = 0.0;
                    ws.zrow[kz - 1].im = 0.0;
                    self.c2r
                        .process_with_scratch(&mut ws.zrow, &mut ws.rrow, &mut ws.scratch)
                        .expect("c2r lengths match the plan");
                    for az in 0..nsz {
                        let jz = (az + lz - cz) % lz;
                        let v = ws.rrow[jz];
                        let m = round_small(v);
                        max_err = max_err.max((v - m).abs());
                        visit(m as i64, [ax, ay, az]);
                    }
                }
            }
            a0 += nb;
        }
        ws.max_rounding_error = max_err;
        let t3 = Instant::now();
        ws.t_forward += t1 - t0;
        ws.t_product += t2 - t1;
        ws.t_inverse += t3 - t2;
    }
}

/// Brute-force match scores, straight from the definition (SPEC §2 steps 3–4): pad the
/// source "same" with −1, correlate with the ±1/5 kernel, and subtract the constant
/// `|K| − 6·n_k` then divide by 6. Returns `m(a)` in x-major C order. For tests.
pub fn brute_force_scores(source: &Occupancy, kernel: &Occupancy) -> Vec<i64> {
    let nr = kernel.dims;
    let ns = source.dims;
    let c: Vec<usize> = (0..3).map(|d| nr[d].div_ceil(2) - 1).collect();
    let pv = |o: bool| if o { 5i64 } else { -1 };
    let n_k = kernel.occupied() as i64;
    let k_cells = kernel.cells.len() as i64;
    let mut out = Vec::with_capacity(ns.iter().product());
    for ax in 0..ns[0] {
        for ay in 0..ns[1] {
            for az in 0..ns[2] {
                let mut s = 0i64;
                for ux in 0..nr[0] {
                    for uy in 0..nr[1] {
                        for uz in 0..nr[2] {
                            // Padded index a + u maps to source index a + u − C.
                            let sx = (ax + ux) as isize - c[0] as isize;
                            let sy = (ay + uy) as isize - c[1] as isize;
                            let sz = (az + uz) as isize - c[2] as isize;
                            let inside = sx >= 0
                                && sy >= 0
                                && sz >= 0
                                && (sx as usize) < ns[0]
                                && (sy as usize) < ns[1]
                                && (sz as usize) < ns[2];
                            let sv = if inside {
                                pv(source.get(sx as usize, sy as usize, sz as usize))
                            } else {
                                -1
                            };
                            s += sv * pv(kernel.get(ux, uy, uz));
                        }
                    }
                }
                let m = s - (k_cells - 6 * n_k);
                assert_eq!(m % 6, 0, "SPEC score minus constant is a multiple of 6");
                out.push(m / 6);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn occupancy(dims: [usize; 3], bits: &[bool]) -> Occupancy {
        let n = dims.iter().product();
        Occupancy {
            dims,
            cells: bits.iter().copied().cycle().take(n).collect(),
        }
    }

    fn fft_scores(source: &Occupancy, kernel: &Occupancy) -> Vec<i64> {
        let geo = Geometry::new(kernel.dims, source.dims);
        let c = CpuCorrelator::new(geo, kernel);
        let mut ws = c.workspace();
        ws.begin(source.dims);
        for i in 0..source.dims[0] {
            for j in 0..source.dims[1] {
                for k in 0..source.dims[2] {
                    if source.get(i, j, k) {
                        ws.set(i, j, k);
                    }
                }
            }
        }
        c.all_scores(&mut ws)
    }

    #[test]
    fn smooth_lengths() {
        assert_eq!(fast_len(11, false), 12);
        assert_eq!(fast_len(13, true), 14);
        assert_eq!(fast_len(97, false), 98);
        assert_eq!(fast_len(1, true), 2);
        assert!(is_7_smooth(2 * 3 * 5 * 7 * 7));
        assert!(!is_7_smooth(22));
    }

    #[test]
    fn byte_counts_saturate_instead_of_wrapping() {
        let g = Geometry::new([9_000_000; 3], [9_000_000; 3]);
        assert_eq!(g.kernel_bytes(), u64::MAX);
        assert_eq!(g.workspace_bytes(), u64::MAX);
    }

    #[test]
    fn center_voxel_matches_paper() {
        let g = Geometry::new([4, 5, 1], [3, 3, 3]);
        assert_eq!(g.center, [1, 2, 0]);
        for d in 0..3 {
            assert!(g.fft_len[d] >= g.source_max[d] + g.kernel_dims[d] / 2);
        }
        assert_eq!(g.fft_len[2] % 2, 0);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn fft_equals_brute_force(
            sd in prop::array::uniform3(1usize..7),
            kd in prop::array::uniform3(1usize..7),
            sbits in prop::collection::vec(any::<bool>(), 1..64),
            kbits in prop::collection::vec(any::<bool>(), 1..64),
        ) {
            let s = occupancy(sd, &sbits);
            let k = occupancy(kd, &kbits);
            prop_assert_eq!(fft_scores(&s, &k), brute_force_scores(&s, &k));
        }
    }

    #[test]
    fn workspace_is_reusable_across_sizes() {
        let k = occupancy([5, 4, 6], &[true, false, false, true, false]);
        let big = occupancy([7, 6, 5], &[false, true, true]);
        let small = occupancy([2, 3, 2], &[true, false]);
        let geo = Geometry::new(k.dims, [7, 6, 6]);
        let c = CpuCorrelator::new(geo, &k);
        let mut ws = c.workspace();
        for s in [&big, &small, &big] {
            ws.begin(s.dims);
            for i in 0..s.dims[0] {
                for j in 0..s.dims[1] {
                    for l in 0..s.dims[2] {
                        if s.get(i, j, l) {
                            ws.set(i, j, l);
                        }
                    }
                }
            }
            assert_eq!(c.all_scores(&mut ws), brute_force_scores(s, &k));
        }
        assert!(ws.max_rounding_error < 1e-9);
    }
}
