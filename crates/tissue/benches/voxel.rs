//! Voxel models: a ChainMail probe move on a 1,000,000-voxel lattice (the target: a
//! move displacing up to 10,000 elements propagates in under 1 ms on one core), and
//! linked-volumes steps at 100,000 voxels with 26-neighbour springs.
//!
//! Run: `cargo bench --offline -p tissue --bench voxel -- --warm-up-time 1 --measurement-time 3`
//! Times are the benchmark thread's CPU time (`support/cpu_time.rs`).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use tissue::integrate::Scheme;
use tissue::material::Material;
use tissue::math::Vec3;
use tissue::model::Deformable;
use tissue::model::chainmail::{ChainMailParams, Lattice};
use tissue::model::linked_volumes::{LinkedVolumes, LinkedVolumesParams};
use tissue::voxel::VoxelGrid;

#[path = "support/cpu_time.rs"]
mod cpu_time;

fn chainmail(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let mut group = c.benchmark_group("chainmail");
    let h = 0.001;
    let grid = VoxelGrid::filled([100, 100, 100], h);
    let mut lattice = Lattice::new(&grid, &[ChainMailParams::default().limits(); 2]);
    // The centre of the top face, pushed down by 2.4 voxels: the wave displaces an
    // octahedral half-ball of about 10,000 elements (printed below).
    let probe = grid.index(50, 50, 99).expect("in the grid") as u32;
    let target = lattice.rest[probe as usize] - Vec3::Z * 2.4 * h;
    let p = lattice.move_elements(&[(probe, target)]);
    eprintln!(
        "chainmail 1M: a 2.4-voxel probe move displaces {} elements ({} link checks, converged {})",
        p.moved, p.checks, p.converged
    );
    lattice.unpin(&[probe]);
    lattice.reset();
    group.bench_function("probe_move_1M_voxels_propagate_and_reset", |b| {
        b.iter(|| {
            let p = lattice.move_elements(&[(probe, target)]);
            lattice.unpin(&[probe]);
            lattice.reset();
            black_box(p)
        })
    });
    group.finish();
}

/// A scalpel sweep of one voxel across a 1,000,000-voxel block, alternating between two
/// parallel planes so that every sweep cuts new links: the cost of an edit, dominated by
/// redrawing the voxel boundary (`voxel::boundary::redraw`).
fn chainmail_cut(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let mut group = c.benchmark_group("chainmail");
    group.sample_size(10);
    let h = 0.001;
    let grid = VoxelGrid::filled([100, 100, 100], h);
    let mut m = tissue::model::chainmail::ChainMail::new(
        grid,
        None,
        Material::new(3000.0, 0.3).expect("material"),
        ChainMailParams::default(),
    )
    .expect("model");
    eprintln!(
        "chainmail 1M: {} drawn vertices, {} triangles",
        m.surface().positions.len(),
        m.surface().triangles.len()
    );
    let top = 0.1;
    let mut k = 0usize;
    group.bench_function("cut_sweep_1M_voxels", |b| {
        b.iter(|| {
            // Planes x = const between voxel centres, 1 voxel long each, marching in y.
            let x = (10.5 + (k % 80) as f64) * h;
            let y = ((k / 80) % 90) as f64 * h + 0.0055;
            k += 1;
            let blade = tissue::model::CutPath {
                start: [Vec3::new(x, y, top), Vec3::new(x, y, top - 0.01)],
                end: [Vec3::new(x, y + h, top), Vec3::new(x, y + h, top - 0.01)],
            };
            black_box(m.cut(&blade).expect("cut"))
        })
    });
    group.finish();
}

