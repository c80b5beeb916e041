//! The implicit Euler step of `FemCorotational`: right-hand side, projected PCG solve (the
//! contacts' active set settled by solving again, `contact`), trial state, checks, commit,
//! reactions.

use crate::error::SimError;
use crate::math::{Real, Vec3, flatten, unflatten, unflatten_mut};
use crate::model::StepInfo;
use crate::solve::{CgResult, CgWorkspace};

use super::bsr::BlockStiffness;
use super::contact::{self, Filter, MAX_CONTACT_SOLVES, PointsDone};
use super::force;
use super::warp::WarpPreconditioner;
use super::{FemCorotational, Hold, Resolved};
use crate::integrate::contact::filtered_share;

/// One solve of A Δv = b: what is fixed over the step's solves.
struct Solve<'a> {
    stiffness: &'a BlockStiffness,
    masses: &'a [Real],
    cm: Real,
    ck: Real,
    inv_diag: &'a [Real],
    rhs: &'a [Real],
    cap: usize,
}

impl Solve<'_> {
    /// Modified PCG (`CgWorkspace::solve_filtered`) from `dv`, whose filtered-out part
    /// (held dofs, contacts' normal components) is the known velocity change, to the
    /// relative residual `tol` of S b.
    fn run(
        &self,
        cg: &mut CgWorkspace,
        warp: Option<&mut WarpPreconditioner>,
        filter: &Filter,
        dv: &mut [Real],
        tol: Real,
    ) -> CgResult {
        let (masses, stiffness, cm, ck) = (self.masses, self.stiffness, self.cm, self.ck);
        let apply = |z: &[Real], y: &mut [Real]| stiffness.apply(cm, ck, masses, z, y);
        let filter = |v: &mut [Real]| filter.apply(v);
        let cap = self.cap;
        match warp {
            Some(w) => {
                let precondition = |r: &[Real], z: &mut [Real]| w.apply(r, z);
                cg.solve_filtered(apply, precondition, filter, self.rhs, dv, cap, tol)
            }
            None => {
                let inv_diag = self.inv_diag;
                let jacobi = |r: &[Real], z: &mut [Real]| {
                    for ((zi, ri), d) in z.iter_mut().zip(r).zip(inv_diag) {
                        *zi = d * ri;
                    }
                };
                cg.solve_filtered(apply, jacobi, filter, self.rhs, dv, cap, tol)
            }
        }
    }
}

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
        let (elements, lame, rotations) = (&self.elements, &self.lame, &self.rotations);
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
        ws.filter.held.clear();
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
                        ws.filter.held.push(j);
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
        let (cap, tol) = (self.params.cg_iterations, self.params.cg_tolerance);
        let mut warp = match (&self.resolved, self.warp.as_mut()) {
            (Some(Resolved::Warp), Some(w)) => {
                // Contact nodes are free here: a contact taken or let go never refactorises.
                let held = self.holds.iter().map(|h| *h != Hold::Free);
                w.ensure_factored(cm, ck, &self.masses, held)?;
                w.update_rotations(elements, rotations);
                Some(w)
            }
            _ => None,
        };
        let solve = Solve {
            stiffness: &ws.stiffness,
            masses: &self.masses,
            cm,
            ck,
            inv_diag: &ws.inv_diag,
            rhs: &ws.rhs,
            cap,
        };
        // The contacts' active set (`contact`): the ones that pushed in the last step or
        // start past their planes are held first.
        let contacts = &self.contacts;
        ws.held.start(
            contacts
                .iter()
                .map(|k| self.pushed[k.node] || k.gap(self.x[k.node]) < 0.0),
        );
        ws.pushes.clear();
        ws.pushes.resize(contacts.len(), 0.0);
        // Pulls and penetrations below roundoff of the pushes and of the motion are none.
        let depth = 1e-12 * self.length;
        let mut solves = 0;
        let mut iterations = 0;
        // ‖S b‖ over the load the tolerance is relative to (`share` below).
        let mut share: Real;
        let (cg, settled) = loop {
            solves += 1;
            ws.filter.along.clear();
            for (k, _) in contacts.iter().zip(&ws.held.active).filter(|(_, a)| **a) {
                // Δv along n takes the node onto the plane at the end of the step.
                let i = k.node;
                let n = k.normal;
                let known = n.dot(k.target - self.x[i]) / h - n.dot(self.v[i]);
                let d = &mut unflatten_mut(&mut ws.dv)[i];
                *d += n * (known - n.dot(*d));
                ws.filter.along.push((i, n));
            }
            // The tolerance is relative to the step's load on the unknowns not held in full,
            // the contacts' normal loads included: settled, the filtered load S b alone is
            // roundoff (the targets follow the vertices), and a tolerance relative to it
            // stopped every step of a still hold at the cap. Without contacts the two agree.
            ws.kv.copy_from_slice(&ws.rhs);
            ws.filter.held.iter().for_each(|&d| ws.kv[d] = 0.0);
            let load = ws.kv.iter().map(|b| b * b).sum::<Real>().sqrt();
            ws.filter.apply(&mut ws.kv);
            let filtered = ws.kv.iter().map(|b| b * b).sum::<Real>().sqrt();
            share = filtered_share(load, filtered);
            let cg = solve.run(
                &mut ws.cg,
                warp.as_deref_mut(),
                &ws.filter,
                &mut ws.dv,
                tol / share,
            );
            iterations += cg.iterations;
            if contacts.is_empty() || !cg.relative_residual.is_finite() {
                break (cg, true);
            }
            // The pushes: the normal rows of A Δv − b (which the filter left out) over h.
            ws.stiffness.apply(cm, ck, &self.masses, &ws.dv, &mut ws.kv);
            for ((k, &a), p) in contacts.iter().zip(&ws.held.active).zip(&mut ws.pushes) {
                *p = if a {
                    k.normal
                        .dot(unflatten(&ws.kv)[k.node] - unflatten(&ws.rhs)[k.node])
                        / h
                } else {
                    0.0
                };
            }
            let (x, v, dv) = (&self.x, &self.v, &ws.dv);
            let end_gap = |j: usize| {
                let k = &contacts[j];
                let i = k.node;
                k.gap(x[i] + (v[i] + unflatten(dv)[i]) * h)
            };
            let changed = ws.held.update(&ws.pushes, end_gap, depth);
            if !changed {
                break (cg, true);
            }
            if solves >= MAX_CONTACT_SOLVES {
                break (cg, false);
            }
        };

        // A fine surface's points, held by their contact problem on this step's matrix
        // (`contact::hold_points`), the vertex contacts' active set settled.
        let mut points_done = PointsDone::default();
        if !self.points.is_empty() && cg.relative_residual.is_finite() {
            let holds = &self.holds;
            let free = |d: usize| holds[d / 3] == Hold::Free;
            let (cg_work, filter) = (&mut ws.cg, &ws.filter);
            let column = |r: &[Real], y: &mut [Real]| {
                let s = Solve { rhs: r, ..solve };
                let c = s.run(cg_work, warp.as_deref_mut(), filter, y, tol);
                let capped = !c.relative_residual.is_finite()
                    || (c.iterations >= cap && c.relative_residual > tol);
                (c.iterations, capped)
            };
            points_done = contact::hold_points(
                &self.points,
                &self.x,
                &self.v,
                h,
                depth,
                // Ten times the CG's tolerance: W's roundoff (`hold_points`).
                10.0 * tol.max(1e-10),
                free,
                filter,
                column,
                &mut ws.dv,
                &mut ws.points,
            )?;
            iterations += points_done.iterations;
        }
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
        // The residual relative to the load the tolerance is relative to.
        let residual = cg.relative_residual * share;
        self.last_cg = CgResult {
            iterations: cg.iterations,
            relative_residual: residual,
        };
        // A contact pushes only: one left pulling by an unsettled active set reads 0 (the
        // step says `capped`).
        self.pushed.iter_mut().for_each(|p| *p = false);
        for (k, &p) in self.contacts.iter_mut().zip(&ws.pushes) {
            k.push = p.max(0.0);
            self.pushed[k.node] = k.push > 0.0;
        }
        for (p, l) in self.point_push.iter_mut().zip(&self.ws.points.lambda) {
            *p = l.max(0.0);
        }
        self.contact_solves = solves;
        self.contact_caps += u64::from(!settled);
        self.update_reactions();
        self.update_surface();
        Ok(StepInfo {
            iterations,
            residual,
            capped: (cg.iterations >= cap && residual > tol) || !settled || points_done.capped,
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
                &self.lame,
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
        for k in &self.contacts {
            self.node_reactions[k.node] = -k.normal * k.push;
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
        self.contacts.iter_mut().for_each(|k| k.push = 0.0);
        self.point_push.iter_mut().for_each(|p| *p = 0.0);
        self.pushed.iter_mut().for_each(|p| *p = false);
        if let Some(w) = self.warp.as_mut() {
            w.reset();
        }
        self.update_reactions();
        self.update_surface();
    }
}
