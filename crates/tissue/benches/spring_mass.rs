//! Steps per second of the spring-mass kinds (one core; criterion reports the time per step):
//! - `spring-mass` on liver-smooth.obj (2194 vertices, 4384 triangles, 6576 springs; cm → m),
//!   E = 3 kPa, ν = 0.3, thickness 5 mm, pressure on, three vertices fixed, gravity,
//!   friction 20/s, dt = 1e-5 s (below every explicit limit), with each integrator (implicit
//!   Euler: 20 CG iterations at most);
//! - `volumetric-spring-mass` on a box of 19 200 tetrahedra (40×8×10 cells, 6-split),
//!   E = 100 kPa, symplectic Euler, dt = 1e-5 s, one end clamped, gravity.
//!
//! Goal: ≥ 5000 steps/s on the liver surface with symplectic Euler.
//! `cargo bench --offline -p tissue --bench spring_mass -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use tissue::integrate::Scheme;
use tissue::interact::{Constraints, Loads};
use tissue::material::Material;
use tissue::math::{Real, Vec3};
use tissue::mesh::MeshData;
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::model::spring_mass::{Kind, SpringModel};
use tissue::model::{BuildInput, Deformable};

const LIVER_SMOOTH: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../assets/meshes/liver-smooth.obj"
);

fn build(kind: Kind, mesh: &MeshData, e: Real, table: &str) -> SpringModel {
    let params: toml::Table = toml::from_str(table).expect("toml");
    let input = BuildInput {
        mesh,
        source: "bench",
        material: Material {
            damping: 20.0,
            ..Material::new(e, 0.3).expect("material")
        },
        params: &params,
        regions: &[],
    };
    SpringModel::from_input(kind, &input).expect("model")
}

fn gravity() -> Loads {
    Loads {
        gravity: Vec3::new(0.0, -9.81, 0.0),
        point_loads: vec![],
    }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("spring_mass");
    let mut liver = tissue::io::read(LIVER_SMOOTH).expect("liver-smooth.obj");
    liver.vertices.iter_mut().for_each(|v| *v *= 0.01);
    for scheme in Scheme::ALL {
        let table = format!("integrator = \"{scheme}\"\npressure = true\ncg_iterations = 20\n");
        let mut m = build(Kind::Surface, &liver, 3000.0, &table);
        m.set_constraints(&Constraints::fixed(vec![0, 700, 1400]))
            .expect("fixed");
        m.set_loads(&gravity()).expect("gravity");
        group.bench_function(format!("liver_smooth_4384_tris_{scheme}"), |b| {
            // Explicit Euler drifts even when damped: start over if the guard refuses a step.
            b.iter(|| {
                if m.step(1e-5).is_err() {
                    m.reset();
                }
                black_box(m.surface().positions[0])
            })
        });
    }

    let cells = [40, 8, 10];
    let size = Vec3::new(cells[0] as Real, cells[1] as Real, cells[2] as Real) * 0.01;
    let mesh = box_tets(Vec3::ZERO, size, cells, BoxSplit::Six);
    let data = MeshData::from_tets(&mesh);
    let mut m = build(Kind::Volumetric, &data, 1.0e5, "");
    let rest = m.rest_surface().to_vec();
    let clamped = (0..rest.len() as u32)
        .filter(|&i| rest[i as usize].x == 0.0)
        .collect();
    m.set_constraints(&Constraints::fixed(clamped))
        .expect("clamp");
    m.set_loads(&gravity()).expect("gravity");
    group.bench_function(
        format!("box_{}_tets_symplectic-euler", mesh.tets.len()),
        |b| b.iter(|| black_box(m.step(1e-5).expect("step"))),
    );
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
