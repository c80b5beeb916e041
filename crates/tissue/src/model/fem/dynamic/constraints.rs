//! Constraints, loads and reactions of the dynamic models, on surface vertices: fixed
//! vertices are held at rest, prescribed ones reach their target at the end of each step
//! (fixed wins); gravity is the lumped mass times g; each given constraint gets the reaction
//! of its vertex (the first mention of a vertex owns it).

use crate::error::SimError;
use crate::interact::{Constraints, Loads};
use crate::math::{Real, Vec3};

use super::super::surface_nodes::nodal_forces;
use super::super::system::DofProblem;
use super::common::Core;

impl Core {
    /// Fixed vertices are held at rest, prescribed ones reach their target at the end of
    /// each step; fixed wins. Checked fully before anything changes.
    pub fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        let disp = c.surface_displacements(&self.boundary.surface.vertices)?;
        let mut dp = DofProblem::new(self.dofs());
        for (s, d) in disp.iter().enumerate() {
            if let Some(d) = d {
                dp.hold_node(self.boundary.nodes[s] as usize, *d)?;
            }
        }
        dp.finish();
        dp.forces = std::mem::take(&mut self.problem.forces);
        self.problem = dp;
        self.reactions.set(c);
        self.update_energy_floor();
        Ok(())
    }

    /// Gravity gives each node its lumped mass times g (the consistent load of the linear
    /// tet); point loads act on the node of their surface vertex.
    pub fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        self.problem.forces = nodal_forces(loads, &self.boundary.nodes, |g| {
            let mass = self.mass.iter().enumerate();
            mass.map(|(d, m)| m * g[d % 3]).collect()
        })?;
        self.update_energy_floor();
        Ok(())
    }

    /// An energy scale of the current loads and targets (Σ f²/K_ii + Σ K_ii g²)/2, so that
    /// the growth test has a reference even when starting from rest.
    pub(super) fn update_energy_floor(&mut self) {
        let diag = self.assembler.pattern.diagonal_slots();
        let mut e = 0.0;
        for (d, &s) in diag.iter().enumerate() {
            let kd = self.k[s];
            if self.problem.constrained[d] {
                e += 0.5 * kd * self.problem.targets[d].powi(2);
            } else {
                e += 0.5 * self.problem.forces[d].powi(2) / kd;
            }
        }
        self.energy_floor = e.max(Real::MIN_POSITIVE);
    }

    pub(super) fn update_reactions(&mut self) {
        let r = |n: u32| {
            let n = n as usize;
            Vec3::new(self.r[3 * n], self.r[3 * n + 1], self.r[3 * n + 2])
        };
        let nodes = &self.boundary.nodes;
        self.reactions
            .distribute(|v| nodes.get(v as usize).map_or(Vec3::ZERO, |&n| r(n)));
    }

    pub fn reactions(&self) -> crate::model::Reactions<'_> {
        self.reactions.reactions()
    }
}
