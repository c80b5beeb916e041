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

pub mod contact;
pub mod coupling;
mod implicit;
mod points;
pub mod rest_factor;
mod schemes;
pub mod split_damping;
pub mod stable_step;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_points;
#[cfg(test)]
mod tests_substeps;

use serde::Deserialize;

use crate::error::SimError;
use crate::math::{Mat3, Real, Vec3, is_finite_vec};
use crate::model::StepInfo;

pub use points::{PointHold, PointProjection};
pub use rest_factor::RankOneJacobians;
pub use stable_step::Substeps;
use stable_step::{RateEstimate, substeps_for};

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

    /// `out = a_c·C·x + a_k·K·x`: the Jacobians' part of the implicit solve's operator,
    /// applied at every CG iteration. The default calls the two products (`scratch` holds
    /// one of them); a model whose K and C share their structure (one pass over the
    /// springs) overrides it to read that structure once.
    fn system_product(
        &self,
        a_c: Real,
        a_k: Real,
        x: &[Vec3],
        out: &mut [Vec3],
        scratch: &mut [Vec3],
    ) {
        self.stiffness_product(x, out);
        self.damping_product(x, scratch);
        for (o, c) in out.iter_mut().zip(scratch.iter()) {
            *o = a_k * *o + a_c * *c;
        }
    }

    /// Implicit Euler's factorised preconditioner (`rest_factor`): a number that changes
    /// whenever the Jacobians at rest do (a topology edit), or None (the default) when the
    /// system does not give them; then the solve uses Jacobi.
    fn rest_jacobians_version(&self) -> Option<u64> {
        None
    }

    /// Writes K and C at rest into `out` (cleared for the particles by the caller) as
    /// rank-one terms. Only called when `rest_jacobians_version` is Some. They must be
    /// positive semi-definite; they need not be exact (they only precondition).
    fn rest_jacobians(&self, out: &mut RankOneJacobians) {
        let _ = out;
    }

    /// The 3x3 diagonal blocks' diagonals of K and C, for the Jacobi preconditioner. Leaving
    /// them zero is correct, only slower to converge.
    fn jacobian_diagonal(&self, stiffness: &mut [Vec3], damping: &mut [Vec3]) {
        stiffness.fill(Vec3::ZERO);
        damping.fill(Vec3::ZERO);
    }

    /// The 3x3 diagonal blocks of K and C, for the block-Jacobi preconditioner. The default
    /// puts `jacobian_diagonal`'s diagonals on the blocks' diagonals (plain Jacobi).
    fn jacobian_blocks(&self, stiffness: &mut [Mat3], damping: &mut [Mat3]) {
        let mut k = vec![Vec3::ZERO; stiffness.len()];
        let mut c = vec![Vec3::ZERO; damping.len()];
        self.jacobian_diagonal(&mut k, &mut c);
        for (b, d) in stiffness.iter_mut().zip(&k) {
            *b = Mat3::from_diagonal(*d);
        }
        for (b, d) in damping.iter_mut().zip(&c) {
            *b = Mat3::from_diagonal(*d);
        }
    }

    /// Explicit schemes: prepares a velocity update applied once per step after the
    /// substeps (stiffness damping taken out of `forces`, see `split_damping`), for step
    /// `dt` with the particles flagged in `held` held. Returns whether there is one. Called
    /// before the step, so that an error leaves the state as it was.
    fn prepare_velocity_split(&mut self, dt: Real, held: &[bool]) -> Result<bool, SimError> {
        let _ = (dt, held);
        Ok(false)
    }

    /// Applies the prepared update to `v` and writes the forces it stands for into `force`
    /// (the held particles' share goes into their reactions). False when nothing was done.
    fn apply_velocity_split(&mut self, v: &mut [Vec3], force: &mut [Vec3]) -> bool {
        let _ = (v, force);
        false
    }

    /// Whether the last `apply_velocity_split` stopped its iterative solve at a cap before
    /// its tolerance (the step then says `capped`).
    fn velocity_split_capped(&self) -> bool {
        false
    }

    /// Systems with loads that move during a step (the spline's penalty springs pulling
    /// surface vertices to an instrument's moving targets): the forces and energies asked
    /// for next are those at fraction `s` of the step being taken, 0 at its start and 1 at
    /// its end. The explicit schemes set it before every force evaluation (the start of a
    /// substep, a stage, its end); implicit Euler evaluates everything at the end (1), and a
    /// step leaves it at 1. A held particle moves the same way, in a straight line over
    /// the step. Without it a target that jumps at the start of every step (a probe
    /// pressing on) kicks its vertex by the whole step's motion, and an explicit scheme
    /// reports the reaction at one phase of the ringing that follows.
    fn set_step_time(&mut self, s: Real) {
        let _ = s;
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

    /// Whether the scheme is only conditionally stable (a stable-step limit, an unstable
    /// mode beyond it: what the slow-growth watch looks for). Implicit Euler has no limit.
    pub fn has_step_limit(self) -> bool {
        self != Scheme::ImplicitEuler
    }
}

impl std::fmt::Display for Scheme {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The preconditioner of implicit Euler's CG, named in scenes as `preconditioner = "jacobi"`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preconditioner {
    /// The diagonal of the system matrix (cheap per iteration, many iterations).
    #[default]
    Jacobi,
    /// Its 3x3 diagonal blocks (`ParticleSystem::jacobian_blocks`), inverted once per step.
    BlockJacobi,
    /// M + h·C₀ + h²·K₀ at rest, factorised once (`rest_factor`); Jacobi for systems that
    /// do not give their rest Jacobians.
    RestFactor,
}

impl Preconditioner {
    /// The name used in scenes.
    pub fn name(self) -> &'static str {
        match self {
            Preconditioner::Jacobi => "jacobi",
            Preconditioner::BlockJacobi => "block-jacobi",
            Preconditioner::RestFactor => "rest-factor",
        }
    }
}

/// Knobs of the integrators.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntegratorSettings {
    /// Implicit Euler: CG iteration cap per step, a safety net: the tolerance ends a
    /// solve, and a step stopped here says so (`StepInfo::capped`). At 100 every step of
    /// linked-volumes on the pelvis stopped at the cap (residual up to 1.4e-4 against 1e-6,
    /// unreported); converged it takes 99–133 iterations.
    pub cg_max_iterations: usize,
    /// Implicit Euler: CG stops when ‖r‖ ≤ tolerance·‖b‖.
    pub cg_tolerance: Real,
    /// Implicit Euler: CG's preconditioner (default Jacobi).
    pub preconditioner: Preconditioner,
    /// The largest relative energy gain one step may show beyond the work the held particles
    /// did. Default 8: a stable mode's measured energy ½mv² + U swings by up to (1 + hω/2) /
    /// (1 − hω/2) = 9 between two steps at the automatic substeps' hω ≤ 1.6, while a step far
    /// above the limit multiplies it by far more; slower growth is the growth watch's.
    pub energy_growth: Real,
    /// Internal steps per step: `Auto` (default) takes as many as the measured stability
    /// limit needs (see `stable_step`), `Fixed(n)` exactly n.
    pub substeps: Substeps,
    /// Refuse slow energy growth over several steps (`GrowthWatch`); off only to study a
    /// scheme that gains energy by design (explicit Euler).
    pub watch_growth: bool,
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        Self {
            cg_max_iterations: 1000,
            cg_tolerance: 1e-6,
            preconditioner: Preconditioner::default(),
            energy_growth: 8.0,
            substeps: Substeps::Auto,
            watch_growth: true,
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

    /// Every velocity set to zero, the positions kept (`Deformable::stop_motion`).
    pub fn stop(&mut self) {
        self.v.iter_mut().for_each(|v| *v = Vec3::ZERO);
    }
}

