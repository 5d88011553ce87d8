//! Times the correlator's transforms along z both ways (`ggs::search::zaxis`): realfft one
//! call per row against the batched transform (one complex FFT call over 40 rows), f32, rows
//! in cache, ns per row:
//! `cargo bench -p ggs --features internals --bench z_transforms`.
use ggs::search::zaxis::ZAxis;
use rustfft::num_complex::Complex;
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

/// Forward and inverse ns per row of `z` on rows of `len`.
fn time(z: &ZAxis<f32>, len: usize) -> (f64, f64) {
    let kz = len / 2 + 1;
    let mut real: Vec<f32> = (0..ROWS * len).map(|i| (i % 7) as f32).collect();
    let mut spec = vec![Complex::<f32>::default(); ROWS * kz];
    let mut batch = vec![Complex::<f32>::default(); z.batch_len(ROWS)];
    let mut scratch = vec![Complex::<f32>::default(); z.scratch_len()];
    let fwd = per_row(|| z.forward(&mut real, &mut spec, &mut batch, &mut scratch));
    let inv = per_row(|| z.inverse(&mut spec, &mut real, &mut batch, &mut scratch));
    (fwd, inv)
}

fn main() {
    println!("len  forward: per row  batched   inverse: per row  batched  (ns per row)");
    for len in [16usize, 24, 32, 36, 48, 54, 64, 72, 96] {
        let (fr, ir) = time(&ZAxis::per_row(len), len);
        let (fb, ib) = time(&ZAxis::batched(len), len);
        println!("{len:3}  {fr:16.1} {fb:8.1}  {ir:17.1} {ib:8.1}");
    }
}
