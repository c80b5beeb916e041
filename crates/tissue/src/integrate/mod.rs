//! Time integration of particle systems, written once for every model made of point masses
//! (spring-mass, tensor-mass, linked volumes, spline control nets): explicit Euler,
//! symplectic (semi-implicit) Euler, velocity Verlet, classical Runge-Kutta 4, and implicit
//! (backward) Euler solved by Jacobi-preconditioned conjugate gradients on the force
//! Jacobians (Baraff & Witkin 1998).
//!
//! A model implements [`ParticleSystem`], owns a [`ParticleState`] and an [`Integrator`], and
//! calls [`Integrator::step`] with the particles its constraints hold. A held particle moves at
//! constant velocity to its target over the step (so every scheme treats it the same way:
//! its inverse mass is taken as zero); the forces on held particles at the end of the step
//! are the model's reactions. A step that produces non-finite values, or whose energy grows
//! by more than the held particles put in, is refused and leaves the state as it was.
//!
//! The forces at the end of a step are kept and reused as the forces at the start of the
//! next one when the state has not been touched in between, so every explicit scheme costs
//! its textbook number of force evaluations per step and still reports fresh reactions.

pub mod coupling;
mod implicit;
mod schemes;
#[cfg(test)]
mod tests;

use serde::Deserialize;

use crate::error::SimError;
use crate::math::{Real, Vec3, is_finite_vec};
use crate::model::StepInfo;

/// A mechanical system of point masses in 3D, as the integrators see it.
pub trait ParticleSystem {
    /// Lumped mass of each particle, in kg. Every particle that is not held must have a
    /// positive mass.
    fn masses(&self) -> &[Real];

    /// Writes into `f` (zeroed by the caller, one entry per particle) every force on each
    /// particle at positions `x` and velocities `v`: elastic, damping and external loads.
    fn forces(&mut self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]);

    /// Elastic energy plus the potential of conservative loads (−f·x for a constant load) at
    /// `x`, in J. With it the integrator refuses steps that create energy; without it only
    /// non-finite states are caught.
    fn potential_energy(&self, x: &[Vec3]) -> Option<Real> {
        let _ = x;
        None
    }

    /// Implicit Euler only: linearises the forces at (`x`, `v`) for the products below.
    fn prepare_jacobians(&mut self, x: &[Vec3], v: &[Vec3]) -> Result<(), SimError> {
        let _ = (x, v);
        Err(SimError::Unsupported {
            model: "particle system",
            operation: "implicit Euler",
            reason: "it does not provide force Jacobians".into(),
        })
    }

    /// `out = K·dx` with K = −∂f/∂x at the state given to `prepare_jacobians`.
    fn stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        let _ = dx;
        out.fill(Vec3::ZERO);
    }

    /// `out = C·dv` with C = −∂f/∂v at the state given to `prepare_jacobians`.
    fn damping_product(&self, dv: &[Vec3], out: &mut [Vec3]) {
        let _ = dv;
        out.fill(Vec3::ZERO);
    }

    /// The 3x3 diagonal blocks' diagonals of K and C, for the Jacobi preconditioner. Leaving
    /// them zero is correct, only slower to converge.
    fn jacobian_diagonal(&self, stiffness: &mut [Vec3], damping: &mut [Vec3]) {
        stiffness.fill(Vec3::ZERO);
        damping.fill(Vec3::ZERO);
    }
}

/// An integration scheme, named in scenes as `integrator = "symplectic-euler"` etc.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Scheme {
    /// x += h·v, v += h·a (first order; gains energy: for comparison, not for use).
    ExplicitEuler,
    /// v += h·a, x += h·v (first order, symplectic: energy stays bounded).
    #[default]
    SymplecticEuler,
    /// Second order, symplectic; two force evaluations per step when forces depend on v.
    VelocityVerlet,
    /// Classical fourth-order Runge-Kutta; four force evaluations per step.
    Rk4,
    /// Backward Euler linearised once per step, solved by CG: stable at any step, damps.
    ImplicitEuler,
}

