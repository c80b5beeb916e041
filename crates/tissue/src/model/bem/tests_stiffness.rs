//! `Deformable::prescribed_stiffness`: the closed form from the capacitance against finite
//! differences of the reactions, for both contact rules.

use super::tests::{material, press, sphere, top};
use super::*;
use crate::math::Vec3;
use crate::math::testing::{central_jacobian, max_entry};
use crate::model::Deformable;
use crate::model::testing::shifted_entries_force;

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
        let fd = central_jacobian(1e-4, |shift| shifted_entries_force(&mut m, &c, 10, shift));
        let gap = max_entry(k - fd) / max_entry(fd);
        eprintln!(
            "rims {}: k = {k:?} N/m, gap to FD {gap:.1e}",
            params.discontinuous_contacts
        );
        assert!(gap <= 1e-8, "{k:?} vs {fd:?}");
        // Pushing in raises the force that pushes back: negative definite, and symmetric
        // to the discretisation's collocation error.
        let sym = (whole + whole.transpose()) * 0.5;
        let asym = max_entry(whole - sym);
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
    let fd = central_jacobian(1e-4, |shift| {
        sim.set_instrument_position(1, Some(second + shift))
            .unwrap();
        sim.step(0.01).unwrap().forces[1]
    });
    let scale = max_entry(fd);
    let gap = max_entry(k - fd) / scale;
    eprintln!("grasper stiffness {k:?} N/m, gap to FD {gap:.1e}");
    assert!(gap <= 1e-8, "{k:?} vs {fd:?}");
    // The first grasper's own stiffness is another block.
    let first = sim.instrument_stiffness(0).unwrap();
    assert!(max_entry(first - k) > 1e-3 * scale);
}
