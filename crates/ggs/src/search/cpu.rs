//! The CPU correlator: FFT cross-correlation of a source occupancy grid with the target
//! kernel (docs/method.md, "The score as one correlation").
//!
//! With PV = 5 and NV = PPV = −1 the score (docs/method.md, "Exact integers") splits into a constant and an exact
//! integer *match score*
//!
//! `m(a) = Σ_u O_s[a − C + u] · (6·O_k[u] − 1) = 6·n11(a) − W(a) = 5·n11(a) − n01(a)`,
//!
//! where `O_s`, `O_k` are the 0/1 occupancies of source and kernel, `C = ceil(NR/2) − 1`,
//! `n11` counts kernel-occupied cells over source-occupied cells and `W` the source-occupied
//! cells inside the kernel window. The score `Σ S_pad·K` is `|K| − 6·n_k + 6·m(a)` with `|K|` the
//! kernel's cell count and `n_k` its occupied cells. ggs computes `m` for every offset
//! `a ∈ [0, NS)` by one circular correlation of length `L_d ≥ NS_d + floor(NR_d/2)` per axis
//! (no wrap-around reaches a valid offset: padding with −1 contributes to the constant only,
//! so the source needs no explicit padding), rounds it to the integer it equals (the f64
//! error is below 1e-9 here), and picks the best offset in x-major C order.
//!
//! Transforms: r2c along z (only the rows the source occupies), complex along y (only the
//! x-planes the source occupies), complex along x, product with the conjugate kernel
//! spectrum, inverse along x, inverse along y (only the x-planes of valid offsets), c2r along
//! z (only the rows of valid offsets); along z, short rows go through one complex FFT call
//! per batch of rows instead of one realfft call per row ([`super::zaxis`]). Lengths are
//! 2·3-smooth (rustfft's AVX kernels are fastest there: see docs/performance.md), z even.
//!
//! Precision: the correlator is generic over the sample type. In f64 the outputs are rounded
//! to the integers they equal ([`CpuCorrelator::best_offset`]). In f32 (twice the SIMD lanes,
//! 2–3× faster transforms) they are approximations with a proven error bound
//! ([`CpuCorrelator::approx_best`], [`CpuCorrelator::error_bound`]); the search re-scores
//! exactly every rotation whose bound reaches the best exact score, so its picks are the f64
//! ones. The kernel's window enters the spectrum or is counted beside it ([`KernelWindow`]).

pub use super::correlator::{ApproxBest, BestOffset, Candidates, MAX_CANDIDATES};
use super::direct::{DirectKernel, DirectScratch};
use super::geometry::X_BLOCK;
pub use super::geometry::Geometry;
use super::grid_view::GridView;
pub use super::grid_view::Real;
use super::sparse::{SparseKernel, SparseScratch};
use super::transpose::transpose;
use super::voxel::Occupancy;
pub use super::window::KernelWindow;
use super::window::WindowCounts;
use super::zaxis::ZAxis;
use rustfft::num_complex::Complex;

use rustfft::{Fft, FftPlanner};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

type C64 = Complex<f64>;

/// [`CpuCorrelator::approx_best`] stops collecting candidate offsets when more than this many
/// reach within twice the bound of the best so far (a flat correlation): too many to keep.
const NEAR_CAP: usize = 4096;

/// What [`CpuCorrelator::scan_near`] found: the largest output and its offset, and whether
/// the offsets near it were all kept.
#[derive(Debug, Clone, Copy)]
pub(super) struct NearScan {
    pub best: f64,
    pub offset: [usize; 3],
    pub complete: bool,
}

/// Round to the nearest integer (ties to even) for |v| < 2^51, without a libm call:
/// adding and subtracting 1.5·2^52 leaves no fraction bits.
#[inline(always)]
fn round_small(v: f64) -> f64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    (v + MAGIC) - MAGIC
}

/// CPU correlator: FFT plans and the conjugate kernel spectrum of one target, shared by all
/// workers (it is `Sync`); each worker brings its own [`Workspace`].
pub struct CpuCorrelator<T: Real = f64> {
    geo: Geometry,
    /// Real transforms along z (per row, or batched for short rows: [`super::zaxis`]).
    z: ZAxis<T>,
    fft_y: Arc<dyn Fft<T>>,
    ifft_y: Arc<dyn Fft<T>>,
    fft_x: Arc<dyn Fft<T>>,
    ifft_x: Arc<dyn Fft<T>>,
    /// The kernel spectrum, computed when a rotation first needs the transforms.
    spectrum: Arc<KernelSpectrum<T>>,
    /// How the window's −1 enters the outputs ([`KernelWindow`]).
    window: KernelWindow,
    scratch_len: usize,
    /// Cells of the kernel grid, |K|.
    pub kernel_cells: i64,
    /// Occupied kernel cells, n_k.
    pub kernel_occupied: i64,
}

/// Per-worker buffers, allocated once and reused for every rotation (`Default`: none yet;
/// [`CpuCorrelator::fit`] or [`CpuCorrelator::fit_grid`] sizes them).
#[derive(Clone, Default)]
pub struct Workspace<T: Real = f64> {
    /// Source occupancy, layout [x < ax][y < ay][z < Lz]. Zero outside the rows
    /// `x < dirty[0]`, `y < dirty[1]`; when `runs_valid`, zero everywhere but at the runs
    /// of the last gather in `direct` (a grid the direct or sparse path scored is intact).
    real: Vec<T>,
    dirty: [usize; 2],
    runs_valid: bool,
    ay: usize,
    /// `Lz`, the length of a row of `real`.
    lz: usize,
    zspec: Vec<Complex<T>>,
    grid: Vec<Complex<T>>,
    slab: Vec<Complex<T>>,
    /// The z spectra of one x-plane of offsets, layout [y < ay][kz], and their inverse
    /// transforms, [y < ay][Lz].
    zrows: Vec<Complex<T>>,
    rrows: Vec<T>,
    /// The batched z transforms' buffer ([`ZAxis::batch_len`]).
    zbatch: Vec<Complex<T>>,
    scratch: Vec<Complex<T>>,
    /// Outputs near the running best of [`CpuCorrelator::approx_best`] and their offsets.
    near_best: Vec<(T, [usize; 3])>,
    /// Σ over the source grid (its occupied cells), from the spectrum's DC bin.
    occupied_estimate: f64,
    /// Counts of the source grid's occupied cells over windows, and one row of them
    /// ([`KernelWindow::Counted`]).
    window: WindowCounts,
    window_row: Vec<u32>,
    ns: [usize; 3],
    /// Time spent in the forward transforms (z, y).
    pub t_forward: Duration,
    /// Time spent along x: forward, product with the kernel, inverse.
    pub t_product: Duration,
    /// Time spent in the inverse transforms (y, z) and the argmax.
    pub t_inverse: Duration,
    /// Buffers of the direct and sparse correlations ([`Workspace::direct_best`]), their
    /// time, and the nominal FLOPs of the transforms they replaced (rounded per rotation).
    direct: DirectScratch,
    sparse: SparseScratch,
    pub t_direct: Duration,
    pub direct_flops: u64,
    /// Largest |v − round(v)| seen: how far the FFT output was from the exact integers.
    pub max_rounding_error: f64,
}

/// The exact correlators a plan may use instead of its transforms, rotation by rotation:
/// direct correlation with dense kernel rows ([`super::direct`], small grids) and sparse
/// correlation over pairs of occupied cells ([`super::sparse`], sparse grids).
#[derive(Debug, Clone)]
pub struct ExactKernels {
    pub dense: Option<DirectKernel>,
    pub sparse: Option<SparseKernel>,
}

