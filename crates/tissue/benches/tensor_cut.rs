//! CPU time of one cut of `tensor-mass` on box meshes of 20 480 and 78 125 tetrahedra
//! (`box_tets`, 5-split, a 10 cm cube of 16³ and 25³ cells), at rest: the same blade
//! relative to the cells (a 2.4 × 2.4-cell rectangle across the middle of a slab of cells,
//! inside the cube), so the region a cut touches is the same size in both meshes. If a cut
//! costs what it touches, the two times are about equal; before this bench's change the
//! blade search and the fragment search visited every tetrahedron.
//!
//! Each timed iteration cuts at a fresh place; when the places run out the model is reset
//! (not timed). Timed: everything `cut` does (the grid's scan of moved nodes, candidates,
//! exact tests, removal with tensor, mass and surface updates, the sliver guard, the
//! fragment search). The grid is built before timing (`prepare_cutting`).
//!
//! Thread CPU time (`support/cpu_time.rs`): the 2-core machine is shared.
//! Run: `cargo bench --offline -p tissue --bench tensor_cut -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::measurement::Measurement;
use criterion::{Criterion, criterion_group, criterion_main};
use tissue::Material;
use tissue::integrate::Scheme;
use tissue::math::{Real, Vec3};
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::model::tensor_mass::{TensorMass, TensorMassParams};
use tissue::model::{CutPath, Deformable};

#[path = "support/cpu_time.rs"]
mod cpu_time;

const SIZE: Real = 0.1;

fn model(cells: usize) -> TensorMass {
    let mesh = box_tets(Vec3::ZERO, Vec3::splat(SIZE), [cells; 3], BoxSplit::Five);
    let mut material = Material::new(3000.0, 0.45).expect("material");
    material.damping = 5.0;
    let mut m = TensorMass::new(
        &mesh,
        material,
        TensorMassParams::default(),
        false,
        Scheme::SymplecticEuler,
    )
    .expect("model");
    m.prepare_cutting();
    m
}

/// Fresh blade places: slabs 2, 5, 8, ... and windows 4 cells apart, all inside the cube.
fn blades(cells: usize) -> Vec<CutPath> {
    let h = SIZE / cells as Real;
    let mut out = Vec::new();
    for i in (2..cells - 2).step_by(3) {
        for j in (1..cells - 4).step_by(4) {
            for k in (1..cells - 4).step_by(4) {
                let x = (i as Real + 0.5) * h;
                let (y0, z0) = ((j as Real + 0.3) * h, (k as Real + 0.3) * h);
                let (y1, z1) = (y0 + 2.4 * h, z0 + 2.4 * h);
                out.push(CutPath {
                    start: [Vec3::new(x, y0, z0), Vec3::new(x, y1, z0)],
                    end: [Vec3::new(x, y0, z1), Vec3::new(x, y1, z1)],
                });
            }
        }
    }
    out
}

fn bench(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let mut group = c.benchmark_group("tensor_cut");
    let mut table = Vec::new();
    for cells in [16, 25] {
        let t = Instant::now();
        let mut m = model(cells);
        let build = t.elapsed().as_secs_f64();
        let places = blades(cells);
        let tets = 5 * cells * cells * cells;
        // One pass for the counts.
        let (mut cut, mut examined, mut searched) = (0, 0, 0);
        for b in &places {
            m.cut(b).expect("cut");
            let r = m.last_cut();
            cut += r.cut_tets + r.sliver_tets;
            examined += r.examined;
            searched += r.searched;
        }
        let n = places.len();
        table.push((tets, n, build, cut / n, examined / n, searched / n));
        m.reset();
        m.prepare_cutting();
        let mut next = 0;
        group.bench_function(format!("one_cut_{tets}_tets"), |b| {
            b.iter_custom(|iters| {
                let clock = cpu_time::ThreadCpuTime;
                let mut total = 0;
                for _ in 0..iters {
                    if next == places.len() {
                        m.reset();
                        m.prepare_cutting();
                        next = 0;
                    }
                    let start = clock.start();
                    black_box(m.cut(&places[next]).expect("cut"));
                    total += clock.end(start);
                    next += 1;
                }
                total
            })
        });
    }
    group.finish();
    println!(
        "\n{:>8} {:>7} {:>12} {:>10} {:>10} {:>10}",
        "tets", "places", "build s", "cut/place", "examined", "searched"
    );
    for (tets, n, build, cut, examined, searched) in table {
        println!("{tets:>8} {n:>7} {build:>12.3} {cut:>10} {examined:>10} {searched:>10}");
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .with_measurement(cpu_time::ThreadCpuTime)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .sample_size(20);
    targets = bench
}
criterion_main!(benches);
