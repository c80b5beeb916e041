//! A particle system plus forces from outside it that depend on its positions: how a model
//! made of particles is coupled to another model on shared nodes (the `hybrid` model's
//! tensor-mass region receives the forces of its pre-computed rest at the interface).

use crate::error::SimError;
use crate::math::{Real, Vec3};

use super::ParticleSystem;

/// Conservative, position-dependent forces on some particles of a system.
pub trait NodeCoupling {
    /// Adds the coupling forces at positions `x` to `f`.
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]);
    /// The coupling's potential energy at `x` (its forces are minus its gradient), in J.
    fn energy(&self, x: &[Vec3]) -> Real;
    /// Adds K·dx, K = −∂f/∂x of the coupling forces, to `out`.
    fn add_stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]);
    /// Adds the diagonal of K's 3×3 diagonal blocks to `d`.
    fn add_stiffness_diagonal(&self, d: &mut [Vec3]);
}

/// `system` with `coupling`'s forces added: what the integrators step.
pub struct Coupled<'a, S: ?Sized, C: ?Sized> {
    pub system: &'a mut S,
    pub coupling: &'a C,
}

impl<S: ParticleSystem + ?Sized, C: NodeCoupling + ?Sized> ParticleSystem for Coupled<'_, S, C> {
    fn masses(&self) -> &[Real] {
        self.system.masses()
    }

    fn forces(&mut self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        self.system.forces(x, v, f);
        self.coupling.add_forces(x, f);
    }

    fn potential_energy(&self, x: &[Vec3]) -> Option<Real> {
        self.system
            .potential_energy(x)
            .map(|e| e + self.coupling.energy(x))
    }

    fn prepare_jacobians(&mut self, x: &[Vec3], v: &[Vec3]) -> Result<(), SimError> {
        self.system.prepare_jacobians(x, v)
    }

    fn stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        self.system.stiffness_product(dx, out);
        self.coupling.add_stiffness_product(dx, out);
    }

    fn damping_product(&self, dv: &[Vec3], out: &mut [Vec3]) {
        self.system.damping_product(dv, out);
    }

    fn jacobian_diagonal(&self, stiffness: &mut [Vec3], damping: &mut [Vec3]) {
        self.system.jacobian_diagonal(stiffness, damping);
        self.coupling.add_stiffness_diagonal(stiffness);
    }

    fn prepare_velocity_split(&mut self, dt: Real, held: &[bool]) -> Result<bool, SimError> {
        self.system.prepare_velocity_split(dt, held)
    }

    fn apply_velocity_split(&mut self, v: &mut [Vec3], force: &mut [Vec3]) -> bool {
        self.system.apply_velocity_split(v, force)
    }

    fn velocity_split_capped(&self) -> bool {
        self.system.velocity_split_capped()
    }

    fn set_step_time(&mut self, s: Real) {
        self.system.set_step_time(s);
    }
}
