//! State shared by the two dynamic schemes: the compacted mesh, K assembled once with the
//! static model's `Assembler`, lumped masses, the boundary surface, constraints mapped to
//! dofs, the three time levels U_{t−Δt}, U_t and the trial U_{t+Δt}, and the reactions.
//!
//! The last good state is kept by construction: a step writes only into the trial buffer and
//! rotates the three levels once every check has passed, so a failed step leaves
//! (U_t, U_{t−Δt}) as they were.

use std::time::Instant;

use crate::error::{Error, SimError};
use crate::integrate::{PointHold, PointProjection};
use crate::material::{ElementMaterials, Material};
use crate::math::{Real, Vec3};
use crate::mesh::{Boundary, TetMesh, boundary_surface};
use crate::model::ConstraintReactions;

use super::super::assembly::Assembler;
use super::super::element_linear;
use super::super::mass::lumped_masses_of;
use super::super::system::DofProblem;
use super::contacts::PushContact;
pub(super) use super::forward::forward_deformable;

/// Power iterations used for the largest eigenvalue of M⁻¹K at build.
const POWER_ITERATIONS: usize = 60;

pub(super) struct Core {
    /// The default material (damping, and everything without per-region materials).
    pub material: Material,
    /// Each element's material (`Uniform(material)` without regions).
    pub materials: ElementMaterials,
    pub mesh: TetMesh,
    pub rest: Vec<Vec3>,
    pub positions: Vec<Vec3>,
    pub assembler: Assembler,
    /// K over all dofs, pattern `assembler.pattern`.
    pub k: Vec<Real>,
    /// Lumped mass per dof (each node's mass three times).
    pub mass: Vec<Real>,
    pub boundary: Boundary,
    pub surface_positions: Vec<Vec3>,
    /// Slot of each dof's diagonal entry in `k`.
    pub diag: Vec<usize>,
    /// Held dofs, their targets and the external forces F.
    pub problem: DofProblem,
    /// Frictionless contacts that only push, on nodes free in `problem` (`contacts`).
    pub contacts: Vec<PushContact>,
    /// A fine surface's points on the nodes (`points`), held from the next step on.
    pub points: Vec<PointHold>,
    /// Per point: the push over the last step along its normal, N (≥ 0); the momentum the
    /// projections gave it over the accepted substeps of this step, N·s, and over the
    /// substep in progress (`fem-explicit`).
    pub point_push: Vec<Real>,
    pub point_impulse: Vec<Real>,
    pub point_trial: Vec<Real>,
    /// `fem-explicit`'s projection of the points and its per-node buffers (velocities and
    /// inverse masses, set on the points' nodes only).
    pub projection: PointProjection,
    pub point_v: Vec<Vec3>,
    pub point_inv_mass: Vec<Real>,
    pub reactions: ConstraintReactions,
    /// U_t, U_{t−Δt} and the trial U_{t+Δt}.
    pub u: Vec<Real>,
    pub u_prev: Vec<Real>,
    pub u_next: Vec<Real>,
    /// Scratch: K times some displacement.
    pub ku: Vec<Real>,
    /// Per-dof reactions after the last step (zero on free dofs).
    pub r: Vec<Real>,
    /// The Δt the history U_{t−Δt} belongs to.
    pub last_dt: Option<Real>,
    /// U_{t−Δt} and Δt as they were before the step in progress, to undo its rescaling.
    saved_prev: Vec<Real>,
    saved_dt: Option<Real>,
    pub steps: u64,
    /// Energy after the last good step, a floor from the loads and targets, and the work
    /// the prescribed motion can put in over the step in progress (`prescribed_work`), for
    /// the divergence test.
    pub energy: Real,
    pub energy_floor: Real,
    pub step_work: Real,
    /// `step_work` of the last accepted step: the staggered energy (`trial_energy`) shows
    /// a move of a held node one step late.
    pub last_work: Real,
    /// ω_max² of M⁻¹K: power iteration (a sharp lower estimate) and Gershgorin (a bound).
    pub lambda_power: Real,
    pub lambda_gershgorin: Real,
    pub precompute_seconds: Real,
}

