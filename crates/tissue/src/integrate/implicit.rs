//! Implicit (backward) Euler, linearised once per step (Baraff & Witkin 1998):
//!
//! (M + h·C + h²·K) Δv = h·(f0 − h·K·v0),   v1 = v0 + Δv,   x1 = x0 + h·v1,
//!
//! with K = −∂f/∂x and C = −∂f/∂v at the start of the step, solved matrix-free by the shared
//! CG, preconditioned by the factorised rest matrix M + h·C₀ + h²·K₀ where the system gives
//! its rest Jacobians (`rest_factor`), else by Jacobi. The operator's Jacobian part is one
//! `ParticleSystem::system_product` per iteration. Held particles already move at their step velocity in v0, so
//! their Δv is zero: they are masked out of the solve, and their motion enters the right-hand
//! side through K·v0. The last Δv warm-starts the next solve.
//!
//! A push-only contact (`Hold::contact`) is held inside the solve, not put back after it:
//! the touching ones are held along their normals by the filter of the modified CG
//! (`CgWorkspace::solve_filtered`, Baraff & Witkin), so the particle ends on its plane and
//! its neighbours answer to that, and the push is the held row's reaction, the normal part
//! of (A Δv − b)/h. The active set is settled within the step: a held contact whose
//! reaction pulls is let go, a free one that ends past its plane is taken, and it solves
//! again. Put back after the solve instead, a contact left the solve's state a fixed point
//! of (solve, projection) rather than the constrained equilibrium (the solve moved the
//! contact's neighbours with it, the projection returned only the contact), and its
//! impulse read a block pressed by a plane at 0.204 N where the equilibrium is 0.3986 N.

use crate::error::SimError;
use crate::math::{Mat3, Real, Vec3, flatten, flatten_mut, unflatten, unflatten_mut};
use crate::model::StepInfo;
use crate::solve::{CgResult, CgWorkspace};

use super::contact::{self, HeldContacts, MAX_CONTACT_SOLVES};
use super::rest_factor::RestPreconditioner;
use super::{Hold, IntegratorSettings, ParticleSystem, Preconditioner, Workspace};

/// A contact held in the solve: which hold, its particle, normal and plane point.
#[derive(Clone, Copy, Debug)]
struct SolveContact {
    hold: usize,
    particle: usize,
    normal: Vec3,
    target: Vec3,
}

#[derive(Clone, Debug, Default)]
pub(super) struct ImplicitSolver {
    cg: CgWorkspace,
    dv: Vec<Vec3>,
    rhs: Vec<Real>,
    inv_diag: Vec<Real>,
    mass: Vec<Real>,
    stiffness_diag: Vec<Vec3>,
    damping_diag: Vec<Vec3>,
    k_times: Vec<Vec3>,
    c_times: Vec<Vec3>,
    rest: RestPreconditioner,
    stiffness_blocks: Vec<Mat3>,
    damping_blocks: Vec<Mat3>,
    inv_blocks: Vec<Mat3>,
    /// The operator's product A·Δv, for the contacts' reactions.
    product: Vec<Real>,
    /// Per contact held in the last solve: its hold's index and its push along the normal,
    /// N (≥ 0). The integrator reads them after the step (`held_in_solve`).
    pub contact_pushes: Vec<(usize, Real)>,
    /// Particles whose contact pushed in the last step: the next step's first guess.
    pushed: Vec<usize>,
    /// The step's contacts held in the solve, and their pushes after the last solve, N.
    held: HeldContacts,
    pushes: Vec<Real>,
    /// The held contacts' known velocity changes (x_c of the filtered solve).
    known: Vec<Vec3>,
    /// This step's push-only contacts (a buffer kept between steps).
    contacts: Vec<SolveContact>,
}

impl ImplicitSolver {
    pub fn factorizations(&self) -> usize {
        self.rest.factorizations
    }

    pub fn forget_warm_start(&mut self) {
        self.dv.fill(Vec3::ZERO);
    }

