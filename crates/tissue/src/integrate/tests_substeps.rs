//! Automatic substeps and the slow-growth guard: the measured stability limit against the
//! analytical one, substeps equal to steps taken by hand, and refusals that keep the state.

use super::tests::{Springs, oscillator};
use super::*;

fn integrator(scheme: Scheme, substeps: Substeps) -> Integrator {
    let mut i = Integrator::new(scheme);
    i.settings.substeps = substeps;
    i
}

#[test]
fn measured_rates_match_the_analytical_ones() {
    // Particle 1 (2 kg) on a k = 8 N/m spring with a 0.4 N·s/m dashpot to the held particle
    // 0: ω² = k/m = 4 /s², damping rate c/m = 0.2 /s.
    let (mut system, state, holds) = oscillator(0.4);
    let mut i = integrator(Scheme::SymplecticEuler, Substeps::Auto);
    i.measure(&mut system, &state, &holds);
    let (w2, c) = i.measured_rates();
    assert!((w2 / 4.0 - 1.0).abs() < 1e-6, "ω² = {w2}");
    assert!((c / 0.2 - 1.0).abs() < 1e-6, "c = {c}");
    let bound = 4.0 / (0.2 + (0.04_f64 + 16.0).sqrt());
    let h = i.stable_dt().unwrap();
    assert!(
        (h / (stable_step::SAFETY * bound) - 1.0).abs() < 1e-6,
        "{h} vs {bound}"
    );
    // Two free masses (1 and 2 kg) on one spring: the top mode is k(1/m1 + 1/m2) = 12 /s²,
    // not either particle's own k/m (the power iteration finds the coupled mode).
    let mut pair = Springs::new(vec![1.0, 2.0], vec![(0, 1, 8.0, 0.0, 0.0)]);
    let state = ParticleState::at_rest(vec![Vec3::ZERO, Vec3::X]);
    let mut i = integrator(Scheme::SymplecticEuler, Substeps::Auto);
    i.measure(&mut pair, &state, &[]);
    assert!(
        (i.measured_rates().0 / 12.0 - 1.0).abs() < 1e-6,
        "{:?}",
        i.measured_rates()
    );
    // RK4's larger stability region gives it 1.3 times the step; implicit Euler has no limit.
    assert!((stable_step::stable_step(Scheme::Rk4, 4.0, 0.0) - 1.3).abs() < 1e-12);
    assert!(stable_step::stable_step(Scheme::ImplicitEuler, 4.0, 0.0).is_infinite());
}

#[test]
fn auto_substeps_equal_the_same_steps_taken_by_hand() {
    // ω = 2 rad/s: symplectic Euler is stable below 1 s, auto takes 0.8 s at most, so a 5 s
    // step is 7 substeps. The held particle is dragged 1 m during the step; the substeps
    // move it in a straight line, as 7 steps of 5/7 s with targets at k/7 do.
    let (mut system, mut state, _) = oscillator(0.0);
    let target = Vec3::new(1.0, 0.0, 0.0);
    let holds = [Hold::new(0, target)];
    let mut auto = integrator(Scheme::SymplecticEuler, Substeps::Auto);
    let info = auto.step(&mut system, &mut state, &holds, 5.0).unwrap();
    assert_eq!(info.substeps, 7);
    assert_eq!(auto.last_substeps(), 7);
    assert_eq!(auto.steps(), 1);
    assert!(
        auto.details()
            .iter()
            .any(|(k, v)| k == "substeps" && v == "7")
    );

    let (mut system2, mut by_hand, _) = oscillator(0.0);
    let mut single = integrator(Scheme::SymplecticEuler, Substeps::Fixed(1));
    for k in 1..=7 {
        let h = [Hold {
            particle: 0,
            target: target * (k as Real / 7.0),
            along: None,
            unilateral: false,
        }];
        single
            .step(&mut system2, &mut by_hand, &h, 5.0 / 7.0)
            .unwrap();
    }
    for (a, b) in state.x.iter().zip(&by_hand.x) {
        assert!((*a - *b).length() < 1e-12, "{a} vs {b}");
    }
    assert_eq!(state.x[0], target);
    // A forced count is obeyed.
    let (mut system, mut state, holds) = oscillator(0.0);
    let mut fixed = integrator(Scheme::SymplecticEuler, Substeps::Fixed(3));
    assert_eq!(
        fixed
            .step(&mut system, &mut state, &holds, 0.1)
            .unwrap()
            .substeps,
        3
    );
}

