//! `fem-explicit`: the central-difference scheme (7) with lumped M and D = αM.
//!
//! Each step is one sparse product K U_t over the assembled pattern and a diagonal update;
//! nothing is allocated. The scheme is stable only for Δt < 2/ω_max; a larger Δt is still
//! attempted, and a step whose result is not finite or whose energy jumps more than 10⁶-fold
//! returns `SimError::Diverged` and keeps the previous state.

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::material::Material;
use crate::math::Real;
use crate::mesh::TetMesh;
use crate::model::registry::parse_params;
use crate::model::{BuildInput, StepInfo};

use super::common::{Core, forward_deformable};

/// `fem-explicit` takes no `[model]` settings: the damping is the material's `damping`.
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct NoParams {}

/// Linear elastodynamics, central differences, lumped mass (survey eq. (6)-(7)).
pub struct FemExplicit {
    pub(super) core: Core,
}

impl std::fmt::Debug for FemExplicit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemExplicit")
            .field("nodes", &self.core.rest.len())
            .field("critical_dt", &self.core.critical_dt())
            .finish()
    }
}

impl FemExplicit {
    /// Builds from the registry's input (no model settings).
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let _: NoParams = parse_params("fem-explicit", input.params)?;
        Self::new(&input.mesh.tet_mesh(input.source)?, input.material)
    }

    /// Validates, assembles K and the lumped masses, estimates ω_max.
    pub fn new(mesh: &TetMesh, material: Material) -> Result<Self, Error> {
        Ok(Self {
            core: Core::new(mesh, material)?,
        })
    }

    /// 2/ω_max, ω_max² from power iteration on M⁻¹K (a few per cent optimistic at most).
    pub fn critical_dt(&self) -> Real {
        self.core.critical_dt()
    }

    /// 2/ω with ω² the Gershgorin bound of M⁻¹K: steps below it are guaranteed stable.
    pub fn critical_dt_bound(&self) -> Real {
        self.core.critical_dt_bound()
    }

    /// Current displacements U_t, flat per dof (node-major), in m.
    pub fn displacements(&self) -> &[Real] {
        &self.core.u
    }

    /// Discrete energy after the last step, in J (see `Core::trial_energy`).
    pub fn energy(&self) -> Real {
        self.core.energy
    }

    /// Lumped mass per dof, in kg.
    pub fn masses(&self) -> &[Real] {
        &self.core.mass
    }

    /// Mechanical node of each surface vertex.
    pub fn surface_nodes(&self) -> &[u32] {
        &self.core.boundary.nodes
    }

    /// Sets U_t and the velocity (flat per dof) as if the last step had length `dt`.
    pub fn set_state(&mut self, u: &[Real], velocity: &[Real], dt: Real) -> Result<(), SimError> {
        self.core.set_state(u, velocity, dt)
    }

    /// One central-difference step, eq. (7):
    /// U⁺ = (α/2 + 1/Δt)⁻¹ [ (2/Δt) U + (α/2 − 1/Δt) U⁻ − Δt M⁻¹ (K U − F) ],
    /// then held dofs take their targets.
    fn advance(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        let c = &mut self.core;
        c.begin_step(dt)?;
        c.assembler.pattern.mul_vec(&c.k, &c.u, &mut c.ku);
        let half_alpha = 0.5 * c.material.damping;
        let inv = 1.0 / (half_alpha + 1.0 / dt);
        let (a, b) = (2.0 / dt, half_alpha - 1.0 / dt);
        let p = &c.problem;
        for d in 0..c.u.len() {
            c.u_next[d] = if p.constrained[d] {
                p.targets[d]
            } else {
                inv * (a * c.u[d] + b * c.u_prev[d] - dt / c.mass[d] * (c.ku[d] - p.forces[d]))
            };
        }
        let energy = c.trial_energy(dt);
        if let Err(e) = c.check_trial(energy, "explicit step") {
            c.abort_step();
            return Err(e);
        }
        c.accept(dt, energy);
        Ok(StepInfo::default())
    }

    fn details(&self) -> (usize, Vec<(String, String)>) {
        (0, vec![("scheme".into(), "central difference (7)".into())])
    }
}

forward_deformable!(FemExplicit, "fem-explicit");
