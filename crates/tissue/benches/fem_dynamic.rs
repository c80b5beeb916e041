//! Steps per second of `fem-explicit` and `fem-semi-implicit` on the liver (596 tets, held at
//! its three ligament nodes, under gravity) and on a clamped box beam of 20 000 tets
//! (40×10×10 cells, 5-split). The semi-implicit factorisation happens before timing.

use std::hint::black_box;

use criterion::Criterion;

#[path = "support/cpu_time.rs"]
mod cpu_time;
use tissue::Material;
use tissue::interact::{Constraints, Loads};
use tissue::math::{Real, Vec3};
use tissue::mesh::TetMesh;
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::model::Deformable;
use tissue::model::fem::{FemExplicit, FemSemiImplicit};

const LIVER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");

fn liver() -> (TetMesh, Vec<u32>) {
    let data = tissue::io::read(LIVER).expect("liver.msh loads");
    let mut mesh = data.tet_mesh("liver.msh").expect("has tets");
    mesh.vertices.iter_mut().for_each(|v| *v *= 0.01);
    (mesh, vec![3, 39, 64])
}

fn beam() -> (TetMesh, Vec<u32>) {
    let mesh = box_tets(
        Vec3::ZERO,
        Vec3::new(1.0, 0.25, 0.25),
        [40, 10, 10],
        BoxSplit::Five,
    );
    (mesh, Vec::new())
}

/// Fixed surface vertices: those on mechanical nodes `nodes`, or the face x = 0 if empty.
fn constraints(model: &dyn Deformable, nodes: &[u32], surface_nodes: &[u32]) -> Constraints {
    let rest = model.rest_surface();
    let fixed = (0..rest.len() as u32)
        .filter(|&v| {
            if nodes.is_empty() {
                rest[v as usize].x == 0.0
            } else {
                nodes.contains(&surface_nodes[v as usize])
            }
        })
        .collect();
    Constraints::fixed(fixed)
}

fn prepare(model: &mut dyn Deformable, nodes: &[u32], surface_nodes: &[u32]) {
    let c = constraints(model, nodes, surface_nodes);
    model.set_constraints(&c).expect("constraints");
    model
        .set_loads(&Loads {
            gravity: Vec3::new(0.0, -9.81, 0.0),
            point_loads: Vec::new(),
        })
        .expect("loads");
}

fn bench(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let mut material = Material::new(3000.0, 0.3).expect("valid material");
    material.damping = 20.0;
    let mut group = c.benchmark_group("fem_dynamic");
    group.sample_size(20);
    for (name, (mesh, nodes)) in [("liver", liver()), ("beam20k", beam())] {
        let mut ex = FemExplicit::new(&mesh, material).expect("model");
        let sn = ex.surface_nodes().to_vec();
        prepare(&mut ex, &nodes, &sn);
        let dt: Real = 0.9 * ex.critical_dt_bound();
        group.bench_function(format!("explicit/{name}"), |b| {
            b.iter(|| black_box(ex.step(dt).expect("stable step")))
        });
        let mut si = FemSemiImplicit::new(&mesh, material).expect("model");
        prepare(&mut si, &nodes, &sn);
        let dt = 0.01;
        si.step(dt).expect("first step factorises");
        group.bench_function(format!("semi_implicit/{name}"), |b| {
            b.iter(|| black_box(si.step(dt).expect("step")))
        });
    }
    group.finish();
}

cpu_time::cpu_time_main!(bench);