impl ExactKernels {
    /// Both, where the geometry allows them.
    pub fn new(geo: &Geometry, kernel: &Occupancy) -> Self {
        ExactKernels {
            dense: DirectKernel::new(geo, kernel),
            sparse: SparseKernel::new(geo, kernel),
        }
    }

    /// Sparse correlation only: for the voxel-size level, whose grids are too large for the
    /// dense rows to win (their tables, up to [`super::direct::MAX_TABLE_BYTES`], would be
    /// built and held for nothing: 3dmatch_demo's peak memory 34 → 36 MiB).
    pub fn sparse_only(geo: &Geometry, kernel: &Occupancy) -> Self {
        ExactKernels {
            dense: None,
            sparse: SparseKernel::new(geo, kernel),
        }
    }
}

impl<T: Real> Workspace<T> {
    /// Start a new source grid of dims `ns` (each ≤ the geometry's `source_max`): clears the
    /// region it will occupy.
    ///
    /// After a grid that the direct or sparse path scored, only its occupied runs are
    /// zeroed (on the generated human pair's voxel-size level, about 500 cells instead of
    /// 33 × 33 rows of 54); otherwise the rows of the new grid (values left beyond them by a
    /// larger grid are never read, and are recorded in `dirty`).
    pub fn begin(&mut self, ns: [usize; 3]) {
        let (sx, sy) = (self.ay * self.lz, self.lz);
        if self.runs_valid {
            let runs = self.direct.runs();
            for &(i, j, from, to) in self.direct.columns() {
                let row = i as usize * sx + j as usize * sy;
                for &(z, len) in &runs[from as usize..to as usize] {
                    self.real[row + z as usize..][..len as usize].fill(T::zero());
                }
            }
            self.dirty = [ns[0], ns[1]];
        } else {
            for x in 0..ns[0] {
                let start = x * sx;
                self.real[start..start + ns[1] * sy].fill(T::zero());
            }
            self.dirty = [self.dirty[0].max(ns[0]), self.dirty[1].max(ns[1])];
        }
        self.runs_valid = false;
        self.ns = ns;
    }

    /// Cells per axis of the current source grid.
    pub(super) fn ns(&self) -> [usize; 3] {
        self.ns
    }

    /// The source's occupied cells as the forward stage measured them (padded for rounding).
    pub(super) fn occupied_estimate(&self) -> f64 {
        self.occupied_estimate
    }

    /// The offsets [`CpuCorrelator::scan_near`] kept, x-major C order.
    pub(super) fn near_offsets(&self) -> impl Iterator<Item = [usize; 3]> + '_ {
        self.near_best.iter().map(|&(_, a)| a)
    }

    /// The occupied cells of the current source grid (not yet transformed), x-major C order.
    pub(super) fn occupied_cells(&self, out: &mut Vec<[usize; 3]>) {
        out.clear();
        let [nx, ny, nz] = self.ns;
        for i in 0..nx {
            for j in 0..ny {
                let row = &self.real[(i * self.ay + j) * self.lz..][..nz];
                for (k, &v) in row.iter().enumerate() {
                    if v != T::zero() {
                        out.push([i, j, k]);
                    }
                }
            }
        }
    }

    /// The grid buffer with its strides: write 1 to a cell to mark it occupied (the fast
    /// path for voxelizing many points).
    #[inline]
    pub fn grid_mut(&mut self) -> GridView<'_, T> {
        let lz = self.lz;
        GridView {
            cells: &mut self.real[..],
            sx: self.ay * lz,
            sy: lz,
        }
    }

    /// Start a new source grid holding the occupancy `src` (for tests).
    #[cfg(test)]
    pub(crate) fn load(&mut self, src: &Occupancy) {
        self.begin(src.dims);
        for i in 0..src.dims[0] {
            for j in 0..src.dims[1] {
                for l in 0..src.dims[2] {
                    if src.get(i, j, l) {
                        self.set(i, j, l);
                    }
                }
            }
        }
    }

    /// The exact best offset of the current source grid by direct or sparse correlation
    /// ([`ExactKernels`]), whichever is expected to take the least time, or `None` when the
    /// transforms of `geo` are (or the chosen one declines a grid whose scores might overflow
    /// 16 bits).
    pub fn direct_best(&mut self, kernels: &ExactKernels, geo: &Geometry) -> Option<BestOffset> {
        let t = Instant::now();
        let (cells, strides, ns) = (&self.real, [self.ay * self.lz, self.lz], self.ns);
        let runs = DirectKernel::gather(cells, strides, ns, &mut self.direct);
        let fft = geo.flops(ns);
        let dense = (kernels.dense.as_ref()).map_or(f64::INFINITY, |d| d.cost(ns, runs));
        let sparse = (kernels.sparse.as_ref()).map_or(f64::INFINITY, |s| s.cost(ns, runs));
        let best = match (&kernels.dense, &kernels.sparse) {
            (Some(d), _) if dense < fft && dense <= sparse => d.best(ns, &mut self.direct),
            (_, Some(s)) if sparse < fft && sparse < dense => {
                s.best(ns, &self.direct, &mut self.sparse)
            }
            _ => None,
        };
        if best.is_some() {
            self.direct_flops += fft.round() as u64;
            // The grid is intact and its occupied cells are the runs just gathered; once the
            // values an earlier, larger grid left beyond it are cleared, they are the only
            // non-zero cells. Zeroing them one by one pays where they are few against the
            // rows' cache lines (16 cells each): a quarter of those or less (the voxel-size
            // level of partial views, not the coarse level's small grids, where one clearing
            // of the rows costs less).
            self.clear_beyond_grid();
            let lines = self.ns[0] * self.ns[1] * self.lz / 16;
            self.runs_valid = 4 * self.direct.runs().len() <= lines;
        }
        self.t_direct += t.elapsed();
        best
    }

    /// Zero the rows outside the current grid that an earlier, larger one may have left
    /// values in (`dirty`), so that only the current grid's rows may hold any.
    fn clear_beyond_grid(&mut self) {
        let (sx, sy) = (self.ay * self.lz, self.lz);
        let ([nx, ny, _], [dx, dy]) = (self.ns, self.dirty);
        if [dx, dy] == [nx, ny] {
            return;
        }
        for x in 0..dx {
            let from = if x < nx { ny } else { 0 };
            if from < dy {
                self.real[x * sx + from * sy..x * sx + dy * sy].fill(T::zero());
            }
        }
        self.dirty = [nx, ny];
    }

    /// The current source grid: its cells (cell `(i, j, k)` at `i·sx + j·sy + k`), the strides
    /// `[sx, sy]` and its dims.
    #[cfg(feature = "internals")]
    pub fn source_grid(&self) -> (&[T], [usize; 2], [usize; 3]) {
        (&self.real, [self.ay * self.lz, self.lz], self.ns)
    }

    /// Mark cell (i, j, k) of the current source grid as occupied.
    #[cfg(any(test, feature = "internals"))]
    #[inline]
    pub fn set(&mut self, i: usize, j: usize, k: usize) {
        let lz = self.lz;
        self.real[(i * self.ay + j) * lz + k] = T::one();
    }
}

