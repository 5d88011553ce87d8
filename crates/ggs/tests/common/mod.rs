//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

/// The workspace root.
pub fn repo_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// `../shared` beside the checkout (override with `GGS_SHARED`), whose `data/` holds the real
/// scans. The real-data suites need it. In a bare clone they are skipped and say so; with
/// `GGS_REQUIRE_SHARED=1` (as `.ci/run` sets) a missing folder fails them instead.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("GGS_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo_root().join("../shared"));
    if dir.join("data/pairs.tsv").exists() {
        return Some(dir);
    }
    let hint = "the real-data suites need ../shared beside the checkout (or GGS_SHARED=DIR)";
    if std::env::var_os("GGS_REQUIRE_SHARED").is_some_and(|v| v == "1") {
        panic!("{} not found: {hint}", dir.display());
    }
    // Straight to stderr: the test harness captures eprintln! of passing tests.
    use std::io::Write;
    let _ = writeln!(
        std::io::stderr(),
        "SKIPPED (real data): {} not found; {hint}, and GGS_REQUIRE_SHARED=1 makes this an error",
        dir.display()
    );
    None
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
