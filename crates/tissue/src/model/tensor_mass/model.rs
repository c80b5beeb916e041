//! `TensorMass`: a `TensorSystem` with its state, the shared integrator, the cut surface,
//! constraints, loads and reactions. One type for both kinds (`nonlinear` picks the tensors).

use std::time::Instant;

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::integrate::coupling::{Coupled, NodeCoupling};
use crate::integrate::{Hold, Integrator, IntegratorSettings, ParticleState, Scheme};
use crate::interact::{Constraints, Loads};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::TetMesh;
use crate::model::registry::parse_params;
use crate::model::{BuildInput, StepInfo};

use super::cut::{CutReport, Cutter};
use super::cut_surface::CutSurface;
use super::{TensorMassParams, TensorSystem, build_system};

/// A step's start (`TensorMass::step_checkpoint`).
#[derive(Clone, Debug)]
pub struct StepCheckpoint {
    state: ParticleState,
    integrator: crate::integrate::Checkpoint,
}

/// A tensor-mass model (see the module doc of `tensor_mass`).
#[derive(Debug)]
pub struct TensorMass {
    pub(super) nonlinear: bool,
    pub(super) params: TensorMassParams,
    pub(super) material: Material,
    pub(super) mesh: TetMesh,
    pub(super) system: TensorSystem,
    pub(super) state: ParticleState,
    pub(super) integrator: Integrator,
    pub(super) surface: CutSurface,
    /// Held nodes from the constraints (fixed at rest, prescribed at their target).
    pub(super) holds: Vec<Hold>,
    /// The constraints' holds plus the detached nodes, held where they are.
    pub(super) step_holds: Vec<Hold>,
    /// Nodes in `step_holds`.
    pub(super) step_held: Vec<bool>,
    /// The grid, piece labels and sliver guard, built at the first cut.
    pub(super) cutter: Option<Cutter>,
    pub(super) constraints: Constraints,
    pub(super) loads: Loads,
    pub(super) fixed_reactions: Vec<Vec3>,
    pub(super) prescribed_reactions: Vec<Vec3>,
    pub(super) topology_version: u32,
    pub(super) last_cut: CutReport,
    pub(super) fragments_seen: usize,
    /// The surviving tetrahedra, for the volume view (swap-removed on cuts).
    pub(super) alive_tets: Vec<[u32; 4]>,
    pub(super) alive_slot: Vec<u32>,
    pub(super) alive_owner: Vec<u32>,
    pub(super) switched: usize,
    pub(super) precompute_seconds: Real,
    /// Mass added at nodes by a coupled model (kept across a reset).
    pub(super) extra_masses: Vec<(usize, Real)>,
}

impl TensorMass {
    /// Builds either kind from the registry's input.
    pub fn from_input(input: &BuildInput<'_>, nonlinear: bool) -> Result<Self, Error> {
        let kind = if nonlinear {
            "tensor-mass-nonlinear"
        } else {
            "tensor-mass"
        };
        let mut table = input.params.clone();
        let scheme = match table.remove("integrator") {
            None => Scheme::default(),
            Some(v) => Scheme::deserialize(v.clone()).map_err(|e| SimError::BadParameter {
                name: "integrator",
                value: v.to_string(),
                reason: e.to_string().trim().to_string(),
            })?,
        };
        let params: TensorMassParams = parse_params(kind, &table)?;
        let mesh = input.mesh.tet_mesh(input.source)?;
        Self::new(&mesh, input.material, params, nonlinear, scheme)
    }

