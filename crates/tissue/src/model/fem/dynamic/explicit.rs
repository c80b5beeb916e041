//! `fem-explicit`: the central-difference scheme (7) with lumped M and D = αM.
//!
//! Each step is one sparse product K U_t over the assembled pattern and a diagonal update;
//! nothing is allocated. The scheme is stable only for Δt < 2/ω_max: with `substeps = "auto"`
//! (the default) a larger Δt is split into substeps of at most `SAFETY`·2/ω_max (the linear
//! model does not stiffen, so the estimate at build holds for the whole run), prescribed
//! vertices moving in a straight line to their targets across them; `substeps = N` forces a
//! count. A step whose result is not finite or whose energy jumps more than 10⁶-fold returns
//! `SimError::Diverged` and keeps the state of the last good step (all its substeps undone).
//!
//! The material's Rayleigh stiffness damping β (`stiffness_damping`) is applied as the
//! tensor-mass kinds apply it (`integrate::split_damping`): kept in the force, its rates β ω²
//! would set a limit 2/(β ω²_max) far below the elastic one, so it is taken out of the
//! scheme and applied once per step implicitly, (M + Δt β K) v = M v* − Δt β K_fh v_h, on
//! the synchronous velocity v* = (U_t − U_{t−h})/h + (h/2) M⁻¹(F − K U_t) of the last
//! substep h (damping the staggered difference alone is not dissipative for the central
//! difference, as for symplectic Euler). U_{t−h} is then moved to carry the damped velocity,
//! and the held vertices' reactions get the damping force −β K v.

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::integrate::Substeps;
use crate::integrate::split_damping::SplitDamping;
use crate::integrate::stable_step::{MAX_SUBSTEPS, substeps_for};
use crate::material::{ElementMaterials, Material};
use crate::math::{Mat3, Real, Vec3};
use crate::mesh::TetMesh;
use crate::model::registry::parse_params;
use crate::model::{BuildInput, StepInfo};

