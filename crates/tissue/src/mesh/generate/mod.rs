//! Test bodies and simple organs made from parameters: tetrahedral boxes and beams,
//! spheres, cylinders and tubes.

mod box_grid;
mod sphere;
mod tube;

pub use box_grid::{BoxSplit, box_tets};
pub use sphere::{MAX_SUBDIVISIONS, icosphere};
pub use tube::{cylinder, tube, tube_with_wall};