/// Relative 2-norm error bound of one 1-D FFT of length `l` in arithmetic with unit
/// roundoff `u`: `16·u·⌈log2 l⌉`. Higham (Accuracy and Stability of Numerical Algorithms,
/// Thm 24.2) proves `log2(l)·η/(1 − log2(l)·η)` with `η = μ + γ4(√2 + μ) ≈ 6.7u` for radix 2
/// with twiddles correct to `μ ≈ u` (rustfft computes them in f64); the factor 16 also
/// covers the radix-3 butterflies and realfft's extra twiddle pass.
fn fft_error(l: usize, u: f64) -> f64 {
    16.0 * u * (usize::BITS - (l.max(2) - 1).leading_zeros()) as f64
}

/// A correlator's conjugate kernel spectrum and its peak, computed on first use, so that a
/// plan whose rotations are all scored by direct or sparse correlation never transforms its
/// kernel or holds its spectrum (a sparse LiDAR target in a large box: hundreds of MB). The
/// values do not depend on when they are computed.
pub(crate) struct KernelSpectrum<T: Real> {
    geo: Geometry,
    window: KernelWindow,
    source: SpectrumSource,
    cell: OnceLock<(Vec<Complex<T>>, f64)>,
}

/// Where a [`KernelSpectrum`] comes from.
enum SpectrumSource {
    /// The transform of this occupancy, in f64, stored as `T`.
    Kernel(Arc<Occupancy>),
    /// Another correlator's f64 spectrum, rounded to `T`.
    Rounded(Arc<KernelSpectrum<f64>>),
    /// None: a correlator that only transforms (the kernel's own planner).
    None,
}

impl<T: Real> KernelSpectrum<T> {
    /// A spectrum a correlator never reads (see [`SpectrumSource::None`]).
    fn none(geo: Geometry) -> Self {
        KernelSpectrum {
            geo,
            window: KernelWindow::InSpectrum,
            source: SpectrumSource::None,
            cell: OnceLock::new(),
        }
    }

    /// The spectrum, layout [y][kz][x], and `max_j |K_j|` unnormalized (for the error bound).
    fn get(&self) -> (&[Complex<T>], f64) {
        let (spectrum, peak) = self.cell.get_or_init(|| match &self.source {
            SpectrumSource::Kernel(kernel) => {
                let (spectrum, peak) = kernel_spectrum(self.geo, kernel, self.window);
                (round_spectrum(spectrum), peak)
            }
            SpectrumSource::Rounded(exact) => {
                let (spectrum, peak) = exact.get();
                (spectrum.iter().map(|&c| round_complex(c)).collect(), peak)
            }
            SpectrumSource::None => unreachable!("a kernel's planner reads no spectrum"),
        });
        (spectrum, *peak)
    }
}

/// `c` rounded to `T` (a spectrum is finite).
fn round_complex<T: Real>(c: C64) -> Complex<T> {
    Complex::new(cast_finite::<T>(c.re), cast_finite::<T>(c.im))
}

/// An f64 spectrum as `T`: mapped in place when `T` is f64 (no second spectrum at the peak),
/// else into a buffer of its own size (an in-place collect would keep the f64 one).
fn round_spectrum<T: Real>(spectrum: Vec<C64>) -> Vec<Complex<T>> {
    if std::mem::size_of::<T>() == std::mem::size_of::<f64>() {
        spectrum.into_iter().map(round_complex).collect()
    } else {
        spectrum.iter().map(|&c| round_complex(c)).collect()
    }
}

/// Conjugate kernel spectrum for `geo` computed in f64 (layout [y][kz][x], scaled by
/// 1/(Lx·Ly·Lz)) and its unnormalized peak magnitude: of `6·O_k − 1` over the window, or of
/// `6·O_k` when `window` is counted.
fn kernel_spectrum(geo: Geometry, kernel: &Occupancy, window: KernelWindow) -> (Vec<C64>, f64) {
    let me = CpuCorrelator::<f64>::plan(geo, Arc::new(KernelSpectrum::none(geo)));
    let [lx, ly, lz] = geo.fft_len;
    let mut ws = me.workspace();
    ws.begin(geo.kernel_dims);
    let [nx, ny, nz] = geo.kernel_dims;
    for i in 0..nx {
        for j in 0..ny {
            for k in 0..nz {
                let v = match (kernel.get(i, j, k), window) {
                    (true, KernelWindow::InSpectrum) => 5.0,
                    (false, KernelWindow::InSpectrum) => -1.0,
                    (true, KernelWindow::Counted) => 6.0,
                    (false, KernelWindow::Counted) => 0.0,
                };
                ws.real[(i * ws.ay + j) * lz + k] = v;
            }
        }
    }
    me.forward_zy(&mut ws);
    let kz = geo.kz();
    for y in 0..ly {
        let block = &mut ws.grid[y * kz * lx..(y + 1) * kz * lx];
        me.fft_x.process_with_scratch(block, &mut ws.scratch);
    }
    // The largest squared magnitude, then one square root (not a `hypot` per bin: that took
    // 3 ms of a 64×64×48 plan), padded by 4 units of roundoff for the rounding of `re² + im²`
    // and the root, so that the peak is never below the largest |K_j|.
    let peak_sq = ws.grid.iter().map(|c| c.norm_sqr()).fold(0.0, f64::max);
    let peak = peak_sq.sqrt() * (1.0 + 4.0 * f64::EPSILON);
    let scale = 1.0 / (lx * ly * lz) as f64;
    // In place: the grid becomes the spectrum (no second grid-sized buffer at the peak).
    for c in ws.grid.iter_mut() {
        *c = c.conj() * scale;
    }
    (std::mem::take(&mut ws.grid), peak)
}

/// `v` as `T` (a spectrum is finite).
fn cast_finite<T: Real>(v: f64) -> T {
    T::from_f64(v).expect("finite spectrum")
}

impl<T: Real> CpuCorrelator<T> {
    /// Plan the transforms for `geo` with the kernel spectrum of `kernel` (whose dims must
    /// equal `geo.kernel_dims`), computed in f64 and stored as `T`, with the window inside
    /// it, when a rotation first needs it.
    pub fn new(geo: Geometry, kernel: &Occupancy) -> Self {
        Self::with_window(geo, kernel, KernelWindow::InSpectrum)
    }

    /// [`Self::new`] with the window entering as `window` says.
    pub fn with_window(geo: Geometry, kernel: &Occupancy, window: KernelWindow) -> Self {
        Self::with_shared_kernel(geo, Arc::new(kernel.clone()), window)
    }

    /// [`Self::with_window`] with a kernel shared with other plans.
    pub fn with_shared_kernel(geo: Geometry, kernel: Arc<Occupancy>, window: KernelWindow) -> Self {
        assert_eq!(kernel.dims, geo.kernel_dims);
        let (cells, occupied) = (kernel.cells.len() as i64, kernel.occupied() as i64);
        let spectrum = KernelSpectrum {
            geo,
            window,
            source: SpectrumSource::Kernel(kernel),
            cell: OnceLock::new(),
        };
        let mut me = Self::plan(geo, Arc::new(spectrum));
        me.window = window;
        me.kernel_occupied = occupied;
        me.kernel_cells = cells;
        me
    }

    /// The same correlator in another sample type: new plans, the f64 kernel spectrum of
    /// `exact` rounded to `T` when first needed (no second kernel transform).
    pub fn from_f64(exact: &CpuCorrelator<f64>) -> Self {
        let spectrum = KernelSpectrum {
            geo: exact.geo,
            window: exact.window,
            source: SpectrumSource::Rounded(exact.spectrum.clone()),
            cell: OnceLock::new(),
        };
        let mut me = Self::plan(exact.geo, Arc::new(spectrum));
        me.window = exact.window;
        me.kernel_occupied = exact.kernel_occupied;
        me.kernel_cells = exact.kernel_cells;
        me
    }