#[test]
fn auto_substeps_keep_every_explicit_scheme_stable_far_above_its_limit() {
    for scheme in [Scheme::SymplecticEuler, Scheme::VelocityVerlet, Scheme::Rk4] {
        let (mut system, mut state, holds) = oscillator(0.0);
        let e = |s: &Springs, st: &ParticleState| {
            0.5 * s.masses[1] * st.v[1].length_squared() + s.potential_energy(&st.x).unwrap()
        };
        let e0 = e(&system, &state);
        let mut i = integrator(scheme, Substeps::Auto);
        let mut worst: Real = 0.0;
        for _ in 0..200 {
            // 5 s steps: 2.5 times the explicit limit of every scheme.
            let info = i.step(&mut system, &mut state, &holds, 5.0).unwrap();
            assert!(info.substeps >= 5, "{scheme}: {info:?}");
            worst = worst.max(e(&system, &state) / e0);
        }
        // Stable: no drift over 1000 s; the measured energy of symplectic Euler at ωh = 1.4
        // swings by (1 − ωh/2)⁻¹ at most.
        assert!(worst < 3.5, "{scheme}: energy grew {worst}×");
    }
}

#[test]
fn slow_growth_is_refused_long_before_blow_up_and_keeps_the_last_good_state() {
    // Particle 1 (2 kg) on a soft spring (ω² = 0.01 /s²) and a strong dashpot (rate 2 /s)
    // to the held particle 0. Symplectic Euler needs h²ω² + 2hc ≤ 4, h ≤ 0.9995 s; at
    // h = 1.01 s the velocity mode flips sign and grows 2.5% a step (5% in energy), which
    // the one-step test (50%) lets through: only the growth watch can refuse it.
    let make = || {
        let system = Springs::new(vec![1.0, 2.0], vec![(0, 1, 0.02, 0.0, 4.0)]);
        let state = ParticleState {
            x: vec![Vec3::ZERO, Vec3::new(0.1, 0.0, 0.0)],
            v: vec![Vec3::ZERO, Vec3::new(0.0, 0.3, 0.0)],
        };
        let holds = [Hold {
            particle: 0,
            target: Vec3::ZERO,
            along: None,
            unilateral: false,
        }];
        (system, state, holds)
    };
    let (mut system, mut state, holds) = make();
    let e = |s: &Springs, st: &ParticleState| {
        0.5 * s.masses[1] * st.v[1].length_squared() + s.potential_energy(&st.x).unwrap()
    };
    let e0 = e(&system, &state);
    let mut i = integrator(Scheme::SymplecticEuler, Substeps::Fixed(1));
    let mut good = state.clone();
    let mut forces = Vec::new();
    let mut refused = None;
    for _ in 0..2000 {
        match i.step(&mut system, &mut state, &holds, 1.01) {
            Ok(_) => {
                good = state.clone();
                forces = i.held_forces().to_vec();
            }
            Err(err) => {
                refused = Some(err);
                break;
            }
        }
    }
    let err = refused.expect("the growing oscillation was never refused");
    assert!(
        matches!(&err, SimError::Diverged { reason, .. } if reason.contains("rose")),
        "{err}"
    );
    assert_eq!(state, good);
    assert_eq!(i.held_forces(), &forces[..]);
    let grown = e(&system, &state) / e0;
    assert!(grown < 20.0, "refused only after a {grown}× gain");
    // The same run with auto substeps is stable.
    let (mut system, mut state, holds) = oscillator(0.0);
    let mut auto = integrator(Scheme::SymplecticEuler, Substeps::Auto);
    for _ in 0..2000 {
        assert_eq!(
            auto.step(&mut system, &mut state, &holds, 1.0005)
                .unwrap()
                .substeps,
            2
        );
    }
}