    pub fn step<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        w: &mut Workspace,
        holds: &[Hold],
        h: Real,
        settings: &IntegratorSettings,
        step: u64,
    ) -> Result<StepInfo, SimError> {
        let n = w.x0.len();
        self.resize(n);
        self.contact_pushes.clear();
        // Kept between steps: no allocation per step.
        let mut contacts = std::mem::take(&mut self.contacts);
        contacts.clear();
        contacts.extend(
            holds
                .iter()
                .enumerate()
                .filter(|(_, c)| c.unilateral && c.particle < n && w.inv_mass[c.particle] > 0.0)
                .filter_map(|(k, c)| {
                    c.along.map(|normal| SolveContact {
                        hold: k,
                        particle: c.particle,
                        normal,
                        target: c.target,
                    })
                }),
        );
        system.prepare_jacobians(&w.x0, &w.v0)?;
        system.stiffness_product(&w.v0, &mut w.a);
        system.jacobian_diagonal(&mut self.stiffness_diag, &mut self.damping_diag);
        for i in 0..n {
            let free = w.inv_mass[i] > 0.0;
            let m = if free { 1.0 / w.inv_mass[i] } else { 0.0 };
            let rhs = h * (w.f0[i] - h * w.a[i]);
            let diag = Vec3::splat(m) + h * self.damping_diag[i] + h * h * self.stiffness_diag[i];
            for k in 0..3 {
                let j = 3 * i + k;
                self.mass[j] = m;
                self.rhs[j] = if free { rhs[k] } else { 0.0 };
                // A non-positive diagonal (an unstable linearisation) falls back to the mass.
                let d = if diag[k] > 0.0 && diag[k].is_finite() {
                    diag[k]
                } else {
                    m
                };
                self.inv_diag[j] = if free { 1.0 / d } else { 0.0 };
            }
            if !free {
                self.dv[i] = Vec3::ZERO;
            }
        }
        let blocks = settings.preconditioner == Preconditioner::BlockJacobi;
        if blocks {
            self.invert_blocks(system, &w.inv_mass, h);
        }
        let factored = settings.preconditioner == Preconditioner::RestFactor
            && system.rest_jacobians_version().is_some_and(|version| {
                self.rest
                    .ensure(h, version, system.masses(), &w.held, &w.x0, |out| {
                        system.rest_jacobians(out)
                    })
            });
        let Self {
            cg,
            dv,
            rhs,
            inv_diag,
            mass,
            k_times,
            c_times,
            rest,
            inv_blocks,
            product,
            contact_pushes,
            pushed,
            held,
            pushes,
            known,
            ..
        } = self;
        let mut apply = |p: &[Real], y: &mut [Real]| {
            system.system_product(h, h * h, unflatten(p), k_times, c_times);
            let jp = flatten(k_times);
            for j in 0..y.len() {
                y[j] = mass[j] * p[j] + jp[j];
            }
        };
        let (max_it, tol) = (settings.cg_max_iterations, settings.cg_tolerance);
        let mut contacts_settled = true;
        // ‖S b‖ over the load the tolerance is relative to (`contact::filtered_share`).
        let mut share: Real = 1.0;
        let mut iterations = 0;
        let result = if !contacts.is_empty() {
            let mut precondition = |r: &[Real], z: &mut [Real]| {
                if factored {
                    rest.apply(r, z);
                } else if blocks {
                    for ((zi, ri), b) in unflatten_mut(z)
                        .iter_mut()
                        .zip(unflatten(r))
                        .zip(&*inv_blocks)
                    {
                        *zi = *b * *ri;
                    }
                } else {
                    for ((zi, ri), d) in z.iter_mut().zip(r).zip(&*inv_diag) {
                        *zi = ri * d;
                    }
                }
            };
            // First guess: the contacts that pushed in the last step, and those the start's
            // motion carries past their planes.
            held.start(contacts.iter().map(|c| {
                pushed.contains(&c.particle)
                    || c.normal
                        .dot(w.x0[c.particle] + h * w.v0[c.particle] - c.target)
                        < 0.0
            }));
            // The load on the unknowns not held in full (held particles' rows are zero).
            let load = rhs.iter().map(|b| b * b).sum::<Real>().sqrt();
            // Penetrations below round-off of the step's motion are none.
            let depth = 1e-12 * extent(&w.x0);
            let mut result = CgResult::default();
            contacts_settled = false;
            for _ in 0..MAX_CONTACT_SOLVES {
                // A held contact's velocity change along n ends its particle on its plane.
                for (c, on) in contacts.iter().zip(&held.active) {
                    if *on {
                        let i = c.particle;
                        let want = c.normal.dot(c.target - w.x0[i]) / h - c.normal.dot(w.v0[i]);
                        let along = c.normal.dot(dv[i]);
                        dv[i] += c.normal * (want - along);
                    }
                }
                let active = &held.active;
                let held_mask = &*mass;
                // S: zero on the held particles (their Δv is known: zero), I − n nᵀ on the
                // held contacts' particles. Without the first part the held rows of A Δv
                // stay in the residual, which no search direction can reduce.
                let filter = |v: &mut [Real]| {
                    for (vj, d) in v.iter_mut().zip(held_mask.iter()) {
                        if *d == 0.0 {
                            *vj = 0.0;
                        }
                    }
                    for (c, on) in contacts.iter().zip(active) {
                        if *on {
                            let j = 3 * c.particle;
                            let x = Vec3::new(v[j], v[j + 1], v[j + 2]);
                            let x = x - c.normal * c.normal.dot(x);
                            v[j..j + 3].copy_from_slice(&x.to_array());
                        }
                    }
                };
                product.copy_from_slice(rhs);
                filter(product);
                let filtered = product.iter().map(|b| b * b).sum::<Real>().sqrt();
                // What drives the free part: S (b − A x_c), x_c the held contacts' known
                // velocity changes along n. A probe moving into still tissue loads it
                // through x_c alone (b is round-off at rest), so the tolerance is relative
                // to the larger of that and the whole load.
                known.iter_mut().for_each(|v| *v = Vec3::ZERO);
                for (c, on) in contacts.iter().zip(active) {
                    if *on {
                        let i = c.particle;
                        known[i] = c.normal * c.normal.dot(dv[i]);
                    }
                }
                apply(flatten(known), product);
                for (p, b) in product.iter_mut().zip(rhs.iter()) {
                    *p = b - *p;
                }
                filter(product);
                let driver = product.iter().map(|b| b * b).sum::<Real>().sqrt();
                share = contact::filtered_share(load.max(driver), filtered);
                result = cg.solve_filtered(
                    &mut apply,
                    &mut precondition,
                    filter,
                    rhs,
                    flatten_mut(dv),
                    max_it,
                    tol / share,
                );
                iterations += result.iterations;
                if !result.relative_residual.is_finite() {
                    contacts_settled = true;
                    break;
                }
                apply(flatten(dv), product);
                // The pushes: the normal rows of A Δv − b (which the filter left out) over h,
                // the reaction over the step: (A Δv − b)ᵢ = h F_c.
                pushes.clear();
                pushes.extend(contacts.iter().map(|c| {
                    let j = 3 * c.particle;
                    let r = Vec3::new(
                        product[j] - rhs[j],
                        product[j + 1] - rhs[j + 1],
                        product[j + 2] - rhs[j + 2],
                    );
                    c.normal.dot(r) / h
                }));
                let end_gap = |k: usize| {
                    let c = &contacts[k];
                    let i = c.particle;
                    c.normal.dot(w.x0[i] + h * (w.v0[i] + dv[i]) - c.target)
                };
                if !held.update(pushes, end_gap, depth) {
                    contacts_settled = true;
                    break;
                }
            }
            pushed.clear();
            for ((c, on), p) in contacts.iter().zip(&held.active).zip(pushes.iter()) {
                if *on {
                    // A contact pushes only: one left pulling by an unsettled set reads 0
                    // (the step says `capped`).
                    contact_pushes.push((c.hold, p.max(0.0)));
                    pushed.push(c.particle);
                }
            }
            result
        } else if blocks || factored {
            // One solve for both: only the preconditioner differs.
            let precondition = |r: &[Real], z: &mut [Real]| {
                if factored {
                    rest.apply(r, z);
                } else {
                    for ((zi, ri), b) in unflatten_mut(z)
                        .iter_mut()
                        .zip(unflatten(r))
                        .zip(&*inv_blocks)
                    {
                        *zi = *b * *ri;
                    }
                }
            };
            let result = cg.solve_preconditioned(
                apply,
                precondition,
                inv_diag,
                rhs,
                flatten_mut(dv),
                max_it,
                tol,
            );
            if factored {
                rest.record(result.iterations);
            }
            result
        } else {
            cg.solve(apply, inv_diag, rhs, flatten_mut(dv), max_it, tol)
        };
        if !result.relative_residual.is_finite() {
            return Err(SimError::Diverged {
                step,
                node: 0,
                reason: "the implicit solve produced a non-finite residual".into(),
            });
        }
        for i in 0..n {
            w.v1[i] = w.v0[i] + self.dv[i];
            w.x1[i] = w.x0[i] + h * w.v1[i];
        }
        // The residual relative to the load the tolerance is relative to; the iterations of
        // every solve of the contacts' active set.
        let residual = result.relative_residual * share;
        let iterations = iterations.max(result.iterations);
        self.contacts = contacts;
        Ok(StepInfo {
            iterations,
            residual,
            // A solve stopped by the cap before its tolerance is an approximation the caller
            // must hear of (`tissue run` counts such steps and their worst residual), and so
            // is a contact active set still changing at its cap.
            capped: (result.iterations >= max_it && residual > tol) || !contacts_settled,
            ..StepInfo::default()
        })
    }

    /// The inverses of the system matrix's 3x3 diagonal blocks m I + h C_ii + h² K_ii (zero
    /// for held particles); a block that is not positive definite (an unstable
    /// linearisation) falls back to the Jacobi diagonal already in `inv_diag`.
    fn invert_blocks<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &S,
        inv_mass: &[Real],
        h: Real,
    ) {
        let n = inv_mass.len();
        self.stiffness_blocks.resize(n, Mat3::ZERO);
        self.damping_blocks.resize(n, Mat3::ZERO);
        self.inv_blocks.resize(n, Mat3::ZERO);
        system.jacobian_blocks(&mut self.stiffness_blocks, &mut self.damping_blocks);
        let blocks = self.stiffness_blocks.iter().zip(&self.damping_blocks);
        let jacobi = self.inv_diag.chunks_exact(3).map(Vec3::from_slice);
        for (((inv, &w), (k, c)), jacobi) in self
            .inv_blocks
            .iter_mut()
            .zip(inv_mass)
            .zip(blocks)
            .zip(jacobi)
        {
            let jacobi = Mat3::from_diagonal(jacobi);
            *inv = if w > 0.0 {
                let b = Mat3::from_diagonal(Vec3::splat(1.0 / w)) + h * *c + (h * h) * *k;
                if positive_definite(&b) {
                    b.inverse()
                } else {
                    jacobi
                }
            } else {
                Mat3::ZERO
            };
        }
    }

    fn resize(&mut self, n: usize) {
        if self.cg.len() != 3 * n {
            self.cg = CgWorkspace::new(3 * n);
        }
        for buf in [
            &mut self.dv,
            &mut self.stiffness_diag,
            &mut self.damping_diag,
            &mut self.k_times,
            &mut self.c_times,
            &mut self.known,
        ] {
            buf.resize(n, Vec3::ZERO);
        }
        for buf in [
            &mut self.rhs,
            &mut self.inv_diag,
            &mut self.mass,
            &mut self.product,
        ] {
            buf.resize(3 * n, 0.0);
        }
    }
}

/// The diagonal of the particles' bounding box, m: the length that round-off is relative to.
fn extent(x: &[Vec3]) -> Real {
    let (lo, hi) = x.iter().fold(
        (Vec3::splat(Real::INFINITY), Vec3::splat(Real::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    if x.is_empty() {
        0.0
    } else {
        (hi - lo).length()
    }
}

/// Sylvester's criterion on the symmetric part, with finite entries.
fn positive_definite(b: &Mat3) -> bool {
    let (c0, c1, c2) = (b.x_axis, b.y_axis, b.z_axis);
    let m1 = c0.x;
    let m2 = c0.x * c1.y - c0.y * c1.x;
    let det = b.determinant();
    m1 > 0.0 && m2 > 0.0 && det > 0.0 && det.is_finite() && c2.is_finite()
}
