//! One incision of the BEM on a 642-vertex sphere (1926 unknowns before the cut): the
//! bordering update (`cut`) against a re-assembly and re-factorisation of the cut surface
//! (`CutUpdate::Reassembly`). Each iteration gets a freshly pre-computed model (not timed).
//! Wall time, not thread CPU time: both updates run their assembly and column solves on the
//! rayon pool, whose threads a thread clock would not count.
//!
//! `cargo bench --offline -p tissue --bench bem_cut -- --warm-up-time 1 --measurement-time 3`

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use tissue::Material;
use tissue::interact::{Constraints, Prescribed};
use tissue::math::Vec3;
use tissue::mesh::generate::icosphere;
use tissue::model::bem::{Bem, BemParams, CutUpdate};
use tissue::model::{CutPath, Deformable};

fn model() -> Bem {
    let sphere = icosphere(Vec3::ZERO, 0.05, 3);
    let material = Material::new(3000.0, 0.3).expect("valid material");
    let mut bem = Bem::new(&sphere, material, BemParams::default()).expect("sphere builds");
    let rest = bem.rest_surface().to_vec();
    let n = rest.len() as u32;
    bem.set_constraints(&Constraints {
        fixed: (0..n).filter(|&v| rest[v as usize].z < -0.045).collect(),
        prescribed: (0..n)
            .filter(|&v| rest[v as usize].x > 0.03 && rest[v as usize].z > 0.03)
            .map(|v| Prescribed {
                vertex: v,
                position: rest[v as usize] - Vec3::Z * 1e-3,
            })
            .collect(),
    })
    .expect("factorises");
    bem
}

fn bench(c: &mut Criterion) {
    let blade = CutPath {
        start: [Vec3::new(-0.03, 0.001, 0.02), Vec3::new(-0.03, 0.001, 0.08)],
        end: [Vec3::new(0.02, 0.001, 0.02), Vec3::new(0.02, 0.001, 0.08)],
    };
    let mut group = c.benchmark_group("bem_cut");
    group.sample_size(10);
    for (name, update) in [
        ("bordering_642", CutUpdate::Bordering),
        ("reassembly_642", CutUpdate::Reassembly),
    ] {
        group.bench_function(name, |b| {
            b.iter_batched(
                model,
                |mut bem| {
                    bem.incise(&blade, update).expect("cuts");
                    bem
                },
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
