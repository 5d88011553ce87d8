//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// The workspace root.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `../shared` beside the checkout (override with `GGS_SHARED`). The real-data suites need
/// it; they fail when it is missing unless `GGS_SKIP_SHARED=1` says to skip them.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("GGS_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join("../shared"));
    if dir.join("SPEC.md").exists() {
        return Some(dir);
    }
    if std::env::var_os("GGS_SKIP_SHARED").is_some_and(|v| v == "1") {
        eprintln!(
            "skipping: {} not found and GGS_SKIP_SHARED=1",
            dir.display()
        );
        return None;
    }
    panic!(
        "{} not found: the real-data tests need ../shared beside the checkout (set GGS_SHARED, or GGS_SKIP_SHARED=1 to skip)",
        dir.display()
    );
}

/// Deterministic pseudo-random numbers in [0, 1) (64-bit LCG, top 53 bits).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next_f64(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}