/// The smooth liver at 96 voxels along its longest side (0.67 mm voxels, about 130,000
/// of them), cut by a scalpel 2 cm deep moving 2 mm per frame (12 cm/s at 60 Hz): one
/// sample is a stroke of `FRAMES` frames across the top, on a copy of a liver that had one
/// earlier cut elsewhere (so every frame is a redraw near an edit, not the first drawing).
/// Per frame: the time / `FRAMES`.
fn chainmail_liver_cut(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    const FRAMES: usize = 10;
    let mut group = c.benchmark_group("chainmail");
    group.sample_size(10);
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/meshes/liver-smooth.obj"
    );
    let mut surface = tissue::io::read(path)
        .expect("liver")
        .surface_mesh()
        .expect("surface");
    surface.vertices.iter_mut().for_each(|p| *p *= 0.01);
    let params = ChainMailParams {
        resolution: 96,
        ..ChainMailParams::default()
    };
    let grid = tissue::voxel::voxelize_to(&surface, None, params.resolution).expect("voxels");
    let material = Material::new(3000.0, 0.3).expect("material");
    let mut base = tissue::model::chainmail::ChainMail::new(grid, Some(surface), material, params)
        .expect("model");
    let (lo, hi) = base.rest_surface().iter().fold(
        (Vec3::splat(f64::MAX), Vec3::splat(f64::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let (top, bottom) = (hi.y + 0.005, hi.y - 0.02);
    let blade = |x: f64, z: f64, dx: f64| tissue::model::CutPath {
        start: [Vec3::new(x, top, z), Vec3::new(x, bottom, z)],
        end: [Vec3::new(x + dx, top, z), Vec3::new(x + dx, bottom, z)],
    };
    let earlier = base.cut(&blade(lo.x + 0.005, lo.z + 0.8 * (hi.z - lo.z), 0.004));
    eprintln!(
        "chainmail liver: {} elements; an earlier cut removed {} links",
        base.info().nodes,
        earlier.expect("cut").removed_elements
    );
    let mut stroke = 0usize;
    group.bench_function("cut_stroke_10_frames_liver_96", |b| {
        b.iter_batched_ref(
            || base.clone(),
            |m| {
                // Strokes at different z, each from 30% of x on, 2 mm a frame.
                let z = lo.z + (0.25 + 0.05 * (stroke % 8) as f64) * (hi.z - lo.z);
                stroke += 1;
                let x0 = lo.x + 0.3 * (hi.x - lo.x);
                for f in 0..FRAMES {
                    let x = x0 + 0.002 * f as f64;
                    black_box(m.cut(&blade(x, z, 0.002)).expect("cut"));
                }
            },
            criterion::BatchSize::PerIteration,
        )
    });
    group.finish();
}

/// A one-voxel scalpel sweep on linked volumes (26 neighbours, 100,000 voxels): besides the
/// redraw near the edit, a cut edits the springs and rebuilds the volume term's stencils.
fn linked_volumes_cut(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let mut group = c.benchmark_group("linked_volumes");
    group.sample_size(10);
    let h = 0.002;
    let params = LinkedVolumesParams {
        neighbours: 26,
        ..Default::default()
    };
    let grid = VoxelGrid::filled([50, 50, 40], h);
    let material = Material::new(3000.0, 0.3).expect("material");
    let mut m = LinkedVolumes::new(grid, None, material, params).expect("model");
    let top = 40.0 * h;
    let mut k = 0usize;
    group.bench_function("cut_sweep_100k_voxels_26", |b| {
        b.iter(|| {
            let x = (5.5 + (k % 40) as f64) * h;
            let y = ((k / 40) % 45) as f64 * h + 0.5 * h;
            k += 1;
            let blade = tissue::model::CutPath {
                start: [Vec3::new(x, y, top), Vec3::new(x, y, top - 5.0 * h)],
                end: [Vec3::new(x, y + h, top), Vec3::new(x, y + h, top - 5.0 * h)],
            };
            black_box(m.cut(&blade).expect("cut"))
        })
    });
    group.finish();
}

fn linked_volumes(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let mut group = c.benchmark_group("linked_volumes");
    group.sample_size(10);
    let material = Material::new(3000.0, 0.3).expect("material");
    // Implicit Euler (CG) on a 27,000-voxel lattice keeps the bench short; at 100k voxels
    // it took 237 ms per step (closing note of issue 7).
    let runs = [
        (Scheme::SymplecticEuler, 1e-4, [50, 50, 40]),
        (Scheme::ImplicitEuler, 1e-2, [30, 30, 30]),
    ];
    for (scheme, dt, dims) in runs {
        let params = LinkedVolumesParams {
            neighbours: 26,
            integrator: scheme,
            ..Default::default()
        };
        let grid = VoxelGrid::filled(dims, 0.002);
        let mut m = LinkedVolumes::new(grid, None, material, params).expect("model");
        m.set_loads(&tissue::interact::Loads {
            gravity: Vec3::new(0.0, 0.0, -9.81),
            point_loads: Vec::new(),
        })
        .expect("gravity");
        let info = m.info();
        eprintln!(
            "linked-volumes {scheme}: {} voxels, {} springs",
            info.nodes, info.elements
        );
        let name = format!("step_{}_voxels_26_{scheme}", info.nodes);
        group.bench_function(name, |b| b.iter(|| black_box(m.step(dt).expect("step"))));
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().with_measurement(cpu_time::ThreadCpuTime);
    targets = chainmail, chainmail_cut, chainmail_liver_cut, linked_volumes_cut, linked_volumes
}
criterion_main!(benches);
