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

/// `f` run on `resolve(n)` threads: in the pool it is called from when that pool has as many
/// (a registration's stages share its pool, and nested parallel work is scheduled there), on
/// a new pool otherwise.
pub fn in_pool<R: Send>(n: usize, f: impl FnOnce() -> R + Send) -> Result<R> {
    let threads = resolve(n);
    if rayon::current_thread_index().is_some() && rayon::current_num_threads() == threads {
        return Ok(f());
    }
    let (pool, _) = pool(n)?;
    Ok(pool.install(f))
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
