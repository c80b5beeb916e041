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
    #[cfg(feature = "parallel")]
    if let Some(n) = threads {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build()
            .map_err(|e| crate::error::SimError::BadParameter {
                name: "threads",
                value: n.to_string(),
                reason: e.to_string(),
            })?;
        return Ok(pool.install(f));
    }
    let _ = threads;
    Ok(f())
}
