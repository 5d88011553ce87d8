//! Deterministic pseudo-random numbers and clouds for unit tests.

use crate::cloud::Point;

/// `n` points of a unit sphere shell 1 % thick, drawn from `r`.
pub fn noisy_sphere(r: &mut impl FnMut() -> f64, n: usize) -> Vec<Point> {
    (0..n)
        .map(|_| {
            let (u, v) = (r() * std::f64::consts::TAU, r() * 2.0 - 1.0);
            let w = (1.0 - v * v).sqrt();
            let rad = 1.0 + 0.01 * r();
            [rad * w * u.cos(), rad * w * u.sin(), rad * v]
        })
        .collect()
}

/// Uniform numbers in [0, 1): a 64-bit LCG (Knuth's MMIX constants), top 53 bits.
pub fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed;
    move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}
