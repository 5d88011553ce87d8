//! The generator's seeded random numbers: xoshiro256** (Blackman and Vigna 2018) seeded
//! through SplitMix64.
//!
//! Written out here rather than taken from `rand` so that a benchmark generated from a seed
//! stays byte-identical across versions of ggs and of its dependencies: these few lines are
//! the whole definition. Independent streams are derived from `(seed, tags…)`, so that what a
//! view or a pair draws does not depend on the order in which threads reach it.

/// SplitMix64 step: the state advances by the golden-ratio increment, the output is mixed.
fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A xoshiro256** generator.
#[derive(Debug, Clone)]
pub struct Rng {
    s: [u64; 4],
}

impl Rng {
    /// The generator of `seed`.
    pub fn new(seed: u64) -> Self {
        let mut sm = seed;
        let s = [
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
        ];
        Rng { s }
    }

    /// An independent stream for `seed` and the `tags` (a purpose, a scan, a pair…): the
    /// tags are folded into the seed through SplitMix64.
    pub fn stream(seed: u64, tags: &[u64]) -> Self {
        let mut h = seed;
        let mut mixed = splitmix64(&mut h);
        for &t in tags {
            let mut st = mixed ^ t.wrapping_mul(0x9e37_79b9_7f4a_7c15);
            mixed = splitmix64(&mut st);
        }
        Rng::new(mixed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let result = self.s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = self.s[1] << 17;
        self.s[2] ^= self.s[0];
        self.s[3] ^= self.s[1];
        self.s[1] ^= self.s[2];
        self.s[0] ^= self.s[3];
        self.s[2] ^= t;
        self.s[3] = self.s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1): the top 53 bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Uniform integer in [0, n) (n > 0), without modulo bias (Lemire's method with
    /// rejection).
    pub fn below(&mut self, n: u64) -> u64 {
        assert!(n > 0, "Rng::below(0)");
        let threshold = n.wrapping_neg() % n;
        loop {
            let m = (self.next_u64() as u128) * (n as u128);
            if (m as u64) >= threshold {
                return (m >> 64) as u64;
            }
        }
    }

    /// +1 or −1 with equal probability.
    pub fn sign(&mut self) -> f64 {
        if self.next_u64() >> 63 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// A direction uniform on the unit sphere (z uniform in [−1, 1], azimuth uniform).
    pub fn unit_vector(&mut self) -> [f64; 3] {
        let z = self.range(-1.0, 1.0);
        let phi = self.range(0.0, std::f64::consts::TAU);
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_values_never_change() {
        // A benchmark's bytes depend on these numbers: changing them is a breaking change.
        // The values come from an independent implementation of SplitMix64 + xoshiro256**
        // written from the published definitions (Python, integers masked to 64 bits).
        let mut r = Rng::new(0);
        let first: Vec<u64> = (0..4).map(|_| r.next_u64()).collect();
        assert_eq!(
            first,
            [
                0x99ec_5f36_cb75_f2b4,
                0xbf6e_1f78_4956_452a,
                0x1a5f_849d_4933_e6e0,
                0x6aa5_94f1_262d_2d2c
            ]
        );
        let mut r = Rng::stream(2022, &[1, 2]);
        let streamed: Vec<u64> = (0..3).map(|_| r.next_u64()).collect();
        assert_eq!(
            streamed,
            [
                0x731b_0f6c_cfa5_a1ba,
                0xb56d_f52e_7c82_8e41,
                0x1ff3_9c4a_81b4_6932
            ]
        );
        // SplitMix64 of 0 (the published first output 0xe220a8397b1dcdaf) seeds s[0].
        let mut sm = 0u64;
        assert_eq!(splitmix64(&mut sm), 0xe220_a839_7b1d_cdaf);
    }

    #[test]
    fn streams_differ_and_repeat() {
        let a: Vec<u64> = {
            let mut r = Rng::stream(7, &[1, 2]);
            (0..4).map(|_| r.next_u64()).collect()
        };
        let b: Vec<u64> = {
            let mut r = Rng::stream(7, &[2, 1]);
            (0..4).map(|_| r.next_u64()).collect()
        };
        let c: Vec<u64> = {
            let mut r = Rng::stream(7, &[1, 2]);
            (0..4).map(|_| r.next_u64()).collect()
        };
        assert_ne!(a, b);
        assert_eq!(a, c);
    }

    #[test]
    fn uniform_below_and_sphere_are_in_range() {
        let mut r = Rng::new(42);
        let mut hist = [0usize; 5];
        let mut mean = 0.0;
        for _ in 0..50_000 {
            let u = r.uniform();
            assert!((0.0..1.0).contains(&u));
            mean += u;
            hist[r.below(5) as usize] += 1;
            let v = r.unit_vector();
            assert!(((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - 1.0).abs() < 1e-12);
        }
        assert!((mean / 50_000.0 - 0.5).abs() < 0.01);
        for h in hist {
            assert!((h as f64 - 10_000.0).abs() < 500.0, "{hist:?}");
        }
    }
}
