//! Instruments and their contact with the surface: constraints, regions, the probe,
//! contact detection with a bounding-volume hierarchy.

pub mod bvh;
pub mod constraints;
pub mod contact;
pub mod fine_points;
pub mod fine_surface;
pub mod instrument;
pub mod plausibility;
pub mod region;
pub mod shape;
pub mod sliding;
pub mod slip;
pub mod trajectory;

pub use bvh::Bvh;
pub use constraints::{Constraints, Loads, PointContact, Prescribed, SurfaceHold};
pub use contact::Contact;
pub use fine_surface::MappedSurface;
pub use instrument::{Instrument, InstrumentKind};
pub use region::Region;
pub use shape::Shape;
pub use trajectory::{Keyframe, Trajectory, TrajectoryError};

#[cfg(test)]
mod tests_dynamic_sliding;
