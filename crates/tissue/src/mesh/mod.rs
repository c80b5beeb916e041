//! Meshes: triangle surfaces, tetrahedral volumes, the loaded-file union `MeshData`,
//! topology, quality checks and repairs, generators, and the surface mapping.

pub mod boundary;
pub mod check;
pub mod data;
pub mod generate;
pub mod inspect;
pub mod mapping;
pub mod quality;
pub mod refine;
pub mod repair;
pub mod spatial_grid;
pub mod stuffing;
pub mod surface;
pub mod tet;
pub mod topology;

pub use boundary::{Boundary, TET_FACES, boundary_surface};
pub use check::{Problem, check, check_surface, check_tets};
pub use data::{Field, MaterialRecord, MeshData};
pub use inspect::{Inspection, inspect};
pub use mapping::SurfaceMapping;
pub use quality::{QualityStats, tet_quality, triangle_quality};
pub use refine::split_tets;
pub use repair::{RepairOptions, RepairReport, repair};
pub use surface::SurfaceMesh;
pub use tet::TetMesh;
