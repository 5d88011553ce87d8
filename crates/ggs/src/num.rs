//! Float-to-integer floors without a library call.
//!
//! On baseline x86-64 (SSE2, what release builds target) `f64::floor` is a call into libm:
//! about 20 instructions and a call, paid three times a point where points are put into
//! cells (thinning, the point spacing, the radius grids). These give the same integers
//! inline: truncate, then step down where truncation rounded up.

/// `⌊x⌋` as an `i64`, equal to `x.floor() as i64` for every `x`: saturating beyond ±2^63,
/// 0 for NaN.
#[inline(always)]
pub fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    // Below −2^63 the cast gives i64::MIN, which stays.
    t.saturating_sub(((t as f64) > x) as i64)
}

/// `⌊x⌋` clamped at 0 as a `u64`, equal to `x.floor().max(0.0) as u64` for every `x`:
/// saturating beyond 2^64, 0 for negative values and NaN.
#[inline(always)]
pub fn floor_u64(x: f64) -> u64 {
    let t = x as u64;
    // Below 1 the cast gives 0, and 0 stays 0.
    t.saturating_sub(((t as f64) > x) as u64)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn check(x: f64) {
        assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        assert_eq!(floor_u64(x), x.floor().max(0.0) as u64, "{x}");
    }

    #[test]
    fn the_edges_floor_as_the_library_does() {
        let big = [
            2f64.powi(52),
            2f64.powi(53),
            2f64.powi(63),
            2f64.powi(64),
            1e300,
        ];
        for b in big {
            for x in [
                b,
                b - 1.0,
                b + 1.0,
                b.next_down(),
                b.next_up(),
                -b,
                -b + 1.0,
            ] {
                check(x);
            }
        }
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            1.0 - f64::EPSILON,
            -1e-300,
            1e-300,
        ] {
            check(x);
        }
        for x in [
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            f64::MIN,
        ] {
            check(x);
        }
    }

    proptest! {
        #[test]
        fn floors_equal_the_library_floor(x in proptest::num::f64::ANY) {
            check(x);
        }

        #[test]
        fn floors_of_cell_coordinates_equal_the_library_floor(x in -1e7f64..1e7, h in 1e-6f64..10.0) {
            check(x / h);
        }
    }
}
