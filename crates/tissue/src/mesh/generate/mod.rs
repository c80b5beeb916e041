//! Test bodies and simple organs made from parameters: tetrahedral boxes and beams,
//! spheres, cylinders and tubes.

mod box_grid;

pub use box_grid::{BoxSplit, box_tets};
