//! Worker pools. Results never depend on the thread count: each caller splits work so that
//! every item is computed independently and reduced in a fixed order.

use crate::error::{GgsError, Result};

/// Threads for a request of `n` (0 = one per available core).
pub fn resolve(n: usize) -> usize {
    if n == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        n
    }
}

/// A rayon pool of `resolve(n)` threads, and that count.
pub fn pool(n: usize) -> Result<(rayon::ThreadPool, usize)> {
    let threads = resolve(n);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| GgsError::param("threads", e.to_string()))?;
    Ok((pool, threads))
}
