//! `fem-explicit`: the central-difference scheme (7) with lumped M and D = αM.
//!
//! Each step is one sparse product K U_t over the assembled pattern and a diagonal update;
//! nothing is allocated. The scheme is stable only for Δt < 2/ω_max: with `substeps = "auto"`
//! (the default) a larger Δt is split into substeps of at most `SAFETY`·2/ω_max (the linear
//! model does not stiffen, so the estimate at build holds for the whole run), prescribed
//! vertices moving in a straight line to their targets across them; `substeps = N` forces a
//! count. A step whose result is not finite or whose energy jumps more than 10⁶-fold returns
//! `SimError::Diverged` and keeps the state of the last good step (all its substeps undone).

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::integrate::Substeps;
use crate::integrate::stable_step::{MAX_SUBSTEPS, substeps_for};
use crate::material::Material;
use crate::math::Real;
use crate::mesh::TetMesh;
use crate::model::registry::parse_params;
use crate::model::{BuildInput, StepInfo};

use super::common::{Core, forward_deformable};

/// `fem-explicit`'s `[model]` settings (the damping is the material's `damping`).
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// `"auto"` (default) or a forced count of central-difference steps per step.
    #[serde(default)]
    substeps: Substeps,
}

/// Fraction of the power-iteration estimate of 2/ω_max an automatic substep takes (the
/// estimate is a few per cent optimistic at most).
pub const SAFETY: Real = 0.9;

/// The step in progress, kept to undo its substeps if one fails.
#[derive(Default)]
struct Saved {
    u: Vec<Real>,
    u_prev: Vec<Real>,
    r: Vec<Real>,
    targets: Vec<Real>,
    last_dt: Option<Real>,
    energy: Real,
    steps: u64,
}

/// Linear elastodynamics, central differences, lumped mass (survey eq. (6)-(7)).
pub struct FemExplicit {
    pub(super) core: Core,
    substeps: Substeps,
    last_substeps: u32,
    saved: Saved,
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
        let p: Params = parse_params("fem-explicit", input.params)?;
        let mut m = Self::new(&input.mesh.tet_mesh(input.source)?, input.material)?;
        m.substeps = p.substeps;
        Ok(m)
    }

    /// Validates, assembles K and the lumped masses, estimates ω_max.
    pub fn new(mesh: &TetMesh, material: Material) -> Result<Self, Error> {
        Ok(Self {
            core: Core::new(mesh, material)?,
            substeps: Substeps::Auto,
            last_substeps: 0,
            saved: Saved::default(),
        })
    }

    /// Sets the substep rule (`Auto` by default).
    pub fn set_substeps(&mut self, substeps: Substeps) {
        self.substeps = substeps;
    }

    /// The longest substep `Auto` takes: `SAFETY` times the power-iteration 2/ω_max.
    pub fn stable_dt(&self) -> Real {
        SAFETY * self.core.critical_dt()
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
        Core::check_dt(dt)?;
        let n = match self.substeps {
            Substeps::Fixed(n) => n.max(1),
            Substeps::Auto => {
                substeps_for(dt, self.stable_dt()).ok_or_else(|| SimError::BadParameter {
                    name: "dt",
                    value: format!("{dt:e}"),
                    reason: format!(
                        "fem-explicit is stable only below {:.3e} s on this mesh: more than \
                         {MAX_SUBSTEPS} substeps; use fem-semi-implicit or a smaller dt",
                        self.core.critical_dt()
                    ),
                })?
            }
        };
        if n == 1 {
            self.single(dt)?;
            self.last_substeps = 1;
            return Ok(StepInfo {
                substeps: 1,
                ..StepInfo::default()
            });
        }
        let (c, s) = (&mut self.core, &mut self.saved);
        s.u.clone_from(&c.u);
        s.u_prev.clone_from(&c.u_prev);
        s.r.clone_from(&c.r);
        s.targets.clone_from(&c.problem.targets);
        s.last_dt = c.last_dt;
        s.energy = c.energy;
        s.steps = c.steps;
        let h = dt / Real::from(n);
        let mut result = Ok(());
        for k in 1..=n {
            let f = Real::from(k) / Real::from(n);
            let (c, s) = (&mut self.core, &self.saved);
            for &d in &c.problem.list {
                c.problem.targets[d] = s.u[d] + (s.targets[d] - s.u[d]) * f;
            }
            if let Err(e) = self.single(h) {
                result = Err(e);
                break;
            }
        }
        let (c, s) = (&mut self.core, &self.saved);
        c.problem.targets.clone_from(&s.targets);
        if let Err(e) = result {
            c.u.clone_from(&s.u);
            c.u_prev.clone_from(&s.u_prev);
            c.r.clone_from(&s.r);
            c.last_dt = s.last_dt;
            c.energy = s.energy;
            c.steps = s.steps;
            c.update_positions();
            c.update_reactions();
            return Err(match e {
                SimError::Diverged { node, reason, .. } => SimError::Diverged {
                    step: s.steps + 1,
                    node,
                    reason,
                },
                other => other,
            });
        }
        c.steps = s.steps + 1;
        self.last_substeps = n;
        Ok(StepInfo {
            substeps: n,
            ..StepInfo::default()
        })
    }

    /// One central-difference step of length `dt` (the doc of `advance`).
    fn single(&mut self, dt: Real) -> Result<(), SimError> {
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
        Ok(())
    }

    fn details(&self) -> (usize, Vec<(String, String)>) {
        (
            0,
            vec![
                ("scheme".into(), "central difference (7)".into()),
                ("substeps_setting".into(), self.substeps.describe()),
                ("stable_dt".into(), format!("{:.6e}", self.stable_dt())),
                ("substeps".into(), self.last_substeps.to_string()),
            ],
        )
    }
}

forward_deformable!(FemExplicit, "fem-explicit");