/// Particle 1 (1 kg) on a hardening spring k d + k₃|d|² d to particle 0, which is held and
/// pulled at constant speed, and on a dashpot c to the ground: the spring stretches until
/// k s + k₃ s³ = c V, where its tangent stiffness k + 3k₃s² is hundreds of times the rest one.
struct Hardening {
    masses: Vec<Real>,
}

const K: Real = 1.0;
const K3: Real = 1e4;
const C: Real = 10.0;
const SPEED: Real = 5.0;

impl ParticleSystem for Hardening {
    fn masses(&self) -> &[Real] {
        &self.masses
    }
    fn forces(&mut self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        let d = x[1] - x[0];
        let s = (K + K3 * d.length_squared()) * d;
        f[1] += -s - C * v[1];
        f[0] += s;
    }
    fn potential_energy(&self, x: &[Vec3]) -> Option<Real> {
        let d2 = (x[1] - x[0]).length_squared();
        Some(0.5 * K * d2 + 0.25 * K3 * d2 * d2)
    }
}

#[test]
fn a_hardening_spring_is_measured_again_as_it_stiffens() {
    let mut system = Hardening {
        masses: vec![0.0, 1.0],
    };
    let mut state = ParticleState::at_rest(vec![Vec3::ZERO, Vec3::new(0.01, 0.0, 0.0)]);
    let mut i = integrator(Scheme::SymplecticEuler, Substeps::Auto);
    let dt = 0.1;
    let mut rest_dt = None;
    for step in 1..=100 {
        let holds = [Hold {
            particle: 0,
            target: Vec3::new(SPEED * dt * step as Real, 0.0, 0.0),
            along: None,
            unilateral: false,
        }];
        i.step(&mut system, &mut state, &holds, dt)
            .unwrap_or_else(|e| panic!("step {step}: {e}"));
        rest_dt.get_or_insert(i.stable_dt().unwrap());
    }
    // Steady state: the dashpot's drag c·V balances the spring.
    let s = (state.x[0] - state.x[1]).length();
    let balance = K * s + K3 * s * s * s;
    assert!(
        (balance / (C * SPEED) - 1.0).abs() < 0.01,
        "stretch {s}: {balance} N"
    );
    let stiff_dt = i.stable_dt().unwrap();
    assert!(
        stiff_dt < 0.5 * rest_dt.unwrap(),
        "{stiff_dt} vs {rest_dt:?}"
    );
    // The tangent stiffness at the stretch the model measured, against k + 3k₃s².
    let w2 = i.measured_rates().0;
    assert!(
        (w2 / (K + 3.0 * K3 * s * s) - 1.0).abs() < 0.05,
        "ω² = {w2}"
    );
}

/// One particle pushed by a constant load F along +x and held back by a penalty spring k to
/// a target moving at constant speed V along −x (a probe pressing on: the spline's held
/// vertices), with mass damping α. At the steady state the particle moves with the target
/// and the spring's reading k(x − t) is F − α m V. `ramp`: the target moves over the step
/// (`ParticleSystem::set_step_time`), else it jumps to its new place at the step's start.
struct Tethered {
    masses: Vec<Real>,
    from: Real,
    to: Real,
    time: Real,
    ramp: bool,
}

const TETHER_K: Real = 1e3;
const TETHER_F: Real = 1.0;
const TETHER_ALPHA: Real = 20.0;
const TETHER_V: Real = -0.01;

