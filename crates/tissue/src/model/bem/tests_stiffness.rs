//! `Deformable::prescribed_stiffness`: the closed form from the capacitance against finite
//! differences of the reactions, for both contact rules.

use super::tests::{material, press, sphere, top};
use super::*;
use crate::math::{Mat3, Real, Vec3};
use crate::model::Deformable;

/// The summed reactions of `entries` after a step with their targets moved by `shift`.
fn force(m: &mut Bem, c: &crate::interact::Constraints, entries: usize, shift: Vec3) -> Vec3 {
    let mut moved = c.clone();
    for p in &mut moved.prescribed[..entries] {
        p.position += shift;
    }
    m.set_constraints(&moved).unwrap();
    m.step(0.01).unwrap();
    m.reactions().prescribed[..entries].iter().copied().sum()
}

#[test]
fn prescribed_stiffness_equals_finite_differences_of_the_reactions() {
    let s = sphere(2);
    let rest = s.vertices.clone();
    let top = top(&rest);
    // Two instruments: entries 0..10 and 10..16; a vertex given twice belongs to its last
    // entry, so the repeat at the end takes vertex top[3] from the first instrument.
    let mut c = press(&rest, -0.03, &top[..16]);
    let mut repeat = c.prescribed[3];
    repeat.position += Vec3::new(0.0, 0.0, -1e-4);
    c.prescribed.push(repeat);
    for params in [BemParams::default(), BemParams::continuous()] {
        let mut m = Bem::new(&s, material(), params).unwrap();
        m.set_constraints(&c).unwrap();
        m.step(0.01).unwrap();
        let k = m.prescribed_stiffness(0..10).unwrap();
        let whole = m.prescribed_stiffness(0..c.prescribed.len()).unwrap();
        assert!(m.prescribed_stiffness(0..0).is_none());
        assert!(m.prescribed_stiffness(0..100).is_none());
        // Linear in the targets: central differences are exact up to rounding.
        let h = 1e-4;
        let f0 = force(&mut m, &c, 10, Vec3::ZERO);
        let mut columns = [Vec3::ZERO; 3];
        for (j, column) in columns.iter_mut().enumerate() {
            let e = Vec3::AXES[j] * h;
            *column = (force(&mut m, &c, 10, e) - force(&mut m, &c, 10, -e)) / (2.0 * h);
        }
        let fd = Mat3::from_cols(columns[0], columns[1], columns[2]);
        let scale = fd
            .to_cols_array()
            .iter()
            .fold(0.0, |a: Real, b| a.max(b.abs()));
        let gap = (k - fd)
            .to_cols_array()
            .iter()
            .fold(0.0, |a: Real, b| a.max(b.abs()));
        eprintln!(
            "rims {}: k = {k:?} N/m, gap to FD {:.1e}, force {f0}",
            params.discontinuous_contacts,
            gap / scale
        );
        assert!(gap <= 1e-8 * scale, "{k:?} vs {fd:?}");
        // Pushing in raises the force that pushes back: negative definite, and symmetric
        // to the discretisation's collocation error.
        let sym = (whole + whole.transpose()) * 0.5;
        let asym = (whole - sym)
            .to_cols_array()
            .iter()
            .fold(0.0, |a: Real, b| a.max(b.abs()));
        assert!(sym.z_axis.z < 0.0 && sym.determinant() < 0.0, "{whole:?}");
        for v in [Vec3::X, Vec3::Y, Vec3::Z, Vec3::new(1.0, -2.0, 0.5)] {
            assert!(v.dot(sym * v) < 0.0, "{whole:?}");
        }
        assert!(asym < 0.05 * sym.z_axis.z.abs(), "{whole:?}");
    }
}

#[test]
fn instrument_stiffness_predicts_the_force_of_a_moved_grasper() {
    use crate::interact::instrument::{Instrument, InstrumentKind};
    use crate::interact::trajectory::Trajectory;
    use crate::interact::{Constraints, Loads};
    use crate::sim::Simulation;

    // Two graspers on a sphere held below its equator: the second one's entries come after
    // the first's, so its stiffness is read from the right range.
    let s = sphere(2);
    let fixed = Constraints::fixed(
        (0..s.vertices.len() as u32)
            .filter(|&v| s.vertices[v as usize].z < -0.03)
            .collect(),
    );
    let model = Bem::new(&s, material(), BemParams::default()).unwrap();
    let mut sim = Simulation::new(Box::new(model), fixed.fixed, Loads::default()).unwrap();
    let grasp = InstrumentKind::Grasper {
        grasp_at: 0.0,
        release_at: None,
    };
    for at in [Vec3::new(0.0, 0.0, 0.05), Vec3::new(0.05, 0.0, 0.0)] {
        let tool = Instrument::new("grasper", grasp.clone(), 0.02, Trajectory::fixed(at));
        sim.add_instrument(tool.unwrap());
    }
    let report = sim.step(0.01).unwrap();
    assert!(
        report.contacts.iter().all(|&n| n >= 3),
        "{:?}",
        report.contacts
    );
    assert!(sim.instrument_stiffness(2).is_none());
    let second = Vec3::new(0.05, 0.0, 0.0);
    let k = sim.instrument_stiffness(1).unwrap();
    let h = 1e-4;
    let mut columns = [Vec3::ZERO; 3];
    for (j, column) in columns.iter_mut().enumerate() {
        let mut at = |x: Vec3| {
            sim.set_instrument_position(1, Some(x)).unwrap();
            sim.step(0.01).unwrap().forces[1]
        };
        let e = Vec3::AXES[j] * h;
        *column = (at(second + e) - at(second - e)) / (2.0 * h);
    }
    let fd = Mat3::from_cols(columns[0], columns[1], columns[2]);
    let scale = fd
        .to_cols_array()
        .iter()
        .fold(0.0, |a: Real, b| a.max(b.abs()));
    let gap = (k - fd)
        .to_cols_array()
        .iter()
        .fold(0.0, |a: Real, b| a.max(b.abs()));
    eprintln!("grasper stiffness {k:?} N/m, gap to FD {:.1e}", gap / scale);
    assert!(gap <= 1e-8 * scale, "{k:?} vs {fd:?}");
    // The first grasper's own stiffness is another block.
    let first = sim.instrument_stiffness(0).unwrap();
    assert!(
        (first - k)
            .to_cols_array()
            .iter()
            .any(|d| d.abs() > 1e-3 * scale)
    );
}
