//! The run-time costs of the BEM on a 642-vertex sphere (1926 unknowns): a static update
//! with 20 contact vertices, and a contact change of 10 vertices (the Woodbury update in
//! `set_constraints`) followed by the update. Both are O(n·contacts) or less, so the figures
//! scale linearly to the liver. The O(n³) pre-computation on the 2194-vertex liver is
//! measured by the ignored test `liver_smooth_speed` in `tests/bem_validation.rs`.
//!
//! `cargo bench --offline -p tissue --bench bem -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use tissue::Material;
use tissue::interact::{Constraints, Prescribed};
use tissue::math::Vec3;
use tissue::mesh::generate::icosphere;
use tissue::model::Deformable;
use tissue::model::bem::{Bem, BemParams};

/// `count` vertices nearest to the north pole from rank `skip` on, pushed 1 mm down.
fn contacts(rest: &[Vec3], fixed: &[u32], skip: usize, count: usize) -> Constraints {
    let mut order: Vec<u32> = (0..rest.len() as u32).collect();
    order.sort_by(|&a, &b| rest[b as usize].z.total_cmp(&rest[a as usize].z));
    Constraints {
        fixed: fixed.to_vec(),
        prescribed: order[skip..skip + count]
            .iter()
            .map(|&v| Prescribed {
                vertex: v,
                position: rest[v as usize] - Vec3::Z * 1e-3,
            })
            .collect(),
    }
}

fn bench(c: &mut Criterion) {
    let sphere = icosphere(Vec3::ZERO, 0.05, 3);
    let material = Material::new(3000.0, 0.3).expect("valid material");
    let mut bem = Bem::new(&sphere, material, BemParams::default()).expect("sphere builds");
    let rest = bem.rest_surface().to_vec();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z < -0.045)
        .collect();
    let twenty = contacts(&rest, &fixed, 0, 20);
    bem.set_constraints(&twenty).expect("factorises");
    c.bench_function("bem/static_update_20_contacts", |b| {
        b.iter(|| black_box(bem.step(0.01).expect("solves")))
    });
    // Two sets of 10 that share nothing: every iteration changes 10 contact vertices.
    let (a, b) = (
        contacts(&rest, &fixed, 0, 10),
        contacts(&rest, &fixed, 10, 10),
    );
    let mut flip = false;
    c.bench_function("bem/woodbury_change_10_vertices", |bch| {
        bch.iter(|| {
            flip = !flip;
            bem.set_constraints(if flip { &a } else { &b })
                .expect("updates");
        })
    });
    c.bench_function("bem/woodbury_change_10_then_update", |bch| {
        bch.iter(|| {
            flip = !flip;
            bem.set_constraints(if flip { &a } else { &b })
                .expect("updates");
            black_box(bem.step(0.01).expect("solves"))
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
