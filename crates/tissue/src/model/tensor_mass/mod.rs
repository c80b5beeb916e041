//! The tensor-mass family: `tensor-mass` (Cotin et al. 1999, linear) and
//! `tensor-mass-nonlinear` (Picinbono et al. 2000/2003, St Venant–Kirchhoff), survey §2.4.
//!
//! Masses are lumped on the vertices of a tetrahedral mesh; the elastic forces come from
//! stiffness tensors stored on the mesh's vertices and edges, each a sum over the
//! tetrahedra that share it. The non-linear kind computes its St Venant–Kirchhoff terms per
//! element by default (`form = "elements"`, a packed vectorised kernel), or from
//! Picinbono's tensors on vertices, edges, triangles and tetrahedra (`form = "tensors"`;
//! same forces to rounding, about 3× the cost). The forces are
//! those of linear FEM (`tensor-mass`, checked against the assembled K·u) or of St
//! Venant–Kirchhoff (checked against a per-element computation), so the non-linear kind is
//! invariant under rigid rotations where the linear one inflates. Time integration is the
//! shared `integrate` module (explicit by default). Because every tensor is a sum over
//! tetrahedra, removing tetrahedra touched by a scalpel (cutting, electrocautery style)
//! updates the tensors locally.
//!
//! - `elasticity`: ℂ (isotropic + transversely isotropic fibre), per-tetrahedron rest data
//! - `tensors`: edges, the vertex and edge tensors, their local update (Cotin)
//! - `stvk`: the non-linear tensors on vertices, edges, triangles, tetrahedra (Picinbono)
//! - `element`: plain per-element StVK (cross-check, energy, tangent), volume penalty
//! - `kernel`: the element form's StVK force + energy pass, packed 4 tetrahedra per block,
//!   AVX2 when the CPU has it (the baseline's SSE2 / NEON otherwise; the same bits)
//! - `system`: tensors + masses + damping + loads → forces (the `ParticleSystem` the shared
//!   integrators step); the hybrid switch; tetrahedron removal
//! - `cut`: which tetrahedra a blade touches and what else a cut removes; `cut_surface`: the
//!   locally patched boundary; `spatial`: the grid of tetrahedra; `pieces`: fragments found
//!   by local searches; `stability`: the sliver guard that keeps the explicit time step
//! - `model`: `TensorMass`, state + integrator + constraints; `deformable`: the interface

pub mod cut;
pub mod cut_surface;
mod deformable;
pub mod elasticity;
pub mod element;
mod kernel;
mod model;
mod model_cut;
pub mod pieces;
pub mod spatial;
pub mod stability;
pub mod stvk;
pub mod system;
pub mod tensors;

use serde::Deserialize;

use crate::error::{Error, MeshError, SimError};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::TetMesh;

use elasticity::{Elasticity, TetRest};
pub use model::TensorMass;
pub use system::{NonlinearForm, TensorSystem};

/// What happens to pieces a cut separates from the largest one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Fragments {
    /// They keep simulating (falling under gravity, say).
    Keep,
    /// Their tetrahedra are removed too.
    #[default]
    Remove,
}

/// The `[model]` settings of both kinds.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TensorMassParams {
    /// Hybrid switch (non-linear kind only): tetrahedra whose displacement gradient |∂u/∂X|
    /// (Frobenius; strain and rotation together) exceeds this use St Venant–Kirchhoff, the
    /// others the linear force; they return below half of it. 0 (default): all non-linear.
    #[serde(default)]
    pub strain_threshold: Real,
    /// Steps between two hybrid checks (default 10): the check costs about one linear
    /// force evaluation, so it is not done every step.
    #[serde(default = "default_interval")]
    pub hybrid_interval: u32,
    /// Non-linear kind: `elements` (default: the forces per element from the deformation
    /// gradient, a packed vectorised kernel) or `tensors` (Picinbono's tensor form, the
    /// same forces to rounding, about 3× the cost).
    #[serde(default)]
    pub form: NonlinearForm,
    /// Volume-conservation penalty κ, in Pa (default 0: off).
    #[serde(default)]
    pub volume_penalty: Real,
    /// Fibre direction of a transversely isotropic material (default: isotropic).
    #[serde(default)]
    pub fibre: Option<[Real; 3]>,
    /// Extra stiffness along the fibre, λ_f and μ_f, in Pa.
    #[serde(default)]
    pub fibre_lambda: Real,
    #[serde(default)]
    pub fibre_mu: Real,
    /// `remove` (default) or `keep` the pieces a cut separates.
    #[serde(default)]
    pub fragments: Fragments,
    /// `"auto"` (default: as many integrator steps per step as the measured stability limit
    /// needs) or a forced count.
    #[serde(default)]
    pub substeps: crate::integrate::Substeps,
}

fn default_interval() -> u32 {
    10
}

impl Default for TensorMassParams {
    fn default() -> Self {
        Self {
            strain_threshold: 0.0,
            hybrid_interval: default_interval(),
            form: NonlinearForm::Elements,
            volume_penalty: 0.0,
            fibre: None,
            fibre_lambda: 0.0,
            fibre_mu: 0.0,
            fragments: Fragments::Remove,
            substeps: crate::integrate::Substeps::Auto,
        }
    }
}

impl TensorMassParams {
    fn validated(self) -> Result<Self, SimError> {
        let check = |name: &'static str, v: Real| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(SimError::BadParameter {
                    name,
                    value: v.to_string(),
                    reason: "must be a finite value >= 0".into(),
                })
            }
        };
        check("strain_threshold", self.strain_threshold)?;
        check("volume_penalty", self.volume_penalty)?;
        check("fibre_lambda", self.fibre_lambda)?;
        check("fibre_mu", self.fibre_mu)?;
        if let Some(a) = self.fibre {
            let v = Vec3::from_array(a);
            if !(v.is_finite() && v.length() > 0.0) {
                return Err(SimError::BadParameter {
                    name: "fibre",
                    value: format!("{a:?}"),
                    reason: "must be a finite non-zero direction".into(),
                });
            }
        }
        Ok(self)
    }
}

/// Validates the mesh, material and settings and builds the system (all tetrahedra in the
/// non-linear set when `nonlinear`, before any hybrid switch).
pub fn build_system(
    mesh: &TetMesh,
    material: Material,
    params: &TensorMassParams,
    nonlinear: bool,
) -> Result<(TetMesh, TensorSystem), Error> {
    let material = material.validated()?;
    let params = params.clone().validated()?;
    mesh.validate_for_simulation()?;
    let mesh = mesh.compacted();
    let mut rest = Vec::with_capacity(mesh.tets.len());
    for t in 0..mesh.tets.len() {
        rest.push(
            TetRest::new(&mesh.corners(t)).ok_or(MeshError::DegenerateTet {
                tet: t,
                volume: mesh.tet_volume(t),
                quality: 0.0,
            })?,
        );
    }
    let mut el = Elasticity::isotropic(material.lambda(), material.mu());
    if let Some(a) = params.fibre {
        el = el.with_fibre(Vec3::from_array(a), params.fibre_lambda, params.fibre_mu);
    }
    let elasticity = vec![el; mesh.tets.len()];
    let system = TensorSystem::new(
        &mesh,
        rest,
        elasticity,
        &material,
        params.volume_penalty,
        nonlinear.then_some(params.form),
    );
    Ok((mesh, system))
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_cut;
#[cfg(test)]
mod tests_damping;
#[cfg(test)]
mod tests_dynamics;
