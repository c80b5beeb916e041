//! `fem-static`: linear elastostatics on tetrahedra, the reference every other model is
//! compared with.
//!
//! It solves K u = f (eq. (4) of the survey): small strains, linear isotropic elasticity,
//! 4-node (constant strain) or 10-node (linear strain) tetrahedra, constraints eliminated,
//! sparse Cholesky factorised once per set of constrained vertices. Because the strain is
//! linearised, large rotations are not rigid: a rotated body gains volume and spurious
//! stress (the corotational and hyperelastic models fix that). It cannot cut: its matrix and
//! factorisation are built for a fixed topology.
//!
//! - `element_linear`: the 4-node tetrahedron (gradients, B and D, 12×12 stiffness, body load)
//! - `element_quadratic`: the 10-node tetrahedron (VTK order, 4-point rule, 30×30 stiffness)
//! - `quadratic_mesh`: 10-node mesh from a linear one (one node per unique edge)
//! - `assembly`: sparsity pattern once, element-to-slot table, scatter-add
//! - `system`: constraint elimination keeping the pattern, factorisation cache, rigid-mode check
//! - `mass`: lumped nodal masses for the dynamic variants
//! - `static_model`: `FemStatic`, node-level API; `deformable_impl`: the `Deformable` interface
//! - `surface_nodes`: surface vertices (as constraints and loads name them) to mesh nodes
//! - `surface_response`: K condensed onto the surface (C, W = C⁻¹), shared by the two below
//! - `condensed`: `fem-condensed`, fast finite elements (Bro-Nielsen), pre-inverted compliance
//! - `precomputed`: `fem-precomputed-tensors`, Cotin's displacement/force tensors
//! - `dynamic`: `fem-explicit` and `fem-semi-implicit`, linear elastodynamics (eq. (6)-(10))
//! - `corotational`: `fem-corotational`, rotated linear elements, implicit Euler + PCG

mod assembly;
mod condensed;
pub mod corotational;
mod deformable_impl;
pub mod dynamic;
pub mod element_linear;
pub mod element_quadratic;
pub mod mass;
mod precomputed;
pub mod quadratic_mesh;
mod static_model;
mod surface_nodes;
mod surface_response;
mod system;

pub use assembly::Assembler;
pub use condensed::FemCondensed;
pub use corotational::{CorotationalParams, CorotationalSolver, FemCorotational};
pub use dynamic::{FemExplicit, FemSemiImplicit};
pub use precomputed::FemPrecomputedTensors;
pub use quadratic_mesh::QuadraticMesh;
pub use static_model::{FemStatic, NodalProblem, NodalSolution, Order, SurfaceNodes};
pub use system::{ALONG_CAP, AlongHold, DofProblem, SchurRule};

#[cfg(test)]
mod tests;
