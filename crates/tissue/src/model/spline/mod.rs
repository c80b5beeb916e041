//! `spline`: elastically deformable B-spline surfaces (Terzopoulos et al. 1987), the first
//! deformable models: a smooth cubic spline surface whose control points carry mass, with an
//! energy for stretching and bending measured against the rest shape.
//!
//! - `basis`: cubic B-spline basis, clamped and periodic knots
//! - `surface`: tensor-product surfaces (open patches, tubes periodic around)
//! - `energy`: the shell energy, its exact gradient and a Gauss–Newton stiffness

pub mod basis;
pub mod energy;
pub mod fit;
pub mod surface;

pub use basis::{Basis, KnotKind};
pub use energy::ShellEnergy;
pub use surface::{SplineSurface, Stencil};

#[cfg(test)]
mod tests;