/// A particle held by a constraint: it reaches `target` at the end of the step.
///
/// With `along = Some(n)` (a unit direction; a frictionless contact) it is held along n
/// only: it moves as a free particle, and after each (sub)step its position's component
/// along n is set to the target's and its velocity's to that of the straight path there
/// (a projection), so it slides freely across n; its held force is the component along n
/// of the force on it.
///
/// With `unilateral` as well (an instrument's surface, `Hold::contact`) the hold only
/// pushes: after each (sub)step a particle that went past the target's plane along −n is
/// put back on it and its velocity's inward part along n removed (an inelastic contact
/// with the still plane; a particle short of the plane keeps at most the inward velocity
/// that reaches it in one more substep), one that stays out is left free. The active set is so settled
/// at every substep, inside the step, and the held force is the momentum the projections
/// gave over the step divided by its length: never a pull.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hold {
    pub particle: usize,
    pub target: Vec3,
    pub along: Option<Vec3>,
    /// Only with `along`: a contact that pushes and never pulls (see above).
    pub unilateral: bool,
}

impl Hold {
    /// Held in all three directions.
    pub fn new(particle: usize, target: Vec3) -> Self {
        Self {
            particle,
            target,
            along: None,
            unilateral: false,
        }
    }

    /// A frictionless contact with the plane through `target` of outward unit normal `n`
    /// (toward the particle's side): it keeps the particle from going past the plane and
    /// lets it leave.
    pub fn contact(particle: usize, target: Vec3, n: Vec3) -> Self {
        Self {
            particle,
            target,
            along: Some(n),
            unilateral: true,
        }
    }

    /// A contact's plane stays at its end-of-step target for the whole step: a straight
    /// path from where the particle starts would sweep the plane from the particle (which
    /// may start off the instrument) and push it early.
    fn ramped(&self) -> bool {
        !(self.unilateral && self.along.is_some())
    }

    /// The part of a force on the particle its hold takes: all of it, or its component
    /// along the hold's direction.
    pub fn held_part(&self, f: Vec3) -> Vec3 {
        match self.along {
            Some(n) => n * n.dot(f),
            None => f,
        }
    }
}

/// Puts the held particles where their holds say at the end of a (sub)step of length `h`
/// from x0: a full hold at its target, one along n projected (position along n at the
/// target's, velocity along n that of the straight path from x0). The change of the kinetic
/// energy along n of the particles held along a direction, from the (sub)step's start, is
/// work of their holds (`Workspace::along_work`).
/// Implicit Euler's contacts held in its solve (`implicit`): each push over the (sub)step is
/// its reaction there (`pushes`: hold index, push in N), and the particle, which the solve
/// ended on its plane, counts as held in the energy ledger: the whole change of its kinetic
/// energy along n is the contact's work, as for a two-sided hold along a direction.
fn held_in_solve(w: &mut Workspace, holds: &[Hold], pushes: &[(usize, Real)], h: Real) {
    for &(k, push) in pushes {
        let Some(hold) = holds.get(k) else {
            continue;
        };
        let (Some(n), Some(slot)) = (hold.along, w.contact_impulse.get_mut(k)) else {
            continue;
        };
        // Summed over the substeps, as the projections' impulses are.
        *slot += h * push;
        if let Some(active) = w.contact_active.get_mut(k)
            && !*active
        {
            *active = true;
            let i = hold.particle;
            let m = if w.inv_mass[i] > 0.0 {
                1.0 / w.inv_mass[i]
            } else {
                0.0
            };
            let (v1n, v0n) = (n.dot(w.v1[i]), n.dot(w.v0[i]));
            w.along_work += 0.5 * m * (v1n * v1n - v0n * v0n);
        }
    }
}

fn place_holds(w: &mut Workspace, holds: &[Hold], h: Real) {
    w.along_work = 0.0;
    w.contact_active.clear();
    w.contact_active.resize(holds.len(), true);
    w.contact_impulse.resize(holds.len(), 0.0);
    for (k, hold) in holds.iter().enumerate() {
        let i = hold.particle;
        match hold.along {
            None => w.x1[i] = hold.target,
            Some(n) if hold.unilateral => {
                let Some(push) = contact::push_only(w.x1[i], w.v1[i], hold.target, n, h) else {
                    // Out of the instrument and not reaching it: free, pushes nothing.
                    w.contact_active[k] = false;
                    continue;
                };
                let m = if w.inv_mass[i] > 0.0 {
                    1.0 / w.inv_mass[i]
                } else {
                    0.0
                };
                w.x1[i] = push.position;
                w.v1[i] = push.velocity;
                // The push's momentum (never negative) and, as for a two-sided hold, the
                // change of the kinetic energy along n over the substep as its work.
                w.contact_impulse[k] += m * push.dv;
                let (kept, v0n) = (n.dot(push.velocity), n.dot(w.v0[i]));
                w.along_work += 0.5 * m * (kept * kept - v0n * v0n);
            }
            Some(n) => {
                let x = w.x1[i] + n * n.dot(hold.target - w.x1[i]);
                let vn = n.dot(x - w.x0[i]) / h;
                let v = w.v1[i];
                w.x1[i] = x;
                w.v1[i] = v + n * (vn - n.dot(v));
                let m = if w.inv_mass[i] > 0.0 {
                    1.0 / w.inv_mass[i]
                } else {
                    0.0
                };
                // The hold decides the motion along n, so the whole change of the kinetic
                // energy along n over the (sub)step is its work, not only what the projection
                // took off the scheme's velocity: the scheme's kick along n (½h²f_n²/m and
                // more per substep) is undone by the projection and no potential pays for it,
                // and counting the projection alone let the ledger creep up under a sliding
                // contact until the growth watch refused a stable step.
                let v0n = n.dot(w.v0[i]);
                w.along_work += 0.5 * m * (vn * vn - v0n * v0n);
            }
        }
    }
}