    /// The kernel spectrum and its peak, computed on the first call.
    fn spectrum(&self) -> (&[Complex<T>], f64) {
        self.spectrum.get()
    }

    /// Compute the kernel spectrum now, if it is not yet (before the workers of a pass that
    /// will correlate by the transforms allocate their buffers: the peak memory of a search
    /// stays that of the spectra, then the workspaces).
    pub fn compute_spectrum(&self) {
        self.spectrum.get();
    }

    /// FFT plans for `geo` with the kernel spectrum `spectrum`.
    fn plan(geo: Geometry, spectrum: Arc<KernelSpectrum<T>>) -> Self {
        let [lx, ly, lz] = geo.fft_len;
        let z = ZAxis::plan(lz);
        let mut cp = FftPlanner::<T>::new();
        let fft_y = cp.plan_fft_forward(ly);
        let ifft_y = cp.plan_fft_inverse(ly);
        let fft_x = cp.plan_fft_forward(lx);
        let ifft_x = cp.plan_fft_inverse(lx);
        let scratch_len = [
            z.scratch_len(),
            fft_y.get_inplace_scratch_len(),
            ifft_y.get_inplace_scratch_len(),
            fft_x.get_inplace_scratch_len(),
            ifft_x.get_inplace_scratch_len(),
        ]
        .into_iter()
        .max()
        .unwrap_or(0);
        CpuCorrelator {
            geo,
            z,
            fft_y,
            ifft_y,
            fft_x,
            ifft_x,
            spectrum,
            window: KernelWindow::InSpectrum,
            scratch_len,
            kernel_cells: 0,
            kernel_occupied: 0,
        }
    }

    pub fn geometry(&self) -> &Geometry {
        &self.geo
    }

    /// How the window's −1 enters the outputs.
    pub fn window(&self) -> KernelWindow {
        self.window
    }

    /// Fresh buffers for one worker.
    pub fn workspace(&self) -> Workspace<T> {
        let mut ws = Workspace::default();
        self.fit(&mut ws);
        ws
    }

    /// Size a worker's buffers for this correlator's geometry, keeping their allocations
    /// (a pass over rotations planned at several FFT sizes moves one workspace from size to
    /// size) and the stage times. Every buffer is written before it is read for each rotation
    /// ([`Workspace::begin`] clears the source rows a grid occupies), so nothing stale is
    /// read.
    pub fn fit(&self, ws: &mut Workspace<T>) {
        self.fit_grid(ws);
        self.fit_transforms(ws);
    }

    /// Size the transforms' buffers of a worker whose source grid [`Self::fit_grid`] sized
    /// (the grid is kept): done by the first transform of a rotation, so a worker whose
    /// rotations are all scored by direct or sparse correlation never allocates them.
    fn fit_transforms(&self, ws: &mut Workspace<T>) {
        let [lx, ly, lz] = self.geo.fft_len;
        let kz = self.geo.kz();
        let ay = ws.ay;
        let ax = self.geo.source_max[0].max(self.geo.kernel_dims[0]);
        let zero = Complex::<T>::default();
        ws.zspec.resize(ax * ay * kz, zero);
        ws.grid.resize(ly * kz * lx, zero);
        ws.slab.resize(X_BLOCK * kz * ly, zero);
        ws.zrows.resize(ay * kz, zero);
        ws.rrows.resize(ay * lz, T::zero());
        ws.zbatch.resize(self.z.batch_len(ay), zero);
        ws.scratch.resize(self.scratch_len, zero);
    }

    /// Size only the source grid of a worker's buffers (enough for voxelizing and
    /// [`CpuCorrelator::exact_among`], not for correlating); returns the grid's y extent.
    pub fn fit_grid(&self, ws: &mut Workspace<T>) -> usize {
        let lz = self.geo.fft_len[2];
        let ax = self.geo.source_max[0].max(self.geo.kernel_dims[0]);
        let ay = self.geo.source_max[1].max(self.geo.kernel_dims[1]);
        if (ws.ay, ws.lz) != (ay, lz) || ws.real.len() != ax * ay * lz {
            // A new layout: the old one's values would sit anywhere in it.
            ws.real.clear();
            ws.dirty = [0, 0];
            ws.runs_valid = false;
        }
        ws.real.resize(ax * ay * lz, T::zero());
        ws.ay = ay;
        ws.lz = lz;
        ws.ns = [0; 3];
        ay
    }

    /// r2c along z and FFT along y of the workspace's current grid into `ws.grid`
    /// (layout [y][kz][x]; columns x ≥ NS_x are zero).
    fn forward_zy(&self, ws: &mut Workspace<T>) {
        let [lx, ly, lz] = self.geo.fft_len;
        let kz = self.geo.kz();
        let [nsx, nsy, _] = ws.ns;
        let ay = ws.ay;
        for x in 0..nsx {
            let (r, c) = (x * ay * lz, x * ay * kz);
            self.z.forward(
                &mut ws.real[r..r + nsy * lz],
                &mut ws.zspec[c..c + nsy * kz],
                &mut ws.zbatch,
                &mut ws.scratch,
            );
        }
        for line in ws.grid.chunks_exact_mut(lx) {
            line[nsx..].fill(Complex::default());
        }
        // Blocks of X_BLOCK x-planes: one batched FFT call, and the scatter into the grid
        // writes X_BLOCK neighbouring x values at a time.
        let mut x0 = 0;
        while x0 < nsx {
            let nb = X_BLOCK.min(nsx - x0);
            for b in 0..nb {
                let x = x0 + b;
                let slab = &mut ws.slab[b * kz * ly..(b + 1) * kz * ly];
                transpose(&ws.zspec[x * ay * kz..], kz, slab, ly, nsy, kz);
                for line in slab.chunks_exact_mut(ly) {
                    line[nsy..].fill(Complex::default());
                }
            }
            self.fft_y
                .process_with_scratch(&mut ws.slab[..nb * kz * ly], &mut ws.scratch);
            // Per k: the nb slab lines (x0 + b, k, ·) become column x0 + b of the grid lines
            // (·, k, x).
            for k in 0..kz {
                let (src, dst) = (&ws.slab[k * ly..], &mut ws.grid[k * lx + x0..]);
                transpose(src, kz * ly, dst, kz * lx, nb, ly);
            }
            x0 += nb;
        }
    }

    /// Bound on `max_a |computed(a) − m(a)|` for a source grid with `occupied` occupied cells:
    /// `(2·ε_F + 4u)·√occupied·max_j|K_j|` with `ε_F = Σ_d ε(L_d)` the 3-D transform's
    /// relative error (`fft_error`), `u` the unit roundoff and `K` the unnormalized kernel
    /// spectrum. Derivation: `‖x‖₂ = √occupied`; the forward transform errs by `ε_F·‖X‖₂`,
    /// the product (kernel rounded to `T`, one complex multiply) by `4u·‖X‖₂·max|K|`, the
    /// inverse by `ε_F` of its result, and the 2-norm of the error bounds its largest entry.
    /// Doubled for second-order terms. With the window counted, subtracting `W(a)` (an
    /// integer up to `occupied`, rounded to `T`) from an output of magnitude up to
    /// `6·occupied + bound` adds `u` of each: `u·(7·occupied + bound)`, doubled.
    pub fn error_bound(&self, occupied: f64) -> f64 {
        let u = T::UNIT_ROUNDOFF;
        let eps: f64 = self.geo.fft_len.iter().map(|&l| fft_error(l, u)).sum();
        let occupied = occupied.max(0.0);
        let bound = 2.0 * (2.0 * eps + 4.0 * u) * occupied.sqrt() * self.spectrum().1;
        match self.window {
            KernelWindow::InSpectrum => bound,
            KernelWindow::Counted => bound + 2.0 * u * (7.0 * occupied + bound),
        }
    }

