//! Point contacts (`PointHold`) against the vertex contact they generalise and against the
//! equilibrium of a point tied to several particles.

use super::tests::Springs;
use super::*;

fn integrator(scheme: Scheme, substeps: u32) -> Integrator {
    Integrator::with_settings(
        scheme,
        IntegratorSettings {
            substeps: Substeps::Fixed(substeps),
            ..IntegratorSettings::default()
        },
    )
}

/// A point on one particle (weights 1, 0, 0) is `Hold::contact` on that particle: the same
/// motion and the same push, to round-off, at every step of a press and a release, in every
/// scheme, with and without substeps.
#[test]
fn a_point_on_one_particle_is_the_vertex_contact() {
    let (k, d) = (100.0, 0.01);
    // Implicit Euler holds vertex contacts in its solve and takes no points
    // (`Integrator::holds_points`).
    for scheme in Scheme::ALL
        .into_iter()
        .filter(|s| *s != Scheme::ImplicitEuler)
    {
        for substeps in [1, 3] {
            let sys = || Springs::new(vec![1.0, 1.0], vec![(0, 1, k, 0.0, 20.0)]);
            let (mut a_sys, mut b_sys) = (sys(), sys());
            let below = Vec3::new(0.05, 0.02, -d);
            let start = ParticleState {
                x: vec![below, Vec3::new(0.0, 0.0, 0.002)],
                v: vec![Vec3::ZERO, Vec3::new(0.1, 0.0, -0.5)],
            };
            let (mut a, mut b) = (start.clone(), start);
            let (mut ia, mut ib) = (integrator(scheme, substeps), integrator(scheme, substeps));
            let contact = Hold::contact(1, Vec3::new(-0.3, 0.7, 0.0), Vec3::Z);
            ib.set_points(vec![PointHold {
                particles: [1, 0, 0],
                weights: [1.0, 0.0, 0.0],
                normal: Vec3::Z,
                level: 0.0,
            }]);
            let mut worst: Real = 0.0;
            for step in 0..600 {
                let anchor = if step < 300 {
                    below
                } else {
                    Vec3::new(below.x, below.y, d)
                };
                ia.step(&mut a_sys, &mut a, &[Hold::new(0, anchor), contact], 2e-3)
                    .unwrap();
                ib.step(&mut b_sys, &mut b, &[Hold::new(0, anchor)], 2e-3)
                    .unwrap();
                let (fa, fb) = (ia.held_forces()[1], ib.point_pushes()[0]);
                assert!(fb >= 0.0, "{scheme}: {fb}");
                worst = worst
                    .max((fa.z + fb).abs() / (k * d))
                    .max((a.x[1] - b.x[1]).length() / d)
                    .max((a.v[1] - b.v[1]).length());
            }
            assert!(worst < 1e-12, "{scheme}, {substeps} substeps: {worst:e}");
            // It pressed, then let go.
            assert_eq!(ib.point_pushes()[0], 0.0, "{scheme}");
        }
    }
}

/// Three particles, each on a zero-length spring k to an anchor a distance d below the
/// plane z = 0, hold up one point Σ wᵢ zᵢ ≥ 0. At rest zᵢ = λ wᵢ / k − d on the free
/// particles and the point is on the plane: λ = k d Σ' wᵢ / Σ' wᵢ² over the free ones. With
/// every particle free, λ = k d / Σ wᵢ²; with the third held at z = 0 it takes none of the
/// move and λ = k d (w₁ + w₂) / (w₁² + w₂²). The push is never a pull, and the growth watch
/// refuses no step.
#[test]
fn a_point_on_three_particles_rests_on_its_plane_with_the_equilibrium_push() {
    let (k, d, c) = (100.0, 0.01, 20.0);
    let w = [0.5, 0.3, 0.2];
    for scheme in Scheme::ALL {
        for held_third in [false, true] {
            let mut sys = Springs::new(
                vec![1.0; 6],
                (0..3).map(|i| (i + 3, i, k, 0.0, c)).collect(),
            );
            let spots = [Vec3::ZERO, Vec3::X * 0.01, Vec3::Y * 0.01];
            let mut x: Vec<Vec3> = spots.to_vec();
            x.extend(spots.iter().map(|s| *s - Vec3::Z * d));
            let mut state = ParticleState::at_rest(x);
            let mut holds: Vec<Hold> = (0..3).map(|i| Hold::new(i + 3, state.x[i + 3])).collect();
            if held_third {
                holds.push(Hold::new(2, spots[2]));
            }
            let mut integ = integrator(scheme, 2);
            integ.set_points(vec![PointHold::tied([0, 1, 2], w, Vec3::Z, 0.0, spots)]);
            for _ in 0..3000 {
                integ.step(&mut sys, &mut state, &holds, 2e-3).unwrap();
                assert!(integ.point_pushes()[0] >= 0.0);
                let z: Real = (0..3).map(|i| w[i] * state.x[i].z).sum();
                assert!(
                    z > -1e-12,
                    "{scheme}: the point went past its plane by {z:e}"
                );
            }
            let expected = if held_third {
                k * d * (w[0] + w[1]) / (w[0] * w[0] + w[1] * w[1])
            } else {
                k * d / w.iter().map(|w| w * w).sum::<Real>()
            };
            let got = integ.point_pushes()[0];
            // The damped schemes' push reads the damping of a predicted velocity into the
            // plane (see the vertex contact's test): a bias of at most c·h/m.
            assert!(
                (got - expected).abs() < 0.03 * expected,
                "{scheme}, third held {held_third}: {got} N, expected {expected} N"
            );
            for (i, wi) in w.iter().enumerate() {
                let free = !(held_third && i == 2);
                let z = if free { got * wi / k - d } else { 0.0 };
                assert!(
                    (state.x[i].z - z).abs() < 0.03 * d,
                    "{scheme}: particle {i} at {}, expected z = {z}",
                    state.x[i]
                );
            }
            if held_third {
                assert_eq!(state.x[2], spots[2], "{scheme}: the held particle moved");
            }
        }
    }
}

