//! Meshes: triangle surfaces, tetrahedral volumes, the loaded-file union `MeshData`,
//! topology, quality checks and repairs, generators, and the surface mapping.

pub mod boundary;
pub mod check;
pub mod data;
pub mod generate;
pub mod mapping;
pub mod quality;
pub mod repair;
pub mod surface;
pub mod tet;
pub mod topology;

pub use boundary::{Boundary, TET_FACES, boundary_surface};
pub use data::{Field, MaterialRecord, MeshData};
pub use mapping::SurfaceMapping;
pub use surface::SurfaceMesh;
pub use tet::TetMesh;
