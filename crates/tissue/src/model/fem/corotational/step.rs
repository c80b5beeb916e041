//! The implicit Euler step of `FemCorotational`: right-hand side, projected PCG solve,
//! trial state, checks, commit, reactions.

use crate::error::SimError;
use crate::math::{Real, Vec3, flatten};
use crate::model::StepInfo;

use super::force;
use super::{FemCorotational, Hold, Resolved};

impl FemCorotational {
    /// Advances by `dt` seconds. On a non-finite result the state is left as it was.
    pub fn advance(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SimError::BadTimeStep { dt });
        }
        self.ensure_elastic();
        if self.resolved.is_none() {
            self.resolve_solver()?;
        }
        let h = dt;
        let (alpha, beta) = (self.material.damping, self.material.stiffness_damping);
        let (elements, lame, rotations) = (&self.elements, self.lame, &self.rotations);
        let ws = &mut self.ws;
        let v = flatten(&self.v);
        let x = flatten(&self.x);

        // rhs = h (f_el + f_ext − α M v − (β + h) K v).
        // K is fixed over the step: assembled once, it makes each CG product one mat-vec.
        ws.stiffness.assemble(elements, lame, rotations);
        ws.stiffness.apply(0.0, 1.0, &self.masses, v, &mut ws.kv);
        // A = (1 + hα) M + (hβ + h²) K, its diagonal for the preconditioner.
        let (cm, ck) = (1.0 + h * alpha, h * beta + h * h);
        ws.inv_diag.iter_mut().for_each(|d| *d = 0.0);
        ws.stiffness.add_diagonal(&mut ws.inv_diag);
        for (i, hold) in self.holds.iter().enumerate() {
            let m = self.masses[i];
            let fext = self.external[i];
            for k in 0..3 {
                let j = 3 * i + k;
                ws.rhs[j] =
                    h * (self.elastic[j] + fext[k] - alpha * m * v[j] - (beta + h) * ws.kv[j]);
                // Constrained dofs: Δv is known and the unknown is masked out of CG.
                let known = match hold {
                    Hold::Free => None,
                    Hold::Fixed => Some(-v[j]),
                    Hold::Target(p) => Some((p[k] - x[j]) / h - v[j]),
                };
                match known {
                    None => {
                        ws.dv[j] = self.last_dv[j];
                        ws.inv_diag[j] = 1.0 / (cm * m + ck * ws.inv_diag[j]);
                    }
                    Some(d) => {
                        ws.dv[j] = d;
                        ws.inv_diag[j] = 0.0;
                    }
                }
            }
        }
        // A step so large that h² or the loads overflow cannot be solved meaningfully.
        if let Some(j) =
            (0..ws.rhs.len()).find(|&j| !(ws.rhs[j].is_finite() && ws.inv_diag[j].is_finite()))
        {
            return Err(SimError::Diverged {
                step: self.steps + 1,
                node: j / 3,
                reason: format!("the step's system is not finite (dt = {dt} s)"),
            });
        }
        let masses = &self.masses;
        let stiffness = &ws.stiffness;
        let apply = |z: &[Real], y: &mut [Real]| stiffness.apply(cm, ck, masses, z, y);
        let (cap, tol) = (self.params.cg_iterations, self.params.cg_tolerance);
        let cg = match (&self.resolved, self.warp.as_mut()) {
            (Some(Resolved::Warp), Some(w)) => {
                let held = self.holds.iter().map(|h| *h != Hold::Free);
                w.ensure_factored(cm, ck, masses, held)?;
                w.update_rotations(elements, rotations);
                let precondition = |r: &[Real], z: &mut [Real]| w.apply(r, z);
                ws.cg.solve_preconditioned(
                    apply,
                    precondition,
                    &ws.inv_diag,
                    &ws.rhs,
                    &mut ws.dv,
                    cap,
                    tol,
                )
            }
            _ => ws
                .cg
                .solve(apply, &ws.inv_diag, &ws.rhs, &mut ws.dv, cap, tol),
        };

        if !cg.relative_residual.is_finite() {
            return Err(SimError::Diverged {
                step: self.steps + 1,
                node: 0,
                reason: "the conjugate-gradient residual is not finite".into(),
            });
        }
        // Trial state.
        for (i, hold) in self.holds.iter().enumerate() {
            let dv = Vec3::new(ws.dv[3 * i], ws.dv[3 * i + 1], ws.dv[3 * i + 2]);
            let vi = self.v[i] + dv;
            ws.v[i] = vi;
            ws.x[i] = match hold {
                Hold::Target(p) => *p,
                _ => self.x[i] + vi * h,
            };
        }
        let bad = |node: usize, reason: &str| SimError::Diverged {
            step: self.steps + 1,
            node,
            reason: reason.into(),
        };
        if let Some(i) = (0..ws.x.len()).find(|&i| {
            !(crate::math::is_finite_vec(ws.x[i]) && crate::math::is_finite_vec(ws.v[i]))
        }) {
            return Err(bad(i, "position or velocity is not finite"));
        }
        ws.rotations.copy_from_slice(&self.rotations);
        ws.elastic.iter_mut().for_each(|f| *f = 0.0);
        force::elastic_forces(
            elements,
            lame,
            flatten(&ws.x),
            &mut ws.rotations,
            &mut ws.elastic,
            &mut ws.element_forces,
        );
        if let Some(j) = ws.elastic.iter().position(|f| !f.is_finite()) {
            return Err(bad(j / 3, "elastic force is not finite"));
        }

        // Commit.
        std::mem::swap(&mut self.x, &mut ws.x);
        std::mem::swap(&mut self.v, &mut ws.v);
        std::mem::swap(&mut self.rotations, &mut ws.rotations);
        std::mem::swap(&mut self.elastic, &mut ws.elastic);
        std::mem::swap(&mut self.last_dv, &mut ws.dv);
        self.steps += 1;
        self.last_cg = cg;
        self.update_reactions();
        self.update_surface();
        Ok(StepInfo {
            iterations: cg.iterations,
            residual: cg.relative_residual,
            capped: cg.iterations >= cap && cg.relative_residual > tol,
            substeps: 1,
        })
    }

    /// Reactions at the constrained nodes: elastic + damping + external share at (x, v).
    pub(super) fn update_reactions(&mut self) {
        let beta = self.material.stiffness_damping;
        let kv = &mut self.ws.kv;
        kv.iter_mut().for_each(|y| *y = 0.0);
        if beta > 0.0 {
            // Only the held nodes' rows are read below, so only their elements are needed:
            // each held row gets the same terms in the same order as from the full product.
            let holds = &self.holds;
            force::add_stiffness_product_where(
                &self.elements,
                self.lame,
                &self.rotations,
                flatten(&self.v),
                kv,
                |e| e.nodes.iter().any(|&n| holds[n as usize] != Hold::Free),
            );
        }
        let alpha = self.material.damping;
        for (i, hold) in self.holds.iter().enumerate() {
            self.node_reactions[i] = match hold {
                Hold::Free => Vec3::ZERO,
                _ => {
                    let j = 3 * i;
                    let el = Vec3::new(self.elastic[j], self.elastic[j + 1], self.elastic[j + 2]);
                    let kvi = Vec3::new(kv[j], kv[j + 1], kv[j + 2]);
                    el + self.external[i] - self.v[i] * (alpha * self.masses[i]) - kvi * beta
                }
            };
        }
        self.distribute_reactions();
    }

    /// Back to rest, velocities zero (constraints and loads kept).
    pub fn reset_state(&mut self) {
        self.x.copy_from_slice(&self.rest);
        self.v.iter_mut().for_each(|v| *v = Vec3::ZERO);
        self.last_dv.iter_mut().for_each(|v| *v = 0.0);
        self.rotations
            .iter_mut()
            .for_each(|r| *r = crate::math::Mat3::IDENTITY);
        self.elastic.iter_mut().for_each(|f| *f = 0.0);
        self.elastic_valid = true;
        self.steps = 0;
        if let Some(w) = self.warp.as_mut() {
            w.reset();
        }
        self.update_reactions();
        self.update_surface();
    }
}
