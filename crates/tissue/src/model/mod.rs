//! The deformable models, one module per family, all behind the `Deformable` interface.
//!
//! The survey's view of interaction, shared by every model: an instrument touches the
//! surface; the touched surface vertices get prescribed positions; the model computes the
//! deformation of everything else and the reaction force at each constrained vertex. Fixed
//! vertices are constraints with zero displacement. Cutting is accepted or refused with
//! `SimError::Unsupported`.

pub mod bem;
pub mod chainmail;
mod deformable;
pub mod fem;
pub mod hybrid;
pub mod linked_volumes;
mod progress;
mod reactions;
#[cfg(test)]
mod region_tests;
pub mod registry;
pub mod spline;
pub mod spring_mass;
pub mod tensor_mass;
#[cfg(test)]
pub(crate) mod testing;

pub use deformable::{
    ContactSurface, CutInfo, CutPath, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView,
    VolumeView,
};
pub use progress::Progress;
pub use reactions::ConstraintReactions;
pub use registry::{
    BodyNeed, BodyShape, BuildInput, KINDS, KindInfo, REGION_KINDS, build, regions_refusal,
};
