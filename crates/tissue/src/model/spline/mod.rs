//! `spline`: elastically deformable B-spline surfaces (Terzopoulos et al. 1987), the first
//! deformable models: a smooth cubic spline surface whose control points carry mass, with an
//! energy for stretching and bending measured against the rest shape.
//!
//! - `basis`: cubic B-spline basis, clamped and periodic knots
//! - `surface`: tensor-product surfaces (open patches, tubes periodic around)
//! - `energy`: the shell energy, its exact gradient and a Gauss–Newton stiffness
//! - `fit`: least-squares fit to a sheet or tube mesh; other topologies refused with a reason
//! - `tessellation`: control points → rendered surface grid, and the transpose for forces
//! - `system`: the control net as a `ParticleSystem` (masses, damping, penalty holds)
//! - `deformable`: `SplineModel`, the `Deformable` interface and the `[model]` settings
//!
//! Dynamics are Lagrangian: M ẍ + α M ẋ = f(x) with lumped masses ρ h ∫ N_i dA₀ and
//! mass-proportional damping α (`material.damping`; the stiffness-proportional β is not
//! used), integrated by any shared scheme (`integrator = "..."`).
//!
//! What it cannot do: cut (one smooth patch), represent closed organs (one patch is a sheet
//! or a tube), or conserve volume (it is a hollow shell). Held surface vertices sit |f|/k from
//! their targets (penalty springs, see `system`).

pub mod basis;
mod deformable;
pub mod energy;
pub mod fit;
mod params;
pub mod surface;
pub mod system;
pub mod tessellation;

pub use basis::{Basis, KnotKind};
pub use deformable::{SplineModel, SplineParams};
pub use energy::ShellEnergy;
pub use fit::{Fit, Topology, fit_mesh, fit_points};
pub use surface::{SplineSurface, Stencil};
pub use system::ControlNet;
pub use tessellation::Tessellation;

#[cfg(test)]
mod deformable_tests;
#[cfg(test)]
mod tests;
