//! Times the correlator's transforms along z both ways (`coarse::zaxis`): realfft one call
//! per row, against one complex FFT call over 40 rows (zero imaginary parts in, the
//! Hermitian half completed for the inverse), f32, rows in cache, ns per row:
//! `cargo run --release --example z_transforms -p ggs`.
use realfft::RealFftPlanner;
use rustfft::{num_complex::Complex, FftPlanner};
use std::time::Instant;

const ROWS: usize = 40;
const REPS: usize = 20_000;

/// ns per row of `f` run `REPS` times over `ROWS` rows.
fn per_row(mut f: impl FnMut()) -> f64 {
    let t = Instant::now();
    for _ in 0..REPS {
        f();
    }
    t.elapsed().as_secs_f64() / (REPS * ROWS) as f64 * 1e9
}

fn main() {
    println!("len  forward: per row  batched   inverse: per row  batched  (ns per row)");
    for len in [16usize, 24, 32, 36, 48, 54, 64, 72, 96] {
        let kz = len / 2 + 1;
        let mut rp = RealFftPlanner::<f32>::new();
        let mut cp = FftPlanner::<f32>::new();
        let (r2c, c2r) = (rp.plan_fft_forward(len), rp.plan_fft_inverse(len));
        let (fft, ifft) = (cp.plan_fft_forward(len), cp.plan_fft_inverse(len));
        let mut real: Vec<f32> = (0..ROWS * len).map(|i| (i % 7) as f32).collect();
        let mut spec = vec![Complex::<f32>::new(0.5, 0.25); ROWS * kz];
        let mut batch = vec![Complex::<f32>::default(); ROWS * len];
        let mut scratch = vec![Complex::<f32>::default(); 4096];
        let fwd_row = per_row(|| {
            for (row, out) in real.chunks_exact_mut(len).zip(spec.chunks_exact_mut(kz)) {
                r2c.process_with_scratch(row, out, &mut scratch).unwrap();
            }
        });
        let fwd_batch = per_row(|| {
            for (c, &r) in batch.iter_mut().zip(real.iter()) {
                *c = Complex::new(r, 0.0);
            }
            fft.process_with_scratch(&mut batch, &mut scratch);
            for (row, out) in batch.chunks_exact(len).zip(spec.chunks_exact_mut(kz)) {
                out.copy_from_slice(&row[..kz]);
            }
        });
        let inv_row = per_row(|| {
            for (row, out) in spec.chunks_exact_mut(kz).zip(real.chunks_exact_mut(len)) {
                row[0].im = 0.0;
                row[kz - 1].im = 0.0;
                c2r.process_with_scratch(row, out, &mut scratch).unwrap();
            }
        });
        let inv_batch = per_row(|| {
            for (row, full) in spec.chunks_exact(kz).zip(batch.chunks_exact_mut(len)) {
                full[..kz].copy_from_slice(row);
                full[0].im = 0.0;
                full[kz - 1].im = 0.0;
                for k in kz..len {
                    full[k] = full[len - k].conj();
                }
            }
            ifft.process_with_scratch(&mut batch, &mut scratch);
            for (out, c) in real.iter_mut().zip(batch.iter()) {
                *out = c.re;
            }
        });
        println!("{len:3}  {fwd_row:16.1} {fwd_batch:8.1}  {inv_row:17.1} {inv_batch:8.1}");
    }
}