impl Core {
    /// Validates, assembles K (each element with its material) and the lumped masses (each
    /// element's density). `material` keeps the default: damping applies to the whole body.
    pub fn new(mesh: &TetMesh, materials: &ElementMaterials) -> Result<Self, Error> {
        let material = materials.default_material().validated()?;
        mesh.validate_for_simulation()?;
        let start = Instant::now();
        let mesh = mesh.compacted();
        let rest = mesh.vertices.clone();
        let assembler = Assembler::new(rest.len(), mesh.tets.concat(), 4)?;
        let k = assembler.assemble(|e, ke| {
            element_linear::stiffness(&mesh.corners(e), materials.of(e))
                .map(|k| ke.copy_from_slice(k.as_flattened()))
                .is_some()
        })?;
        let mass: Vec<Real> = lumped_masses_of(&mesh, materials)
            .into_iter()
            .flat_map(|m| [m; 3])
            .collect();
        let boundary = boundary_surface(&mesh);
        let dofs = 3 * rest.len();
        let mut core = Self {
            material,
            materials: materials.clone(),
            positions: rest.clone(),
            rest,
            k,
            mass,
            surface_positions: boundary.surface.vertices.clone(),
            boundary,
            diag: assembler.pattern.diagonal_slots(),
            problem: DofProblem::new(dofs),
            contacts: Vec::new(),
            points: Vec::new(),
            point_push: Vec::new(),
            point_impulse: Vec::new(),
            point_trial: Vec::new(),
            projection: PointProjection::default(),
            point_v: vec![Vec3::ZERO; dofs / 3],
            point_inv_mass: vec![0.0; dofs / 3],
            reactions: ConstraintReactions::default(),
            u: vec![0.0; dofs],
            u_prev: vec![0.0; dofs],
            u_next: vec![0.0; dofs],
            ku: vec![0.0; dofs],
            r: vec![0.0; dofs],
            last_dt: None,
            saved_prev: vec![0.0; dofs],
            saved_dt: None,
            steps: 0,
            energy: 0.0,
            energy_floor: Real::MIN_POSITIVE,
            step_work: 0.0,
            last_work: 0.0,
            lambda_power: 0.0,
            lambda_gershgorin: 0.0,
            precompute_seconds: 0.0,
            assembler,
            mesh,
        };
        core.estimate_lambda_max();
        core.precompute_seconds = start.elapsed().as_secs_f64();
        Ok(core)
    }

    pub fn dofs(&self) -> usize {
        self.u.len()
    }