    /// Correlate in `T` and return the largest computed output with its error bound and, when
    /// `keep_candidates` (an exact re-scoring may follow), the offsets whose outputs reach
    /// within twice the bound of it ([`Candidates`]).
    pub fn approx_best(&self, ws: &mut Workspace<T>, keep_candidates: bool) -> ApproxBest {
        self.stage_forward(ws);
        self.stage_product(ws);
        let bound = self.error_bound(ws.occupied_estimate);
        self.approx_scan(ws, bound, keep_candidates)
    }

    /// The inverse stage of [`Self::approx_best`], given the outputs' error bound.
    fn approx_scan(&self, ws: &mut Workspace<T>, bound: f64, keep_candidates: bool) -> ApproxBest {
        let cap = if keep_candidates { NEAR_CAP } else { 0 };
        let scan = self.scan_near(ws, bound, f64::NEG_INFINITY, cap);
        let candidates = if scan.complete {
            Candidates::of(ws.near_best.iter().map(|&(_, a)| a))
        } else {
            Candidates::NONE
        };
        ws.near_best.clear();
        ApproxBest {
            value: scan.best,
            error_bound: bound,
            offset: scan.offset,
            candidates,
        }
    }

    /// The inverse stage with the largest output, its offset, and in `ws.near_best` (x-major
    /// C order) every offset whose output reaches `t − bound` with
    /// `t = max(at_least, best − bound)`, unless more than `cap` do (`complete: false`).
    ///
    /// Every offset where the exact best `M` is reached when `M ≥ t` is among them:
    /// `computed(a') ≥ M − bound ≥ t − bound`. And `M ≥ best − bound` always (the output of
    /// `best` is within `bound` of its exact score), so with `at_least = −∞` they settle `M`.
    pub(super) fn scan_near(
        &self,
        ws: &mut Workspace<T>,
        bound: f64,
        at_least: f64,
        cap: usize,
    ) -> NearScan {
        let mut best = T::neg_infinity();
        let mut offset = [0; 3];
        // Outputs are kept while they reach the floor of the best so far (which only rises,
        // so the final list holds the final one's). Compared in f64, where every T output is
        // exact, with the floor lowered by more than its rounding: keeping more is safe,
        // missing one is not.
        let floor_of = |best: T| {
            let t = at_least.max(best.to_f64().unwrap_or(f64::NAN) - bound);
            (t - bound) - (t.abs() + 2.0 * bound) * 1e-12
        };
        let reaches = |v: T, floor: f64| v.to_f64().is_none_or(|v| v >= floor || v.is_nan());
        let mut near = std::mem::take(&mut ws.near_best);
        near.clear();
        // Pruned when it doubles (linear work in all), given up beyond `cap`.
        let mut prune_at = 4 * MAX_CANDIDATES;
        let mut gave_up = cap == 0;
        self.stage_inverse_rows(ws, |[ax, ay], first, second| {
            // A branch-free maximum per row; the position only when it wins.
            let m = row_max(first).max(row_max(second));
            if m > best {
                best = m;
                let az = first
                    .iter()
                    .chain(second)
                    .position(|&v| v == m)
                    .unwrap_or(0);
                offset = [ax, ay, az];
            }
            let floor = floor_of(best);
            if !gave_up && reaches(m, floor) {
                for (az, &v) in first.iter().chain(second).enumerate() {
                    if reaches(v, floor) {
                        near.push((v, [ax, ay, az]));
                    }
                }
                if near.len() > prune_at {
                    near.retain(|&(v, _)| reaches(v, floor));
                    gave_up = near.len() > cap;
                    prune_at = (2 * near.len()).max(4 * MAX_CANDIDATES);
                }
            }
        });
        let floor = floor_of(best);
        near.retain(|&(v, _)| reaches(v, floor));
        let complete = !gave_up && near.len() <= cap;
        if !complete {
            near.clear();
        }
        ws.near_best = near;
        NearScan {
            best: best.to_f64().unwrap_or(f64::NAN),
            offset,
            complete,
        }
    }

    /// The best offset by exact match score when the outputs' error bound is below ½: each
    /// output then rounds to the integer it approximates, so the largest rounded output is
    /// the exact maximum and its first offset (x-major C order) the exact argmax, whatever
    /// the FFT's rounding (plan size, SIMD width). Returned with a bound of 0. With a larger
    /// bound, [`Self::approx_best`] without candidates.
    pub fn rounded_best(&self, ws: &mut Workspace<T>) -> ApproxBest {
        self.stage_forward(ws);
        self.stage_product(ws);
        let bound = self.error_bound(ws.occupied_estimate);
        if bound.is_nan() || bound >= 0.5 {
            return self.approx_scan(ws, bound, false);
        }
        let round = |v: T| round_small(v.to_f64().unwrap_or(f64::NAN));
        let mut best = f64::NEG_INFINITY;
        let mut offset = [0; 3];
        self.stage_inverse_rows(ws, |[ax, ay], first, second| {
            // Rounding is monotonic: the rounded maximum is the maximum of the rounded.
            let m = round(row_max(first).max(row_max(second)));
            if m > best {
                best = m;
                let az = first.iter().chain(second).position(|&v| round(v) == m);
                offset = [ax, ay, az.unwrap_or(0)];
            }
        });
        ApproxBest {
            value: best,
            error_bound: 0.0,
            offset,
            candidates: Candidates::NONE,
        }
    }

    /// Every output of the correlation, in x-major C order over the valid offsets.
    fn correlate(&self, ws: &mut Workspace<T>, visit: impl FnMut(T, [usize; 3])) {
        self.stage_forward(ws);
        self.stage_product(ws);
        self.stage_inverse(ws, visit);
    }

    /// Stage 1: r2c along z and FFT along y of the source grid (pruned to the occupied
    /// rows and planes). Destroys the source grid (realfft uses it as scratch).
    pub fn stage_forward(&self, ws: &mut Workspace<T>) {
        // The spectrum before the buffers: the first transform of a pass computes it while no
        // worker holds transform buffers yet (the others wait for it), so the peak is that of
        // computing it up front.
        self.spectrum();
        self.fit_transforms(ws);
        let t0 = Instant::now();
        let nsx = ws.ns[0];
        if self.window == KernelWindow::Counted {
            let (real, ay, lz) = (&ws.real, ws.ay, ws.lz);
            ws.window
                .build(ws.ns, |x, y, z| real[(x * ay + y) * lz + z] != T::zero());
        }
        self.forward_zy(ws);
        // DC bins along y and z: per-x sums of the source grid. Their total is the number of
        // occupied cells (up to rounding: pad it for the error bound).
        let dc: f64 = ws.grid[..nsx]
            .iter()
            .map(|c| c.re.to_f64().unwrap_or(f64::INFINITY).abs())
            .sum();
        ws.occupied_estimate = dc * (1.0 + 1e-4) + 1.0;
        ws.t_forward += t0.elapsed();
    }

