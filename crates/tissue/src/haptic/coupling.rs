//! Coupling of the full simulation to the haptic loop: the simulation thread moves the
//! instrument to the device pose, steps the model and hands the result to the local contact
//! model the loop evaluates at 1 kHz.

use std::time::{Duration, Instant};

use crate::error::SimError;
use crate::haptic::haptic_loop::HapticHandle;
use crate::math::Real;
use crate::sim::{Simulation, StepReport};

/// One full update: instrument `index` goes to the device pose, the simulation steps `dt`,
/// and its force on that instrument becomes the local model's new anchor, with the model's
/// tangent stiffness where it gives one (else the loop estimates it). A loop of its
/// own that calls this against the clock tells the model so once (`sim.model_mut().
/// set_real_time(true)`), as `run_coupled` does.
pub fn step_coupled(
    sim: &mut Simulation,
    index: usize,
    handle: &HapticHandle,
    dt: Real,
) -> Result<StepReport, SimError> {
    let pose = handle.pose();
    sim.set_instrument_position(index, Some(pose.position))?;
    let report = sim.step(dt)?;
    let force = report.forces.get(index).copied().unwrap_or_default();
    let touching = report.contacts.get(index).is_some_and(|&n| n > 0);
    let stiffness = sim.instrument_stiffness(index);
    handle.update_contact_with_stiffness(pose.position, force, touching, stiffness);
    Ok(report)
}

/// What `run_coupled` did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CouplingReport {
    pub steps: u64,
    /// Full updates per second of wall time.
    pub update_rate_hz: Real,
    /// Simulated time, s (behind the wall time when the model is slower than real time).
    pub simulated: Real,
    pub errors: u64,
    pub last_error: Option<String>,
}

/// Steps the simulation in real time (never ahead of the wall clock) for `seconds`, with
/// the model told so (`Deformable::set_real_time`). A failed step is counted and retried
/// with the next pose; the model keeps its last good state.
pub fn run_coupled(
    sim: &mut Simulation,
    index: usize,
    handle: &HapticHandle,
    dt: Real,
    seconds: Real,
) -> CouplingReport {
    sim.model_mut().set_real_time(true);
    let start = Instant::now();
    let t0 = sim.time();
    let mut r = CouplingReport::default();
    let limit = Duration::from_secs_f64(seconds.clamp(0.0, 1e6));
    while start.elapsed() < limit {
        let ahead = (sim.time() - t0) - start.elapsed().as_secs_f64();
        if ahead > 0.0 {
            std::thread::sleep(Duration::from_secs_f64(ahead.min(0.05)));
            continue;
        }
        match step_coupled(sim, index, handle, dt) {
            Ok(_) => r.steps += 1,
            Err(e) => {
                r.errors += 1;
                r.last_error = Some(e.to_string());
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }
    let secs = start.elapsed().as_secs_f64();
    r.update_rate_hz = r.steps as Real / secs.max(1e-9);
    r.simulated = sim.time() - t0;
    r
}
