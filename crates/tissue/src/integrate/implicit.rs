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

use super::rest_factor::RestPreconditioner;
use super::{Hold, IntegratorSettings, ParticleSystem, Preconditioner, Workspace};

/// Solves of one step's contact active set before it keeps the last one (and says so).
const MAX_CONTACT_SOLVES: usize = 12;

/// A free contact's particle may end this far past its plane without being taken, in m
/// (the solve's tolerance moves positions by about that much; `place_holds` puts it back).
const GAP_TOLERANCE: Real = 1e-10;

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
        let contacts: Vec<SolveContact> = holds
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
            })
            .collect();
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
            let mut active: Vec<bool> = contacts
                .iter()
                .map(|c| {
                    pushed.contains(&c.particle)
                        || c.normal
                            .dot(w.x0[c.particle] + h * w.v0[c.particle] - c.target)
                            < 0.0
                })
                .collect();
            let scale = rhs.iter().fold(0.0, |a: Real, v| a.max(v.abs())) / h;
            let mut result = CgResult::default();
            contacts_settled = false;
            for _ in 0..MAX_CONTACT_SOLVES {
                // A held contact's velocity change along n ends its particle on its plane.
                for (c, on) in contacts.iter().zip(&active) {
                    if *on {
                        let i = c.particle;
                        let want = c.normal.dot(c.target - w.x0[i]) / h - c.normal.dot(w.v0[i]);
                        let along = c.normal.dot(dv[i]);
                        dv[i] += c.normal * (want - along);
                    }
                }
                let filter = |v: &mut [Real]| {
                    for (c, on) in contacts.iter().zip(&active) {
                        if *on {
                            let j = 3 * c.particle;
                            let x = Vec3::new(v[j], v[j + 1], v[j + 2]);
                            let x = x - c.normal * c.normal.dot(x);
                            v[j..j + 3].copy_from_slice(&x.to_array());
                        }
                    }
                };
                result = cg.solve_filtered(
                    &mut apply,
                    &mut precondition,
                    filter,
                    rhs,
                    flatten_mut(dv),
                    max_it,
                    tol,
                );
                apply(flatten(dv), product);
                let mut changed = false;
                for (c, on) in contacts.iter().zip(active.iter_mut()) {
                    let i = c.particle;
                    if *on {
                        let j = 3 * i;
                        let r = Vec3::new(
                            product[j] - rhs[j],
                            product[j + 1] - rhs[j + 1],
                            product[j + 2] - rhs[j + 2],
                        );
                        // The reaction over the step: (A Δv − b)ᵢ = h F_c.
                        if c.normal.dot(r) / h < -1e-9 * scale {
                            *on = false;
                            changed = true;
                        }
                    } else {
                        let x1 = w.x0[i] + h * (w.v0[i] + dv[i]);
                        if c.normal.dot(x1 - c.target) < -GAP_TOLERANCE {
                            *on = true;
                            changed = true;
                        }
                    }
                }
                if !changed {
                    contacts_settled = true;
                    break;
                }
            }
            pushed.clear();
            for (c, on) in contacts.iter().zip(&active) {
                if *on {
                    let j = 3 * c.particle;
                    let r = Vec3::new(
                        product[j] - rhs[j],
                        product[j + 1] - rhs[j + 1],
                        product[j + 2] - rhs[j + 2],
                    );
                    contact_pushes.push((c.hold, (c.normal.dot(r) / h).max(0.0)));
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
        Ok(StepInfo {
            iterations: result.iterations,
            residual: result.relative_residual,
            // A solve stopped by the cap before its tolerance is an approximation the caller
            // must hear of (`tissue run` counts such steps and their worst residual), and so
            // is a contact active set still changing at its cap.
            capped: (result.iterations >= max_it && result.relative_residual > tol)
                || !contacts_settled,
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

/// Sylvester's criterion on the symmetric part, with finite entries.
fn positive_definite(b: &Mat3) -> bool {
    let (c0, c1, c2) = (b.x_axis, b.y_axis, b.z_axis);
    let m1 = c0.x;
    let m2 = c0.x * c1.y - c0.y * c1.x;
    let det = b.determinant();
    m1 > 0.0 && m2 > 0.0 && det > 0.0 && det.is_finite() && c2.is_finite()
}
