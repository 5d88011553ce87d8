//! The real transforms along z of the correlator: many short rows per rotation.
//!
//! A rotation's forward transform starts with one real-to-complex FFT per occupied (x, y) row
//! and its inverse ends with one complex-to-real FFT per row of valid offsets: 121 rows of 16
//! at the default coarse level, 1640 rows of 48 at the bunny pair's voxel. realfft does one
//! call per row, and on rows this short the call costs more than the transform. Measured on
//! this machine (`cargo bench -p ggs --features internals --bench z_transforms`: f32, 40 rows in cache,
//! ns per row, this module's transforms), forward: 25 ns a row of 16 against 13 for a complex FFT of the same rows
//! (zero imaginary parts) in one rustfft call, copies in and out included; 59 against 37 at
//! 48, 72 against 53 at 64, 82 against 61 at 72, but 110 against 135 at 96. The inverse must
//! first complete each row's Hermitian half: 29 against 18 ns at 16, 35 against 29 at 24,
//! about even at 32 and 48, worse from 54 on. So forward rows of up to
//! [`BATCHED_FORWARD_MAX_LEN`] points and inverse rows of up to [`BATCHED_INVERSE_MAX_LEN`]
//! go through one complex call per batch of rows, the others through realfft. (Two rows
//! packed as the real and imaginary parts of one complex row were slower both ways.
//! realfft's own algorithm batched, each row read as half as many complex points, one FFT
//! of half the length over all rows and a twiddle pass, won more in such a timing, most of
//! all for the inverse, but took the same time in the pipeline: bunny pair, 3dmatch_demo,
//! lidar_koide and the generated human pair, 6 interleaved runs each.)
//!
//! Both compute the same discrete transform, unnormalized, in floating point: the outputs
//! differ in their last bits only, within the error bound the correlator's callers rely on
//! (`CpuCorrelator::error_bound`: a radix-2·3 complex FFT has no more error than realfft's,
//! which adds a twiddle pass to one of half the length).

use super::grid_view::Real;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// Forward transforms of rows of at most this many points are batched.
pub const BATCHED_FORWARD_MAX_LEN: usize = 72;

/// Inverse transforms of rows of at most this many points are batched (the inverse needs
/// the Hermitian half of each row completed first, which costs more than the calls saved
/// on longer rows).
pub const BATCHED_INVERSE_MAX_LEN: usize = 24;

/// One direction of the z transforms of a plan (`R`: realfft's transform that way).
enum Way<T: Real, R: ?Sized> {
    /// realfft, one call per row.
    PerRow(Arc<R>),
    /// A complex FFT over many rows in one call.
    Batched(Arc<dyn Fft<T>>),
}

/// The z transforms of one plan: rows of `len` real points (even), `len / 2 + 1` complex
/// bins each.
pub struct ZAxis<T: Real> {
    len: usize,
    forward: Way<T, dyn RealToComplex<T>>,
    inverse: Way<T, dyn ComplexToReal<T>>,
}

impl<T: Real> ZAxis<T> {
    /// Plans for rows of `len` points (even), batched where that is faster
    /// ([`BATCHED_FORWARD_MAX_LEN`], [`BATCHED_INVERSE_MAX_LEN`]).
    pub fn plan(len: usize) -> Self {
        Self::with_limits(len, BATCHED_FORWARD_MAX_LEN, BATCHED_INVERSE_MAX_LEN)
    }

    /// realfft one row at a time, both ways.
    #[cfg(any(test, feature = "internals"))]
    pub fn per_row(len: usize) -> Self {
        Self::with_limits(len, 0, 0)
    }

    /// Batched both ways.
    #[cfg(any(test, feature = "internals"))]
    pub fn batched(len: usize) -> Self {
        Self::with_limits(len, len, len)
    }

    /// [`Self::plan`] with the batched transforms for rows of up to `forward_max` and
    /// `inverse_max` points.
    fn with_limits(len: usize, forward_max: usize, inverse_max: usize) -> Self {
        let mut rp = RealFftPlanner::<T>::new();
        let mut cp = FftPlanner::<T>::new();
        let forward = if len <= forward_max {
            Way::Batched(cp.plan_fft_forward(len))
        } else {
            Way::PerRow(rp.plan_fft_forward(len))
        };
        let inverse = if len <= inverse_max {
            Way::Batched(cp.plan_fft_inverse(len))
        } else {
            Way::PerRow(rp.plan_fft_inverse(len))
        };
        ZAxis {
            len,
            forward,
            inverse,
        }
    }

    /// Scratch (complex values) the transforms need.
    pub fn scratch_len(&self) -> usize {
        let f = match &self.forward {
            Way::PerRow(p) => p.get_scratch_len(),
            Way::Batched(p) => p.get_inplace_scratch_len(),
        };
        let i = match &self.inverse {
            Way::PerRow(p) => p.get_scratch_len(),
            Way::Batched(p) => p.get_inplace_scratch_len(),
        };
        f.max(i)
    }

    /// Complex values of the batch buffer ([`Self::forward`], [`Self::inverse`]) for up to
    /// `rows` rows.
    pub fn batch_len(&self, rows: usize) -> usize {
        let batched =
            matches!(self.forward, Way::Batched(_)) || matches!(self.inverse, Way::Batched(_));
        if batched {
            rows * self.len
        } else {
            0
        }
    }