    /// Stage 2: FFT along x, product with the conjugate kernel spectrum, inverse along x.
    pub fn stage_product(&self, ws: &mut Workspace<T>) {
        let t1 = Instant::now();
        let [lx, ly, _] = self.geo.fft_len;
        let kz = self.geo.kz();
        let kernel = self.spectrum().0;
        for y in 0..ly {
            let range = y * kz * lx..(y + 1) * kz * lx;
            let block = &mut ws.grid[range.clone()];
            self.fft_x.process_with_scratch(block, &mut ws.scratch);
            multiply_spectra(block, &kernel[range]);
            self.ifft_x.process_with_scratch(block, &mut ws.scratch);
        }
        ws.t_product += t1.elapsed();
    }

    /// Stage 3: inverse FFT along y and c2r along z (pruned to the valid offsets), each
    /// output handed to `visit` in x-major C order of the offsets.
    pub fn stage_inverse(&self, ws: &mut Workspace<T>, mut visit: impl FnMut(T, [usize; 3])) {
        self.stage_inverse_rows(ws, |[ax, ay], first, second| {
            for (az, &v) in first.iter().chain(second).enumerate() {
                visit(v, [ax, ay, az]);
            }
        });
    }

    /// [`Self::stage_inverse`] a row at a time: `visit_row([ax, ay], first, second)` gets the
    /// outputs of offsets `(ax, ay, 0..NS_z)` as two slices, `first` then `second`.
    fn stage_inverse_rows(
        &self,
        ws: &mut Workspace<T>,
        mut visit_row: impl FnMut([usize; 2], &[T], &[T]),
    ) {
        let [lx, ly, lz] = self.geo.fft_len;
        let kz = self.geo.kz();
        let [cx, cy, cz] = self.geo.center;
        let [nsx, nsy, nsz] = ws.ns;
        let t2 = Instant::now();
        // Offset a maps to circular index (a − C) mod L: the valid offsets of one axis are
        // two contiguous runs of the output, [L − C, L) then [0, NS − C).
        let wrap = |a: usize, c: usize, l: usize| if a >= c { a - c } else { a + l - c };
        let first = cz.min(nsz);
        let (z_tail, z_head) = ((lz - cz)..(lz - cz + first), 0..(nsz - first));
        let mut a0 = 0;
        while a0 < nsx {
            let nb = X_BLOCK.min(nsx - a0);
            // Offsets a0 + b read grid columns wrap(a0 + b): at most two contiguous runs.
            let mut b0 = 0;
            while b0 < nb {
                let j0 = wrap(a0 + b0, cx, lx);
                let run = (nb - b0).min(lx - j0);
                for k in 0..kz {
                    let src = &ws.grid[k * lx + j0..];
                    let dst = &mut ws.slab[(b0 * kz + k) * ly..];
                    transpose(src, kz * lx, dst, kz * ly, ly, run);
                }
                b0 += run;
            }
            self.ifft_y
                .process_with_scratch(&mut ws.slab[..nb * kz * ly], &mut ws.scratch);
            for b in 0..nb {
                let ax = a0 + b;
                // Offsets ay read slab columns wrap(ay): [L − C, L) for ay < C, then from 0.
                let slab = &ws.slab[b * kz * ly..(b + 1) * kz * ly];
                let below = cy.min(nsy);
                transpose(&slab[ly - cy..], ly, &mut ws.zrows, kz, kz, below);
                let rest = &mut ws.zrows[below * kz..];
                transpose(slab, ly, rest, kz, kz, nsy - below);
                // The result is real (the z axis takes the DC and Nyquist bins as real).
                self.z.inverse(
                    &mut ws.zrows[..nsy * kz],
                    &mut ws.rrows[..nsy * lz],
                    &mut ws.zbatch,
                    &mut ws.scratch,
                );
                for ay in 0..nsy {
                    let row = &mut ws.rrows[ay * lz..(ay + 1) * lz];
                    if self.window == KernelWindow::Counted {
                        let w = &mut ws.window_row;
                        w.resize(nsz, 0);
                        ws.window
                            .row(ax, ay, self.geo.center, self.geo.kernel_dims, w);
                        let (tail, head) = w.split_at(first);
                        subtract_counts(&mut row[z_tail.clone()], tail);
                        subtract_counts(&mut row[z_head.clone()], head);
                    }
                    visit_row([ax, ay], &row[z_tail.clone()], &row[z_head.clone()]);
                }
            }
            a0 += nb;
        }
        ws.t_inverse += t2.elapsed();
    }
}

/// `out[i] ← out[i] − counts[i]` (`W(a)` taken off the outputs of a counted window).
#[inline(always)]
fn subtract_counts<T: Real>(out: &mut [T], counts: &[u32]) {
    for (v, &w) in out.iter_mut().zip(counts) {
        *v = *v - T::from_u32(w).unwrap_or_else(T::nan);
    }
}

/// The largest entry of `r` (−∞ for none): a branch-free fold the compiler vectorizes.
#[inline(always)]
fn row_max<T: Real>(r: &[T]) -> T {
    r.iter()
        .fold(T::neg_infinity(), |m, &v| if v > m { v } else { m })
}

