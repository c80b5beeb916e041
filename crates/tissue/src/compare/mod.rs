//! `tissue compare`'s engine: every model kind on the same organ and scenarios, measured
//! through the public interface only (`Deformable`, `Simulation`, `ModelInfo`, `StepInfo`),
//! then scored against the survey's Table 1 (13 weighted criteria in three groups).
//!
//! - `setup`: the organ and the scenario geometry taken from its bounding box;
//! - `drive`: quasi-static ramps that hold until the model settles;
//! - `measure`: the measurements of one kind;
//! - `reference`: quadratic `fem-static` on the organ and on refined meshes;
//! - `score`: the documented rules turning measurements into 0..weight;
//! - `survey`: Table 1's criteria, weights and the survey's own scores;
//! - `record`: the JSON record (serde).

pub mod drive;
pub mod measure;
pub mod record;
pub mod reference;
pub mod score;
pub mod setup;
pub mod survey;
#[cfg(test)]
mod tests_settle;

use serde::{Deserialize, Serialize};

use crate::math::{Real, Vec3};
use crate::mesh::MeshData;
use crate::mesh::generate::{BoxSplit, box_tets};

pub use measure::measure_kind;
pub use record::{CompareRecord, KindRecord, KindScores, Measure};
pub use reference::{Reference, reference};
pub use score::score_kind;
pub use setup::{Organ, Scenario, Stuffing};

/// `Settings::settle_dt_max` (records written before it had 4 ms with `--quick`).
fn default_settle_dt_max() -> Real {
    1e-3
}

/// How thorough the comparison is. `quick` is CI's: coarse and short.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    pub quick: bool,
    /// Steps of the stability test at each tried step.
    pub stability_steps: usize,
    /// Bisections of the stable step between `dt_min` and `dt_max`.
    pub bisections: usize,
    pub dt_min: Real,
    pub dt_max: Real,
    /// Largest step of dynamic models in the quasi-static scenarios, s (half the stable step
    /// below it).
    pub run_dt_max: Real,
    /// Largest step of the quasi-static runs that settle by kinetic damping (the shallow and
    /// deep indentations, the plate, the bar), s. Kinetic damping stops the motion the step
    /// after a peak of the kinetic energy: with few steps per period of the mode that carries
    /// it, that is far past the peak and leaves most of the mode's energy. At `--quick`'s
    /// 4 ms the plate at ν = 0.45 (its dilatational modes 1.7 times faster than at 0.3) and
    /// `tensor-mass-nonlinear`'s shallow press stopped every second or third step with the
    /// kinetic energy stuck near 2e-6 of its peak, never at rest; at 1 ms both come to rest
    /// (below 1e-9) by 1.3 s (`compare::tests_settle::settling_trace_study`,
    /// `SETTLE_DT_MAX`). The full run's `run_dt_max` is already 1 ms.
    #[serde(default = "default_settle_dt_max")]
    pub settle_dt_max: Real,
    /// Haptic steps timed for the cost of a simulated millisecond.
    pub cost_steps: usize,
    pub random_paths: usize,
    pub random_step_cap: usize,
    /// Ramp time and time limit of quasi-static runs of dynamic models, s. The limit is the
    /// full run's with `--quick` too: on the k = 3 fine surface (`drive::fine_levels`) the
    /// shallow press of `fem-explicit` comes to rest after 1.48 s, at the edge of the former
    /// 1.5 s, and the deep presses of `fem-explicit` and `tensor-mass` at 1.85 and 1.93 s
    /// (`compare::tests_settle`). A run that settles stops early: only the unsettled ones
    /// pay for it.
    pub ramp: Real,
    pub settle_time: Real,
    /// Load increments of static models.
    pub increments: usize,
    /// Simulated time of the step response, s.
    pub dynamics_time: Real,
    /// Refinements (`split_tets`) of the organ for the reference, after the organ itself.
    pub reference_refinements: usize,
    /// Cells of the bar along its length.
    pub bar_cells: usize,
    /// Tetrahedra stuffed into an organ given as a surface (for the kinds that need a volume
    /// and for the reference).
    pub surface_tets: usize,
    /// Refinements (`split_tets`) of the organ each kind is also measured on: the mesh-size
    /// ladder of "mesh dimension" and of the cost-size plot.
    pub ladder_refinements: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self::quick()
    }
}

impl Settings {
    pub fn quick() -> Self {
        Self {
            quick: true,
            stability_steps: 40,
            bisections: 4,
            dt_min: 1e-6,
            dt_max: 0.05,
            run_dt_max: 4e-3,
            settle_dt_max: default_settle_dt_max(),
            cost_steps: 50,
            random_paths: 4,
            random_step_cap: 300,
            ramp: 0.15,
            settle_time: 2.5,
            increments: 3,
            dynamics_time: 0.4,
            reference_refinements: 1,
            bar_cells: 8,
            surface_tets: 800,
            ladder_refinements: 0,
        }
    }

    pub fn full() -> Self {
        Self {
            quick: false,
            stability_steps: 100,
            bisections: 7,
            dt_min: 1e-6,
            dt_max: 0.05,
            run_dt_max: 1e-3,
            settle_dt_max: default_settle_dt_max(),
            cost_steps: 200,
            random_paths: 12,
            random_step_cap: 2000,
            ramp: 0.2,
            settle_time: 2.5,
            increments: 5,
            dynamics_time: 0.8,
            reference_refinements: 2,
            bar_cells: 12,
            surface_tets: 2000,
            ladder_refinements: 1,
        }
    }
}

/// The bar of the parameter test: length, width, height in m (4:1:1).
pub const BAR: [Real; 3] = [0.08, 0.02, 0.02];

/// The bar's tetrahedral mesh.
pub fn bar_mesh(s: &Settings) -> MeshData {
    let n = s.bar_cells.max(4);
    let w = (n / 4).max(2);
    MeshData::from_tets(&box_tets(
        Vec3::ZERO,
        Vec3::from(BAR),
        [n, w, w],
        BoxSplit::Six,
    ))
}
