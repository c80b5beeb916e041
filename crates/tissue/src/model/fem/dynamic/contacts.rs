//! Frictionless contacts that only push (issue 20): an instrument's contact on a surface
//! vertex, given with a direction (`set_constraints_along`), is not a held dof. The node
//! stays free in the scheme and the contact is decided within the step, so it never pulls:
//!
//! - `fem-explicit` puts a node that went past its contact's plane back on it after every
//!   central-difference substep and removes its inward velocity (`integrate::contact`, the
//!   same mechanics as the integrator's `Hold::contact`); the push is the momentum that
//!   took over the step, per second.
//! - `fem-semi-implicit` solves with an active set: the touching contacts held along their
//!   normals in its sparse solve (`DofProblem::along`), a held one whose reaction pulls let
//!   go, a free one that ends past its plane taken, until nothing changes.

use crate::integrate::contact::push_only;
use crate::math::{Real, Vec3, unflatten, unflatten_mut};

use super::common::Core;

/// A contact on a node: the plane through `target` (a displacement from rest) with unit
/// normal `normal`, pointing out of the instrument toward the tissue.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PushContact {
    pub node: usize,
    pub normal: Vec3,
    pub target: Vec3,
    /// The push on the instrument over the last step, N (never negative): the reaction is
    /// −push·normal.
    pub push: Real,
    /// Momentum the contact gave the node over the accepted substeps of this step, N·s.
    pub impulse: Real,
    /// The same for the substep in progress (`fem-explicit`).
    pub trial: Real,
}

impl PushContact {
    /// How far the node at `u` is out of the plane (negative: past it).
    pub fn gap(&self, u: &[Real]) -> Real {
        self.normal.dot(unflatten(u)[self.node] - self.target)
    }
}

impl Core {
    /// `fem-explicit`, after a central-difference (sub)step of length `h` left the contact
    /// nodes free in `u_next`: each node past its plane goes back on it with its inward
    /// velocity removed (`integrate::contact::push_only`). The velocity of the difference
    /// scheme is (U⁺ − U)/h, so a changed velocity moves the node's U as well; its old value
    /// is pushed on `undo` to restore a refused step. The push's momentum is the scheme's:
    /// the central difference gives the force R on a node as m(1 + αh/2) Δv / h, so on a
    /// node resting on its plane the push is exactly the static residual along n.
    pub fn push_contacts(&mut self, h: Real, undo: &mut Vec<(usize, Vec3)>) {
        let scale = 1.0 + 0.5 * self.material.damping * h;
        for k in &mut self.contacts {
            k.trial = 0.0;
            let (x, u0) = (unflatten(&self.u_next)[k.node], unflatten(&self.u)[k.node]);
            let Some(p) = push_only(x, (x - u0) / h, k.target, k.normal, h) else {
                continue;
            };
            undo.push((k.node, u0));
            unflatten_mut(&mut self.u_next)[k.node] = p.position;
            unflatten_mut(&mut self.u)[k.node] = p.position - p.velocity * h;
            k.trial = self.mass[3 * k.node] * scale * p.dv;
        }
    }

    /// Restores the nodes `push_contacts` and `project_points` moved in a refused
    /// (sub)step (last first: a node both moved gets its value from before either).
    pub fn undo_pushes(&mut self, undo: &[(usize, Vec3)]) {
        for &(i, u0) in undo.iter().rev() {
            unflatten_mut(&mut self.u)[i] = u0;
        }
    }

    /// Starts a step's momentum count.
    pub fn clear_impulses(&mut self) {
        self.contacts.iter_mut().for_each(|k| k.impulse = 0.0);
        self.point_impulse.iter_mut().for_each(|p| *p = 0.0);
    }

    /// Ends a step of length `dt`: the push is the momentum per second.
    pub fn finish_pushes(&mut self, dt: Real) {
        for k in &mut self.contacts {
            k.push = k.impulse / dt;
        }
        for (p, i) in self.point_push.iter_mut().zip(&self.point_impulse) {
            *p = i / dt;
        }
        self.write_contact_reactions();
        self.update_reactions();
    }

    /// The contacts' reactions into the per-dof reactions: −push·n on each contact node.
    pub fn write_contact_reactions(&mut self) {
        for k in &self.contacts {
            unflatten_mut(&mut self.r)[k.node] = -k.normal * k.push;
        }
    }

    /// The energy the prescribed motion can put in over the step about to be taken: for
    /// every held dof ½K_dd (g_d − u_d)², for a node held along n ½K (n·(g − u))², for a
    /// contact whose plane lies past its node ½K (its depth)² (K the stiffest diagonal
    /// entry of the node). A body at rest given a first contact or a target jump gains up to
    /// about this much in one step, so the growth test compares with it as well.
    pub(super) fn prescribed_work(&self) -> Real {
        let diag = &self.diag;
        let stiffest = |i: usize| (0..3).map(|k| self.k[diag[3 * i + k]]).fold(0.0, Real::max);
        let mut e = 0.0;
        for &d in &self.problem.list {
            e += 0.5 * self.k[diag[d]] * (self.problem.targets[d] - self.u[d]).powi(2);
        }
        for a in &self.problem.along {
            let moved = a.value - a.normal.dot(unflatten(&self.u)[a.node]);
            e += 0.5 * stiffest(a.node) * moved * moved;
        }
        for k in &self.contacts {
            let depth = (-k.gap(&self.u)).max(0.0);
            e += 0.5 * stiffest(k.node) * depth * depth;
        }
        e + self.points_work(stiffest)
    }
}
