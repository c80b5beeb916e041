//! Frictionless contacts that only push (issue 20), inside the implicit step.
//!
//! An instrument's contact given with a direction (`set_constraints_along`) is not a held
//! node: the node stays free, and the step decides it. An active contact is held along its
//! normal n only, by the filter S = I − n nᵀ of the modified PCG (`solve::CgWorkspace::
//! solve_filtered`, Baraff & Witkin 1998): its velocity change along n is set so that the
//! node ends the step on the plane through its target, and CG moves it freely across n. The
//! warp preconditioner is factorised with the supports (fixed and fully held nodes) only, so
//! a contact taken or let go never refactorises.
//!
//! The active set is settled within the step, as `fem-semi-implicit` does: it starts from
//! the contacts that pushed in the last step or start past their planes; a held contact
//! whose reaction pulls is let go (for the rest of the step, so the loop ends), a free one
//! that ends past its plane is taken, and it solves again (warm-started) until nothing
//! changes, at most `MAX_CONTACT_SOLVES` times (a step that stops there says `capped`).
//! The push is the held row's reaction: the normal component of A Δv − b over h, the force
//! the instrument put on the node over the step (the filter dropped it from the solve).

use crate::math::{Real, Vec3};

/// Solves of one step's active set before it stops unsettled (and says so).
pub const MAX_CONTACT_SOLVES: usize = 25;

/// A contact on a node: the plane through `target` with unit normal `normal`, pointing out
/// of the instrument toward the tissue.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PushContact {
    pub node: usize,
    pub normal: Vec3,
    /// A point of the plane (a position), m.
    pub target: Vec3,
    /// The push on the instrument over the last step, N (never negative): the reaction is
    /// −push·normal.
    pub push: Real,
}

impl PushContact {
    /// How far `x` is out of the plane (negative: past it).
    pub fn gap(&self, x: Vec3) -> Real {
        self.normal.dot(x - self.target)
    }
}

/// The filter S of the modified PCG: zero on held dofs, I − n nᵀ on the nodes of the
/// active contacts, the identity elsewhere.
#[derive(Clone, Debug, Default)]
pub(super) struct Filter {
    /// Dofs with a known velocity change (fixed and prescribed nodes).
    pub held: Vec<usize>,
    /// Nodes held along a unit direction only.
    pub along: Vec<(usize, Vec3)>,
}

impl Filter {
    /// v ← S v (flat, 3 entries per node).
    pub fn apply(&self, v: &mut [Real]) {
        for &d in &self.held {
            if let Some(x) = v.get_mut(d) {
                *x = 0.0;
            }
        }
        for &(i, n) in &self.along {
            if let Some(c) = v.get_mut(3 * i..3 * i + 3) {
                let s = n.x * c[0] + n.y * c[1] + n.z * c[2];
                c[0] -= s * n.x;
                c[1] -= s * n.y;
                c[2] -= s * n.z;
            }
        }
    }
}
