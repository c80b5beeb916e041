//! The explicit schemes. Each reads x0, v0, f0 and the inverse masses from the workspace and
//! writes x1, v1; held particles have inverse mass zero, so they keep their step velocity and
//! move in a straight line to their target without special cases.

use crate::math::Real;
use crate::model::StepInfo;

use super::{ParticleSystem, Workspace, eval_forces};

/// x1 = x0 + h·v0, v1 = v0 + h·M⁻¹f(x0, v0).
pub(super) fn explicit_euler(w: &mut Workspace, h: Real) -> StepInfo {
    for i in 0..w.x0.len() {
        w.x1[i] = w.x0[i] + h * w.v0[i];
        w.v1[i] = w.v0[i] + h * w.inv_mass[i] * w.f0[i];
    }
    StepInfo::default()
}

/// v1 = v0 + kick·h·M⁻¹f(x0, v0), x1 = x0 + h·v1. `kick` is 1, or ½ for the first
/// substep after the motion was stopped (`Integrator::motion_stopped`): the scheme's
/// velocity is the one half a step ahead of its positions (leapfrog's v at t + h/2), and a
/// state at rest at t is v(t + h/2) = (h/2)·a, not v(t − h/2) = 0 followed by a whole kick.
pub(super) fn symplectic_euler(w: &mut Workspace, h: Real, kick: Real) -> StepInfo {
    for i in 0..w.x0.len() {
        w.v1[i] = w.v0[i] + kick * h * w.inv_mass[i] * w.f0[i];
        w.x1[i] = w.x0[i] + h * w.v1[i];
    }
    StepInfo::default()
}

/// x1 = x0 + h·v0 + ½h²·a0, a1 = M⁻¹f(x1, v0 + h·a0), v1 = v0 + ½h·(a0 + a1). Velocity-
/// dependent forces are evaluated at the first-order velocity predictor, the usual choice.
pub(super) fn velocity_verlet<S: ParticleSystem + ?Sized>(
    system: &mut S,
    w: &mut Workspace,
    h: Real,
) -> StepInfo {
    for i in 0..w.x0.len() {
        let a0 = w.inv_mass[i] * w.f0[i];
        w.x1[i] = w.x0[i] + h * w.v0[i] + 0.5 * h * h * a0;
        w.a[i] = w.v0[i] + h * a0;
    }
    system.set_step_time(w.span.1);
    eval_forces(system, &w.x1, &w.a, &mut w.b);
    for i in 0..w.x0.len() {
        let a_sum = w.inv_mass[i] * (w.f0[i] + w.b[i]);
        w.v1[i] = w.v0[i] + 0.5 * h * a_sum;
    }
    StepInfo::default()
}

/// Classical RK4 on the first-order system (x, v)' = (v, M⁻¹f(x, v)). The weighted sums of
/// the stage slopes accumulate in x1 and v1 as the stages go.
pub(super) fn rk4<S: ParticleSystem + ?Sized>(
    system: &mut S,
    w: &mut Workspace,
    h: Real,
) -> StepInfo {
    let n = w.x0.len();
    // Stage 1: slopes (v0, a0).
    for i in 0..n {
        w.x1[i] = w.v0[i];
        w.v1[i] = w.inv_mass[i] * w.f0[i];
    }
    // Stages 2 and 3 at the midpoint, stage 4 at the end; `a`/`b` hold the previous stage's
    // slopes (velocity, acceleration), `c`/`d` the stage's state.
    for i in 0..n {
        w.a[i] = w.v0[i];
        w.b[i] = w.inv_mass[i] * w.f0[i];
    }
    for (fraction, weight) in [(0.5, 2.0), (0.5, 2.0), (1.0, 1.0)] {
        for i in 0..n {
            w.c[i] = w.x0[i] + fraction * h * w.a[i];
            w.d[i] = w.v0[i] + fraction * h * w.b[i];
        }
        // The stage force goes into `b` (the previous acceleration is no longer needed once
        // c and d are formed).
        system.set_step_time(w.span.0 + fraction * (w.span.1 - w.span.0));
        eval_forces(system, &w.c, &w.d, &mut w.b);
        for i in 0..n {
            w.a[i] = w.d[i];
            w.b[i] *= w.inv_mass[i];
            w.x1[i] += weight * w.a[i];
            w.v1[i] += weight * w.b[i];
        }
    }
    for i in 0..n {
        w.x1[i] = w.x0[i] + h / 6.0 * w.x1[i];
        w.v1[i] = w.v0[i] + h / 6.0 * w.v1[i];
    }
    StepInfo::default()
}
