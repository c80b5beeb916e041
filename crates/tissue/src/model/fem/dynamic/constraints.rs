//! Constraints, loads and reactions of the dynamic models, on surface vertices: fixed
//! vertices are held at rest, prescribed ones reach their target at the end of each step
//! (fixed wins); gravity is the lumped mass times g; each given constraint gets the reaction
//! of its vertex (the first mention of a vertex owns it).

use crate::error::SimError;
use crate::interact::{Constraints, Loads, SurfaceHold};
use crate::math::{Real, Vec3};

use super::super::surface_nodes::nodal_forces;
use super::super::system::{ALONG_CAP, DofProblem, oblique_holds};
use super::common::Core;
use super::contacts::PushContact;

impl Core {
    /// Fixed vertices are held at rest, prescribed ones reach their target at the end of
    /// each step; fixed wins. Checked fully before anything changes.
    pub fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        self.set_constraints_along(c, &[]).map(|_| ())
    }

    /// `set_constraints` with the prescribed entry k given a direction `normals[k]` a
    /// frictionless contact that only pushes (`contacts`): the plane through its target
    /// with that normal, pointing out of the instrument. Returns whether every entry is
    /// held as asked: with more than `ALONG_CAP` oblique directions all are held in full
    /// (the semi-implicit solve would hold that many contacts along their normals).
    pub fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        self.hold_entries(c, normals, false)
    }

    /// `set_constraints_along` with the entries given a coordinate axis held along it both
    /// ways (`Deformable::set_constraints_two_sided`): one held dof each, its target the
    /// entry's displacement along the axis, the other two free. An entry given an oblique
    /// direction is held in full (the central difference has no row for it) and the answer
    /// is false.
    pub fn set_constraints_two_sided(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        self.hold_entries(c, normals, true)
    }

    fn hold_entries(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
        two_sided: bool,
    ) -> Result<bool, SimError> {
        let mut holds = c.surface_holds(&self.boundary.surface.vertices, normals)?;
        let as_asked = if two_sided {
            oblique_holds(&holds) == 0
        } else {
            oblique_holds(&holds) <= ALONG_CAP
        };
        if !as_asked {
            holds.iter_mut().flatten().for_each(|h| h.along = None);
        }
        let mut contacts = Vec::new();
        for (h, &node) in holds.iter_mut().zip(&self.boundary.nodes) {
            if let Some(SurfaceHold {
                displacement,
                along: Some(n),
            }) = *h
                && !two_sided
            {
                contacts.push(PushContact {
                    node: node as usize,
                    normal: n,
                    target: displacement,
                    push: 0.0,
                    impulse: 0.0,
                    trial: 0.0,
                });
                *h = None;
            }
        }
        let mut dp = DofProblem::new(self.dofs());
        dp.hold_surface(&self.boundary.nodes, &[], &holds)?;
        dp.finish();
        dp.forces = std::mem::take(&mut self.problem.forces);
        self.problem = dp;
        self.contacts = contacts;
        self.points.clear();
        self.point_push.clear();
        self.point_impulse.clear();
        self.point_trial.clear();
        self.reactions.set(c);
        self.update_energy_floor();
        Ok(as_asked)
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

    /// An energy scale of the current loads and targets (Σ f²/K_ii + Σ K_ii g²)/2 (g along
    /// its direction for a node held along one or a contact), so that the growth test has
    /// a reference even when starting from rest.
    pub(super) fn update_energy_floor(&mut self) {
        let diag = &self.diag;
        let mut e = 0.0;
        for (d, &s) in diag.iter().enumerate() {
            let kd = self.k[s];
            if self.problem.constrained[d] {
                e += 0.5 * kd * self.problem.targets[d].powi(2);
            } else {
                e += 0.5 * self.problem.forces[d].powi(2) / kd;
            }
        }
        // A node held along n at g: the stiffest of its diagonal entries times g².
        let stiffest = |node: usize| {
            (0..3)
                .map(|k| self.k[diag[3 * node + k]])
                .fold(0.0, Real::max)
        };
        for a in &self.problem.along {
            e += 0.5 * stiffest(a.node) * a.value.powi(2);
        }
        for k in &self.contacts {
            e += 0.5 * stiffest(k.node) * k.normal.dot(k.target).powi(2);
        }
        e += self.points_floor(stiffest);
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