/// The 45 points of a triangle cut 8 times along each edge (a fine surface's face), all
/// riding on its three particles: dependent rows.
fn face_points(
    normal: impl Fn(Vec3) -> Vec3,
    level: impl Fn(Vec3, Vec3) -> Real,
) -> Vec<PointHold> {
    let corners = [Vec3::ZERO, Vec3::X * 0.01, Vec3::Y * 0.01];
    let cuts = 8;
    let mut points = Vec::new();
    for i in 0..=cuts {
        for j in 0..=cuts - i {
            let w = [i, j, cuts - i - j].map(|n| Real::from(n) / Real::from(cuts));
            let at: Vec3 = (0..3).map(|k| corners[k] * w[k]).sum();
            let n = normal(at);
            points.push(PointHold {
                particles: [0, 1, 2],
                weights: w,
                normal: n,
                level: level(at, n),
            });
        }
    }
    assert_eq!(points.len(), 45);
    points
}

/// Dependent points projected exactly (`PointProjection::run`, the dual active set of
/// `solve::lcp`; the projected Gauss-Seidel sweeps alone stopped at their cap on such rows
/// with up to 1e-7 m left past the liver's k = 3 planes). Pressed d past a flat plane and
/// moving into it at s, the least mass-weighted correction is known: every particle onto
/// the plane with no inward speed (the corners are points), the momentum taken Σ mᵢ s.
/// Under a ball's tangent planes (each point its own normal), every point ends on or off its
/// plane, a pushed one keeps no more inward speed than it may, a point pushes only where it
/// ends on that bound (complementarity), and the particles' momentum changed by Σ λₖ nₖ:
/// the pushes reported are what the particles took. Neither is capped.
#[test]
fn dependent_points_are_projected_exactly() {
    let (d, s, h) = (1e-3, 0.2, 1e-3);
    let mass = [1.0, 2.0, 3.0];
    let inv: Vec<Real> = mass.iter().map(|m| 1.0 / m).collect();
    let start = |z: Real| {
        let x = vec![
            Vec3::new(0.0, 0.0, z),
            Vec3::new(0.01, 0.0, z),
            Vec3::new(0.0, 0.01, z),
        ];
        (x, vec![Vec3::new(0.1, 0.0, -s); 3])
    };
    let mut projection = PointProjection::default();
    // A flat plane z ≥ 0.
    let points = face_points(|_| Vec3::Z, |_, _| 0.0);
    let (mut x, mut v) = start(-d);
    projection.run(&points, &mut x, &mut v, &inv, h);
    for i in 0..3 {
        assert!(x[i].z.abs() < 1e-15, "particle {i}: z {}", x[i].z);
        assert!(v[i].z.abs() < 1e-12, "particle {i}: vz {}", v[i].z);
        assert_eq!(v[i].x, 0.1, "the tangential velocity is kept");
    }
    let taken: Real = (0..points.len()).map(|k| projection.momentum(k)).sum();
    let expected: Real = mass.iter().map(|m| m * s).sum();
    assert!(
        (taken / expected - 1.0).abs() < 1e-12,
        "{taken} against {expected}"
    );
    assert!(!projection.take_capped());
    // A ball of radius 2 cm poking d up through the face near its middle.
    let (radius, centre) = (0.02, Vec3::new(0.003, 0.004, d - 0.02));
    let points = face_points(|p| (p - centre).normalize(), |_, n| n.dot(centre) + radius);
    let (x0, v0) = start(0.0);
    let (mut x, mut v) = (x0.clone(), v0.clone());
    let allowed: Vec<Real> = points
        .iter()
        .map(|pt| {
            let gap = pt.gap(&x);
            if gap < 0.0 { 0.0 } else { -gap / h }
        })
        .collect();
    assert!(
        allowed.iter().filter(|a| **a == 0.0).count() > 3,
        "points past the ball"
    );
    projection.run(&points, &mut x, &mut v, &inv, h);
    let mut given = Vec3::ZERO;
    for (k, pt) in points.iter().enumerate() {
        assert!(
            pt.gap(&x) > -1e-14,
            "point {k}: {:e} past its plane",
            -pt.gap(&x)
        );
        let (speed, push) = (pt.coordinate(&v), projection.momentum(k));
        assert!(push >= 0.0, "point {k} pulls: {push}");
        assert!(
            speed > allowed[k] - 1e-12,
            "point {k}: {speed} into the ball"
        );
        if push > 0.0 {
            assert!(
                (speed - allowed[k]).abs() < 1e-12,
                "point {k} pushes off its bound"
            );
        }
        given += pt.normal * push;
    }
    let took: Vec3 = (0..3).map(|i| (v[i] - v0[i]) * mass[i]).sum();
    assert!(
        (took - given).length() < 1e-12 * given.length(),
        "the particles took {took}, the pushes gave {given}"
    );
    assert!(given.z > 0.5 * expected, "{given}");
    assert!(!projection.take_capped());
}

