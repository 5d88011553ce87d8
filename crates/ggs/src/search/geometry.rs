//! The sizes of one correlation problem: kernel and source grids, FFT lengths, bytes, FLOPs.
//!
//! Shared by every correlator backend and by the memory model: the FFT lengths are
//! 2·3-smooth (the fastest lengths of rustfft's AVX kernels; docs/performance.md) and long
//! enough that no circular wrap-around reaches a valid offset (docs/method.md).

use super::window::WindowCounts;

/// `true` if `n` has no prime factor above 3.
pub fn is_3_smooth(mut n: usize) -> bool {
    if n == 0 {
        return false;
    }
    for p in [2, 3] {
        while n.is_multiple_of(p) {
            n /= p;
        }
    }
    n == 1
}

/// Smallest 2·3-smooth length ≥ `min` (and even when `even`). Measured on rustfft 6.4 with
/// AVX: 64 costs 1.75 ns per f64 element against 2.66 for 56 = 7·8 and 5.0 for 50, so a
/// longer 3-smooth length is cheaper per line than a shorter one with factors 5 or 7.
pub fn fast_len(min: usize, even: bool) -> usize {
    let mut n = min.max(1);
    loop {
        if is_3_smooth(n) && (!even || n.is_multiple_of(2)) {
            return n;
        }
        n += 1;
    }
}

/// x-planes transformed along y in one batch.
pub(crate) const X_BLOCK: usize = 8;

/// Sizes of one correlation problem, all in cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Geometry {
    /// Kernel (target) grid dims NR.
    pub kernel_dims: [usize; 3],
    /// Central kernel voxel C = ceil(NR/2) − 1 (0-based).
    pub center: [usize; 3],
    /// Largest source grid dims NS over all rotations.
    pub source_max: [usize; 3],
    /// FFT lengths L ≥ NS_max + floor(NR/2), 3-smooth, z even.
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

    /// [`Geometry::new`] at the FFT lengths `fft_len` instead of the ones `source_max` needs:
    /// a smaller plan beside a full one (`super::sized`). `source_max` stays the full
    /// plan's (it sizes a workspace's rows); every source correlated at this geometry must
    /// fit `fft_len` (`L_d ≥ max(NS_d, NR_d) + floor(NR_d/2)`).
    pub fn with_fft_len(
        kernel_dims: [usize; 3],
        source_max: [usize; 3],
        fft_len: [usize; 3],
    ) -> Self {
        Geometry {
            fft_len,
            ..Self::new(kernel_dims, source_max)
        }
    }

    /// Nominal floating-point operations of one correlation for a source grid of dims `ns`,
    /// as the transforms are pruned here: `5·L·log2 L` per complex transform of length `L`,
    /// `2.5·L·log2 L` per real one (the usual FFT convention: the count of a radix-2
    /// algorithm, whatever the algorithm used), 6 per complex product.
    ///
    /// Forward: `nsx·nsy` real transforms along z, `nsx·kz` along y; `Ly·kz` forward and
    /// inverse along x and `Lx·Ly·kz` products; inverse: `nsx·kz` along y, `nsx·nsy` real
    /// along z.
    pub fn flops(&self, ns: [usize; 3]) -> f64 {
        let c = |l: usize| 5.0 * l as f64 * (l as f64).log2();
        let [lx, ly, lz] = self.fft_len;
        let kz = self.kz() as f64;
        let (nsx, nsy) = (ns[0] as f64, ns[1] as f64);
        let z = 2.0 * nsx * nsy * 0.5 * c(lz);
        let y = 2.0 * nsx * kz * c(ly);
        let x = 2.0 * ly as f64 * kz * c(lx) + 6.0 * (lx * ly) as f64 * kz;
        z + y + x
    }

    /// Complex bins along z of the real transform: `L_z/2 + 1`.
    pub fn kz(&self) -> usize {
        self.fft_len[2] / 2 + 1
    }

    /// Bytes of the kernel spectrum (shared by all workers) with `real_bytes` per real
    /// sample (4 for f32, 8 for f64), saturating at `u64::MAX`.
    pub fn kernel_bytes(&self, real_bytes: u64) -> u64 {
        saturate(
            self.fft_len[0] as u128
                * self.fft_len[1] as u128
                * self.kz() as u128
                * 2
                * real_bytes as u128,
        )
    }

    /// Bytes of one worker's buffers with `real_bytes` per real sample (and the window's
    /// counts of a counted kernel window), saturating at `u64::MAX`.
    pub fn workspace_bytes(&self, real_bytes: u64) -> u64 {
        let [lx, ly, lz] = self.fft_len.map(|v| v as u128);
        let kz = self.kz() as u128;
        let ax = self.source_max[0].max(self.kernel_dims[0]) as u128;
        let ay = self.source_max[1].max(self.kernel_dims[1]) as u128;
        let real = ax * ay * lz;
        let zspec = ax * ay * kz * 2;
        let grid = ly * kz * lx * 2;
        let slab = X_BLOCK as u128 * kz * ly * 2;
        let window = WindowCounts::bytes(self.source_max);
        saturate((real + zspec + grid + slab + 8 * (lx + ly + lz)) * real_bytes as u128 + window)
    }
}

/// `v` as u64, or `u64::MAX` when it does not fit.
fn saturate(v: u128) -> u64 {
    u64::try_from(v).unwrap_or(u64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smooth_lengths() {
        assert_eq!(fast_len(11, false), 12);
        assert_eq!(fast_len(13, true), 16);
        assert_eq!(fast_len(97, false), 108);
        assert_eq!(fast_len(55, true), 64);
        assert_eq!(fast_len(25, false), 27);
        assert_eq!(fast_len(27, true), 32);
        assert_eq!(fast_len(1, true), 2);
        assert!(is_3_smooth(2 * 2 * 3 * 3 * 3));
        assert!(!is_3_smooth(2 * 3 * 5));
        assert!(!is_3_smooth(0));
    }

    #[test]
    fn byte_counts_saturate_instead_of_wrapping() {
        let g = Geometry::new([9_000_000; 3], [9_000_000; 3]);
        assert_eq!(g.kernel_bytes(8), u64::MAX);
        assert_eq!(g.workspace_bytes(4), u64::MAX);
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
}