impl Tethered {
    fn target(&self) -> Real {
        if self.ramp {
            self.from + (self.to - self.from) * self.time
        } else {
            self.to
        }
    }
}

impl ParticleSystem for Tethered {
    fn masses(&self) -> &[Real] {
        &self.masses
    }
    fn forces(&mut self, x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        let m = self.masses[0];
        f[0] += Vec3::new(
            TETHER_F - TETHER_K * (x[0].x - self.target()),
            -TETHER_K * x[0].y,
            -TETHER_K * x[0].z,
        ) - TETHER_ALPHA * m * v[0];
    }
    fn potential_energy(&self, x: &[Vec3]) -> Option<Real> {
        let e = Vec3::new(x[0].x - self.target(), x[0].y, x[0].z);
        Some(0.5 * TETHER_K * e.length_squared() - TETHER_F * x[0].x)
    }
    fn prepare_jacobians(&mut self, _x: &[Vec3], _v: &[Vec3]) -> Result<(), SimError> {
        Ok(())
    }
    fn stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        out[0] = TETHER_K * dx[0];
    }
    fn damping_product(&self, dv: &[Vec3], out: &mut [Vec3]) {
        out[0] = TETHER_ALPHA * self.masses[0] * dv[0];
    }
    fn set_step_time(&mut self, s: Real) {
        self.time = s;
    }
}

/// The spring's reading after 2 s of steps of 10 ms, relative error against F − α m V.
fn tether_reading(scheme: Scheme, ramp: bool) -> (Real, u32) {
    let m = 1e-3; // ω = √(k/m) = 1000 rad/s: several substeps per 10 ms step
    let mut system = Tethered {
        masses: vec![m],
        from: 0.0,
        to: 0.0,
        time: 1.0,
        ramp,
    };
    let mut state = ParticleState::at_rest(vec![Vec3::new(TETHER_F / TETHER_K, 0.0, 0.0)]);
    let mut i = integrator(scheme, Substeps::Auto);
    let dt = 0.01;
    let mut substeps = 0;
    for step in 1..=200 {
        system.from = system.to;
        system.to = TETHER_V * dt * step as Real;
        // The targets moved: as the spline does (`Integrator::forget_forces`).
        i.forget_forces();
        let info = i
            .step(&mut system, &mut state, &[], dt)
            .unwrap_or_else(|e| panic!("{scheme}, step {step}: {e}"));
        substeps = substeps.max(info.substeps);
    }
    let reading = TETHER_K * (state.x[0].x - system.to);
    let expected = TETHER_F - TETHER_ALPHA * m * TETHER_V;
    ((reading / expected - 1.0).abs(), substeps)
}

#[test]
fn a_spring_to_a_moving_target_reads_the_load_under_every_scheme() {
    // The target moves 0.1 mm a step (k·δ = 0.1 N, a tenth of the load).
    for scheme in [
        Scheme::SymplecticEuler,
        Scheme::VelocityVerlet,
        Scheme::Rk4,
        Scheme::ImplicitEuler,
    ] {
        // Measured: 2e-11 (symplectic Euler, 7 substeps) to 2e-16.
        let (err, substeps) = tether_reading(scheme, true);
        eprintln!("{scheme}: {substeps} substeps, relative error {err:.2e}");
        assert!(err < 1e-6, "{scheme}: relative error {err}");
        if scheme != Scheme::ImplicitEuler {
            assert!(substeps >= 5, "{scheme}: {substeps} substeps");
        }
    }
    // A target jumping at the step's start kicks the particle every step; the explicit
    // reading at the step's end is then off by a part of k·δ (what the spline did; measured
    // 2.2% of the load here).
    let (err, _) = tether_reading(Scheme::SymplecticEuler, false);
    eprintln!("jumping target, symplectic Euler: relative error {err:.2e}");
    assert!(err > 0.01, "jumping target: relative error {err}");
}