/// Forces at the end of the last step, valid while the state is the one they were computed at.
#[derive(Clone, Debug, Default)]
struct EndOfStep {
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    f: Vec<Vec3>,
    energy: Option<Real>,
    /// The particles a hold moved in that step (their kinetic energy was not in `energy`).
    held: Vec<bool>,
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
    /// The fractions of the step at which the scheme's current (sub)step starts and ends
    /// (`ParticleSystem::set_step_time`).
    pub span: (Real, Real),
    /// The change of kinetic energy along their direction of the particles held along one over
    /// the last (sub)step (`place_holds`), J: work of their holds.
    pub along_work: Real,
    /// Per hold: false for a contact (`Hold::contact`) that left its particle free in the
    /// last (sub)step.
    pub contact_active: Vec<bool>,
    /// Per hold: the momentum a contact's projections gave its particle along n since the
    /// step began, N·s.
    pub contact_impulse: Vec<Real>,
    /// Per point contact (`points`): the momentum its projections gave along its normal
    /// since the step began, N·s.
    pub point_impulse: Vec<Real>,
    /// The points' projection (`points::PointProjection`) and its pushes of the last
    /// (sub)step.
    pub points: points::PointProjection,
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

/// Watches the energy ledger L = E − (work the held particles put in) for slow growth: a
/// stable, passive system never raises L for long (damping lowers it, an undamped one
/// oscillates about a constant), while an unstable mode raises it at every step. A run of
/// `GROWTH_RUN` or more consecutive rises whose total exceeds the kinetic energy the body had
/// before the run (its recent peak, times `PEAK_ALLOWANCE`: what a stable oscillation can
/// move about), plus half the work of the run, is refused. (The one-step kick allowance of
/// the one-step test is given only to explicit Euler, which gains it every step by design:
/// under the other schemes a velocity mode flipping sign under damping would earn one every
/// step while it grows.) (The
/// symplectic schemes' modified energy would swing less, but it stays conserved by an
/// unstable linear step too, so it cannot show a blow-up.)
#[derive(Clone, Copy, Debug, Default)]
struct GrowthWatch {
    /// Ledger after the last accepted step.
    last: Option<Real>,
    /// Signed work the held particles did since the watch started, J.
    work: Real,
    /// Recent peak of the kinetic energy (decays by `PEAK_DECAY` per step), J.
    kinetic_peak: Real,
    /// Consecutive rises so far, the ledger before them and what they may add.
    run: u32,
    run_start: Real,
    allowance: Real,
}

/// Times a refused step is measured again and retried under `Substeps::Auto`.
const RETRIES: usize = 3;
/// Consecutive rises of the ledger before it is compared with its allowance.
const GROWTH_RUN: u32 = 8;
/// The rise a run may show, in recent kinetic-energy peaks: a stable mode's measured energy
/// ½mv² + U swings between H/(1 + hω/2) and H/(1 − hω/2) about its conserved (modified)
/// energy H, a factor 9 at the automatic substeps' hω ≤ 1.6.
const PEAK_ALLOWANCE: Real = 8.0;
/// Per-step decay of the kinetic-energy peak.
const PEAK_DECAY: Real = 1.0 - 1.0 / 2000.0;
/// Energy rises below this are rounding noise, never growth, J. Near an unloaded rest (after
/// a viewer's Reset) the ledger and the kinetic peak are both ~0, and the last bits of the
/// forces made "rises" of 4e-35 J that were refused as divergence. An organ-sized body's
/// energies are far above it (a 10 mN probe pressing 1 mm does 1e-5 J), and a real blow-up,
/// growing geometrically, passes it within a few steps.
const ENERGY_NOISE: Real = 1e-12;

impl GrowthWatch {
    /// The watch after a trial step, or the excess over the allowance when it is refused.
    fn next(
        &self,
        energy: Real,
        kinetic: Real,
        work: Real,
        work_abs: Real,
        kick: Real,
    ) -> Result<Self, (Real, u32)> {
        let mut w = *self;
        w.work += work;
        let ledger = energy - w.work;
        let floor = 1e-9 * energy.abs() + 1e-300;
        match self.last {
            Some(last) if ledger > last + floor => {
                if w.run == 0 {
                    w.run_start = last;
                    w.allowance = PEAK_ALLOWANCE * self.kinetic_peak + floor + ENERGY_NOISE;
                }
                w.run += 1;
                w.allowance += 0.5 * work_abs + kick;
                let rise = ledger - w.run_start;
                if w.run >= GROWTH_RUN && rise > w.allowance {
                    return Err((rise, w.run));
                }
            }
            _ => w.run = 0,
        }
        w.last = Some(ledger);
        w.kinetic_peak = (self.kinetic_peak * PEAK_DECAY).max(kinetic);
        Ok(w)
    }
}

/// The state at the start of a step split into substeps, restored if one of them fails.
#[derive(Clone, Debug, Default)]
struct Saved {
    state: ParticleState,
    held_forces: Vec<Vec3>,
    end: Option<EndOfStep>,
    watch: GrowthWatch,
}

/// An integrator's step counters and held forces at a step's start (`Integrator::checkpoint`).
#[derive(Clone, Debug, Default)]
pub struct Checkpoint {
    steps: u64,
    last_substeps: u32,
    held_forces: Vec<Vec3>,
    from_rest: bool,
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
    watch: GrowthWatch,
    /// Stiffness and damping rates of the system, for automatic substeps.
    rates: RateEstimate,
    /// Whether `rates` describes the system as it is (false after `invalidate`).
    measured: bool,
    /// Extra factor on the measured ω² after a refused step (1 until then; ×4 per refusal).
    margin: Real,
    /// Steps the divergence guard refused and that were taken again with more substeps.
    refused: u64,
    last_substeps: u32,
    /// The velocities were zeroed (`motion_stopped`) after the last step: the next
    /// symplectic Euler step starts with half a kick (`schemes::symplectic_euler`), and its
    /// contacts' pushes are read over the time its kicks cover (`step`).
    from_rest: bool,
    saved: Saved,
    sub_holds: Vec<Hold>,
    /// Push-only contacts on points tied to particles (`set_points`), and the push on each
    /// over the last step (its momentum / dt), N.
    points: Vec<PointHold>,
    point_pushes: Vec<Real>,
    scratch_inv_mass: Vec<Real>,
    /// Held flags and forces of the velocity split (`ParticleSystem::apply_velocity_split`).
    split_held: Vec<bool>,
    split_force: Vec<Vec3>,
}

impl Integrator {
    pub fn new(scheme: Scheme) -> Self {
        Self::with_settings(scheme, IntegratorSettings::default())
    }

    pub fn with_settings(scheme: Scheme, settings: IntegratorSettings) -> Self {
        Self {
            scheme,
            settings,
            margin: 1.0,
            ..Self::default()
        }
    }

    /// Steps taken successfully (each made of `last_substeps` internal steps).
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Steps the divergence guard refused so far that were taken again with more substeps
    /// (automatic substeps): a stiff mode the stability measure had missed.
    pub fn refused_steps(&self) -> u64 {
        self.refused
    }

    /// Factorisations of implicit Euler's rest-matrix preconditioner so far.
    pub fn implicit_factorizations(&self) -> usize {
        self.implicit.factorizations()
    }

    /// Internal steps the last step took (0 before the first).
    pub fn last_substeps(&self) -> u32 {
        self.last_substeps
    }

