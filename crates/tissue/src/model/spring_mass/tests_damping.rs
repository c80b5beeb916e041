//! Spring damping under explicit schemes: split off and applied implicitly once per step
//! (`integrate::split_damping`), checked against the same damping kept in the force.

use super::*;
use crate::interact::{Constraints, Loads};
use crate::mesh::generate::{BoxSplit, box_tets};
use crate::model::Deformable;
use crate::model::testing::decay;

/// A clamped volumetric spring beam 0.5 m × 0.1 m × 0.1 m (10 × 2 × 2 cells), E = 1e6 Pa,
/// β = `beta`, under gravity from rest, symplectic Euler; the tip's mean height per step.
fn tip_history(beta: Real, split: bool, dt: Real, steps: usize) -> Vec<Real> {
    let mesh = box_tets(
        Vec3::ZERO,
        Vec3::new(0.5, 0.1, 0.1),
        [10, 2, 2],
        BoxSplit::Six,
    );
    let mut mat = Material::new(1e6, 0.3).unwrap();
    mat.stiffness_damping = beta;
    let mut m = volumetric::build(&mesh, mat, SpringParams::default()).unwrap();
    assert_eq!(m.body.split_damping(), beta > 0.0);
    if !split {
        m.body.set_split_damping(false, &[]);
        m.integrator.invalidate();
    }
    let rest = m.rest_surface().to_vec();
    let at = |x: Real| -> Vec<u32> {
        (0..rest.len() as u32)
            .filter(|&s| (rest[s as usize].x - x).abs() < 1e-9)
            .collect()
    };
    let (clamp, tip) = (at(0.0), at(0.5));
    m.set_constraints(&Constraints {
        fixed: clamp,
        prescribed: vec![],
    })
    .unwrap();
    m.set_loads(&Loads {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        point_loads: vec![],
    })
    .unwrap();
    (0..steps)
        .map(|_| {
            m.step(dt).unwrap();
            let x = m.surface().positions;
            tip.iter().map(|&s| x[s as usize].z).sum::<Real>() / tip.len() as Real
        })
        .collect()
}

#[test]
fn split_spring_damping_decays_the_beam_like_the_explicit_damping() {
    // Two implementations of the same spring damping c = β k: kept in the force (explicit,
    // many substeps per 1 ms step) and split off (implicit once per step, along the springs'
    // current directions). At a large sag (11% of the length, so damping along the rest
    // directions would not do: it was 30% off) the tips follow each other to 1% of the sag
    // (measured 0.3% at 1 ms, 0.09% at 0.25 ms) and the first mode's decay rate and
    // frequency agree to 1% (measured 1e-4).
    let beta = 0.004;
    let reference = tip_history(beta, false, 1e-3, 1500);
    let (s0, w0) = decay(&reference, 1e-3, 50);
    assert!(s0 > 0.1, "no decay: σ = {s0}");
    for dt in [1e-3, 2.5e-4] {
        let n = (1.5 / dt) as usize;
        let z = tip_history(beta, true, dt, n);
        let every = (1e-3 / dt) as usize;
        let diff = z
            .iter()
            .skip(every - 1)
            .step_by(every)
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, Real::max);
        let sag = 0.05 - reference[reference.len() - 1];
        assert!(
            diff < 0.01 * sag,
            "dt {dt:e}: the tips differ by up to {diff:.3e} m, sag {sag:.3e} m"
        );
        let (sigma, wd) = decay(&z, dt, n / 30);
        eprintln!(
            "dt {dt:e}: split σ = {sigma:.5}, ω_d = {wd:.4}; explicit σ = {s0:.5}, ω_d = {w0:.4}"
        );
        assert!(
            (sigma / s0 - 1.0).abs() < 0.01 && (wd / w0 - 1.0).abs() < 0.01,
            "dt {dt:e}: split σ = {sigma:.4}, ω_d = {wd:.3}; explicit σ = {s0:.4}, ω_d = {w0:.3}"
        );
    }
}

#[test]
fn split_spring_damping_uses_few_substeps_and_implicit_euler_keeps_it_in_its_solve() {
    // On stiff springs the damping rate β k/m dominates the explicit limit: kept in the
    // force it asks for thousands of substeps; split off, only the elastic limit counts.
    let mesh = box_tets(
        Vec3::ZERO,
        Vec3::new(0.5, 0.1, 0.1),
        [10, 2, 2],
        BoxSplit::Six,
    );
    let mut mat = Material::new(1e8, 0.3).unwrap();
    mat.stiffness_damping = 0.02;
    let mut m = volumetric::build(&mesh, mat, SpringParams::default()).unwrap();
    let split = m.step(1e-3).unwrap().substeps;
    m.body.set_split_damping(false, &[]);
    m.integrator.invalidate();
    let kept = m.step(1e-3).unwrap().substeps;
    assert!(
        split < 100 && kept > 20 * split,
        "substeps: split {split}, kept in the force {kept}"
    );
    m.set_scheme(Scheme::ImplicitEuler);
    assert!(!m.body.split_damping());
    m.set_scheme(Scheme::SymplecticEuler);
    assert!(m.body.split_damping());
}
