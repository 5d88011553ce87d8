//! Which compiled body the vectorized loops (voxelization of rotated sources, the spectrum
//! product) run: the widest the CPU has, or a narrower one named by the environment variable
//! `GGS_SIMD` (`scalar`, `avx2`, `avx512`), read once per process. Every body computes the
//! same bits (tested by running the CLI under each); the variable lets a machine with AVX-512
//! check the others. rustfft picks its own kernels and is not affected.

use std::sync::OnceLock;

/// A vector width, narrowest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    Scalar,
    Avx2,
    Avx512,
}

impl Level {
    fn from_name(s: &str) -> Option<Level> {
        Some(match s {
            "scalar" => Level::Scalar,
            "avx2" => Level::Avx2,
            "avx512" => Level::Avx512,
            _ => return None,
        })
    }
}

/// The widest level this CPU supports.
fn detected() -> Level {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            return Level::Avx512;
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            return Level::Avx2;
        }
    }
    Level::Scalar
}

/// The level the loops run at: the CPU's, lowered (never raised) by `GGS_SIMD`. An unknown
/// value is reported once on stderr and ignored.
pub fn level() -> Level {
    static LEVEL: OnceLock<Level> = OnceLock::new();
    *LEVEL.get_or_init(|| {
        let cpu = detected();
        match std::env::var("GGS_SIMD") {
            Ok(v) if v.is_empty() => cpu,
            Ok(v) => match Level::from_name(&v) {
                Some(asked) => asked.min(cpu),
                None => {
                    eprintln!("ggs: GGS_SIMD={v:?} is not scalar, avx2 or avx512; ignored");
                    cpu
                }
            },
            Err(_) => cpu,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_are_ordered_and_named() {
        assert!(Level::Scalar < Level::Avx2 && Level::Avx2 < Level::Avx512);
        assert_eq!(Level::from_name("avx2"), Some(Level::Avx2));
        assert_eq!(Level::from_name("sse"), None);
        assert!(level() <= detected());
    }
}