    /// Validates and builds: tensors of every tetrahedron, lumped masses, the surface.
    pub fn new(
        mesh: &TetMesh,
        material: Material,
        params: TensorMassParams,
        nonlinear: bool,
        scheme: Scheme,
    ) -> Result<Self, Error> {
        let start = Instant::now();
        let (mesh, system) = build_system(mesh, material, &params, nonlinear)?;
        let surface = CutSurface::new(&mesh.tets, &mesh.vertices);
        let mut m = Self {
            nonlinear,
            material,
            state: ParticleState::at_rest(mesh.vertices.clone()),
            integrator: Integrator::with_settings(
                scheme,
                IntegratorSettings {
                    substeps: params.substeps,
                    ..IntegratorSettings::default()
                },
            ),
            surface,
            holds: Vec::new(),
            step_holds: Vec::new(),
            step_held: vec![false; mesh.vertices.len()],
            cutter: None,
            constraints: Constraints::default(),
            loads: Loads::default(),
            fixed_reactions: Vec::new(),
            prescribed_reactions: Vec::new(),
            topology_version: 0,
            last_cut: CutReport::default(),
            fragments_seen: 0,
            alive_tets: mesh.tets.clone(),
            alive_slot: (0..mesh.tets.len() as u32).collect(),
            alive_owner: (0..mesh.tets.len() as u32).collect(),
            switched: 0,
            precompute_seconds: 0.0,
            extra_masses: Vec::new(),
            params,
            mesh,
            system,
        };
        m.system
            .set_split_damping(m.integrator.scheme != Scheme::ImplicitEuler);
        if nonlinear && m.params.strain_threshold > 0.0 {
            // Start from the linear force everywhere; the switch brings tetrahedra in.
            m.system.switch_hybrid(&m.mesh.vertices, Real::INFINITY);
            m.switched = 0;
        }
        // The stability limit, measured at build so the model info shows it.
        m.integrator.measure(&mut m.system, &m.state, &[]);
        m.precompute_seconds = start.elapsed().as_secs_f64();
        Ok(m)
    }

    pub fn system(&self) -> &TensorSystem {
        &self.system
    }
    pub fn material(&self) -> &Material {
        &self.material
    }
    pub fn params(&self) -> &TensorMassParams {
        &self.params
    }
    pub fn integrator(&self) -> &Integrator {
        &self.integrator
    }
    /// Adds mass at nodes (the `hybrid` model puts the rest's share on the interface nodes,
    /// which the region integrates): kept across resets; loads are re-applied.
    pub fn add_node_masses(&mut self, masses: &[(usize, Real)]) {
        for &(n, m) in masses {
            self.system.add_node_mass(n, m);
        }
        self.extra_masses.extend_from_slice(masses);
        let loads = self.loads.clone();
        let _ = self.apply_loads(&loads);
    }

    /// Measures the stability limit now, with `coupling`'s forces added to the system's
    /// (the `hybrid` model's interface stiffness raises the interface nodes' frequency).
    pub fn measure_stability(&mut self, coupling: Option<&dyn NodeCoupling>) {
        match coupling {
            None => self
                .integrator
                .measure(&mut self.system, &self.state, &self.step_holds),
            Some(coupling) => {
                let mut coupled = Coupled {
                    system: &mut self.system,
                    coupling,
                };
                self.integrator
                    .measure(&mut coupled, &self.state, &self.step_holds);
            }
        }
    }

    /// Re-measures the stiffness rate now by `iterations` power iterations warm-started
    /// from the last dominant vector, with `coupling`'s forces added (never below the last
    /// full measurement), after forgetting the kept forces: the `hybrid` model's contact set
    /// on its rest changed, a low-rank change of the interface stiffness that a cold measure
    /// (30 iterations) overpays.
    pub fn recheck_stability(&mut self, coupling: &dyn NodeCoupling, iterations: usize) {
        let mut coupled = Coupled {
            system: &mut self.system,
            coupling,
        };
        self.integrator
            .recheck_stiffness(&mut coupled, &self.state, &self.step_holds, iterations);
    }

    /// The stable step a cold measurement (`iterations` power iterations, nothing kept)
    /// gives now, with `coupling`'s forces added; the model is unchanged. For tests of
    /// the warm-started re-measures.
    #[cfg(test)]
    pub fn cold_stable_dt(
        &mut self,
        coupling: Option<&dyn NodeCoupling>,
        iterations: usize,
    ) -> Real {
        match coupling {
            None => self.integrator.cold_stable_dt(
                &mut self.system,
                &self.state,
                &self.step_holds,
                iterations,
            ),
            Some(coupling) => {
                let mut coupled = Coupled {
                    system: &mut self.system,
                    coupling,
                };
                self.integrator.cold_stable_dt(
                    &mut coupled,
                    &self.state,
                    &self.step_holds,
                    iterations,
                )
            }
        }
    }