impl Scheme {
    pub const ALL: [Scheme; 5] = [
        Scheme::ExplicitEuler,
        Scheme::SymplecticEuler,
        Scheme::VelocityVerlet,
        Scheme::Rk4,
        Scheme::ImplicitEuler,
    ];

    /// The name used in scenes.
    pub fn name(self) -> &'static str {
        match self {
            Scheme::ExplicitEuler => "explicit-euler",
            Scheme::SymplecticEuler => "symplectic-euler",
            Scheme::VelocityVerlet => "velocity-verlet",
            Scheme::Rk4 => "rk4",
            Scheme::ImplicitEuler => "implicit-euler",
        }
    }
}

impl std::fmt::Display for Scheme {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Knobs of the integrators.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntegratorSettings {
    /// Implicit Euler: CG iteration cap per step.
    pub cg_max_iterations: usize,
    /// Implicit Euler: CG stops when ‖r‖ ≤ tolerance·‖b‖.
    pub cg_tolerance: Real,
    /// The largest relative energy gain a step may show beyond the work the held particles
    /// did (explicit schemes gain a little energy each step when stable, a lot when not).
    pub energy_growth: Real,
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        Self {
            cg_max_iterations: 100,
            cg_tolerance: 1e-6,
            energy_growth: 0.5,
        }
    }
}

/// Positions and velocities of the particles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParticleState {
    pub x: Vec<Vec3>,
    pub v: Vec<Vec3>,
}

impl ParticleState {
    /// Particles at the given positions, at rest.
    pub fn at_rest(x: Vec<Vec3>) -> Self {
        let v = vec![Vec3::ZERO; x.len()];
        Self { x, v }
    }

    /// Kinetic energy of the particles whose entry in `weights` is non-zero: ½ Σ m v².
    pub fn kinetic_energy(&self, masses: &[Real]) -> Real {
        self.v
            .iter()
            .zip(masses)
            .map(|(v, m)| 0.5 * m * v.length_squared())
            .sum()
    }
}

/// A particle held by a constraint: it reaches `target` at the end of the step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hold {
    pub particle: usize,
    pub target: Vec3,
}

/// Forces at the end of the last step, valid while the state is the one they were computed at.
#[derive(Clone, Debug, Default)]
struct EndOfStep {
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    f: Vec<Vec3>,
    energy: Option<Real>,
}

/// Buffers reused by every step, sized on first use.
#[derive(Clone, Debug, Default)]
pub(crate) struct Workspace {
    pub inv_mass: Vec<Real>,
    /// Which particles a hold moves this step.
    pub held: Vec<bool>,
    pub x0: Vec<Vec3>,
    pub v0: Vec<Vec3>,
    pub f0: Vec<Vec3>,
    pub x1: Vec<Vec3>,
    pub v1: Vec<Vec3>,
    pub f1: Vec<Vec3>,
    /// Stage buffers of RK4 and the implicit solve.
    pub a: Vec<Vec3>,
    pub b: Vec<Vec3>,
    pub c: Vec<Vec3>,
    pub d: Vec<Vec3>,
}

impl Workspace {
    fn resize(&mut self, n: usize) {
        for buf in [
            &mut self.x0,
            &mut self.v0,
            &mut self.f0,
            &mut self.x1,
            &mut self.v1,
            &mut self.f1,
            &mut self.a,
            &mut self.b,
            &mut self.c,
            &mut self.d,
        ] {
            buf.resize(n, Vec3::ZERO);
        }
        self.inv_mass.resize(n, 0.0);
        self.held.clear();
        self.held.resize(n, false);
    }
}

/// Evaluates the system's forces into `f`, zeroing it first.
pub(crate) fn eval_forces<S: ParticleSystem + ?Sized>(
    system: &mut S,
    x: &[Vec3],
    v: &[Vec3],
    f: &mut [Vec3],
) {
    f.fill(Vec3::ZERO);
    system.forces(x, v, f);
}

/// Steps a particle system in time with one scheme; see the module documentation.
#[derive(Clone, Debug, Default)]
pub struct Integrator {
    pub scheme: Scheme,
    pub settings: IntegratorSettings,
    steps: u64,
    work: Workspace,
    end: Option<EndOfStep>,
    held_forces: Vec<Vec3>,
    implicit: implicit::ImplicitSolver,
}

