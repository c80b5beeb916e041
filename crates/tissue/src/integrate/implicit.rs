//! Implicit (backward) Euler, linearised once per step (Baraff & Witkin 1998):
//!
//! (M + h·C + h²·K) Δv = h·(f0 − h·K·v0),   v1 = v0 + Δv,   x1 = x0 + h·v1,
//!
//! with K = −∂f/∂x and C = −∂f/∂v at the start of the step, solved matrix-free by the shared
//! Jacobi-preconditioned CG. Held particles already move at their step velocity in v0, so
//! their Δv is zero: they are masked out of the solve, and their motion enters the right-hand
//! side through K·v0. The last Δv warm-starts the next solve.

use crate::error::SimError;
use crate::math::{Real, Vec3, flatten, flatten_mut, unflatten};
use crate::model::StepInfo;
use crate::solve::CgWorkspace;

use super::{IntegratorSettings, ParticleSystem, Workspace};

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
}

impl ImplicitSolver {
    pub fn forget_warm_start(&mut self) {
        self.dv.fill(Vec3::ZERO);
    }

    pub fn step<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        w: &mut Workspace,
        h: Real,
        settings: &IntegratorSettings,
        step: u64,
    ) -> Result<StepInfo, SimError> {
        let n = w.x0.len();
        self.resize(n);
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
        let Self {
            cg,
            dv,
            rhs,
            inv_diag,
            mass,
            k_times,
            c_times,
            ..
        } = self;
        let apply = |p: &[Real], y: &mut [Real]| {
            let p3 = unflatten(p);
            system.stiffness_product(p3, k_times);
            system.damping_product(p3, c_times);
            let (k, c) = (flatten(k_times), flatten(c_times));
            for j in 0..y.len() {
                y[j] = mass[j] * p[j] + h * c[j] + h * h * k[j];
            }
        };
        let result = cg.solve(
            apply,
            inv_diag,
            rhs,
            flatten_mut(dv),
            settings.cg_max_iterations,
            settings.cg_tolerance,
        );
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
            ..StepInfo::default()
        })
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
        for buf in [&mut self.rhs, &mut self.inv_diag, &mut self.mass] {
            buf.resize(3 * n, 0.0);
        }
    }
}
