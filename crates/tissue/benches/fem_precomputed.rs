//! One contact update (new constraints with 10 contact vertices, then the solve) on the
//! liver for the pre-computed static models, and the same update with `fem-static`, which
//! must refactorise its sparse matrix for every new contact set. Two contact sets alternate
//! so that every iteration is a change of the contact set.

use std::hint::black_box;

use criterion::Criterion;

#[path = "support/cpu_time.rs"]
mod cpu_time;
use tissue::Material;
use tissue::interact::{Constraints, Prescribed};
use tissue::math::Vec3;
use tissue::mesh::TetMesh;
use tissue::model::Deformable;
use tissue::model::fem::{FemCondensed, FemPrecomputedTensors, FemStatic, Order};

const LIVER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");

fn liver() -> TetMesh {
    let mut m = tissue::io::read(LIVER)
        .expect("liver.msh loads")
        .tet_mesh(LIVER)
        .expect("liver has tets");
    m.vertices.iter_mut().for_each(|v| *v *= 0.01);
    m
}

/// Surface vertices nearest to file vertices 3, 39, 64 (the ligaments).
fn fixed(fem: &FemStatic) -> Vec<u32> {
    let (nodes, rest) = (fem.surface_nodes(), fem.rest_nodes());
    [3usize, 39, 64]
        .iter()
        .filter_map(|&v| {
            (0..nodes.len() as u32).min_by(|&a, &b| {
                let d = |s: u32| (rest[nodes[s as usize] as usize] - rest[v]).length();
                d(a).total_cmp(&d(b))
            })
        })
        .collect()
}

/// Ten contact vertices starting at `first`, every 7th surface vertex, pushed 2 mm down.
fn contacts(rest: &[Vec3], fixed: &[u32], first: u32) -> Constraints {
    let mut c = Constraints::fixed(fixed.to_vec());
    let mut v = first;
    while c.prescribed.len() < 10 {
        v = (v + 7) % rest.len() as u32;
        if !fixed.contains(&v) && c.prescribed.iter().all(|p| p.vertex != v) {
            c.prescribed.push(Prescribed {
                vertex: v,
                position: rest[v as usize] + Vec3::new(0.0, 0.0, -2e-3),
            });
        }
    }
    c
}

fn update(model: &mut dyn Deformable, sets: &[Constraints; 2], i: &mut usize) {
    *i += 1;
    model
        .set_constraints(&sets[*i % 2])
        .expect("valid constraints");
    model.step(0.0).expect("solves");
    black_box(model.surface().positions[0]);
}

fn bench(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let mesh = liver();
    let material = Material::new(3000.0, 0.3).expect("valid material");
    let mut reference = FemStatic::new(&mesh, material, Order::Linear).expect("builds");
    let fixed = fixed(&reference);
    let rest = reference.rest_surface().to_vec();
    let sets = [contacts(&rest, &fixed, 1), contacts(&rest, &fixed, 4)];
    let mut condensed = FemCondensed::new(&mesh, material, &fixed).expect("builds");
    let mut tensors = FemPrecomputedTensors::new(&mesh, material, &fixed).expect("builds");
    let mut group = c.benchmark_group("liver_contact_update_10");
    let mut i = 0;
    group.bench_function("fem-condensed", |b| {
        b.iter(|| update(&mut condensed, &sets, &mut i))
    });
    group.bench_function("fem-precomputed-tensors", |b| {
        b.iter(|| update(&mut tensors, &sets, &mut i))
    });
    group.bench_function("fem-static (refactorise + solve)", |b| {
        b.iter(|| update(&mut reference, &sets, &mut i))
    });
    group.finish();
}

cpu_time::cpu_time_main!(bench);