    /// Forgets the integrator's end-of-step forces and energy without measuring the
    /// stability limit again: the caller changed forces whose stiffness stays the same (the
    /// `hybrid` model's contact targets).
    pub fn forget_forces(&mut self) {
        self.integrator.forget_forces();
    }
    /// The state at the start of a step, to take it again (`roll_back`): a coupled model
    /// that settles its own contacts within the step (`hybrid`'s rest).
    pub fn step_checkpoint(&self) -> StepCheckpoint {
        StepCheckpoint {
            state: self.state.clone(),
            integrator: self.integrator.checkpoint(),
        }
    }

    /// Back to `checkpoint`'s state, to take the step again under other coupling forces
    /// (the integrator forgets the forces and energy it kept, as after `forget_forces`).
    pub fn roll_back(&mut self, checkpoint: &StepCheckpoint) {
        self.state.clone_from(&checkpoint.state);
        self.integrator.roll_back(&checkpoint.integrator);
        self.surface.update_positions(&self.state.x);
        self.distribute_reactions();
    }

    /// Chooses the integration scheme.
    pub fn set_scheme(&mut self, scheme: Scheme) {
        self.integrator = Integrator::with_settings(scheme, self.integrator.settings);
        self.system
            .set_split_damping(scheme != Scheme::ImplicitEuler);
    }
    pub fn positions(&self) -> &[Vec3] {
        &self.state.x
    }
    pub fn velocities(&self) -> &[Vec3] {
        &self.state.v
    }
    /// ½ Σ m v² of the nodes, J.
    pub fn node_kinetic_energy(&self) -> Real {
        use crate::integrate::ParticleSystem;
        self.state.kinetic_energy(self.system.masses())
    }
    /// Every node's velocity zeroed (`Deformable::stop_motion`; `Integrator::motion_stopped`).
    pub fn stop_nodes(&mut self) {
        self.state.stop();
        self.integrator.motion_stopped();
    }
    pub fn rest_nodes(&self) -> &[Vec3] {
        &self.mesh.vertices
    }
    /// What the last cut did (fragments found, tetrahedra removed).
    pub fn last_cut(&self) -> &CutReport {
        &self.last_cut
    }
    /// The mechanical node of each surface vertex.
    pub fn surface_nodes(&self) -> &[u32] {
        &self.surface.nodes
    }

    /// Replaces positions and velocities (lengths must match, values finite).
    pub fn set_state(&mut self, x: &[Vec3], v: &[Vec3]) -> Result<(), SimError> {
        let n = self.state.x.len();
        if x.len() != n || v.len() != n || !x.iter().chain(v).all(|p| p.is_finite()) {
            return Err(SimError::BadParameter {
                name: "state",
                value: format!("{} positions, {} velocities", x.len(), v.len()),
                reason: format!("needs {n} finite positions and velocities"),
            });
        }
        self.state.x.copy_from_slice(x);
        self.state.v.copy_from_slice(v);
        self.integrator.invalidate();
        self.surface.update_positions(&self.state.x);
        Ok(())
    }

