//! Contact-rim solves off the simulation thread (`background_rim_solves`).
//!
//! A contact change onto triangles whose q = A₀⁻¹ g is not cached costs O(n²) per
//! (triangle, corner) pair, about 6 ms each on a 2194-vertex liver: a probe sliding onto
//! new triangles would stall every step. In the background the pairs are solved by worker
//! threads (one batch each, as many as there are cores, each in the idle scheduling class)
//! while the contact set keeps the continuous rule (all of it:
//! see `BemSystem::contact_rim_response`); when the last pair it needs lands, the set is
//! re-formed with the rims (`BemSystem::collect_rim_solves`). The worker holds its own
//! handles to the geometry and the LU (`BaseInverse` shares them), so the system never
//! waits for it; a batch solved for an A₀ that has since changed is dropped with its
//! channel (`cancel`).

use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, TryRecvError};

use faer::Mat;

use crate::math::Real;

use super::assembly::Geometry;
use super::border::BaseInverse;
use super::contact_rims::solve_pairs;
use super::system::SOLVE_BLOCK;

/// Pairs per batch: their 3 columns each make one block of `solve_columns`, so a batch
/// runs on one core, and it takes about 0.1 s on the liver, so a contact set that needs
/// few pairs is not held up behind a long batch.
const BATCH: usize = SOLVE_BLOCK / 3;

/// Pairs solved by the worker: column block j of `q` is `pairs[j]`.
pub(super) struct Solved {
    pub pairs: Vec<(usize, usize)>,
    pub q: Mat<Real>,
}

/// What a poll of the worker found.
pub(super) enum Poll {
    /// Nothing was running.
    Idle,
    /// A batch is still being solved.
    Busy,
    /// A batch finished.
    Done(Solved),
    /// The batch's thread died without a result (its pairs are asked for again).
    Lost,
}

struct Running {
    pairs: Vec<(usize, usize)>,
    result: Receiver<Mat<Real>>,
}

/// The batches being solved, oldest first, and the pairs waiting for the next ones.
pub(super) struct RimWorker {
    running: Vec<Running>,
    queue: Vec<(usize, usize)>,
    /// Batches solved at once, one thread each.
    threads: usize,
}

impl Default for RimWorker {
    /// One thread per core: they only take the time the simulation leaves idle.
    fn default() -> Self {
        Self {
            running: Vec::new(),
            queue: Vec::new(),
            threads: cores(),
        }
    }
}

impl RimWorker {
    /// Whether `pair` is being solved now.
    pub fn in_flight(&self, pair: (usize, usize)) -> bool {
        self.running.iter().any(|r| r.pairs.contains(&pair))
    }

    /// Pairs asked for and not delivered yet (running or queued).
    pub fn pending(&self) -> usize {
        self.running.iter().map(|r| r.pairs.len()).sum::<usize>() + self.queue.len()
    }

    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Batches solved at once, between one and the number of cores (more threads than
    /// cores would only share them); the running ones finish either way.
    pub fn set_threads(&mut self, threads: usize) {
        self.threads = threads.clamp(1, cores());
    }

    /// Replaces the waiting pairs (those the current contacts still need, and not in flight)
    /// and starts batches on the free threads.
    pub fn request(&mut self, pairs: Vec<(usize, usize)>, geo: &Arc<Geometry>, inv: &BaseInverse) {
        self.queue = pairs;
        self.start_next(geo, inv);
    }

    /// Starts batches from the front of the queue while threads are free.
    pub fn start_next(&mut self, geo: &Arc<Geometry>, inv: &BaseInverse) {
        while self.running.len() < self.threads && !self.queue.is_empty() {
            self.start_batch(geo, inv);
        }
    }

    fn start_batch(&mut self, geo: &Arc<Geometry>, inv: &BaseInverse) {
        let rest = self.queue.split_off(self.queue.len().min(BATCH));
        let pairs = std::mem::replace(&mut self.queue, rest);
        let (send, result) = mpsc::channel();
        let (geo_job, inv_job, job, send_job) =
            (Arc::clone(geo), inv.clone(), pairs.clone(), send.clone());
        let spawned = std::thread::Builder::new()
            .name("bem-rim-solves".into())
            .spawn(move || {
                // One core only (no thread pool), and only its idle time: the simulation's
                // and the haptic loop's threads come first. The receiver is gone when A₀
                // changed: nothing to deliver.
                yield_to_other_threads();
                let _ = send_job.send(solve_pairs(&geo_job, &inv_job, &job, false));
            });
        if spawned.is_err() {
            // No thread to be had: solve here, at the blocking rule's cost, same result.
            let _ = send.send(solve_pairs(geo, inv, &pairs, true));
        }
        self.running.push(Running { pairs, result });
    }

    /// Takes a finished batch, the oldest first, without waiting.
    pub fn poll(&mut self) -> Poll {
        if self.running.is_empty() {
            return Poll::Idle;
        }
        for i in 0..self.running.len() {
            match self.running[i].result.try_recv() {
                Ok(q) => return self.finish(i, q),
                Err(TryRecvError::Empty) => {}
                Err(TryRecvError::Disconnected) => {
                    self.running.remove(i);
                    return Poll::Lost;
                }
            }
        }
        Poll::Busy
    }

    /// Waits for the oldest running batch, if any.
    pub fn wait(&mut self) -> Poll {
        let Some(run) = self.running.first() else {
            return Poll::Idle;
        };
        match run.result.recv() {
            Ok(q) => self.finish(0, q),
            Err(_) => {
                self.running.remove(0);
                Poll::Lost
            }
        }
    }

    fn finish(&mut self, i: usize, q: Mat<Real>) -> Poll {
        let run = self.running.remove(i);
        Poll::Done(Solved {
            pairs: run.pairs,
            q,
        })
    }

    /// Forgets the waiting pairs (the running batches go on).
    pub fn drop_queue(&mut self) {
        self.queue.clear();
    }

    /// Forgets the running batches and the queue (A₀ changed: their q would be stale). The
    /// threads finish on their own and their results are dropped.
    pub fn cancel(&mut self) {
        self.running.clear();
        self.queue.clear();
    }
}

fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Puts the calling thread in the idle scheduling class (Linux's SCHED_IDLE, which needs no
/// privilege): it runs only when no other thread wants the core. On a 2-core machine the
/// solves otherwise took whole time slices from the simulation thread (steps of 10-25 ms
/// against a median of 0.5 ms). Elsewhere the thread keeps its priority.
#[cfg(target_os = "linux")]
fn yield_to_other_threads() {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: sched_setscheduler reads `param` only during the call; pid 0 is this thread.
    unsafe {
        libc::sched_setscheduler(0, libc::SCHED_IDLE, &param);
    }
}

#[cfg(not(target_os = "linux"))]
fn yield_to_other_threads() {}
