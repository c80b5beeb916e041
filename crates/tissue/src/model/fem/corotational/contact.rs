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
//! The active set is settled within the step (`integrate::contact::HeldContacts`, shared
//! with the integrator's implicit Euler): it starts from the contacts that pushed in the
//! last step or start past their planes; a held contact whose reaction pulls is let go (for
//! the rest of the step, so the loop ends), a free one that ends past its plane is taken,
//! and it solves again (warm-started) until nothing changes, at most `MAX_CONTACT_SOLVES`
//! times (a step that stops there says `capped`).
//! The push is the held row's reaction: the normal component of A Δv − b over h, the force
//! the instrument put on the node over the step (the filter dropped it from the solve).
//!
//! A fine surface's points (`hold_points`) tie three nodes each, which a per-node filter
//! cannot hold: after the vertex contacts settle, each point that ends past its plane gets a
//! column A⁻¹c of the filtered system (one CG solve), and their pushes solve the mixed
//! complementarity problem on W = Cᵀ A⁻¹ C (`solve::lcp`).

use crate::error::SimError;
use crate::integrate::PointHold;
use crate::math::{Real, Vec3, unflatten};
use crate::solve::lcp;

/// Solves of one step's active set before it stops unsettled (and says so): the shared one.
pub use crate::integrate::contact::MAX_CONTACT_SOLVES;

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

/// The points' contact problem of one step (`hold_points`) and its buffers.
#[derive(Clone, Debug, Default)]
pub(super) struct PointWork {
    /// Per point: in the problem; its push, N.
    inside: Vec<bool>,
    pub lambda: Vec<Real>,
    /// The points in the problem, in its order, and their columns y = (S A S)⁺ S c (flat,
    /// one per row).
    rows: Vec<usize>,
    columns: Vec<Real>,
    /// A column's right-hand side, and Δv without the points' pushes.
    rhs: Vec<Real>,
    dv0: Vec<Real>,
}

/// What `hold_points` took: CG iterations, whether a column's solve stopped at its cap (or
/// the problem at `MAX_CONTACT_SOLVES` rounds), and rounds.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct PointsDone {
    pub iterations: usize,
    pub capped: bool,
    pub rounds: usize,
}

/// A fine surface's points (a point ties three nodes, Σ wᵢ n·xᵢ ≥ level, which the per-node
/// filter cannot hold) held in the implicit step: with Δv₀ the step's solve without them
/// (`dv` on entry) and c a point's row over the free dofs, their pushes μ = hλ move Δv by
/// Σ yⱼ μⱼ, yⱼ = A⁻¹ cⱼ on the filtered system (one CG solve per point, `column`: its
/// iterations and whether it stopped at its cap), so each
/// point's end position is (q₀ − level)/h + Σ (cₖ·yⱼ) μⱼ along its normal over h: the
/// mixed LCP of `solve::lcp` on W = Cᵀ A⁻¹ C, exactly the step with the points (to the CG's
/// tolerance), as `fem-static` and `fem-semi-implicit` solve theirs on their own matrices.
/// Only the points past their planes after the solve without them enter; one that ends past
/// its plane after the pushes enters and the problem is solved again. On return `dv` holds
/// the step's Δv and `work.lambda` each point's push, N.
#[allow(clippy::too_many_arguments)]
pub(super) fn hold_points(
    points: &[PointHold],
    x: &[Vec3],
    v: &[Vec3],
    h: Real,
    depth: Real,
    compliance: Real,
    free: impl Fn(usize) -> bool,
    filter: &Filter,
    mut column: impl FnMut(&[Real], &mut [Real]) -> (usize, bool),
    dv: &mut [Real],
    work: &mut PointWork,
) -> Result<PointsDone, SimError> {
    let n = dv.len();
    work.inside.clear();
    work.inside.resize(points.len(), false);
    work.lambda.clear();
    work.lambda.resize(points.len(), 0.0);
    work.rows.clear();
    work.columns.clear();
    work.rhs.resize(n, 0.0);
    work.dv0.clear();
    work.dv0.extend_from_slice(dv);
    let mut done = PointsDone::default();
    // The point's row cₖ·y over its nodes' free dofs.
    let row = |pt: &PointHold, y: &[Real]| -> Real {
        let mut s = 0.0;
        for (&i, &w) in pt.particles.iter().zip(&pt.weights) {
            for axis in 0..3 {
                let d = 3 * i + axis;
                if free(d) {
                    s += w * pt.normal[axis] * y[d];
                }
            }
        }
        s
    };
    // How far a point ends out of its plane with the step's Δv (negative: past it).
    let end_gap = |pt: &PointHold, dv: &[Real]| -> Real {
        let dv = unflatten(dv);
        (0..3)
            .map(|k| {
                let i = pt.particles[k];
                pt.weights[k] * pt.normal.dot(x[i] + (v[i] + dv[i]) * h)
            })
            .sum::<Real>()
            - pt.level
    };
    loop {
        let mut added = false;
        for (k, pt) in points.iter().enumerate() {
            if work.inside[k] || end_gap(pt, dv) >= -depth {
                continue;
            }
            work.rhs.iter_mut().for_each(|r| *r = 0.0);
            for (&i, &w) in pt.particles.iter().zip(&pt.weights) {
                for axis in 0..3 {
                    let d = 3 * i + axis;
                    if free(d) {
                        work.rhs[d] += w * pt.normal[axis];
                    }
                }
            }
            filter.apply(&mut work.rhs);
            if work.rhs.iter().all(|r| *r == 0.0) {
                // On held nodes only: nothing moves it.
                work.inside[k] = true;
                continue;
            }
            let start = work.columns.len();
            work.columns.resize(start + n, 0.0);
            let (iterations, capped) = column(&work.rhs, &mut work.columns[start..]);
            done.iterations += iterations;
            done.capped |= capped;
            work.inside[k] = true;
            work.rows.push(k);
            added = true;
        }
        if !added {
            break;
        }
        done.rounds += 1;
        let m = work.rows.len();
        let y = |j: usize| &work.columns[j * n..(j + 1) * n];
        // W from CG solves is symmetric and semi-definite only to the CG's tolerance (and
        // exactly singular for points on one coarse vertex, which a fine surface repeats per
        // face): its symmetric part, the diagonal raised by `compliance` of the largest (a
        // penetration of that fraction of the pushes' own motion).
        let mut matrix = faer::Mat::from_fn(m, m, |a, b| {
            0.5 * (row(&points[work.rows[a]], y(b)) + row(&points[work.rows[b]], y(a)))
        });
        let largest = (0..m).map(|a| matrix[(a, a)]).fold(0.0, Real::max);
        for a in 0..m {
            matrix[(a, a)] += compliance * largest;
        }
        let b: Vec<Real> = work
            .rows
            .iter()
            .map(|&k| end_gap(&points[k], &work.dv0) / h)
            .collect();
        let guess = lcp::first_guess(&b, 0, |a| points[work.rows[a]].particles);
        let solution = lcp::solve_mixed(matrix.as_ref(), &b, 0, &guess)?;
        dv.copy_from_slice(&work.dv0);
        work.lambda.iter_mut().for_each(|l| *l = 0.0);
        for (j, &mu) in solution.lambda.iter().enumerate() {
            work.lambda[work.rows[j]] = mu / h;
            if mu != 0.0 {
                for (d, yj) in dv.iter_mut().zip(y(j)) {
                    *d += mu * yj;
                }
            }
        }
        if done.rounds >= MAX_CONTACT_SOLVES {
            done.capped = true;
            break;
        }
    }
    Ok(done)
}