use super::super::element_linear;
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
    /// The split stiffness damping (β > 0 only) and its per-node buffers.
    split: Option<Box<SplitDamping>>,
    split_v: Vec<Vec3>,
    split_force: Vec<Vec3>,
    node_mass: Vec<Real>,
    held: Vec<bool>,
    /// Contact nodes' U before `push_contacts` moved them in the (sub)step in progress.
    undo: Vec<(usize, Vec3)>,
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
        let mesh = input.mesh.tet_mesh(input.source)?;
        let materials = input.element_materials(mesh.tets.len())?;
        let mut m = Self::with_materials(&mesh, &materials)?;
        m.substeps = p.substeps;
        Ok(m)
    }

    /// Validates, assembles K and the lumped masses, estimates ω_max.
    pub fn new(mesh: &TetMesh, material: Material) -> Result<Self, Error> {
        Self::with_materials(mesh, &ElementMaterials::Uniform(material))
    }

    /// Like `new`, each element with its own material (e in the order of `mesh.tets`).
    pub fn with_materials(mesh: &TetMesh, materials: &ElementMaterials) -> Result<Self, Error> {
        let core = Core::new(mesh, materials)?;
        let beta = core.material.stiffness_damping;
        let split = (beta > 0.0).then(|| {
            let m = &core.mesh;
            let mut split =
                SplitDamping::new(core.rest.len(), &m.tets, beta).with_positions(&core.rest);
            split.assemble((0..m.tets.len()).filter_map(|e| {
                let k = element_linear::stiffness(&m.corners(e), core.materials.of(e))?;
                let block = |a: usize, b: usize| {
                    let col = |j: usize| {
                        Vec3::new(
                            k[3 * a][3 * b + j],
                            k[3 * a + 1][3 * b + j],
                            k[3 * a + 2][3 * b + j],
                        )
                    };
                    Mat3::from_cols(col(0), col(1), col(2))
                };
                Some((
                    m.tets[e],
                    std::array::from_fn(|a| std::array::from_fn(|b| block(a, b))),
                ))
            }));
            Box::new(split)
        });
        let nodes = core.rest.len();
        let node_mass = (0..nodes).map(|i| core.mass[3 * i]).collect();
        Ok(Self {
            core,
            substeps: Substeps::Auto,
            last_substeps: 0,
            saved: Saved::default(),
            split,
            split_v: vec![Vec3::ZERO; nodes],
            split_force: vec![Vec3::ZERO; nodes],
            node_mass,
            held: vec![false; nodes],
            undo: Vec::new(),
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
    /// then held dofs take their targets; then the split stiffness damping (β > 0).
    fn advance(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        Core::check_dt(dt)?;
        // Factorised before the step, so that a failure leaves the state as it was.
        let split = self.prepare_split(dt)?;
        let info = self.advance_elastic(dt)?;
        if split {
            self.apply_split(dt / Real::from(info.substeps.max(1)));
        }
        Ok(info)
    }

    /// Factorises the split damping's matrix for `dt` and the held nodes (once, again when
    /// they change). False without β.
    fn prepare_split(&mut self, dt: Real) -> Result<bool, SimError> {
        let Some(split) = self.split.as_mut() else {
            return Ok(false);
        };
        let constrained = &self.core.problem.constrained;
        for (i, h) in self.held.iter_mut().enumerate() {
            *h = constrained[3 * i];
        }
        split.prepare(dt, &self.node_mass, &self.held)?;
        Ok(true)
    }

    /// The damping step after the elastic substeps of length `h` (see the module doc).
    fn apply_split(&mut self, h: Real) {
        let Some(split) = self.split.as_mut() else {
            return;
        };
        let c = &mut self.core;
        c.assembler.pattern.mul_vec(&c.k, &c.u, &mut c.ku);
        let shift = |d: usize| {
            if c.problem.constrained[d] {
                0.0
            } else {
                0.5 * h * (c.problem.forces[d] - c.ku[d]) / c.mass[d]
            }
        };
        for (i, v) in self.split_v.iter_mut().enumerate() {
            *v = Vec3::from_array(std::array::from_fn(|j| {
                let d = 3 * i + j;
                (c.u[d] - c.u_prev[d]) / h + shift(d)
            }));
        }
        if !split.apply(&self.node_mass, &mut self.split_v, &mut self.split_force) {
            return;
        }
        for (i, (v, f)) in self.split_v.iter().zip(&self.split_force).enumerate() {
            for j in 0..3 {
                let d = 3 * i + j;
                if c.problem.constrained[d] {
                    c.r[d] += f[j];
                } else {
                    c.u_prev[d] = c.u[d] - h * (v[j] - shift(d));
                }
            }
        }
        c.update_reactions();
    }

    /// The elastic central-difference substeps of `advance`.
    fn advance_elastic(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        self.core.clear_impulses();
        // A refused step's sweep cap is not this step's.
        self.core.projection.take_capped();
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
            self.core.finish_pushes(dt);
            self.last_substeps = 1;
            return Ok(StepInfo {
                substeps: 1,
                capped: self.core.projection.take_capped(),
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
        c.finish_pushes(dt);
        self.last_substeps = n;
        Ok(StepInfo {
            substeps: n,
            capped: c.projection.take_capped(),
            ..StepInfo::default()
        })
    }

    /// One central-difference step of length `dt` (the doc of `advance`); contact nodes
    /// are free in it and put back out of their instruments after it (`push_contacts`).
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
        self.undo.clear();
        c.push_contacts(dt, &mut self.undo);
        c.project_points(dt, &mut self.undo);
        let energy = c.trial_energy(dt);
        if let Err(e) = c.check_trial(energy, "explicit step") {
            c.undo_pushes(&self.undo);
            c.abort_step();
            return Err(e);
        }
        for k in &mut c.contacts {
            k.impulse += k.trial;
        }
        for (i, t) in c.point_impulse.iter_mut().zip(&c.point_trial) {
            *i += t;
        }
        c.accept(dt, energy);
        Ok(())
    }

    fn details(&self) -> (usize, Vec<(String, String)>) {
        (
            0,
            vec![
                ("scheme".into(), "central difference (7)".into()),
                (
                    "split_stiffness_damping".into(),
                    self.split.is_some().to_string(),
                ),
                ("substeps_setting".into(), self.substeps.describe()),
                ("stable_dt".into(), format!("{:.6e}", self.stable_dt())),
                ("substeps".into(), self.last_substeps.to_string()),
            ],
        )
    }
}

forward_deformable!(FemExplicit, "fem-explicit");
