//! `fem-semi-implicit`: eq. (8)-(10), the same difference quotients as (7) with the elastic
//! force taken at the end of the step, K̂ U⁺ = F̂.
//!
//! K̂ = K + (1/Δt² + α/(2Δt)) M keeps K's pattern (M is diagonal), so it goes through the
//! static model's `System`: held dofs eliminated without changing the pattern, symbolic
//! analysis once, a numeric factorisation once per (Δt, held set), then one solve per step.
//! For this linear system the scheme is implicit in K and unconditionally stable.

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::integrate::contact::HeldContacts;
use crate::material::{ElementMaterials, Material};
use crate::math::{Real, Vec3};
use crate::mesh::TetMesh;
use crate::model::registry::parse_params;
use crate::model::{BuildInput, StepInfo};

use super::super::system::{DofProblem, System};
use super::common::{Core, forward_deformable};
use super::contacts;

#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct NoParams {}

/// Linear elastodynamics with the stiffness at the end of the step (survey eq. (8)-(10)).
pub struct FemSemiImplicit {
    pub(super) core: Core,
    system: System,
    /// The Δt whose K̂ is in `system`.
    factored_dt: Option<Real>,
    /// The problem handed to `system`: held set and targets of `core.problem`, forces F̂.
    hat: DofProblem,
    khat: Vec<Real>,
    diag: Vec<usize>,
    reactions_scratch: Vec<Real>,
    /// The step in progress's contacts held along their normals, and their pushes, N.
    held: HeldContacts,
    pushes: Vec<Real>,
    /// Per node: a contact on it pushed in the last step.
    pushed: Vec<bool>,
    /// Solves the last step's active set took.
    rounds: usize,
    /// The mesh's size (bounding-box diagonal), m: the scale of roundoff in positions.
    length: Real,
}

impl std::fmt::Debug for FemSemiImplicit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FemSemiImplicit")
            .field("nodes", &self.core.rest.len())
            .field("factored_dt", &self.factored_dt)
            .finish()
    }
}

