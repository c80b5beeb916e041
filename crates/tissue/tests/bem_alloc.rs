//! `Bem::set_constraints` with the same vertices as the last call (only the targets move, as
//! under a probe held in place) and `step` allocate nothing, with either contact rule: counted
//! with a global allocator (this file is its own test binary, with one test, so no other test
//! allocates meanwhile).

mod common;

use tissue::Material;
use tissue::interact::{Constraints, Prescribed};
use tissue::math::Vec3;
use tissue::mesh::generate::icosphere;
use tissue::model::Deformable;
use tissue::model::bem::{Bem, BemParams};

use common::counting_alloc::{self, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn moving_targets_allocate_nothing() {
    let s = icosphere(Vec3::ZERO, 0.05, 2);
    let material = Material::new(3000.0, 0.3).unwrap();
    for discontinuous_contacts in [false, true] {
        let params = BemParams {
            discontinuous_contacts,
            ..BemParams::default()
        };
        let mut m = Bem::new(&s, material, params).unwrap();
        let rest = m.rest_surface().to_vec();
        let fixed: Vec<u32> = (0..rest.len() as u32)
            .filter(|&v| rest[v as usize].z < -0.04)
            .collect();
        // A patch around the north pole, one vertex listed twice (the last entry counts)
        // and one fixed vertex also prescribed (fixed wins).
        let mut patch: Vec<u32> = (0..rest.len() as u32)
            .filter(|&v| rest[v as usize].z > 0.04)
            .collect();
        patch.push(patch[0]);
        patch.push(fixed[0]);
        let at = |depth: f64| Constraints {
            fixed: fixed.clone(),
            prescribed: patch
                .iter()
                .map(|&v| Prescribed {
                    vertex: v,
                    position: rest[v as usize] - Vec3::Z * depth,
                })
                .collect(),
        };
        let frames: Vec<Constraints> = (0..20).map(|k| at(1e-4 * (k + 1) as f64)).collect();
        m.set_constraints(&frames[0]).unwrap();
        m.step(0.01).unwrap();
        let mut allocations = 0;
        for c in &frames {
            let before = counting_alloc::allocations();
            m.set_constraints(c).unwrap();
            m.step(0.01).unwrap();
            allocations += counting_alloc::allocations() - before;
        }
        assert_eq!(
            allocations, 0,
            "discontinuous_contacts = {discontinuous_contacts}: {allocations} allocations"
        );
        // The last frame's depth reached the probe: linear in the push.
        let force: Vec3 = m.reactions().prescribed.iter().copied().sum();
        m.set_constraints(&frames[0]).unwrap();
        m.step(0.01).unwrap();
        let first: Vec3 = m.reactions().prescribed.iter().copied().sum();
        assert!(
            (force - first * 20.0).length() < 1e-9 * force.length(),
            "{force} vs 20 x {first}"
        );
        assert!(force.z > 0.0, "{force}");
    }
}