    /// Largest eigenvalue of M⁻¹K (free body: constraints only lower it, so the estimate is
    /// safe for every constraint set), by power iteration on the similar symmetric matrix
    /// M^{-1/2} K M^{-1/2}, and the Gershgorin bound max_i Σ_j |K_ij| / m_i.
    fn estimate_lambda_max(&mut self) {
        let p = &self.assembler.pattern;
        let n = self.dofs();
        let mut rows = vec![0.0; n];
        for c in 0..n {
            for s in p.col_ptr[c]..p.col_ptr[c + 1] {
                rows[p.row_idx[s]] += self.k[s].abs();
            }
        }
        self.lambda_gershgorin = rows
            .iter()
            .zip(&self.mass)
            .map(|(r, m)| r / m)
            .fold(0.0, Real::max);
        let scale: Vec<Real> = self.mass.iter().map(|m| 1.0 / m.sqrt()).collect();
        // A start vector with every sign pattern represented (the top modes alternate).
        let mut x: Vec<Real> = (0..n)
            .map(|i| {
                let h = (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
                let v = 1.0 + (h % 89) as Real / 89.0;
                if h & 1 == 0 { v } else { -v }
            })
            .collect();
        let (mut y, mut t) = (vec![0.0; n], vec![0.0; n]);
        let mut lambda = 0.0;
        for _ in 0..POWER_ITERATIONS {
            let norm = x.iter().map(|v| v * v).sum::<Real>().sqrt();
            if norm == 0.0 || !norm.is_finite() {
                break;
            }
            for (ti, (xi, si)) in t.iter_mut().zip(x.iter().zip(&scale)) {
                *ti = xi * si / norm;
            }
            p.mul_vec(&self.k, &t, &mut y);
            let mut dot = 0.0;
            for (i, yi) in y.iter_mut().enumerate() {
                *yi *= scale[i];
                dot += *yi * x[i] / norm;
            }
            lambda = dot;
            std::mem::swap(&mut x, &mut y);
        }
        self.lambda_power = lambda.min(self.lambda_gershgorin);
    }

    /// Δt_crit = 2/ω_max from the power-iteration estimate of ω_max.
    pub fn critical_dt(&self) -> Real {
        2.0 / self.lambda_power.sqrt()
    }

    /// 2/ω with ω from the Gershgorin bound: a time step below it is guaranteed stable.
    pub fn critical_dt_bound(&self) -> Real {
        2.0 / self.lambda_gershgorin.sqrt()
    }

    pub fn check_dt(dt: Real) -> Result<(), SimError> {
        if dt.is_finite() && dt > 0.0 {
            Ok(())
        } else {
            Err(SimError::BadParameter {
                name: "dt",
                value: dt.to_string(),
                reason: "the time step must be finite and positive".into(),
            })
        }
    }

    /// Starts a step: checks Δt, saves the history, and when Δt changed keeps the velocity
    /// (U_t − U_{t−Δt})/Δt by moving U_{t−Δt}.
    pub fn begin_step(&mut self, dt: Real) -> Result<(), SimError> {
        Self::check_dt(dt)?;
        self.saved_prev.copy_from_slice(&self.u_prev);
        self.saved_dt = self.last_dt;
        if let Some(old) = self.last_dt
            && old != dt
        {
            let s = dt / old;
            for (p, u) in self.u_prev.iter_mut().zip(&self.u) {
                *p = u - (u - *p) * s;
            }
        }
        self.last_dt = Some(dt);
        self.step_work = self.prescribed_work();
        Ok(())
    }

    /// Undoes `begin_step` after a failed step: the state is the last good one again.
    pub fn abort_step(&mut self) {
        self.u_prev.copy_from_slice(&self.saved_prev);
        self.last_dt = self.saved_dt;
    }

    /// Discrete energy of the trial level: ½ vᵀMv with v = (U⁺ − U)/Δt over free dofs plus
    /// ½ U⁺ᵀ (K U), where `ku` holds K U. For the central difference this staggered form is
    /// exactly conserved without damping and non-increasing with it.
    pub fn trial_energy(&self, dt: Real) -> Real {
        let mut kinetic = 0.0;
        let mut strain = 0.0;
        for d in 0..self.dofs() {
            if !self.problem.constrained[d] {
                let v = (self.u_next[d] - self.u[d]) / dt;
                kinetic += self.mass[d] * v * v;
            }
            strain += self.u_next[d] * self.ku[d];
        }
        0.5 * (kinetic + strain)
    }

    /// Checks the trial level: non-finite values, or energy grown more than 10⁶-fold over
    /// the step, are a divergence naming the node that moved most. The growth is measured
    /// from the largest of the energy before the step, the floor of the loads and targets
    /// and the work the prescribed motion can put in this step or could in the last (the
    /// staggered energy shows it a step late): a first contact on a body at rest (energy
    /// and floor 0 before it) is work put in, not a blow-up.
    pub fn check_trial(&self, energy: Real, what: &str) -> Result<(), SimError> {
        let worst = || {
            let mut best = (0usize, -1.0);
            for (d, (a, b)) in self.u_next.iter().zip(&self.u).enumerate() {
                let change = (a - b).abs();
                if !change.is_finite() {
                    return d / 3;
                }
                if change > best.1 {
                    best = (d / 3, change);
                }
            }
            best.0
        };
        if !energy.is_finite() || self.u_next.iter().any(|v| !v.is_finite()) {
            return Err(SimError::Diverged {
                step: self.steps + 1,
                node: worst(),
                reason: format!("{what}: non-finite displacement or energy"),
            });
        }
        let reference = self
            .energy
            .abs()
            .max(self.energy_floor)
            .max(self.step_work)
            .max(self.last_work);
        if energy.abs() > 1e6 * reference {
            return Err(SimError::Diverged {
                step: self.steps + 1,
                node: worst(),
                reason: format!(
                    "{what}: energy grew from {reference:.3e} J to {energy:.3e} J in one step \
                     (is dt above the critical {:.3e} s?)",
                    self.critical_dt()
                ),
            });
        }
        Ok(())
    }

    /// Accepts the trial level: reactions, rotation of the time levels, positions.
    /// Reactions = F − (K U⁺ + M Ü + α M U̇) on held dofs, Ü and U̇ by central differences
    /// (on a node held along n, the sum is along n: across it the node moved freely).
    pub fn accept(&mut self, dt: Real, energy: Real) {
        let p = &self.assembler.pattern;
        let alpha = self.material.damping;
        self.r.iter_mut().for_each(|v| *v = 0.0);
        for c in self.problem.held_dofs() {
            let ku: Real = (p.col_ptr[c]..p.col_ptr[c + 1])
                .map(|s| self.k[s] * self.u_next[p.row_idx[s]])
                .sum();
            let (a, b, z) = (self.u_next[c], self.u[c], self.u_prev[c]);
            let acc = (a - 2.0 * b + z) / (dt * dt);
            let vel = (a - z) / (2.0 * dt);
            self.r[c] = self.problem.forces[c] - ku - self.mass[c] * (acc + alpha * vel);
        }
        std::mem::swap(&mut self.u_prev, &mut self.u);
        std::mem::swap(&mut self.u, &mut self.u_next);
        self.energy = energy;
        self.last_work = self.step_work;
        self.steps += 1;
        self.update_positions();
        self.write_contact_reactions();
        self.update_reactions();
    }

    pub fn update_positions(&mut self) {
        for (i, (p, x)) in self.positions.iter_mut().zip(&self.rest).enumerate() {
            *p = *x + Vec3::new(self.u[3 * i], self.u[3 * i + 1], self.u[3 * i + 2]);
        }
        for (s, &n) in self.boundary.nodes.iter().enumerate() {
            self.surface_positions[s] = self.positions[n as usize];
        }
    }

    /// Sets U_t and the velocity (U_t − U_{t−Δt})/Δt of the next step (flat, per dof; held
    /// dofs included as given). Nothing changes on error.
    pub fn set_state(&mut self, u: &[Real], velocity: &[Real], dt: Real) -> Result<(), SimError> {
        Self::check_dt(dt)?;
        let n = self.dofs();
        if u.len() != n || velocity.len() != n {
            return Err(SimError::BadParameter {
                name: "state",
                value: format!("{} displacements, {} velocities", u.len(), velocity.len()),
                reason: format!("the model has {n} dofs"),
            });
        }
        if let Some(d) = u.iter().chain(velocity).position(|v| !v.is_finite()) {
            return Err(SimError::BadParameter {
                name: "state",
                value: format!("dof {}", d % n),
                reason: "not finite".into(),
            });
        }
        self.u.copy_from_slice(u);
        for ((p, x), v) in self.u_prev.iter_mut().zip(u).zip(velocity) {
            *p = x - v * dt;
        }
        self.last_dt = Some(dt);
        self.assembler
            .pattern
            .mul_vec(&self.k, &self.u, &mut self.ku);
        let strain: Real = self.u.iter().zip(&self.ku).map(|(a, b)| a * b).sum();
        let kinetic: Real = velocity
            .iter()
            .zip(&self.mass)
            .map(|(v, m)| m * v * v)
            .sum();
        self.energy = 0.5 * (strain + kinetic);
        self.update_positions();
        Ok(())
    }

    /// ½ Σ m v² with v = (U_t − U_{t−Δt})/Δt over the last (sub)step, J (0 before the
    /// first step).
    pub fn kinetic_energy(&self) -> Real {
        let Some(dt) = self.last_dt else {
            return 0.0;
        };
        let inv = 1.0 / dt;
        0.5 * self
            .u
            .iter()
            .zip(&self.u_prev)
            .zip(&self.mass)
            .map(|((u, p), m)| m * ((u - p) * inv).powi(2))
            .sum::<Real>()
    }

    /// Zero velocity, the displacements kept: U_{t−Δt} = U_t (both schemes read the
    /// velocity from that difference), and the energy the step checks is the strain energy
    /// alone.
    pub fn stop_motion(&mut self) {
        self.u_prev.copy_from_slice(&self.u);
        self.assembler
            .pattern
            .mul_vec(&self.k, &self.u, &mut self.ku);
        self.energy = 0.5
            * self
                .u
                .iter()
                .zip(&self.ku)
                .map(|(a, b)| a * b)
                .sum::<Real>();
    }

    pub fn reset(&mut self) {
        for buf in [&mut self.u, &mut self.u_prev, &mut self.u_next, &mut self.r] {
            buf.iter_mut().for_each(|v| *v = 0.0);
        }
        self.last_dt = None;
        self.energy = 0.0;
        self.last_work = 0.0;
        self.contacts.iter_mut().for_each(|k| k.push = 0.0);
        self.point_push.iter_mut().for_each(|p| *p = 0.0);
        self.update_positions();
        self.update_reactions();
    }

    /// Info shared by both schemes; `details` are appended after the common ones.
    pub fn info(
        &self,
        kind: &'static str,
        extra_bytes: usize,
        details: Vec<(String, String)>,
    ) -> crate::model::ModelInfo {
        let nnz = self.assembler.pattern.nnz();
        let dofs = self.dofs();
        let mut all = vec![
            ("critical_dt".into(), format!("{:.6e}", self.critical_dt())),
            (
                "critical_dt_bound".into(),
                format!("{:.6e}", self.critical_dt_bound()),
            ),
            ("damping".into(), self.material.damping.to_string()),
            ("nnz".into(), nnz.to_string()),
            ("steps".into(), self.steps.to_string()),
        ];
        all.extend(details);
        crate::model::ModelInfo {
            kind,
            nodes: self.rest.len(),
            dofs,
            elements: self.mesh.tets.len(),
            surface_vertices: self.boundary.nodes.len(),
            memory_bytes: nnz * 24 + self.mesh.tets.len() * 16 * 4 + dofs * 8 * 7 + extra_bytes,
            precompute_seconds: self.precompute_seconds,
            is_static: false,
            details: all,
        }
    }
}