impl FemSemiImplicit {
    /// Builds from the registry's input (no model settings).
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let _: NoParams = parse_params("fem-semi-implicit", input.params)?;
        let mesh = input.mesh.tet_mesh(input.source)?;
        let materials = input.element_materials(mesh.tets.len())?;
        Self::with_materials(&mesh, &materials)
    }

    /// Validates, assembles K and M and analyses K̂'s pattern (factorised at the first step).
    pub fn new(mesh: &TetMesh, material: Material) -> Result<Self, Error> {
        Self::with_materials(mesh, &ElementMaterials::Uniform(material))
    }

    /// Like `new`, each element with its own material (e in the order of `mesh.tets`).
    pub fn with_materials(mesh: &TetMesh, materials: &ElementMaterials) -> Result<Self, Error> {
        let start = std::time::Instant::now();
        let mut core = Core::new(mesh, materials)?;
        let mut system = System::new(core.assembler.clone(), core.k.clone(), core.rest.clone())?;
        system.allow_free_body = true;
        let dofs = core.dofs();
        let (lo, hi) = core.rest.iter().fold(
            (Vec3::splat(Real::INFINITY), Vec3::splat(Real::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let length = (hi - lo).length();
        core.precompute_seconds += start.elapsed().as_secs_f64();
        Ok(Self {
            diag: core.assembler.pattern.diagonal_slots(),
            khat: core.k.clone(),
            core,
            system,
            factored_dt: None,
            hat: DofProblem::new(dofs),
            reactions_scratch: vec![0.0; dofs],
            held: HeldContacts::default(),
            pushes: Vec::new(),
            pushed: vec![false; dofs / 3],
            rounds: 0,
            length,
        })
    }

    /// The explicit scheme's 2/ω_max on the same mesh, for comparison.
    pub fn explicit_critical_dt(&self) -> Real {
        self.core.critical_dt()
    }

    /// Current displacements U_t, flat per dof, in m.
    pub fn displacements(&self) -> &[Real] {
        &self.core.u
    }

    /// Energy ½ vᵀMv + ½ UᵀKU after the last step (v over free dofs), in J.
    pub fn energy(&self) -> Real {
        self.core.energy
    }

    /// Mechanical node of each surface vertex.
    pub fn surface_nodes(&self) -> &[u32] {
        &self.core.boundary.nodes
    }

    /// Numeric factorisations so far: one per (Δt, held set).
    pub fn refactorizations(&self) -> usize {
        self.system.refactorizations
    }

    /// Sets U_t and the velocity (flat per dof) as if the last step had length `dt`.
    pub fn set_state(&mut self, u: &[Real], velocity: &[Real], dt: Real) -> Result<(), SimError> {
        self.core.set_state(u, velocity, dt)
    }

    /// One step: K̂ U⁺ = F̂ with F̂ = F + M [ (2/Δt²) U − (1/Δt² − α/(2Δt)) U⁻ ] (eq. (10)),
    /// plus Rayleigh stiffness damping β K on the central velocity (U⁺ − U⁻)/(2Δt), which the
    /// survey's form leaves out: K̂ gains β/(2Δt) K and F̂ gains β/(2Δt) K U⁻.
    fn advance(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        Core::check_dt(dt)?;
        let alpha = self.core.material.damping;
        let (inv2, damp) = (1.0 / (dt * dt), alpha / (2.0 * dt));
        let stiff_damp = self.core.material.stiffness_damping / (2.0 * dt);
        if self.factored_dt != Some(dt) {
            for (kh, &k) in self.khat.iter_mut().zip(&self.core.k) {
                *kh = (1.0 + stiff_damp) * k;
            }
            for (d, &s) in self.diag.iter().enumerate() {
                self.khat[s] += (inv2 + damp) * self.core.mass[d];
            }
            self.system.set_values(&self.khat);
            self.factored_dt = Some(dt);
        }
        let c = &mut self.core;
        c.begin_step(dt)?;
        let p = &c.problem;
        for d in 0..c.u.len() {
            self.hat.forces[d] =
                p.forces[d] + c.mass[d] * (2.0 * inv2 * c.u[d] - (inv2 - damp) * c.u_prev[d]);
        }
        if stiff_damp > 0.0 {
            // K U⁻ into `ku`, which is recomputed from U⁺ below.
            c.assembler.pattern.mul_vec(&c.k, &c.u_prev, &mut c.ku);
            for (f, ku) in self.hat.forces.iter_mut().zip(&c.ku) {
                *f += stiff_damp * ku;
            }
        }
        if let Err(e) = self.solve_with_contacts() {
            self.core.abort_step();
            return Err(e);
        }
        let c = &mut self.core;
        c.assembler.pattern.mul_vec(&c.k, &c.u_next, &mut c.ku);
        let mut energy = 0.0;
        for d in 0..c.u.len() {
            energy += c.u_next[d] * c.ku[d];
            if !c.problem.constrained[d] {
                let v = (c.u_next[d] - c.u[d]) / dt;
                energy += c.mass[d] * v * v;
            }
        }
        energy *= 0.5;
        if let Err(e) = c.check_trial(energy, "semi-implicit step") {
            c.abort_step();
            return Err(e);
        }
        c.accept(dt, energy);
        // The linear solves of the active set cover the whole step: no substeps.
        Ok(StepInfo {
            substeps: 1,
            ..StepInfo::default()
        })
    }

    /// Solves K̂ U⁺ = F̂ (`hat.forces` set) into `core.u_next` with the contacts that only
    /// push: the active ones held along their normals (`DofProblem::along`), the others
    /// free. It starts from the contacts that pushed in the last step or start past their
    /// planes; a held contact whose reaction pulls is let go (for the rest of the step, so
    /// the loop ends), a free one that ends past its plane is taken, and it solves again
    /// until nothing changes (`integrate::contact::HeldContacts`, shared with the implicit
    /// steps). The pushes are the held contacts' reactions along −n.
    fn solve_with_contacts(&mut self) -> Result<(), SimError> {
        let c = &mut self.core;
        self.held.start(
            c.contacts
                .iter()
                .map(|k| self.pushed[k.node] || k.gap(&c.u) < 0.0),
        );
        self.rounds = 0;
        loop {
            self.rounds += 1;
            let p = &c.problem;
            self.hat.constrained.clone_from(&p.constrained);
            self.hat.list.clone_from(&p.list);
            self.hat.targets.clone_from(&p.targets);
            self.hat.along.clone_from(&p.along);
            for (k, _) in c
                .contacts
                .iter()
                .zip(&self.held.active)
                .filter(|(_, a)| **a)
            {
                self.hat
                    .hold_along(k.node, k.normal, k.normal.dot(k.target))?;
            }
            self.hat.finish();
            self.hat.points.clear();
            self.hat.points.extend(c.point_rows());
            self.system
                .solve(&self.hat, &mut c.u_next, &mut self.reactions_scratch)?;
            // Pulls and penetrations below roundoff of the pushes and of the motion are none.
            let push = |k: &contacts::PushContact| {
                -k.normal
                    .dot(crate::math::unflatten(&self.reactions_scratch)[k.node])
            };
            self.pushes.clear();
            self.pushes.extend(c.contacts.iter().map(push));
            let depth = 1e-12 * self.length;
            let u_next = &c.u_next;
            let contacts = &c.contacts;
            let changed = self
                .held
                .update(&self.pushes, |i| contacts[i].gap(u_next), depth);
            if !changed {
                break;
            }
        }
        for (i, k) in c.contacts.iter_mut().enumerate() {
            let pushed = if self.held.active[i] {
                (-k.normal
                    .dot(crate::math::unflatten(&self.reactions_scratch)[k.node]))
                .max(0.0)
            } else {
                0.0
            };
            k.push = pushed;
        }
        // The points' multipliers: K̂ U⁺ = F̂ + C λ is the equation of motion at the end of
        // the step, so λ is the push then, N.
        c.point_push.clear();
        c.point_push.extend(
            (0..c.points.len())
                .map(|j| self.system.point_pushes.get(j).map_or(0.0, |l| l.max(0.0))),
        );
        self.pushed.iter_mut().for_each(|p| *p = false);
        for k in &c.contacts {
            self.pushed[k.node] = k.push > 0.0;
        }
        Ok(())
    }

    fn details(&self) -> (usize, Vec<(String, String)>) {
        (
            self.system.factor_nnz() * 16 + self.khat.len() * 16,
            vec![
                ("scheme".into(), "semi-implicit (8)-(10)".into()),
                ("factor_nnz".into(), self.system.factor_nnz().to_string()),
                (
                    "refactorizations".into(),
                    self.system.refactorizations.to_string(),
                ),
                (
                    "schur_columns".into(),
                    self.system.schur_columns.to_string(),
                ),
                ("contact_solves".into(), self.rounds.to_string()),
            ],
        )
    }
}

forward_deformable!(FemSemiImplicit, "fem-semi-implicit");
