//! Keeping the explicit time step after cuts: the sliver guard.
//!
//! Lumped masses after a cut are exactly the surviving tetrahedra's (mass is conserved).
//! A node that is left hanging on one or two badly shaped tetrahedra then has little mass
//! and their full stiffness, so its own frequency, and with it the largest stable explicit
//! time step, can collapse. The guard bounds each node's frequency by Gershgorin's
//! theorem: ω² ≤ r_n = (Σ over its tetrahedra of the absolute row sums of their stiffness
//! at the node) / m_n, which bounds the largest eigenvalue of M⁻¹K (the tetrahedra's
//! blocks summed in absolute value, so also after any of them leave). When a cut leaves a
//! node with r_n above the largest r of the uncut model, the node's worst tetrahedron (the
//! largest stiffness per corner mass: the sliver) is removed as part of the cut, and the
//! check repeats on its corners. The uncut model's bound therefore still holds after any
//! number of cuts: the stable step cannot drop below the uncut model's Gershgorin step.

use crate::math::{Mat3, Real};

use super::spatial::TetLocator;
use super::system::TensorSystem;
use super::tensors::tet_blocks;

/// Per-corner stiffness bounds and the limit.
#[derive(Clone, Debug)]
pub struct StabilityGuard {
    /// Largest absolute row sum of each tetrahedron's stiffness rows at each corner, N/m.
    corner: Vec<[Real; 4]>,
    /// The largest r_n of the uncut model, 1/s².
    limit: Real,
}

fn abs_row_sums(m: &Mat3) -> [Real; 3] {
    [0, 1, 2].map(|r| m.row(r).abs().element_sum())
}

impl StabilityGuard {
    /// The bounds of every tetrahedron of `system` (before any cut).
    pub fn new(system: &TensorSystem, locator: &TetLocator) -> Self {
        let kappa = system.volume_penalty;
        let corner = (0..system.tets.len())
            .map(|t| {
                let (r, el) = (&system.rest_tets[t], &system.elasticity[t]);
                let k = tet_blocks(r, el);
                // Volume penalty at rest: κ V g_a g_bᵀ (g: shape-function gradients).
                let g = r.gradients;
                let gsum: Real = g.iter().map(|v| v.abs().element_sum()).sum();
                [0, 1, 2, 3].map(|a| {
                    let mut rows = [0.0; 3];
                    for blk in &k[a] {
                        let s = abs_row_sums(blk);
                        (0..3).for_each(|i| rows[i] += s[i]);
                    }
                    let pen = kappa * r.volume * g[a].abs().max_element() * gsum;
                    rows[0].max(rows[1]).max(rows[2]) + pen
                })
            })
            .collect();
        let mut guard = Self { corner, limit: 0.0 };
        guard.limit = (0..system.node_count())
            .map(|n| guard.rate(system, locator, n))
            .fold(0.0, Real::max);
        guard
    }

    /// Replaces the limit (infinity: the guard removes nothing).
    pub fn set_limit(&mut self, limit: Real) {
        self.limit = limit;
    }

    /// The explicit step the limit guarantees: 2/√limit (symplectic Euler, undamped).
    pub fn guaranteed_dt(&self) -> Real {
        2.0 / self.limit.sqrt()
    }

    /// The limit: the largest frequency bound r of the uncut model, 1/s².
    pub fn limit(&self) -> Real {
        self.limit
    }

    /// The bound r_n of node `n` with the tetrahedra alive now (0 for a detached node).
    pub fn rate(&self, system: &TensorSystem, locator: &TetLocator, n: usize) -> Real {
        let mut stiffness = 0.0;
        for &t in locator.tets_of(n) {
            let t = t as usize;
            if let (true, Some(a)) = (system.is_alive(t), corner_of(system, t, n)) {
                stiffness += self.corner[t][a];
            }
        }
        let m = system.masses.get(n).copied().unwrap_or(0.0);
        if stiffness == 0.0 {
            0.0
        } else if m > 0.0 {
            stiffness / m
        } else {
            Real::INFINITY
        }
    }

    /// The tetrahedron to remove at node `n`, if its bound exceeds the limit: the one with
    /// the largest stiffness per corner mass.
    pub fn offender(&self, system: &TensorSystem, locator: &TetLocator, n: usize) -> Option<usize> {
        if self.rate(system, locator, n) <= self.limit {
            return None;
        }
        let mut worst: Option<(Real, usize)> = None;
        for &t in locator.tets_of(n) {
            let t = t as usize;
            let Some(a) = corner_of(system, t, n).filter(|_| system.is_alive(t)) else {
                continue;
            };
            let quarter = 0.25 * system.density * system.rest_tets[t].volume;
            let r = self.corner[t][a] / quarter;
            if worst.is_none_or(|(w, _)| r > w) {
                worst = Some((r, t));
            }
        }
        worst.map(|(_, t)| t)
    }
}

fn corner_of(system: &TensorSystem, t: usize, n: usize) -> Option<usize> {
    system.tets.get(t)?.iter().position(|&v| v as usize == n)
}
