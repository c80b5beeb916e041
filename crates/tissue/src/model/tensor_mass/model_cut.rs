//! Cutting, loads and reset of `TensorMass`: the model-side bookkeeping around `Cutter`
//! (the alive list of the volume view, holds for detached nodes, topology version) and the
//! return to the uncut model.

use crate::error::SimError;
use crate::integrate::Hold;
use crate::interact::Loads;
use crate::math::{Real, Vec3};
use crate::model::{CutInfo, CutPath};

use super::cut::{CutReport, Cutter};
use super::model::TensorMass;
use super::system::NonlinearForm;
use super::{Fragments, TensorSystem};

impl TensorMass {
    /// Holds the nodes a cut detached, where they are (a constraint's hold on such a node
    /// stays in the list; `advance` moves its target with the node). Local to the cut.
    pub(super) fn hold_detached(&mut self, detached: &[usize]) {
        for &n in detached {
            if let Some(h) = self.step_held.get_mut(n)
                && !*h
            {
                *h = true;
                self.step_holds.push(Hold::new(n, self.state.x[n]));
            }
        }
    }

    /// Builds the cutting state (the grid of tetrahedra, piece labels, sliver guard) now
    /// rather than at the first cut.
    pub fn prepare_cutting(&mut self) {
        if self.cutter.is_none() {
            self.cutter = Some(Cutter::new(&self.system, &self.state.x));
        }
    }

    /// Rebuilds the system from the mesh and the per-tetrahedron rest data and elasticity
    /// (so fibres set per tetrahedron survive), then re-applies loads and holds.
    pub(super) fn restore_uncut(&mut self) {
        let form = if self.system.nonlinear.is_some() {
            Some(NonlinearForm::Tensors)
        } else if self.system.elements.is_some() {
            Some(NonlinearForm::Elements)
        } else {
            None
        };
        self.system = TensorSystem::new(
            &self.mesh,
            self.system.rest_tets.clone(),
            self.system.elasticity.clone(),
            &self.material,
            self.params.volume_penalty,
            form,
        );
        self.system
            .set_split_damping(self.integrator.scheme != crate::integrate::Scheme::ImplicitEuler);
        if self.nonlinear && self.params.strain_threshold > 0.0 {
            self.system
                .switch_hybrid(&self.mesh.vertices, Real::INFINITY);
        }
        for &(n, m) in &self.extra_masses {
            self.system.add_node_mass(n, m);
        }
        self.surface
            .restore(&self.mesh.tets, &self.mesh.vertices, &self.mesh.vertices);
        self.alive_tets = self.mesh.tets.clone();
        self.alive_slot = (0..self.mesh.tets.len() as u32).collect();
        self.alive_owner = self.alive_slot.clone();
        self.cutter = None;
        self.last_cut = CutReport::default();
        self.fragments_seen = 0;
        self.topology_version += 1;
        let loads = self.loads.clone();
        // The loads were accepted before and name surface vertices that still exist.
        let _ = self.apply_loads(&loads);
        self.refresh_step_holds();
    }

    /// Gravity as the lumped share m_i g; point loads on their vertex's node.
    pub(super) fn apply_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        if !loads.gravity.is_finite() {
            return Err(SimError::BadParameter {
                name: "gravity",
                value: loads.gravity.to_string(),
                reason: "must be finite".into(),
            });
        }
        let mut forces = Vec::with_capacity(loads.point_loads.len());
        for &(v, f) in &loads.point_loads {
            let node = self
                .surface
                .nodes
                .get(v as usize)
                .ok_or(SimError::BadConstraint {
                    vertex: v as usize,
                    count: self.surface.nodes.len(),
                })?;
            if !f.is_finite() {
                return Err(SimError::BadParameter {
                    name: "point_loads",
                    value: format!("surface vertex {v} -> {f}"),
                    reason: "the force must be finite".into(),
                });
            }
            forces.push((*node as usize, f));
        }
        self.system.set_node_loads(loads.gravity, &forces);
        self.integrator.invalidate();
        self.loads = loads.clone();
        Ok(())
    }

    /// Removes the listed tetrahedra as a cut would (then the slivers they leave, and the
    /// fragments if the settings remove them): how the `hybrid` model carries its cuts over
    /// to a grown region's new tensor-mass part.
    pub fn remove_tets(&mut self, tets: &[usize]) -> CutInfo {
        let remove = self.params.fragments == Fragments::Remove;
        let cutter = self
            .cutter
            .get_or_insert_with(|| Cutter::new(&self.system, &self.state.x));
        let report = cutter.remove_tets(
            &mut self.system,
            &mut self.surface,
            &self.state.x,
            tets,
            remove,
            CutReport::default(),
        );
        self.after_removal(report)
    }

    /// Removes what the blade touches (see `cut`).
    pub fn cut_along(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        let ok = |p: &[Vec3; 2]| p.iter().all(|v| v.is_finite());
        if !(ok(&blade.start) && ok(&blade.end)) {
            return Err(SimError::BadParameter {
                name: "blade",
                value: format!("{blade:?}"),
                reason: "the blade positions must be finite".into(),
            });
        }
        let remove = self.params.fragments == Fragments::Remove;
        let cutter = self
            .cutter
            .get_or_insert_with(|| Cutter::new(&self.system, &self.state.x));
        let report = cutter.cut(
            &mut self.system,
            &mut self.surface,
            &self.state.x,
            blade,
            remove,
        );
        Ok(self.after_removal(report))
    }

    /// The model-side bookkeeping of a removal: alive list, holds, topology version.
    fn after_removal(&mut self, report: CutReport) -> CutInfo {
        let removed = report.removed.len();
        for &t in &report.removed {
            let slot = self.alive_slot[t] as usize;
            self.alive_tets.swap_remove(slot);
            self.alive_owner.swap_remove(slot);
            if let Some(&moved) = self.alive_owner.get(slot) {
                self.alive_slot[moved as usize] = slot as u32;
            }
        }
        if removed > 0 {
            self.topology_version += 1;
            self.fragments_seen += report.fragments.len();
            self.integrator.invalidate();
            self.hold_detached(&report.detached);
            // Surface vertex count grew: constraint bookkeeping stays valid (stable ids).
        }
        let info = CutInfo {
            removed_elements: removed,
            added_vertices: report.added_vertices,
            topology_version: self.topology_version,
        };
        self.last_cut = report;
        info
    }

    /// Back to the uncut model at rest with zero velocity: removed tetrahedra, tensors,
    /// masses, surface triangles and the hybrid set as built (surface vertex numbers handed
    /// out by cuts stay valid, unused); constraints and loads kept.
    pub fn reset_state(&mut self) {
        if self.system.alive_count() != self.system.tets.len() {
            self.restore_uncut();
        } else if self.nonlinear && self.params.strain_threshold > 0.0 {
            self.system
                .switch_hybrid(&self.mesh.vertices, Real::INFINITY);
        }
        self.switched = 0;
        self.state.x.copy_from_slice(&self.mesh.vertices);
        self.state.v.iter_mut().for_each(|v| *v = Vec3::ZERO);
        self.integrator.invalidate();
        self.surface.update_positions(&self.state.x);
        for h in &mut self.step_holds {
            if !self.system.is_attached(h.particle) {
                h.target = self.state.x[h.particle];
            }
        }
        self.fixed_reactions
            .iter_mut()
            .for_each(|r| *r = Vec3::ZERO);
        self.prescribed_reactions
            .iter_mut()
            .for_each(|r| *r = Vec3::ZERO);
    }
}
