//! What the timing probes share.

/// The command-line arguments without the `--bench` flag that `cargo bench` adds.
pub fn args() -> impl Iterator<Item = String> {
    std::env::args().filter(|a| a != "--bench")
}