/// The energy ledger under dependent points whose pushed set keeps changing: a face of three
/// particles (springs along its edges, each on a zero-length spring to a held anchor at its
/// rest) carries 45 points (`face_points`) under a plane tilted 0.2 rad whose tilt turns
/// twice a second while it rises 5 mm into the face over 0.5 s and stays: the pushed points
/// move from corner to corner. Undamped, the energy changes only by the contact's work and
/// the scheme's own error, so the ledger E − ΣW (`GrowthWatch`) never rises by more than
/// 1e-3 of the energy stored above any earlier value of its own (what the growth watch
/// looks for), and falls by at most the scheme's own loss against a pressed plane (under
/// symplectic Euler ½h²|f|²/m a substep, the kick the projection takes back: 1.9 % of the
/// stored energy here, 0.44 % under velocity Verlet and RK4; bounded at 5 %). Measured: no
/// rise beyond round-off (7e-35 J). No step is refused and no point ends past its plane. (Counted per
/// point, the ledger read the shared motion of the dependent points once per point: the
/// exact projection's block press in `tests/dynamic_points.rs` was refused at step 258.)
#[test]
fn the_ledger_balances_the_energy_while_the_pushed_points_change() {
    let k = 100.0;
    let spots = [Vec3::ZERO, Vec3::X * 0.01, Vec3::Y * 0.01];
    for scheme in [Scheme::SymplecticEuler, Scheme::VelocityVerlet, Scheme::Rk4] {
        let mut springs = vec![
            (0, 1, k, 0.01, 0.0),
            (1, 2, k, 0.01 * std::f64::consts::SQRT_2, 0.0),
            (0, 2, k, 0.01, 0.0),
        ];
        springs.extend((0..3).map(|i| (i + 3, i, k, 0.0, 0.0)));
        let mut sys = Springs::new(vec![1.0, 2.0, 3.0, 1.0, 1.0, 1.0], springs);
        let mut state = ParticleState::at_rest([spots, spots].concat());
        let holds: Vec<Hold> = (3..6).map(|i| Hold::new(i, state.x[i])).collect();
        let mut integ = integrator(scheme, 2);
        let dt = 1e-3;
        let (mut start, mut pushing) = (None, Vec::new());
        let mut stored: Real = 0.0;
        let (mut rise, mut fall, mut low): (Real, Real, Real) = (0.0, 0.0, Real::INFINITY);
        let mut changes = 0;
        for step in 1..=1000 {
            let t = Real::from(step) * dt;
            let tilt: Real = 0.2;
            let turn = 4.0 * std::f64::consts::PI * t;
            let n = Vec3::new(tilt.sin() * turn.cos(), tilt.sin() * turn.sin(), tilt.cos());
            let lift = -0.002 + 0.007 * (t / 0.5).min(1.0);
            let through = Vec3::new(0.0033, 0.0033, lift);
            let points = face_points(|_| n, |_, n| n.dot(through));
            integ.set_points(points.clone());
            integ.step(&mut sys, &mut state, &holds, dt).unwrap();
            for pt in &points {
                assert!(
                    pt.gap(&state.x) > -1e-12,
                    "{scheme}: a point past its plane"
                );
            }
            let now: Vec<bool> = integ.point_pushes().iter().map(|p| *p > 0.0).collect();
            changes += usize::from(!pushing.is_empty() && now != pushing);
            pushing = now;
            let ledger = integ.watch.last.expect("the springs have a potential");
            let start = *start.get_or_insert(ledger);
            low = low.min(ledger);
            rise = rise.max(ledger - low);
            fall = fall.max(start - ledger);
            stored = stored.max(sys.potential_energy(&state.x).unwrap());
        }
        eprintln!(
            "{scheme}: ledger rose {rise:.3e} J and fell {fall:.3e} J at most, {stored:.3e} J \
             stored, the pushed set changed on {changes} of 1000 steps"
        );
        assert!(changes > 50, "{scheme}: {changes}");
        assert!(
            rise < 1e-3 * stored && fall < 0.05 * stored,
            "{scheme}: {rise:e} J, {fall:e} J against {stored:e} J"
        );
    }
}