    /// The first `len / 2 + 1` bins of the DFT of each row of `real` (rows of `len`) into
    /// `spec` (rows of `len / 2 + 1`). `real` may be overwritten.
    pub fn forward(
        &self,
        real: &mut [T],
        spec: &mut [Complex<T>],
        batch: &mut [Complex<T>],
        scratch: &mut [Complex<T>],
    ) {
        let (len, kz) = (self.len, self.len / 2 + 1);
        match &self.forward {
            Way::PerRow(r2c) => {
                for (row, out) in real.chunks_exact_mut(len).zip(spec.chunks_exact_mut(kz)) {
                    r2c.process_with_scratch(row, out, scratch)
                        .expect("r2c lengths match the plan");
                }
            }
            Way::Batched(fft) => {
                let batch = &mut batch[..real.len()];
                for (c, &r) in batch.iter_mut().zip(real.iter()) {
                    *c = Complex::new(r, T::zero());
                }
                fft.process_with_scratch(batch, scratch);
                for (row, out) in batch.chunks_exact(len).zip(spec.chunks_exact_mut(kz)) {
                    out.copy_from_slice(&row[..kz]);
                }
            }
        }
    }

    /// The real inverse DFT (unnormalized) of each row of `spec` (rows of `len / 2 + 1` bins
    /// of a Hermitian spectrum; the imaginary parts of the first and, `len` being even, the
    /// last bin are taken as 0) into `real` (rows of `len`). `spec` may be overwritten.
    pub fn inverse(
        &self,
        spec: &mut [Complex<T>],
        real: &mut [T],
        batch: &mut [Complex<T>],
        scratch: &mut [Complex<T>],
    ) {
        let (len, kz) = (self.len, self.len / 2 + 1);
        match &self.inverse {
            Way::PerRow(c2r) => {
                for (row, out) in spec.chunks_exact_mut(kz).zip(real.chunks_exact_mut(len)) {
                    row[0].im = T::zero();
                    row[kz - 1].im = T::zero();
                    c2r.process_with_scratch(row, out, scratch)
                        .expect("c2r lengths match the plan");
                }
            }
            Way::Batched(ifft) => {
                let batch = &mut batch[..real.len()];
                for (row, full) in spec.chunks_exact(kz).zip(batch.chunks_exact_mut(len)) {
                    full[..kz].copy_from_slice(row);
                    full[0].im = T::zero();
                    full[kz - 1].im = T::zero();
                    // Hermitian: bin len − k is the conjugate of bin k.
                    for k in kz..len {
                        full[k] = full[len - k].conj();
                    }
                }
                ifft.process_with_scratch(batch, scratch);
                for (out, full) in real.iter_mut().zip(batch.iter()) {
                    *out = full.re;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of pseudo-random values, the same for both plans.
    fn rows(len: usize, n: usize) -> Vec<f64> {
        let mut r = crate::test_rng::uniform(7);
        (0..len * n).map(|_| r() * 2.0 - 1.0).collect()
    }

    /// Per row both ways, batched both ways, batched forward only.
    fn three(len: usize) -> [ZAxis<f64>; 3] {
        [
            ZAxis::per_row(len),
            ZAxis::batched(len),
            ZAxis::with_limits(len, len, 0),
        ]
    }

    #[test]
    fn batched_and_per_row_transforms_agree_and_invert() {
        for len in [2, 4, 6, 16, 24, 36, 48, 54, 64, 72, 96, 128] {
            let (n, kz) = (5, len / 2 + 1);
            let input = rows(len, n);
            let mut results = Vec::new();
            for z in three(len) {
                let mut scratch = vec![Complex::default(); z.scratch_len()];
                let mut batch = vec![Complex::default(); z.batch_len(n)];
                let mut spec = vec![Complex::default(); n * kz];
                z.forward(&mut input.clone(), &mut spec, &mut batch, &mut scratch);
                let mut back = vec![0.0; n * len];
                z.inverse(&mut spec.clone(), &mut back, &mut batch, &mut scratch);
                for (b, a) in back.iter().zip(&input) {
                    assert!((b / len as f64 - a).abs() < 1e-12, "len {len}: {b} vs {a}");
                }
                results.push(spec);
            }
            for other in &results[1..] {
                for (a, b) in results[0].iter().zip(other) {
                    assert!((a - b).norm() < 1e-12 * len as f64, "len {len}: {a} vs {b}");
                }
            }
        }
    }

    #[test]
    fn short_rows_are_batched_long_ones_per_row() {
        let kinds = |z: ZAxis<f32>| {
            (
                matches!(z.forward, Way::Batched(_)),
                matches!(z.inverse, Way::Batched(_)),
            )
        };
        assert_eq!(kinds(ZAxis::plan(16)), (true, true));
        assert_eq!(kinds(ZAxis::plan(48)), (true, false));
        assert_eq!(kinds(ZAxis::plan(96)), (false, false));
        assert_eq!(ZAxis::<f32>::plan(96).batch_len(10), 0);
    }
}
