//! Steps per second of `fem-corotational` (one core, criterion reports the time per step):
//! - SOFA's liver scene: liver.msh (596 tets, cm → m), E = 3000 Pa, ν = 0.3, density 1 (as in
//!   SOFA's scene), dt = 0.02 s, 25 CG iterations, nodes 3, 39, 64 fixed, gravity.
//! - a clamped box beam of 19 200 tetrahedra (40×8×10 cells, 6-split), 20 CG iterations,
//!   dt = 0.01 s, gravity.
//!
//! Goals: ≥ 1000 steps/s on the liver, ≥ 60 on the beam. Times are the thread's CPU time
//! (`support/cpu_time.rs`), so a busy machine does not inflate them.

use std::hint::black_box;

use criterion::Criterion;

#[path = "support/cpu_time.rs"]
mod cpu_time;
use tissue::Material;
use tissue::math::{Real, Vec3};
use tissue::mesh::TetMesh;
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::model::fem::{CorotationalParams, FemCorotational};

const LIVER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");

fn liver() -> TetMesh {
    let m = tissue::io::read(LIVER)
        .expect("liver.msh loads")
        .tet_mesh("liver.msh")
        .expect("tets");
    TetMesh::new(m.vertices.iter().map(|v| *v * 0.01).collect(), m.tets)
}

fn bench(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let mut group = c.benchmark_group("fem_corotational");
    let g = Vec3::new(0.0, -9.81, 0.0);

    let material = Material::new(3000.0, 0.3)
        .and_then(|m| m.with_density(1.0))
        .expect("material");
    let params = CorotationalParams {
        cg_iterations: 25,
        cg_tolerance: 1e-10,
        ..CorotationalParams::default()
    };
    let mut m = FemCorotational::new(&liver(), material, params).expect("liver model");
    m.set_node_constraints(&[3, 39, 64], &[]).expect("fixed");
    m.set_node_loads(g, &[]).expect("gravity");
    group.bench_function("liver_596_tets_step", |b| {
        b.iter(|| black_box(m.advance(0.02).expect("step")))
    });

    let cells = [40, 8, 10];
    let size = Vec3::new(cells[0] as Real, cells[1] as Real, cells[2] as Real) * 0.01;
    let mesh = box_tets(Vec3::ZERO, size, cells, BoxSplit::Six);
    let clamped: Vec<usize> = (0..mesh.vertices.len())
        .filter(|&i| mesh.vertices[i].x == 0.0)
        .collect();
    let material = Material::new(1.0e5, 0.45).expect("material");
    let params = CorotationalParams {
        cg_iterations: 20,
        cg_tolerance: 1e-10,
        ..CorotationalParams::default()
    };
    let mut m = FemCorotational::new(&mesh, material, params).expect("beam model");
    m.set_node_constraints(&clamped, &[]).expect("clamp");
    m.set_node_loads(g, &[]).expect("gravity");
    group.bench_function(format!("beam_{}_tets_step", mesh.tets.len()), |b| {
        b.iter(|| black_box(m.advance(0.01).expect("step")))
    });
    group.finish();
}

cpu_time::cpu_time_main!(bench);
