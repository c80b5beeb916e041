//! Incisions off the stepping thread, in real time (`Deformable::set_real_time`).
//!
//! Extending the pre-inverted system after a cut costs O(n² k): seconds on the 2194-vertex
//! liver, during which a viewer or a haptic loop must go on stepping. So in real time a
//! scalpel stroke only plans its new surface on the calling thread (cheap); a worker
//! computes the new H and G columns and the bordering from the system's shared parts
//! (`SystemUpdate::compute`) while the model keeps answering steps on the uncut surface.
//! The finished update is swapped in at the start of a step
//! (`Deformable::finish_background`), and strokes made meanwhile wait in a queue and are
//! planned on the surface the previous one left. Nothing is dropped: an update made stale
//! by a re-factorisation in between (a new fixed set) is computed again, and an error is
//! returned by the step that would have swapped it in.
//!
//! Off real time (`tissue run`, the tests) incisions are computed where they are asked, so
//! a run's result never depends on timing.

use std::collections::VecDeque;
use std::sync::mpsc::{Receiver, TryRecvError, channel};
use std::time::Instant;

use crate::error::SimError;
use crate::model::{CutInfo, CutPath};

use super::cut::{PlannedIncision, SystemUpdate, UpdateBase};
use super::model::Bem;

type Finished = (PlannedIncision, Result<SystemUpdate, SimError>);

/// The incision being computed and the strokes waiting for it.
#[derive(Default)]
pub(super) struct IncisionWorker {
    job: Option<Job>,
    queue: VecDeque<CutPath>,
}

struct Job {
    blade: CutPath,
    /// The system generation the update was computed from (`BemSystem::generation`).
    generation: u64,
    started: Instant,
    done: Receiver<Finished>,
}

impl IncisionWorker {
    pub fn busy(&self) -> bool {
        self.job.is_some() || !self.queue.is_empty()
    }

    /// For a status line: what is computed and for how long, and how many strokes wait.
    pub fn describe(&self, last_seconds: f64) -> Option<String> {
        let job = self.job.as_ref()?;
        let mut s = format!(
            "bem: computing an incision ({:.1} s",
            job.started.elapsed().as_secs_f64()
        );
        if last_seconds > 0.0 {
            s.push_str(&format!("; the last took {last_seconds:.1} s"));
        }
        s.push(')');
        if !self.queue.is_empty() {
            s.push_str(&format!(", {} more stroke(s) waiting", self.queue.len()));
        }
        Some(s)
    }
}

impl Bem {
    /// An incision along `blade`: computed now, or in real time queued for the worker.
    pub(super) fn incise_when_ready(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        if !self.real_time {
            return self.incise(blade, super::CutUpdate::Bordering);
        }
        self.incisions.queue.push_back(*blade);
        self.start_next_incision()?;
        Ok(self.no_cut())
    }

    /// Starts the worker on the first queued stroke that opens a groove, if none is running.
    fn start_next_incision(&mut self) -> Result<(), SimError> {
        while self.incisions.job.is_none() {
            let Some(blade) = self.incisions.queue.pop_front() else {
                return Ok(());
            };
            let Some(plan) = self.plan_incision(&blade)? else {
                continue;
            };
            let base: UpdateBase = self.update_base()?;
            let (tx, rx) = channel();
            let generation = self.system.generation;
            std::thread::Builder::new()
                .name("tissue-bem-incision".into())
                .spawn(move || {
                    let update = SystemUpdate::compute(&plan, &base);
                    // The model may be gone (replaced, dropped): nobody to tell.
                    let _ = tx.send((plan, update));
                })
                .map_err(|e| SimError::BadParameter {
                    name: "cut",
                    value: "an incision in the background".into(),
                    reason: format!("cannot start its thread: {e}"),
                })?;
            self.incisions.job = Some(Job {
                blade,
                generation,
                started: Instant::now(),
                done: rx,
            });
        }
        Ok(())
    }

    /// Swaps in a finished incision (see the module docs); `Some` when the surface changed.
    pub(super) fn finish_incision(&mut self) -> Result<Option<CutInfo>, SimError> {
        let Some(job) = &self.incisions.job else {
            return Ok(None);
        };
        let (plan, update) = match job.done.try_recv() {
            Ok(done) => done,
            Err(TryRecvError::Empty) => return Ok(None),
            Err(TryRecvError::Disconnected) => {
                self.incisions.job = None;
                return Err(worker_failed("its thread stopped without an answer"));
            }
        };
        let Some(job) = self.incisions.job.take() else {
            return Ok(None);
        };
        let seconds = job.started.elapsed().as_secs_f64();
        let landed = match update {
            Err(e) => Err(e),
            // The system changed meanwhile: compute this stroke again on the new one.
            Ok(_) if !self.update_applies(job.generation) => {
                self.incisions.queue.push_front(job.blade);
                Ok(None)
            }
            Ok(update) => self
                .updated_system(update)
                .and_then(|system| self.land_incision(plan, system, seconds))
                .map(Some),
        };
        // The next stroke starts whatever happened to this one.
        let next = self.start_next_incision();
        let landed = landed?;
        next?;
        Ok(landed)
    }

    /// Blocks until every queued incision has landed (tests, and callers leaving real time).
    pub fn wait_for_incisions(&mut self) -> Result<CutInfo, SimError> {
        let mut info = self.no_cut();
        while self.incisions.busy() {
            self.start_next_incision()?;
            if let Some(done) = self.finish_incision()? {
                info = CutInfo {
                    removed_elements: info.removed_elements + done.removed_elements,
                    added_vertices: info.added_vertices + done.added_vertices,
                    topology_version: done.topology_version,
                };
            } else {
                std::thread::sleep(std::time::Duration::from_millis(2));
            }
        }
        Ok(info)
    }
}

fn worker_failed(reason: &str) -> SimError {
    SimError::BadParameter {
        name: "cut",
        value: "an incision in the background".into(),
        reason: reason.into(),
    }
}