/// `a[i] ← a[i]·b[i]` (complex), compiled for the vector unit of [`crate::simd::level`].
fn multiply_spectra<T: Real>(a: &mut [Complex<T>], b: &[Complex<T>]) {
    #[cfg(target_arch = "x86_64")]
    match crate::simd::level() {
        // SAFETY: `simd::level` returns Avx512 only when the CPU has AVX-512F.
        crate::simd::Level::Avx512 => return unsafe { multiply_spectra_avx512(a, b) },
        // SAFETY: Avx2 only when the CPU has AVX2.
        crate::simd::Level::Avx2 => return unsafe { multiply_spectra_avx2(a, b) },
        crate::simd::Level::Scalar => {}
    }
    multiply_spectra_body(a, b)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn multiply_spectra_avx512<T: Real>(a: &mut [Complex<T>], b: &[Complex<T>]) {
    multiply_spectra_body(a, b)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn multiply_spectra_avx2<T: Real>(a: &mut [Complex<T>], b: &[Complex<T>]) {
    multiply_spectra_body(a, b)
}

/// Written out (no FMA: Rust never contracts, so every target gives the same bits).
#[inline(always)]
fn multiply_spectra_body<T: Real>(a: &mut [Complex<T>], b: &[Complex<T>]) {
    for (x, y) in a.iter_mut().zip(b) {
        let re = x.re * y.re - x.im * y.im;
        let im = x.re * y.im + x.im * y.re;
        *x = Complex::new(re, im);
    }
}

impl CpuCorrelator<f64> {
    /// Correlate the workspace's grid with the kernel and return the best offset: the largest
    /// match score, ties to the lowest offset in x-major C order.
    pub fn best_offset(&self, ws: &mut Workspace<f64>) -> BestOffset {
        let mut best = BestOffset {
            match_score: i64::MIN,
            offset: [0; 3],
        };
        self.exact_scores(ws, |m, a| {
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
    #[cfg(any(test, feature = "internals"))]
    pub fn all_scores(&self, ws: &mut Workspace<f64>) -> Vec<i64> {
        let mut out = Vec::with_capacity(ws.ns.iter().product());
        self.exact_scores(ws, |m, _| out.push(m));
        out
    }

    /// The outputs rounded to the integers they equal; records the largest rounding.
    fn exact_scores(&self, ws: &mut Workspace<f64>, mut visit: impl FnMut(i64, [usize; 3])) {
        let mut max_err = ws.max_rounding_error;
        self.correlate(ws, |v, a| {
            let m = round_small(v);
            max_err = max_err.max((v - m).abs());
            visit(m as i64, a);
        });
        ws.max_rounding_error = max_err;
    }
}

/// Brute-force match scores, straight from the definition (docs/method.md, "The score"): pad the
/// source "same" with −1, correlate with the ±1/5 kernel, and subtract the constant
/// `|K| − 6·n_k` then divide by 6. Returns `m(a)` in x-major C order. For tests.
#[cfg(any(test, feature = "internals"))]
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
                assert_eq!(m % 6, 0, "score minus constant is a multiple of 6");
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

    fn random_occupancy(dims: [usize; 3], p: f64, next: &mut dyn FnMut() -> f64) -> Occupancy {
        Occupancy::random(dims, p, next)
    }

    fn fft_scores(source: &Occupancy, kernel: &Occupancy) -> Vec<i64> {
        fft_scores_with(source, kernel, KernelWindow::InSpectrum)
    }

    fn fft_scores_with(source: &Occupancy, kernel: &Occupancy, w: KernelWindow) -> Vec<i64> {
        let geo = Geometry::new(kernel.dims, source.dims);
        let c = CpuCorrelator::with_window(geo, kernel, w);
        let mut ws = c.workspace();
        ws.load(source);
        c.all_scores(&mut ws)
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

        #[test]
        fn fft_with_the_window_counted_equals_brute_force(
            sd in prop::array::uniform3(1usize..8),
            kd in prop::array::uniform3(1usize..8),
            sbits in prop::collection::vec(any::<bool>(), 1..64),
            kbits in prop::collection::vec(any::<bool>(), 1..64),
        ) {
            let s = occupancy(sd, &sbits);
            let k = occupancy(kd, &kbits);
            let counted = fft_scores_with(&s, &k, KernelWindow::Counted);
            prop_assert_eq!(counted, brute_force_scores(&s, &k));
        }
    }

    /// With the window counted, a sparse kernel's f32 bound is several times smaller (the
    /// spectrum's peak is `6·n_k`, not `|K| − 6·n_k`), and still holds.
    #[test]
    fn counting_the_window_shrinks_the_bound_of_a_sparse_kernel() {
        let mut next = crate::test_rng::uniform(5);
        let k = random_occupancy([24, 20, 16], 0.02, &mut next);
        let src = random_occupancy([14, 15, 13], 0.05, &mut next);
        let geo = Geometry::new(k.dims, src.dims);
        let exact = brute_force_scores(&src, &k);
        let max = *exact.iter().max().unwrap() as f64;
        let mut bounds = Vec::new();
        for w in [KernelWindow::InSpectrum, KernelWindow::Counted] {
            let c = CpuCorrelator::<f32>::with_window(geo, &k, w);
            let mut ws = c.workspace();
            ws.load(&src);
            let a = c.approx_best(&mut ws, false);
            assert!((a.value - max).abs() <= a.error_bound, "{w:?}");
            bounds.push(a.error_bound);
        }
        assert!(bounds[1] * 4.0 < bounds[0], "bounds {bounds:?}");
    }

    /// The f32 pass's candidates hold every offset where the exact best is reached, and the
    /// sparse exact score among them equals the f64 correlation's best offset (value and
    /// offset, ties included), on random grids and on grids built to tie.
    #[test]
    fn the_exact_best_among_the_candidates_is_the_f64_best() {
        let mut next = crate::test_rng::uniform(77);
        let mut kept = 0;
        for case in 0..12 {
            let n = 5 + 2 * case;
            let (kd, sd) = ([n, n + 2, n - 1], [n - 2, n + 1, n]);
            let (mut k, mut src) = (
                random_occupancy(kd, 0.3, &mut next),
                random_occupancy(sd, 0.25, &mut next),
            );
            if case % 3 == 2 {
                // One source cell and three kernel cells: the best (5) is reached at three
                // offsets, and the tie goes to the first.
                k.cells.iter_mut().for_each(|c| *c = false);
                src.cells.iter_mut().for_each(|c| *c = false);
                let c = Geometry::new(kd, sd).center;
                for d in [[0, 0, 0], [1, 0, 0], [0, 1, 0]] {
                    let u = [0, 1, 2].map(|a| c[a] + d[a]);
                    k.cells[(u[0] * kd[1] + u[1]) * kd[2] + u[2]] = true;
                }
                let x = sd.map(|n| n / 2);
                src.cells[(x[0] * sd[1] + x[1]) * sd[2] + x[2]] = true;
            }
            let scores = fft_scores(&src, &k);
            let max = *scores.iter().max().unwrap();
            let geo = Geometry::new(k.dims, src.dims);
            let exact = CpuCorrelator::<f64>::new(geo, &k);
            let mut ws64 = exact.workspace();
            ws64.load(&src);
            let want = exact.best_offset(&mut ws64);
            let c = CpuCorrelator::<f32>::from_f64(&exact);
            let mut ws = c.workspace();
            ws.load(&src);
            let approx = c.approx_best(&mut ws, true);
            // Without candidates (a ranking pass): the same best, no offsets kept.
            ws.load(&src);
            let ranking = c.approx_best(&mut ws, false);
            assert_eq!(
                (ranking.value, ranking.offset),
                (approx.value, approx.offset)
            );
            assert_eq!(ranking.candidates, Candidates::NONE);
            let Some(offsets) = approx.candidates.offsets() else {
                continue;
            };
            let offsets: Vec<[usize; 3]> = offsets.collect();
            let ties = scores.iter().filter(|&&m| m == max).count();
            if case % 3 == 2 {
                assert!(ties >= 2, "case {case}: {ties} offset(s) reach the best");
            }
            let flat = |a: [usize; 3]| (a[0] * sd[1] + a[1]) * sd[2] + a[2];
            for (i, &m) in scores.iter().enumerate() {
                if m == max {
                    assert!(offsets.iter().any(|&a| flat(a) == i), "case {case}");
                }
            }
            ws.load(&src);
            assert_eq!(
                c.exact_among(&ws, &k, offsets.into_iter()),
                want,
                "case {case}"
            );
            kept += 1;
        }
        assert!(kept >= 6, "candidates kept in {kept} cases only");
    }

    /// The rounded best equals the f64 correlation's best (value and first offset, ties
    /// included) at the plan the source needs and at a larger one, whenever its bound is
    /// below ½.
    #[test]
    fn the_rounded_best_is_the_exact_best_at_any_plan_size() {
        let mut next = crate::test_rng::uniform(91);
        let mut exact_cases = 0;
        for case in 0..10 {
            let n = 4 + 2 * case;
            let (kd, sd) = ([n + 1, n, n + 2], [n, n + 2, n - 1]);
            // Sparse sources tie often: the first offset of the best score must win.
            let (k, src) = (
                random_occupancy(kd, 0.15, &mut next),
                random_occupancy(sd, 0.05, &mut next),
            );
            let geo = Geometry::new(k.dims, src.dims);
            let exact = CpuCorrelator::<f64>::new(geo, &k);
            let mut ws64 = exact.workspace();
            ws64.load(&src);
            let want = exact.best_offset(&mut ws64);
            // The plan the source needs, and one planned for a source twice as large.
            let big = Geometry::new(k.dims, sd.map(|d| 2 * d));
            let larger = Geometry::with_fft_len(k.dims, big.source_max, big.fft_len);
            for g in [geo, larger] {
                let c = CpuCorrelator::<f32>::new(g, &k);
                let mut ws = c.workspace();
                ws.load(&src);
                let got = c.rounded_best(&mut ws);
                if got.error_bound > 0.0 {
                    // A bound of ½ or more: the approximate best, within its bound.
                    assert!(got.error_bound >= 0.5);
                    assert!((got.value - want.match_score as f64).abs() <= got.error_bound);
                    continue;
                }
                exact_cases += 1;
                assert_eq!(got.value, want.match_score as f64, "case {case}");
                assert_eq!(got.offset, want.offset, "case {case}");
            }
        }
        assert!(
            exact_cases >= 12,
            "most cases have a bound below ½ ({exact_cases})"
        );
    }

    /// A flat correlation (an empty source: every output ties at 0) keeps no candidates, so
    /// a re-scoring correlates again; collecting stops early instead of growing with the grid.
    #[test]
    fn a_flat_correlation_keeps_no_candidates() {
        let k = Occupancy {
            dims: [20, 20, 20],
            cells: (0..8000).map(|i| i % 7 == 0).collect(),
        };
        let src = Occupancy {
            dims: [40, 40, 40],
            cells: vec![false; 64000],
        };
        let geo = Geometry::new(k.dims, src.dims);
        let c = CpuCorrelator::<f32>::new(geo, &k);
        let mut ws = c.workspace();
        ws.load(&src);
        let approx = c.approx_best(&mut ws, true);
        assert_eq!(approx.candidates, Candidates::NONE);
        assert!(ws.near_best.is_empty());
    }

    /// f32 outputs stay within the proven bound of the exact scores, on every offset, and
    /// the bound is small enough to be useful (far below the score range).
    #[test]
    fn f32_outputs_are_within_the_error_bound() {
        let mut next = crate::test_rng::uniform(41);
        for case in 0..6 {
            let n = 6 + 4 * case;
            let kd = [n, n + 3, n - 2];
            let sd = [n - 1, n + 1, n];
            let k = random_occupancy(kd, 0.3, &mut next);
            let src = random_occupancy(sd, 0.2, &mut next);
            let exact = fft_scores(&src, &k);
            let geo = Geometry::new(k.dims, src.dims);
            let c = CpuCorrelator::<f32>::new(geo, &k);
            let mut ws = c.workspace();
            ws.load(&src);
            let mut values = Vec::new();
            c.correlate(&mut ws, |v, _| values.push(v as f64));
            let bound = c.error_bound(ws.occupied_estimate);
            let occupied = src.occupied() as f64;
            assert!(ws.occupied_estimate >= occupied && ws.occupied_estimate < occupied + 2.0);
            let worst = values
                .iter()
                .zip(&exact)
                .map(|(v, &m)| (v - m as f64).abs())
                .fold(0.0, f64::max);
            assert!(worst <= bound, "case {case}: error {worst} > bound {bound}");
            assert!(bound < 0.05 * (5 * k.occupied()) as f64, "bound {bound}");
            let approx = c.approx_best(&mut ws, true);
            let best = *exact.iter().max().unwrap() as f64;
            assert!(approx.lower() <= best && best <= approx.upper());
        }
    }

    #[test]
    fn from_f64_equals_a_fresh_correlator() {
        let k = occupancy([5, 4, 6], &[true, false, false, true, false]);
        let geo = Geometry::new(k.dims, [7, 6, 6]);
        for w in [KernelWindow::InSpectrum, KernelWindow::Counted] {
            let exact = CpuCorrelator::<f64>::with_window(geo, &k, w);
            let (a, b) = (
                CpuCorrelator::<f32>::with_window(geo, &k, w),
                CpuCorrelator::<f32>::from_f64(&exact),
            );
            assert_eq!(a.spectrum().0, b.spectrum().0);
            assert_eq!((a.spectrum().1, a.window), (b.spectrum().1, b.window));
            assert_eq!(
                (a.kernel_cells, a.kernel_occupied),
                (b.kernel_cells, b.kernel_occupied)
            );
            // The f64 spectrum, mapped in place, is the f32 one before rounding.
            let rounded: Vec<Complex<f32>> = (exact.spectrum().0.iter())
                .map(|c| Complex::new(c.re as f32, c.im as f32))
                .collect();
            assert_eq!(rounded, a.spectrum().0);
        }
    }

    /// A plan computes its kernel spectrum, and a worker its transforms' buffers, only when a
    /// rotation is first correlated by the transforms; the scores are those of a plan and a
    /// workspace made whole up front.
    #[test]
    fn the_spectrum_and_the_transform_buffers_come_with_the_first_transform() {
        let k = occupancy([5, 4, 6], &[true, false, false, true, false]);
        let src = occupancy([7, 6, 5], &[false, true, true]);
        let geo = Geometry::new(k.dims, src.dims);
        let exact = CpuCorrelator::<f64>::with_window(geo, &k, KernelWindow::InSpectrum);
        let approx = CpuCorrelator::<f32>::from_f64(&exact);
        assert!(exact.spectrum.cell.get().is_none() && approx.spectrum.cell.get().is_none());
        let mut ws = Workspace::default();
        approx.fit_grid(&mut ws);
        assert!(ws.grid.is_empty() && ws.zspec.is_empty() && ws.scratch.is_empty());
        ws.load(&src);
        let lazy = approx.approx_best(&mut ws, true);
        assert!(!ws.grid.is_empty());
        assert!(approx.spectrum.cell.get().is_some() && exact.spectrum.cell.get().is_some());
        let eager = CpuCorrelator::<f32>::with_window(geo, &k, KernelWindow::InSpectrum);
        let mut whole = eager.workspace();
        whole.load(&src);
        let want = eager.approx_best(&mut whole, true);
        assert_eq!((lazy.value, lazy.offset), (want.value, want.offset));
        assert_eq!(lazy.error_bound, want.error_bound);
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
            ws.load(s);
            assert_eq!(c.all_scores(&mut ws), brute_force_scores(s, &k));
        }
        assert!(ws.max_rounding_error < 1e-9);
    }

    /// One workspace through sparse grids (scored by the exact paths, which leave the grid
    /// intact and are cleared run by run at the next `begin`) and dense ones (the transforms,
    /// which destroy it), larger and smaller in turn: every best equals a fresh workspace's.
    #[test]
    fn a_workspace_cleared_run_by_run_scores_like_a_fresh_one() {
        let mut next = crate::test_rng::uniform(29);
        let k = random_occupancy([6, 5, 7], 0.15, &mut next);
        let geo = Geometry::new(k.dims, [16, 16, 16]);
        let c = CpuCorrelator::<f64>::new(geo, &k);
        let kernels = ExactKernels::new(&geo, &k);
        let mut ws = c.workspace();
        let (mut by_runs, mut by_transforms) = (0, 0);
        for round in 0..40 {
            let dims = [16 - round % 5, 16 - round % 3, 16 - round % 7];
            let p = if round % 4 == 3 { 0.5 } else { 0.01 };
            let src = random_occupancy(dims, p, &mut next);
            let cleared_by_runs = ws.runs_valid;
            ws.load(&src);
            by_runs += usize::from(cleared_by_runs);
            let got = ws.direct_best(&kernels, &geo).unwrap_or_else(|| {
                by_transforms += 1;
                c.best_offset(&mut ws)
            });
            let mut fresh = c.workspace();
            fresh.load(&src);
            assert_eq!(got, c.best_offset(&mut fresh), "round {round}");
        }
        assert!(
            by_runs >= 10 && by_transforms >= 5,
            "{by_runs} {by_transforms}"
        );
    }
}
