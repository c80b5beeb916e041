//! A fine contact surface's points (`interact::PointContact`, issue 20) on the dynamic FEM
//! kinds, each tied to the nodes of three surface vertices by fixed weights, pushed by a
//! frictionless instrument but never pulled:
//!
//! - `fem-explicit` projects them after every central-difference substep with the shared
//!   integrator's projection (`integrate::PointProjection`: the least mass-weighted move of
//!   a point's nodes back onto its plane, its inward velocity removed the same way, points
//!   sharing nodes settled by projected Gauss-Seidel). The central difference's velocity is
//!   (U⁺ − U)/h, so a changed velocity moves the node's U as `push_contacts` does, and the
//!   push is the scheme's: m(1 + αh/2) Δv / h per node, so the projection's momentum times
//!   (1 + αh/2) over the step, per second.
//! - `fem-semi-implicit` holds them inside its sparse solve, as `fem-static` does: each a
//!   unilateral row of `DofProblem::points` (the mixed complementarity problem of
//!   `solve::lcp` on the Schur complement of K̂), so the push is the row's multiplier, the
//!   force at the end of the step (`semi_implicit`).
//!
//! Displacements stand in for positions: a point's level is its reach n·(t − rest) and its
//! coordinate Σ wᵢ n·uᵢ (`PointHold::tied` with zero rest positions).

use crate::error::SimError;
use crate::integrate::PointHold;
use crate::interact::PointContact;
use crate::math::{Real, Vec3, unflatten, unflatten_mut};

use super::super::system;
use super::common::Core;

impl Core {
    /// The points held from the next step on beside the constraints (`set_constraints_along`
    /// clears them).
    pub fn set_points(&mut self, points: &[PointContact]) -> Result<(), SimError> {
        let count = self.boundary.nodes.len();
        let mut holds = Vec::with_capacity(points.len());
        for pt in points {
            pt.check(count)?;
            holds.push(PointHold::tied(
                pt.vertices
                    .map(|v| self.boundary.nodes[v as usize] as usize),
                pt.weights,
                pt.normal,
                pt.reach(),
                [Vec3::ZERO; 3],
            ));
        }
        self.points = holds;
        self.point_push = vec![0.0; points.len()];
        self.point_impulse = vec![0.0; points.len()];
        self.point_trial = vec![0.0; points.len()];
        self.update_energy_floor();
        Ok(())
    }

    /// `fem-semi-implicit`'s rows: Σ wᵢ n·uᵢ ≥ reach over the points' nodes.
    pub fn point_rows(&self) -> impl Iterator<Item = system::PointHold> + '_ {
        self.points.iter().map(|pt| system::PointHold {
            nodes: pt.particles,
            weights: pt.weights,
            normal: pt.normal,
            value: pt.level,
        })
    }

    /// `fem-explicit`, after a central-difference (sub)step of length `h` left the points'
    /// nodes free in `u_next`: the points projected (module doc), each point's momentum
    /// over the substep in `point_trial`, the moved nodes' old U pushed on `undo` to restore
    /// a refused step.
    pub fn project_points(&mut self, h: Real, undo: &mut Vec<(usize, Vec3)>) {
        self.point_trial.iter_mut().for_each(|t| *t = 0.0);
        if self.points.is_empty() {
            return;
        }
        // The nodes' inverse masses, 0 on a held node (it takes none of a point's move),
        // and their velocities (U⁺ − U)/h: only the points' nodes are read or written.
        for pt in &self.points {
            for &i in &pt.particles {
                self.point_inv_mass[i] = if self.problem.constrained[3 * i] {
                    0.0
                } else {
                    1.0 / self.mass[3 * i]
                };
                let (x, u0) = (unflatten(&self.u_next)[i], unflatten(&self.u)[i]);
                self.point_v[i] = (x - u0) / h;
                undo.push((i, u0));
            }
        }
        let x = unflatten_mut(&mut self.u_next);
        self.projection
            .run(&self.points, x, &mut self.point_v, &self.point_inv_mass, h);
        for pt in &self.points {
            for &i in &pt.particles {
                let x = unflatten(&self.u_next)[i];
                unflatten_mut(&mut self.u)[i] = x - self.point_v[i] * h;
            }
        }
        let scale = 1.0 + 0.5 * self.material.damping * h;
        for (k, t) in self.point_trial.iter_mut().enumerate() {
            *t = scale * self.projection.momentum(k);
        }
    }

    /// The points' part of `prescribed_work`: ½K (depth)² for a point whose plane lies
    /// past it (K the stiffest diagonal entry of its nodes).
    pub(super) fn points_work(&self, stiffest: impl Fn(usize) -> Real) -> Real {
        let u = unflatten(&self.u);
        let mut e = 0.0;
        for pt in &self.points {
            let q: Real = (0..3)
                .map(|k| pt.weights[k] * pt.normal.dot(u[pt.particles[k]]))
                .sum();
            let depth = (pt.level - q).max(0.0);
            let k = pt
                .particles
                .iter()
                .map(|&i| stiffest(i))
                .fold(0.0, Real::max);
            e += 0.5 * k * depth * depth;
        }
        e
    }

    /// The points' part of `update_energy_floor`: ½K (reach)².
    pub(super) fn points_floor(&self, stiffest: impl Fn(usize) -> Real) -> Real {
        let mut e = 0.0;
        for pt in &self.points {
            let k = pt
                .particles
                .iter()
                .map(|&i| stiffest(i))
                .fold(0.0, Real::max);
            e += 0.5 * k * pt.level * pt.level;
        }
        e
    }
}
