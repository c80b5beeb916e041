//! The contact update of the pre-computed static models allocates nothing once the largest
//! contact set was seen: counted with a global allocator (this file is its own test binary,
//! with one test, so no other test allocates meanwhile).

mod common;

use tissue::Material;
use tissue::interact::{Constraints, Prescribed};
use tissue::math::Vec3;
use tissue::model::Deformable;
use tissue::model::fem::{FemCondensed, FemPrecomputedTensors};

use common::counting_alloc::{self, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

const LIVER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");

fn contacts(rest: &[Vec3], fixed: &[u32], first: u32, count: usize) -> Constraints {
    let mut c = Constraints::fixed(fixed.to_vec());
    let mut v = first;
    while c.prescribed.len() < count {
        v = (v + 11) % rest.len() as u32;
        if !fixed.contains(&v) && c.prescribed.iter().all(|p| p.vertex != v) {
            c.prescribed.push(Prescribed {
                vertex: v,
                position: rest[v as usize] + Vec3::new(1e-3, 0.0, -2e-3),
            });
        }
    }
    c
}

#[test]
fn contact_updates_allocate_nothing_after_warm_up() {
    let mut mesh = tissue::io::read(LIVER).unwrap().tet_mesh(LIVER).unwrap();
    mesh.vertices.iter_mut().for_each(|v| *v *= 0.01);
    let material = Material::new(3000.0, 0.3).unwrap();
    let fixed = [0u32, 50, 100];
    let condensed = FemCondensed::new(&mesh, material, &fixed).unwrap();
    let tensors = FemPrecomputedTensors::new(&mesh, material, &fixed).unwrap();
    let mut models: [Box<dyn Deformable>; 2] = [Box::new(condensed), Box::new(tensors)];
    for model in &mut models {
        let rest = model.rest_surface().to_vec();
        let sets: Vec<Constraints> = [(1, 20), (2, 10), (3, 1), (4, 15), (5, 0)]
            .iter()
            .map(|&(first, n)| contacts(&rest, &fixed, first, n))
            .collect();
        // Warm-up with the largest set.
        model.set_constraints(&sets[0]).unwrap();
        model.step(0.0).unwrap();
        let before = counting_alloc::allocations();
        for c in sets.iter().cycle().take(20) {
            model.set_constraints(c).unwrap();
            model.step(0.0).unwrap();
        }
        let during = counting_alloc::allocations() - before;
        assert_eq!(during, 0, "{} allocated {during} times", model.kind());
        assert!(model.surface().positions.iter().all(|p| p.is_finite()));
    }
}
