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
