//! Benchmarks of record: scenarios run the same way by `tissue bench` and by tests, so that a
//! figure in `docs/performance.md` can be reproduced and compared across model kinds.
//!
//! - `beam`: the clamped beam of issue 24 (a cantilever sagging under gravity), every dynamic
//!   kind at its defaults against the static linear answer of `fem-static` on the same mesh.

pub mod beam;

/// Runs `f` with `threads` worker threads for the library's parallel loops (rayon, the
/// `parallel` feature); `None` keeps the global pool (one thread per core). Without the
/// feature everything runs on the calling thread anyway.
pub fn with_threads<T: Send>(
    threads: Option<usize>,
    f: impl FnOnce() -> T + Send,
) -> Result<T, crate::error::SimError> {
    Ok(Pool::new(threads)?.install(f))
}

/// A pool of worker threads kept across calls (`beam::run_interleaved` switches between
/// several): `None` is the global pool (one thread per core).
pub struct Pool {
    #[cfg(feature = "parallel")]
    pool: Option<rayon::ThreadPool>,
}

impl Pool {
    pub fn new(threads: Option<usize>) -> Result<Self, crate::error::SimError> {
        #[cfg(feature = "parallel")]
        {
            let pool = match threads {
                Some(n) => Some(
                    rayon::ThreadPoolBuilder::new()
                        .num_threads(n.max(1))
                        .build()
                        .map_err(|e| crate::error::SimError::BadParameter {
                            name: "threads",
                            value: n.to_string(),
                            reason: e.to_string(),
                        })?,
                ),
                None => None,
            };
            Ok(Self { pool })
        }
        #[cfg(not(feature = "parallel"))]
        {
            let _ = threads;
            Ok(Self {})
        }
    }

    /// Runs `f` with this pool's workers for the library's parallel loops.
    pub fn install<T: Send>(&self, f: impl FnOnce() -> T + Send) -> T {
        #[cfg(feature = "parallel")]
        if let Some(pool) = &self.pool {
            return pool.install(f);
        }
        f()
    }
}