    /// The largest step the scheme takes by itself under `substeps = "auto"`: the measured
    /// stability bound times `stable_step::SAFETY` (infinite for implicit Euler; None before
    /// the first measurement).
    pub fn stable_dt(&self) -> Option<Real> {
        if self.scheme == Scheme::ImplicitEuler {
            return Some(Real::INFINITY);
        }
        self.measured.then(|| {
            stable_step::SAFETY
                * stable_step::stable_step(
                    self.scheme,
                    self.rates.omega_sq * self.margin.max(1.0),
                    self.rates.damping_rate,
                )
        })
    }

    /// (ω²_max of M⁻¹K in 1/s², largest rate of M⁻¹C in 1/s) as last measured.
    pub fn measured_rates(&self) -> (Real, Real) {
        (self.rates.omega_sq, self.rates.damping_rate)
    }

    /// `ModelInfo::details` entries: the substep setting, the stable step and the substeps
    /// the last step took.
    pub fn details(&self) -> Vec<(String, String)> {
        let mut d = vec![(
            "substeps_setting".to_string(),
            self.settings.substeps.describe(),
        )];
        if let Some(h) = self.stable_dt() {
            d.push(("stable_dt".into(), format!("{h:.6e}")));
        }
        d.push(("substeps".into(), self.last_substeps.to_string()));
        d
    }

    /// Forces the system exerts on each held particle at the end of the last step, in the
    /// order of the `holds` given to it.
    pub fn held_forces(&self) -> &[Vec3] {
        &self.held_forces
    }

    /// Whether `set_points` gives the right push under this scheme: the explicit ones. After
    /// implicit Euler's solve a projection undoes only the mass part of the step's response
    /// (the velocity answers to M + h C + h² K): a block pressed through a fine surface read
    /// 80 % low (0.005731 N against fem-static's 0.029404 N). Implicit Euler holds vertex
    /// contacts inside its solve (`implicit`), so a model under it keeps the coarse
    /// vertices' planes for a fine surface.
    pub fn holds_points(&self) -> bool {
        self.scheme != Scheme::ImplicitEuler
    }

    /// Push-only contacts on points tied to particles, held from the next step on beside the
    /// holds (`points`: the same projection as `Hold::contact`, over a point's particles).
    /// A held particle (a full `Hold`) takes none of a point's move.
    pub fn set_points(&mut self, points: Vec<PointHold>) {
        self.point_pushes = vec![0.0; points.len()];
        self.points = points;
    }

    /// The points of `set_points`.
    pub fn points(&self) -> &[PointHold] {
        &self.points
    }

    /// The push on each point of `set_points` over the last step along its normal (the
    /// momentum its projections gave / dt, ≥ 0), N.
    pub fn point_pushes(&self) -> &[Real] {
        &self.point_pushes
    }

    /// Forgets the forces kept from the last step: call it after changing the system itself
    /// (a cut, new rest lengths, new material), since the state alone cannot show that. The
    /// stability limit is measured again at the next step.
    pub fn invalidate(&mut self) {
        self.end = None;
        self.implicit.forget_warm_start();
        self.measured = false;
        self.watch = GrowthWatch::default();
    }

    /// What a step changes besides the state and its kept forces: to take it again from
    /// its start (`roll_back`).
    pub fn checkpoint(&self) -> Checkpoint {
        Checkpoint {
            steps: self.steps,
            last_substeps: self.last_substeps,
            held_forces: self.held_forces.clone(),
            from_rest: self.from_rest,
        }
    }

    /// Back to `checkpoint` (the state is the caller's); the kept forces and energy are
    /// forgotten (`forget_forces`): the step is taken again under other forces.
    pub fn roll_back(&mut self, checkpoint: &Checkpoint) {
        self.steps = checkpoint.steps;
        self.last_substeps = checkpoint.last_substeps;
        self.held_forces.clone_from(&checkpoint.held_forces);
        self.from_rest = checkpoint.from_rest;
        self.forget_forces();
    }

    /// Forgets the forces and energy kept from the last step but keeps the measured
    /// stability limit: for a change of external forces that leaves the stiffness as it was
    /// (a coupled model's targets moving, not its contact set).
    pub fn forget_forces(&mut self) {
        self.end = None;
        self.implicit.forget_warm_start();
        self.watch = GrowthWatch::default();
    }

    /// The state's velocities were set to zero (`Deformable::stop_motion`): the kept forces
    /// and the implicit solver's warm start are dropped, the measured stability limit kept
    /// (the stiffness is the same), and so is the growth watch: its ledger sees the drop
    /// as a loss, and its allowance keeps the recent kinetic-energy peak (a watch started
    /// afresh at rest would read the next steps' normal energy swing as growth).
    ///
    /// Under symplectic Euler the next step starts with half a kick (`from_rest`). Its
    /// velocity runs half a step ahead of its positions; zeroed, with a whole kick next, the
    /// state restarted moving at (h/2)·a, more energy than the positions' alone, and
    /// kinetic damping fed a fast mode instead of draining it: a linear oscillator at hω =
    /// 0.5 with two substeps a step grew 1e2-fold in 400 steps of such stops, and the
    /// hybrid's deep press in `tissue compare` grew from 3e-9 to 1e-4 J with its contact
    /// planes frozen (docs/hybrid.md, "Session 20").
    pub fn motion_stopped(&mut self) {
        self.end = None;
        self.implicit.forget_warm_start();
        self.from_rest = true;
    }

    /// Measures the stability limit now at `state` (the models call it when built, so that
    /// their info shows it before the first step).
    pub fn measure<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &ParticleState,
        holds: &[Hold],
    ) {
        if self.scheme == Scheme::ImplicitEuler || state.x.len() != system.masses().len() {
            return;
        }
        self.fill_inv_mass(system, holds);
        self.rates.measure(
            system,
            &state.x,
            &state.v,
            &self.scratch_inv_mass,
            stable_step::ITERATIONS,
            true,
        );
        self.measured = true;
        self.margin = 1.0;
    }

