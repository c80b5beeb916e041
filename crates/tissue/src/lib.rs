//! tissue: real-time deformable models of soft tissue for surgery simulation.
//!
//! Load an organ mesh (`io::read`), build a model by kind (`model::build`) or directly,
//! fix the attachments, touch it with instruments, and step it: the deformed surface for
//! drawing and the instrument force for a haptic device come out. Every model implements
//! `model::Deformable`. SI units (m, kg, s, Pa, N) and `f64` throughout.

pub mod benchmark;
pub mod compare;
pub mod error;
pub mod haptic;
pub mod image;
pub mod integrate;
pub mod interact;
pub mod io;
pub mod material;
pub mod math;
pub mod mesh;
pub mod metrics;
pub mod model;
pub mod scene;
pub mod sim;
pub mod solve;
pub mod voxel;

pub use error::{Error, IoError, MeshError, SceneError, SimError};
pub use material::Material;
pub use math::{Mat3, Real, Vec3};