impl Integrator {
    pub fn new(scheme: Scheme) -> Self {
        Self {
            scheme,
            ..Self::default()
        }
    }

    pub fn with_settings(scheme: Scheme, settings: IntegratorSettings) -> Self {
        Self {
            scheme,
            settings,
            ..Self::default()
        }
    }

    /// Steps taken successfully.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Forces the system exerts on each held particle at the end of the last step, in the
    /// order of the `holds` given to it.
    pub fn held_forces(&self) -> &[Vec3] {
        &self.held_forces
    }

    /// Forgets the forces kept from the last step: call it after changing the system itself
    /// (a cut, new rest lengths, new material), since the state alone cannot show that.
    pub fn invalidate(&mut self) {
        self.end = None;
        self.implicit.forget_warm_start();
    }

    /// Advances `state` by `dt`. On error the state is untouched and the model stays usable.
    pub fn step<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &mut ParticleState,
        holds: &[Hold],
        dt: Real,
    ) -> Result<StepInfo, SimError> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(SimError::BadTimeStep { dt });
        }
        self.begin(system, state, holds, dt)?;
        let info = match self.scheme {
            Scheme::ExplicitEuler => schemes::explicit_euler(&mut self.work, dt),
            Scheme::SymplecticEuler => schemes::symplectic_euler(&mut self.work, dt),
            Scheme::VelocityVerlet => schemes::velocity_verlet(system, &mut self.work, dt),
            Scheme::Rk4 => schemes::rk4(system, &mut self.work, dt),
            Scheme::ImplicitEuler => {
                self.implicit
                    .step(system, &mut self.work, dt, &self.settings, self.steps + 1)?
            }
        };
        let w = &mut self.work;
        for h in holds {
            w.x1[h.particle] = h.target;
        }
        if let Some(node) = (0..w.x1.len()).find(|&i| !is_finite_vec(w.x1[i] + w.v1[i])) {
            return Err(self.diverged(node, "its position or velocity is not finite".into()));
        }
        eval_forces(system, &w.x1, &w.v1, &mut w.f1);
        let energy = self.check_energy(system, holds, dt)?;
        self.commit(state, holds, energy);
        Ok(info)
    }

    /// Validates the input and fills x0, v0 (held particles moving at their step velocity),
    /// the inverse masses (zero for held particles) and f0.
    fn begin<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &ParticleState,
        holds: &[Hold],
        dt: Real,
    ) -> Result<(), SimError> {
        let n = state.x.len();
        let masses = system.masses();
        if masses.len() != n || state.v.len() != n {
            return Err(SimError::BadParameter {
                name: "particle state",
                value: format!(
                    "{n} positions, {} velocities, {} masses",
                    state.v.len(),
                    masses.len()
                ),
                reason: "every particle needs a position, a velocity and a mass".into(),
            });
        }
        let w = &mut self.work;
        w.resize(n);
        for (inv, &m) in w.inv_mass.iter_mut().zip(masses) {
            *inv = if m > 0.0 && m.is_finite() {
                1.0 / m
            } else {
                0.0
            };
        }
        w.x0.copy_from_slice(&state.x);
        w.v0.copy_from_slice(&state.v);
        for h in holds {
            if h.particle >= n {
                return Err(SimError::BadConstraint {
                    vertex: h.particle,
                    count: n,
                });
            }
            if !is_finite_vec(h.target) {
                return Err(SimError::BadParameter {
                    name: "hold",
                    value: format!("particle {} -> {}", h.particle, h.target),
                    reason: "the target is not finite".into(),
                });
            }
            w.inv_mass[h.particle] = 0.0;
            w.held[h.particle] = true;
            w.v0[h.particle] = (h.target - w.x0[h.particle]) / dt;
        }
        if let Some(i) = (0..n).find(|&i| !w.held[i] && w.inv_mass[i] == 0.0) {
            return Err(SimError::BadParameter {
                name: "mass",
                value: format!("particle {i}: {}", masses[i]),
                reason: "a particle that is not held needs a positive, finite mass".into(),
            });
        }
        match &self.end {
            Some(end) if end.x == w.x0 && end.v == w.v0 => w.f0.copy_from_slice(&end.f),
            _ => {
                self.end = None;
                eval_forces(system, &w.x0, &w.v0, &mut w.f0);
            }
        }
        if let Some(i) = (0..n).find(|&i| !is_finite_vec(w.f0[i])) {
            return Err(self.diverged(i, "the force on it is not finite at the start".into()));
        }
        Ok(())
    }

    /// The energy after the trial step, or an error if it grew more than the held particles
    /// can explain. Energy = kinetic energy of free particles + the system's potential.
    fn check_energy<S: ParticleSystem + ?Sized>(
        &self,
        system: &S,
        holds: &[Hold],
        dt: Real,
    ) -> Result<Option<Real>, SimError> {
        let w = &self.work;
        let Some(potential1) = system.potential_energy(&w.x1) else {
            return Ok(None);
        };
        let kinetic = |v: &[Vec3]| -> Real {
            v.iter()
                .zip(&w.inv_mass)
                .filter(|(_, inv)| **inv > 0.0)
                .map(|(v, inv)| 0.5 * v.length_squared() / inv)
                .sum()
        };
        let e1 = kinetic(&w.v1) + potential1;
        let e0 = match self.end.as_ref().and_then(|e| e.energy) {
            Some(e) => e,
            None => kinetic(&w.v0) + system.potential_energy(&w.x0).unwrap_or(potential1),
        };
        // Work the held particles did on the rest: −∫ f·dx along their straight path, by the
        // trapezoid rule (exact for linear forces).
        let work_in: Real = holds
            .iter()
            .map(|h| {
                let i = h.particle;
                (-0.5 * (w.f0[i] + w.f1[i]).dot(w.x1[i] - w.x0[i])).abs()
            })
            .sum();
        // What one explicit kick may add by itself: ½h²Σ|f|²/m (the kinetic energy of one
        // step's velocity change), so that a first step from rest under a load passes.
        let kick: Real = (0..w.f0.len())
            .map(|i| 0.5 * dt * dt * w.f0[i].length_squared() * w.inv_mass[i])
            .sum();
        let scale = e0.abs() + work_in;
        let allowed = e0
            + self.settings.energy_growth * scale
            + 2.0 * work_in
            + kick
            + 1e-12 * (scale + kick);
        if !e1.is_finite() || e1 > allowed {
            let node = self.fastest_free_particle();
            return Err(self.diverged(
                node,
                format!(
                    "the energy grew from {e0:.3e} J to {e1:.3e} J in one step while the held \
                     particles put in {work_in:.3e} J (time step too large for {}?)",
                    self.scheme
                ),
            ));
        }
        Ok(Some(e1))
    }

    fn commit(&mut self, state: &mut ParticleState, holds: &[Hold], energy: Option<Real>) {
        let w = &self.work;
        state.x.copy_from_slice(&w.x1);
        state.v.copy_from_slice(&w.v1);
        self.held_forces.clear();
        self.held_forces
            .extend(holds.iter().map(|h| w.f1[h.particle]));
        let end = self.end.get_or_insert_with(EndOfStep::default);
        end.x.clone_from(&w.x1);
        end.v.clone_from(&w.v1);
        end.f.clone_from(&w.f1);
        end.energy = energy;
        self.steps += 1;
    }

    /// The free particle moving fastest in the trial state: where a blow-up shows first.
    fn fastest_free_particle(&self) -> usize {
        let w = &self.work;
        (0..w.v1.len())
            .filter(|&i| w.inv_mass[i] > 0.0)
            .max_by(|&a, &b| {
                w.v1[a]
                    .length_squared()
                    .total_cmp(&w.v1[b].length_squared())
            })
            .unwrap_or(0)
    }

    fn diverged(&self, node: usize, reason: String) -> SimError {
        SimError::Diverged {
            step: self.steps + 1,
            node,
            reason,
        }
    }
}