    /// Holds from surface constraints: fixed vertices at rest, prescribed ones at their
    /// target (fixed wins; the last of two prescriptions wins). A prescribed entry with a
    /// direction in `normals` is a frictionless contact (`Hold::contact`): it keeps its node
    /// on the instrument's side of the target's tangent plane, within every substep, and
    /// never pulls; with `push_only` false it is held on that plane both ways (a bonded
    /// frictionless plate, `Deformable::set_constraints_two_sided`).
    pub(super) fn apply_constraints(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
        push_only: bool,
    ) -> Result<(), SimError> {
        let holds = c.surface_holds(&self.surface.rest_positions, normals)?;
        self.holds = holds
            .iter()
            .enumerate()
            .filter_map(|(s, h)| {
                let n = self.surface.nodes[s] as usize;
                h.map(|h| {
                    let target = self.mesh.vertices[n] + h.displacement;
                    match h.along {
                        Some(dir) if push_only => Hold::contact(n, target, dir),
                        Some(dir) => Hold {
                            along: Some(dir),
                            ..Hold::new(n, target)
                        },
                        None => Hold::new(n, target),
                    }
                })
            })
            .collect();
        self.integrator.set_points(Vec::new());
        self.constraints = c.clone();
        self.fixed_reactions = vec![Vec3::ZERO; c.fixed.len()];
        self.prescribed_reactions = vec![Vec3::ZERO; c.prescribed.len()];
        self.refresh_step_holds();
        Ok(())
    }

    /// Adds the nodes no tetrahedron holds any more, kept where they are.
    pub(super) fn refresh_step_holds(&mut self) {
        let held = &mut self.step_held;
        held.iter_mut().for_each(|h| *h = false);
        self.step_holds.clear();
        for h in &self.holds {
            if self.system.is_attached(h.particle) && !held[h.particle] {
                held[h.particle] = true;
                self.step_holds.push(*h);
            }
        }
        for (n, x) in self.state.x.iter().enumerate() {
            if !held[n] && !self.system.is_attached(n) {
                held[n] = true;
                self.step_holds.push(Hold::new(n, *x));
            }
        }
    }

    /// One step: the hybrid switch (if on), then the shared integrator. On error the state
    /// is the last good one.
    pub fn advance(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        self.advance_coupled(dt, None)
    }

    /// `advance` with the forces of `coupling` added to the system's (the `hybrid` model's
    /// interface forces): they enter every force evaluation, the energy guard and the
    /// implicit Jacobian.
    pub fn advance_coupled(
        &mut self,
        dt: Real,
        coupling: Option<&dyn NodeCoupling>,
    ) -> Result<StepInfo, SimError> {
        let check = self
            .integrator
            .steps()
            .is_multiple_of(u64::from(self.params.hybrid_interval.max(1)));
        if self.nonlinear && self.params.strain_threshold > 0.0 && check {
            let n = self
                .system
                .switch_hybrid(&self.state.x, self.params.strain_threshold);
            if n > 0 {
                self.switched += n;
                self.integrator.invalidate();
            }
        }
        for h in &mut self.step_holds {
            if !self.system.is_attached(h.particle) {
                h.target = self.state.x[h.particle];
            }
        }
        let info = match coupling {
            None => {
                self.integrator
                    .step(&mut self.system, &mut self.state, &self.step_holds, dt)?
            }
            Some(coupling) => {
                let mut coupled = Coupled {
                    system: &mut self.system,
                    coupling,
                };
                self.integrator
                    .step(&mut coupled, &mut self.state, &self.step_holds, dt)?
            }
        };
        self.surface.update_positions(&self.state.x);
        self.distribute_reactions();
        Ok(info)
    }

    /// Each constrained vertex's reaction goes to its first fixed entry, else its last
    /// prescribed one; other entries for the same vertex get zero.
    fn distribute_reactions(&mut self) {
        let mut node_force = vec![None; self.state.x.len()];
        for (h, f) in self.step_holds.iter().zip(self.integrator.held_forces()) {
            node_force[h.particle] = Some(*f);
        }
        let nodes = &self.surface.nodes;
        let mut taken = vec![false; nodes.len()];
        let mut take = |v: u32| -> Vec3 {
            let v = v as usize;
            match (taken.get(v), nodes.get(v)) {
                (Some(false), Some(&n)) => {
                    taken[v] = true;
                    node_force[n as usize].unwrap_or(Vec3::ZERO)
                }
                _ => Vec3::ZERO,
            }
        };
        for (k, &v) in self.constraints.fixed.iter().enumerate() {
            self.fixed_reactions[k] = take(v);
        }
        for (k, p) in self.constraints.prescribed.iter().enumerate().rev() {
            self.prescribed_reactions[k] = take(p.vertex);
        }
    }
}
