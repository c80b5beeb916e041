//! Instruments and their contact with the surface: constraints, regions, the probe,
//! contact detection with a bounding-volume hierarchy.

pub mod constraints;
pub mod region;

pub use constraints::{Constraints, Loads, Prescribed};
pub use region::Region;
