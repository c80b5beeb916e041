//! Contact-rim solves off the simulation thread (`background_rim_solves`).
//!
//! A contact change onto triangles whose q = A₀⁻¹ g is not cached costs O(n²) per
//! (triangle, corner) pair, about 6 ms each on a 2194-vertex liver: a probe sliding onto
//! new triangles would stall every step. In the background the pairs are solved by a
//! worker thread in batches while the contact set keeps the continuous rule (all of it:
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

/// The batch being solved, if any, and the pairs waiting for the next one.
#[derive(Default)]
pub(super) struct RimWorker {
    running: Option<Running>,
    queue: Vec<(usize, usize)>,
}

impl RimWorker {
    /// Whether `pair` is being solved now.
    pub fn in_flight(&self, pair: (usize, usize)) -> bool {
        self.running
            .as_ref()
            .is_some_and(|r| r.pairs.contains(&pair))
    }

    /// Pairs asked for and not delivered yet (running or queued).
    pub fn pending(&self) -> usize {
        self.running.as_ref().map_or(0, |r| r.pairs.len()) + self.queue.len()
    }

    /// Replaces the waiting pairs (those the current contacts still need, and not in flight)
    /// and starts the next batch if the worker is free.
    pub fn request(&mut self, pairs: Vec<(usize, usize)>, geo: &Arc<Geometry>, inv: &BaseInverse) {
        self.queue = pairs;
        self.start_next(geo, inv);
    }

    /// Starts a batch from the front of the queue unless one is running.
    pub fn start_next(&mut self, geo: &Arc<Geometry>, inv: &BaseInverse) {
        if self.running.is_some() || self.queue.is_empty() {
            return;
        }
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
        self.running = Some(Running { pairs, result });
    }

    /// Takes a finished batch without waiting.
    pub fn poll(&mut self) -> Poll {
        let Some(run) = &self.running else {
            return Poll::Idle;
        };
        match run.result.try_recv() {
            Ok(q) => self.finish(q),
            Err(TryRecvError::Empty) => Poll::Busy,
            Err(TryRecvError::Disconnected) => {
                self.running = None;
                Poll::Lost
            }
        }
    }

    /// Waits for the running batch, if any.
    pub fn wait(&mut self) -> Poll {
        let Some(run) = &self.running else {
            return Poll::Idle;
        };
        match run.result.recv() {
            Ok(q) => self.finish(q),
            Err(_) => {
                self.running = None;
                Poll::Lost
            }
        }
    }

    fn finish(&mut self, q: Mat<Real>) -> Poll {
        match self.running.take() {
            Some(run) => Poll::Done(Solved {
                pairs: run.pairs,
                q,
            }),
            None => Poll::Idle,
        }
    }

    /// Forgets the waiting pairs (the running batch goes on).
    pub fn drop_queue(&mut self) {
        self.queue.clear();
    }

    /// Forgets the running batch and the queue (A₀ changed: their q would be stale). The
    /// thread finishes on its own and its result is dropped.
    pub fn cancel(&mut self) {
        self.running = None;
        self.queue.clear();
    }
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