    /// Forgets the forces kept from the last step and re-measures the stiffness rate at
    /// `state` with `iterations` power iterations warm-started from the last dominant
    /// vector, never below the last full measurement (`measure`): for a change of external
    /// stiffness that is local and leaves the damping as it was (the `hybrid` model's
    /// contact set on its rest). A few iterations instead of a cold `measure`'s
    /// `stable_step::ITERATIONS`; nothing when the limit was never measured (the next
    /// step measures it in full) or the scheme has none.
    pub fn recheck_stiffness<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &ParticleState,
        holds: &[Hold],
        iterations: usize,
    ) {
        self.forget_forces();
        if !self.measured
            || self.scheme == Scheme::ImplicitEuler
            || state.x.len() != system.masses().len()
        {
            return;
        }
        self.fill_inv_mass(system, holds);
        self.rates.measure_stiffness(
            system,
            &state.x,
            &state.v,
            &self.scratch_inv_mass,
            iterations,
        );
    }

    /// The stable step (as `stable_dt`, margin 1) that a cold measurement gives at `state`:
    /// `iterations` power iterations from the fixed start vector, nothing kept, this
    /// integrator unchanged. A reference for the warm-started re-measures' tests.
    #[cfg(test)]
    pub fn cold_stable_dt<S: ParticleSystem + ?Sized>(
        &self,
        system: &mut S,
        state: &ParticleState,
        holds: &[Hold],
        iterations: usize,
    ) -> Real {
        if self.scheme == Scheme::ImplicitEuler {
            return Real::INFINITY;
        }
        let mut probe = Self::with_settings(self.scheme, self.settings);
        probe.fill_inv_mass(system, holds);
        let mut rates = RateEstimate::default();
        rates.measure(
            system,
            &state.x,
            &state.v,
            &probe.scratch_inv_mass,
            iterations,
            true,
        );
        stable_step::SAFETY
            * stable_step::stable_step(self.scheme, rates.omega_sq, rates.damping_rate)
    }

    /// The factor on the measured stiffness that refused steps left (1 until the divergence
    /// guard refuses a step; four times larger at each refusal, back to 1 at the next full
    /// measure).
    #[cfg(test)]
    pub fn stiffness_margin(&self) -> Real {
        self.margin.max(1.0)
    }

    fn fill_inv_mass<S: ParticleSystem + ?Sized>(&mut self, system: &S, holds: &[Hold]) {
        let inv = &mut self.scratch_inv_mass;
        inv.clear();
        inv.extend(system.masses().iter().map(|&m| {
            if m > 0.0 && m.is_finite() {
                1.0 / m
            } else {
                0.0
            }
        }));
        for h in holds.iter().filter(|h| h.along.is_none()) {
            if let Some(i) = inv.get_mut(h.particle) {
                *i = 0.0;
            }
        }
    }

    /// How many substeps `dt` takes: the forced count, or under `Auto` the measured limit's
    /// (measured now if the system changed, re-checked every `RECHECK_STEPS` steps).
    fn substep_count<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &ParticleState,
        holds: &[Hold],
        dt: Real,
    ) -> Result<u32, SimError> {
        match self.settings.substeps {
            Substeps::Fixed(n) => return Ok(n.max(1)),
            Substeps::Auto if self.scheme == Scheme::ImplicitEuler => return Ok(1),
            Substeps::Auto => {}
        }
        if state.x.len() != system.masses().len() {
            return Ok(1); // `begin` reports the mismatch
        }
        if !self.measured {
            self.measure(system, state, holds);
        } else if self.steps > 0 && self.steps.is_multiple_of(stable_step::RECHECK_STEPS) {
            self.fill_inv_mass(system, holds);
            self.rates.measure(
                system,
                &state.x,
                &state.v,
                &self.scratch_inv_mass,
                stable_step::RECHECK_ITERATIONS,
                false,
            );
        }
        let stable = self.stable_dt().unwrap_or(Real::INFINITY);
        substeps_for(dt, stable).ok_or_else(|| SimError::BadParameter {
            name: "dt",
            value: format!("{dt:e}"),
            reason: format!(
                "{} is stable only below {stable:.3e} s on this model (ω_max = {:.3e} rad/s, \
                 damping rate {:.3e} 1/s): that is more than {} substeps per step; use \
                 integrator = \"implicit-euler\", less stiffness damping or a smaller dt",
                self.scheme,
                self.rates.omega_sq.sqrt(),
                self.rates.damping_rate,
                stable_step::MAX_SUBSTEPS
            ),
        })
    }

    /// Advances `state` by `dt`, in as many substeps as the setting asks (held particles
    /// move in a straight line to their targets across them). On error the state, the held
    /// forces and the energy watch are those of the last good step and the model stays
    /// usable. Under `Auto`, a step the divergence guard refuses is measured again at the
    /// start state and retried (up to `RETRIES` times) with four times the stiffness margin
    /// (twice the substeps: a stiff mode that the power iterations missed, such as a
    /// coupled model's new contact at its interface, may need several times the count,
    /// and doubling the margin reached only 2.8 times it in three retries).
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
        let split = self.prepare_split(system, state, holds, dt)?;
        let mut n = self.substep_count(system, state, holds, dt)?;
        let mut result = self.substepped(system, state, holds, dt, n);
        let auto = self.settings.substeps == Substeps::Auto && self.scheme != Scheme::ImplicitEuler;
        for _ in 0..RETRIES {
            if !(auto && matches!(result, Err(SimError::Diverged { .. }))) {
                break;
            }
            // The system stiffened beyond the last measurement: measure where the step
            // starts, quadruple the margin, and retry only if that asks for more substeps.
            self.fill_inv_mass(system, holds);
            self.rates.measure(
                system,
                &state.x,
                &state.v,
                &self.scratch_inv_mass,
                stable_step::ITERATIONS,
                false,
            );
            self.margin = self.margin.max(1.0) * 4.0;
            let stable = self.stable_dt().unwrap_or(Real::INFINITY);
            match substeps_for(dt, stable) {
                Some(m) if m > n => {
                    n = m;
                    self.refused += 1;
                    result = self.substepped(system, state, holds, dt, n);
                }
                _ => break,
            }
        }
        if result.is_ok() {
            // The pushes' momentum over the step is their force times the time the kicks
            // cover: half a substep less after a stop (`from_rest`). Divided by the whole
            // step, a contact resting on its plane read 0.75 of its force on every step
            // after a stop (two substeps), and the hybrid's deep press alternated between
            // 17.2 and 23.1 mN with its planes still to 0.1 µm.
            let kicked =
                if std::mem::take(&mut self.from_rest) && self.scheme == Scheme::SymplecticEuler {
                    dt - 0.5 * dt / Real::from(self.last_substeps.max(1))
                } else {
                    dt
                };
            self.contact_forces(holds, kicked);
            let impulses = &self.work.point_impulse;
            self.point_pushes.clear();
            self.point_pushes.extend(
                (0..self.points.len()).map(|k| impulses.get(k).map_or(0.0, |p| p / kicked)),
            );
        }
        if split && let Ok(info) = &mut result {
            self.apply_split(system, state, holds, dt);
            info.capped |= system.velocity_split_capped();
        }
        system.set_step_time(1.0);
        result
    }

    /// A contact's held force is the push its projections gave over the step, per second:
    /// the mean contact force, which the particles' momentum balance sees. (The force on
    /// the particle at the step's end is what a two-sided hold reads; a contact's particle
    /// touches and leaves within the step, and that snapshot jumps with it.)
    fn contact_forces(&mut self, holds: &[Hold], dt: Real) {
        let impulses = &self.work.contact_impulse;
        for (k, (f, h)) in self.held_forces.iter_mut().zip(holds).enumerate() {
            if let (true, Some(n)) = (h.unilateral, h.along) {
                *f = -n * (impulses.get(k).copied().unwrap_or(0.0) / dt);
            }
        }
    }

    /// Explicit schemes: asks the system to prepare its velocity split for this step.
    fn prepare_split<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &ParticleState,
        holds: &[Hold],
        dt: Real,
    ) -> Result<bool, SimError> {
        if self.scheme == Scheme::ImplicitEuler {
            return Ok(false);
        }
        let n = state.x.len();
        self.split_held.clear();
        self.split_held.resize(n, false);
        for h in holds.iter().filter(|h| h.along.is_none()) {
            if let Some(f) = self.split_held.get_mut(h.particle) {
                *f = true;
            }
        }
        system.prepare_velocity_split(dt, &self.split_held)
    }

    /// Applies the system's velocity split after a successful step: the held particles'
    /// reactions get its forces, the energy ledger loses what it dissipated, and the kept
    /// end-of-step forces (which depend on v) are dropped.
    ///
    /// Symplectic Euler's velocity is that of the last substep's interval, half a substep h
    /// behind the positions. Damping it directly is not dissipative for that scheme: its
    /// conserved energy ½|w|²_M + ½xᵀ(K − h²/4 KM⁻¹K)x is in the synchronous velocity
    /// w = v + (h/2) M⁻¹f(x), and removing v alone lets x grow by up to 1/√(1 − h²ω²/4)
    /// per step (seen: a beam diverging after 136 steps). So w is damped, and v follows.
    /// Velocity Verlet and RK4 carry the synchronous velocity already.
    fn apply_split<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &mut ParticleState,
        holds: &[Hold],
        dt: Real,
    ) {
        let h = dt / Real::from(self.last_substeps.max(1));
        let staggered = self.scheme == Scheme::SymplecticEuler;
        let shift = |v: &mut [Vec3],
                     end: &Option<EndOfStep>,
                     masses: &[Real],
                     held: &[bool],
                     sign: Real| {
            let Some(end) = end.as_ref().filter(|e| e.f.len() == v.len()) else {
                return;
            };
            for (((v, f), &m), &held) in v.iter_mut().zip(&end.f).zip(masses).zip(held) {
                if !held && m > 0.0 {
                    *v += *f * (sign * 0.5 * h / m);
                }
            }
        };
        let kinetic = |v: &[Vec3], masses: &[Real], held: &[bool]| -> Real {
            v.iter()
                .zip(masses)
                .zip(held)
                .filter(|(_, h)| !**h)
                .map(|((v, m), _)| 0.5 * m * v.length_squared())
                .sum()
        };
        let before = kinetic(&state.v, system.masses(), &self.split_held);
        self.split_force.clear();
        self.split_force.resize(state.v.len(), Vec3::ZERO);
        if staggered {
            shift(
                &mut state.v,
                &self.end,
                system.masses(),
                &self.split_held,
                1.0,
            );
        }
        let applied = system.apply_velocity_split(&mut state.v, &mut self.split_force);
        if staggered {
            shift(
                &mut state.v,
                &self.end,
                system.masses(),
                &self.split_held,
                -1.0,
            );
        }
        if !applied {
            return;
        }
        let after = kinetic(&state.v, system.masses(), &self.split_held);
        // A contact's force is its pushes' momentum (`contact_forces`): the damping on its
        // particle is the tissue's, and it shows in the next step's pushes.
        for (f, h) in self.held_forces.iter_mut().zip(holds) {
            if !h.unilateral {
                *f += h.held_part(self.split_force[h.particle]);
            }
        }
        if let Some(last) = self.watch.last.as_mut() {
            *last -= (before - after).max(0.0);
        }
        self.end = None;
    }

    fn substepped<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &mut ParticleState,
        holds: &[Hold],
        dt: Real,
        n: u32,
    ) -> Result<StepInfo, SimError> {
        self.work.contact_impulse.clear();
        self.work.contact_impulse.resize(holds.len(), 0.0);
        self.work.point_impulse.clear();
        self.work.point_impulse.resize(self.points.len(), 0.0);
        if n <= 1 {
            self.work.span = (0.0, 1.0);
            let mut info = self.single(system, state, holds, dt)?;
            self.steps += 1;
            self.last_substeps = 1;
            info.substeps = 1;
            return Ok(info);
        }
        if self.scheme != Scheme::ImplicitEuler {
            let info = self.substepped_explicit(system, state, holds, dt, n)?;
            self.steps += 1;
            self.last_substeps = n;
            return Ok(info);
        }
        let saved = &mut self.saved;
        saved.state.clone_from(state);
        saved.held_forces.clone_from(&self.held_forces);
        saved.end.clone_from(&self.end);
        saved.watch = self.watch;
        let mut sub = std::mem::take(&mut self.sub_holds);
        let h = dt / Real::from(n);
        let mut info = StepInfo::default();
        let mut result = Ok(());
        for k in 1..=n {
            let f = Real::from(k) / Real::from(n);
            sub.clear();
            for hold in holds {
                // From where the step started (`begin` reports a bad index).
                let from = self
                    .saved
                    .state
                    .x
                    .get(hold.particle)
                    .copied()
                    .unwrap_or(hold.target);
                let target = if hold.ramped() {
                    from + (hold.target - from) * f
                } else {
                    hold.target
                };
                sub.push(Hold { target, ..*hold });
            }
            self.work.span = ((Real::from(k) - 1.0) / Real::from(n), f);
            match self.single(system, state, &sub, h) {
                Ok(i) => {
                    info.iterations += i.iterations;
                    info.residual = info.residual.max(i.residual);
                    info.capped |= i.capped;
                }
                Err(e) => {
                    result = Err(e);
                    break;
                }
            }
        }
        self.sub_holds = sub;
        if let Err(e) = result {
            let saved = &self.saved;
            state.clone_from(&saved.state);
            self.held_forces.clone_from(&saved.held_forces);
            self.end.clone_from(&saved.end);
            self.watch = saved.watch;
            return Err(e);
        }
        self.steps += 1;
        self.last_substeps = n;
        info.substeps = n;
        Ok(info)
    }

    /// An explicit step of `n` substeps, lean: the substeps swap the workspace's start and
    /// end buffers instead of copying the state, and the checks that cost a pass over the
    /// particles (finite values, the energy test and the growth watch) run once, on the
    /// whole step. Nothing is written to `state`, the held forces, the kept end-of-step
    /// forces or the watch before the step has passed them, so a refused step leaves the
    /// last good state without a saved copy. Held particles move in a straight line to
    /// their targets, reaching k/n of the way at substep k; the work they do is summed
    /// substep by substep (trapezoid rule).
    fn substepped_explicit<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &mut ParticleState,
        holds: &[Hold],
        dt: Real,
        n: u32,
    ) -> Result<StepInfo, SimError> {
        let h = dt / Real::from(n);
        let mut sub = std::mem::take(&mut self.sub_holds);
        sub.clear();
        // Targets at fraction k/n of the way from where the step starts (`begin` reports a
        // bad index or target).
        let target_at = |hold: &Hold, k: u32| {
            let from = state.x.get(hold.particle).copied().unwrap_or(hold.target);
            if k == n || !hold.ramped() {
                hold.target
            } else {
                from + (hold.target - from) * (Real::from(k) / Real::from(n))
            }
        };
        sub.extend(holds.iter().map(|hold| Hold {
            target: target_at(hold, 1),
            ..*hold
        }));
        self.work.points.take_capped();
        let result = self.run_substeps(system, state, holds, &mut sub, h, n, &target_at);
        self.sub_holds = sub;
        let (energy, watch) = result?;
        self.commit(state, holds, energy);
        self.watch = watch;
        Ok(StepInfo {
            substeps: n,
            capped: self.work.points.take_capped(),
            ..StepInfo::default()
        })
    }

    /// The substeps of `substepped_explicit` and their checks: the end state is left in
    /// the workspace's x1, v1, f1.
    #[allow(clippy::too_many_arguments)]
    fn run_substeps<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &ParticleState,
        holds: &[Hold],
        sub: &mut [Hold],
        h: Real,
        n: u32,
        target_at: &dyn Fn(&Hold, u32) -> Vec3,
    ) -> Result<(Option<Real>, GrowthWatch), SimError> {
        system.set_step_time(0.0);
        self.begin(system, state, sub, h)?;
        // The ledger at the start: the kept one, else measured now (the system's energy
        // cache is at x0 right after `begin`'s force evaluation).
        let w = &self.work;
        // Loads that move over the step (`ParticleSystem::set_step_time`) are counted at
        // their end, at the start as at the end (as `single` does): the ledger then measures
        // what the dynamics did under the step's loads, not the work of a target ramping in.
        let e0 = match self.end.as_ref().and_then(|e| e.energy) {
            Some(e) => Some(e),
            None => {
                system.set_step_time(1.0);
                system
                    .potential_energy(&w.x0)
                    .map(|p| p + free_kinetic(&w.v0, &w.inv_mass))
            }
        };
        // What the explicit kicks may add by themselves: ½h²Σ|f|²/m per substep.
        let kick = 0.5 * h * h * Real::from(n) * kick_sum(w);
        let released = self.released_kinetic();
        let (mut work, mut work_in) = (released, released);
        for k in 1..=n {
            let w = &mut self.work;
            w.span = (
                (Real::from(k) - 1.0) / Real::from(n),
                Real::from(k) / Real::from(n),
            );
            if k > 1 {
                for (s, hold) in sub.iter_mut().zip(holds) {
                    s.target = target_at(hold, k);
                    if s.along.is_none() {
                        w.v0[s.particle] = (s.target - w.x0[s.particle]) / h;
                    }
                }
            }
            match self.scheme {
                Scheme::ExplicitEuler => schemes::explicit_euler(w, h),
                Scheme::SymplecticEuler => {
                    let kick = if k == 1 && self.from_rest { 0.5 } else { 1.0 };
                    schemes::symplectic_euler(w, h, kick)
                }
                Scheme::VelocityVerlet => schemes::velocity_verlet(system, w, h),
                Scheme::Rk4 => schemes::rk4(system, w, h),
                Scheme::ImplicitEuler => unreachable!("implicit Euler substeps take `single`"),
            };
            place_holds(w, sub, h);
            points::project(w, &self.points, h);
            system.set_step_time(w.span.1);
            eval_forces(system, &w.x1, &w.v1, &mut w.f1);
            let (dw, dw_abs) = held_work(w, sub);
            let (pw, pw_abs) = points::work(w);
            work += dw + pw;
            work_in += dw_abs + pw_abs;
            if k < n {
                std::mem::swap(&mut w.x0, &mut w.x1);
                std::mem::swap(&mut w.v0, &mut w.v1);
                std::mem::swap(&mut w.f0, &mut w.f1);
            }
        }
        let w = &self.work;
        if let Some(node) = (0..w.x1.len()).find(|&i| !is_finite_vec(w.x1[i] + w.v1[i])) {
            return Err(self.diverged(node, "its position or velocity is not finite".into()));
        }
        let (Some(e0), Some(p1)) = (e0, system.potential_energy(&w.x1)) else {
            return Ok((None, self.watch));
        };
        let k1 = free_kinetic(&w.v1, &w.inv_mass);
        self.energy_verdict(e0, k1 + p1, k1, work, work_in, kick)
    }

    /// One step of the scheme over `dt` with the given holds; on error nothing changed.
    fn single<S: ParticleSystem + ?Sized>(
        &mut self,
        system: &mut S,
        state: &mut ParticleState,
        holds: &[Hold],
        dt: Real,
    ) -> Result<StepInfo, SimError> {
        // Backward Euler evaluates every force at the end of its step (its linearisation
        // point is the start's positions, not its time).
        let (start, end) = self.work.span;
        system.set_step_time(if self.scheme == Scheme::ImplicitEuler {
            end
        } else {
            start
        });
        // A refused step's cap is not this step's.
        self.work.points.take_capped();
        self.begin(system, state, holds, dt)?;
        let info = match self.scheme {
            Scheme::ExplicitEuler => schemes::explicit_euler(&mut self.work, dt),
            Scheme::SymplecticEuler => {
                // `single` is a whole step here (implicit Euler's substeps never come here).
                let kick = if self.from_rest { 0.5 } else { 1.0 };
                schemes::symplectic_euler(&mut self.work, dt, kick)
            }
            Scheme::VelocityVerlet => schemes::velocity_verlet(system, &mut self.work, dt),
            Scheme::Rk4 => schemes::rk4(system, &mut self.work, dt),
            Scheme::ImplicitEuler => self.implicit.step(
                system,
                &mut self.work,
                holds,
                dt,
                &self.settings,
                self.steps + 1,
            )?,
        };
        let w = &mut self.work;
        place_holds(w, holds, dt);
        if self.scheme == Scheme::ImplicitEuler {
            held_in_solve(w, holds, &self.implicit.contact_pushes, dt);
        }
        points::project(w, &self.points, dt);
        if let Some(node) = (0..w.x1.len()).find(|&i| !is_finite_vec(w.x1[i] + w.v1[i])) {
            return Err(self.diverged(node, "its position or velocity is not finite".into()));
        }
        system.set_step_time(end);
        eval_forces(system, &w.x1, &w.v1, &mut w.f1);
        let (energy, watch) = self.check_energy(system, holds, dt)?;
        self.commit(state, holds, energy);
        self.watch = watch;
        Ok(StepInfo {
            capped: info.capped || self.work.points.take_capped(),
            ..info
        })
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
            if let Some(n) = h.along {
                if !(is_finite_vec(n) && (n.length() - 1.0).abs() < 1e-6) {
                    return Err(SimError::BadParameter {
                        name: "hold",
                        value: format!("particle {} along {n}", h.particle),
                        reason: "the direction must be a finite unit vector".into(),
                    });
                }
                // Free in the scheme, projected after it (`place_holds`).
                continue;
            }
            w.inv_mass[h.particle] = 0.0;
            w.held[h.particle] = true;
            w.v0[h.particle] = (h.target - w.x0[h.particle]) / dt;
        }
        for pt in &self.points {
            pt.check(n)?;
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

    /// The energy after the trial step and the growth watch after it, or an error if the
    /// energy grew in one step more than the held particles can explain, or has been rising
    /// for several steps without work put in (`GrowthWatch`). Energy = kinetic energy of
    /// free particles + the system's potential.
    fn check_energy<S: ParticleSystem + ?Sized>(
        &self,
        system: &S,
        holds: &[Hold],
        dt: Real,
    ) -> Result<(Option<Real>, GrowthWatch), SimError> {
        let w = &self.work;
        let Some(potential1) = system.potential_energy(&w.x1) else {
            return Ok((None, self.watch));
        };
        let k1 = free_kinetic(&w.v1, &w.inv_mass);
        let e0 = match self.end.as_ref().and_then(|e| e.energy) {
            Some(e) => e,
            None => {
                free_kinetic(&w.v0, &w.inv_mass)
                    + system.potential_energy(&w.x0).unwrap_or(potential1)
            }
        };
        // Work the held particles did on the rest: −∫ f·dx along their straight path, by the
        // trapezoid rule (exact for linear forces).
        let (work, work_in) = held_work(w, holds);
        let (pw, pw_abs) = points::work(w);
        let (work, work_in) = (work + pw, work_in + pw_abs);
        let released = self.released_kinetic();
        let (work, work_in) = (work + released, work_in + released);
        // What one explicit kick may add by itself: ½h²Σ|f|²/m (the kinetic energy of one
        // step's velocity change), so that a first step from rest under a load passes.
        let kick = 0.5 * dt * dt * kick_sum(w);
        self.energy_verdict(e0, k1 + potential1, k1, work, work_in, kick)
    }

    /// The one-step test and the growth watch for a step that took the ledger from `e0` to
    /// `e1` (kinetic part `k1`) while the held particles did `work` (absolute `work_in`),
    /// `kick` being what the explicit kicks may add by themselves.
    fn energy_verdict(
        &self,
        e0: Real,
        e1: Real,
        k1: Real,
        work: Real,
        work_in: Real,
        kick: Real,
    ) -> Result<(Option<Real>, GrowthWatch), SimError> {
        // The ledger's zero is arbitrary (the loads' potential): near a loaded equilibrium
        // e0 can pass through 0, so the recent kinetic peak is part of the scale too.
        let scale = e0.abs() + work_in + self.watch.kinetic_peak;
        let allowed = e0
            + self.settings.energy_growth * scale
            + 2.0 * work_in
            + kick
            + 1e-12 * (scale + kick)
            // From rest (after a Reset) every term above is ~0 and round-off alone "grew"
            // the energy from 0 to 4e-36 J; the same absolute floor as the growth watch.
            + ENERGY_NOISE;
        let hint = || {
            if self.settings.substeps == Substeps::Auto {
                format!(
                    "{} stiffened beyond its measured limit {:.3e} s?",
                    self.scheme,
                    self.stable_dt().unwrap_or(Real::INFINITY)
                )
            } else {
                format!("time step too large for {}?", self.scheme)
            }
        };
        if !e1.is_finite() || e1 > allowed {
            let node = self.fastest_free_particle();
            return Err(self.diverged(
                node,
                format!(
                    "the energy grew from {e0:.3e} J to {e1:.3e} J in one step while the held \
                     particles put in {work_in:.3e} J ({})",
                    hint()
                ),
            ));
        }
        match self.watch.next(
            e1,
            k1,
            work,
            work_in,
            if self.scheme == Scheme::ExplicitEuler {
                kick
            } else {
                0.0
            },
        ) {
            Ok(watch) => Ok((Some(e1), watch)),
            // The slow-growth watch looks for an explicit scheme's unstable mode, which raises
            // the ledger at every step. Implicit Euler has no stable-step limit: its energy
            // errors are those of its one linearised solve per step, second order in dt, and
            // under a moving grasp they rise for more than `GROWTH_RUN` steps without any
            // instability (a cut spring-mass liver dragged in the viewer was refused with
            // 1.4e-5 J over 8 steps, one run in two). A diverging implicit solve still fails
            // the one-step test above or the finiteness checks.
            Err(_) if !self.settings.watch_growth || !self.scheme.has_step_limit() => {
                Ok((Some(e1), self.watch))
            }
            Err((rise, run)) => Err(self.diverged(
                self.fastest_free_particle(),
                format!(
                    "the energy rose {rise:.3e} J over {run} steps beyond the work put in \
                     ({})",
                    hint()
                ),
            )),
        }
    }

    fn commit(&mut self, state: &mut ParticleState, holds: &[Hold], energy: Option<Real>) {
        let w = &self.work;
        state.x.copy_from_slice(&w.x1);
        state.v.copy_from_slice(&w.v1);
        self.held_forces.clear();
        self.held_forces
            .extend(holds.iter().map(|h| h.held_part(w.f1[h.particle])));
        let end = self.end.get_or_insert_with(EndOfStep::default);
        end.x.clone_from(&w.x1);
        end.v.clone_from(&w.v1);
        end.f.clone_from(&w.f1);
        end.energy = energy;
        end.held.clone_from(&w.held);
    }

    /// Kinetic energy of the particles a hold moved in the last step and lets go of now.
    /// A held particle moves with its target, and its kinetic energy is the hold's, not in
    /// the ledger; let go, it keeps its velocity and that energy enters the ledger. The hold
    /// put it in, so it counts as the holds' work: otherwise a probe that jumps into the
    /// organ and out again (the viewer's and the haptic device's moves can) reads as a
    /// blow-up of a stable step, and the retries inflate the substeps for good.
    fn released_kinetic(&self) -> Real {
        let (Some(end), w) = (self.end.as_ref(), &self.work) else {
            return 0.0;
        };
        end.held
            .iter()
            .enumerate()
            .filter(|&(i, &was)| was && !w.held.get(i).copied().unwrap_or(true))
            .filter_map(|(i, _)| {
                let (inv, v) = (*w.inv_mass.get(i)?, w.v0.get(i)?);
                (inv > 0.0).then(|| 0.5 * v.length_squared() / inv)
            })
            .sum()
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

/// ½ Σ m v² over the free particles (inverse mass > 0).
fn free_kinetic(v: &[Vec3], inv_mass: &[Real]) -> Real {
    v.iter()
        .zip(inv_mass)
        .filter(|(_, inv)| **inv > 0.0)
        .map(|(v, inv)| 0.5 * v.length_squared() / inv)
        .sum()
}

/// (signed, absolute) work the held particles did from x0 to x1: −½ (f0 + f1)·(x1 − x0),
/// along its direction only for a hold along one (across it the particle is free), plus
/// the kinetic energy such holds' projection gave.
fn held_work(w: &Workspace, holds: &[Hold]) -> (Real, Real) {
    let snap = (w.along_work, w.along_work.abs());
    let active = |k: usize| w.contact_active.get(k).copied().unwrap_or(true);
    holds.iter().enumerate().fold(snap, |(s, a), (k, h)| {
        if !active(k) {
            return (s, a);
        }
        let i = h.particle;
        let dw = -0.5 * h.held_part(w.f0[i] + w.f1[i]).dot(w.x1[i] - w.x0[i]);
        (s + dw, a + dw.abs())
    })
}

/// Σ |f0|²/m over the particles (zero for held ones).
fn kick_sum(w: &Workspace) -> Real {
    w.f0.iter()
        .zip(&w.inv_mass)
        .map(|(f, inv)| f.length_squared() * inv)
        .sum()
}
