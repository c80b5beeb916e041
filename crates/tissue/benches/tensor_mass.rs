//! Time per step of `tensor-mass` and `tensor-mass-nonlinear` on one core, for box meshes
//! of about 5k, 20k and 80k tetrahedra (`box_tets`, 5-split, a 10 cm cube), E = 3 kPa,
//! ν = 0.45, mass damping 5/s, symplectic Euler (the default), dt = 1e-4 s, one face
//! clamped, from a stretched start so that every term is non-zero.
//!
//! Non-linear: the element form (`form = "elements"`, the default) and Picinbono's tensor
//! form (`form = "tensors"`). Times are the thread's CPU time (`support/cpu_time.rs`): the
//! machine is shared, and wall time would count the waits for a core.
//!
//! After criterion's groups it prints a table. The models of one size are timed in
//! interleaved rounds (best round kept), so the non-linear / linear ratios compare times
//! taken under the same load. Columns: CPU µs per step, the model's estimate of bytes moved
//! per step (`TensorSystem::step_traffic_bytes`), the bandwidth that implies and its ratio
//! to a STREAM-like copy measured in the same run, and the time ratio to the linear model;
//! plus the hybrid model with about a tenth of the tetrahedra non-linear, and both kinds with
//! a volume penalty (κ = 1 kPa, rows `lin+vp`, `stvk+vp`). Goals: linear
//! ≥ 300 steps/s at 20k tets; non-linear / linear ≤ 3.
//!
//! Run: `cargo bench --offline -p tissue --bench tensor_mass -- --warm-up-time 1 --measurement-time 2`

use std::hint::black_box;
use std::time::Duration;

use criterion::measurement::Measurement;
use criterion::{Criterion, criterion_group, criterion_main};

#[path = "support/cpu_time.rs"]
mod cpu_time;
use cpu_time::ThreadCpuTime;

use tissue::Material;
use tissue::integrate::Scheme;
use tissue::interact::Constraints;
use tissue::math::{Real, Vec3};
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::model::Deformable;
use tissue::model::tensor_mass::{NonlinearForm, TensorMass, TensorMassParams};

const DT: Real = 1e-4;

fn model(cells: usize, nonlinear: bool, params: TensorMassParams) -> TensorMass {
    let mesh = box_tets(Vec3::ZERO, Vec3::splat(0.1), [cells; 3], BoxSplit::Five);
    let mut material = Material::new(3000.0, 0.45).expect("material");
    material.damping = 5.0;
    let mut m = TensorMass::new(&mesh, material, params, nonlinear, Scheme::SymplecticEuler)
        .expect("model");
    // Clamp the x = 0 face; stretch the rest along x, the strain growing as x³ up to 40 %
    // at the far end (the hybrid's non-linear region: the last ~10 %).
    let clamped: Vec<u32> = (0..m.surface().positions.len() as u32)
        .filter(|&s| m.rest_surface()[s as usize].x == 0.0)
        .collect();
    m.set_constraints(&Constraints::fixed(clamped))
        .expect("clamp");
    let x: Vec<Vec3> = m
        .rest_nodes()
        .iter()
        .map(|p| *p + Vec3::new(0.1 * p.x * (p.x / 0.1).powi(3), 0.0, 0.0))
        .collect();
    let v = vec![Vec3::ZERO; x.len()];
    m.set_state(&x, &v).expect("state");
    m
}

/// Bytes/s of a copy of 2 × 64 MiB (read + write counted), best of 5, in CPU time.
fn copy_bandwidth() -> Real {
    let n = 8 << 20;
    let src: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let mut dst = vec![0.0f64; n];
    let mut best = Real::INFINITY;
    for _ in 0..5 {
        let t = ThreadCpuTime.start();
        dst.copy_from_slice(black_box(&src));
        black_box(&mut dst);
        best = best.min(ThreadCpuTime.end(t) as Real * 1e-9);
    }
    (2 * 8 * n) as Real / best
}

/// CPU seconds per step over about `budget` CPU seconds of steps.
fn seconds_per_step(m: &mut TensorMass, budget: Real) -> Real {
    let t = ThreadCpuTime.start();
    let mut k = 0u32;
    loop {
        m.step(DT).expect("step");
        k += 1;
        let used = ThreadCpuTime.end(t) as Real * 1e-9;
        if used >= budget {
            return used / k as Real;
        }
    }
}

const SIZES: [usize; 3] = [10, 16, 25];

/// The models of the table: label, non-linear, settings, and the row it is compared with.
fn kinds() -> [(&'static str, bool, TensorMassParams, usize); 6] {
    let with = |form, volume_penalty| TensorMassParams {
        form,
        volume_penalty,
        ..Default::default()
    };
    [
        ("linear", false, TensorMassParams::default(), 0),
        ("stvk-e", true, with(NonlinearForm::Elements, 0.0), 0),
        ("stvk-t", true, with(NonlinearForm::Tensors, 0.0), 0),
        (
            "hybrid",
            true,
            TensorMassParams {
                strain_threshold: 0.33,
                ..Default::default()
            },
            0,
        ),
        // With the volume penalty (κ = 1 kPa), compared with the linear model with it.
        ("lin+vp", false, with(NonlinearForm::Elements, 1000.0), 4),
        ("stvk+vp", true, with(NonlinearForm::Elements, 1000.0), 4),
    ]
}

fn bench(c: &mut Criterion<ThreadCpuTime>) {
    let mut group = c.benchmark_group("tensor_mass");
    for cells in SIZES {
        for (kind, nonlinear, params, _) in kinds().into_iter().take(3) {
            let name = format!("{}_{}_tets_step", kind.replace('-', "_"), 5 * cells.pow(3));
            // Built on first use: criterion only calls this for the benchmarks its filter
            // keeps (and calls it once per sample, hence the cache).
            let mut m: Option<TensorMass> = None;
            group.bench_function(name, |b| {
                let m = m.get_or_insert_with(|| model(cells, nonlinear, params.clone()));
                b.iter(|| black_box(m.step(DT).expect("step")))
            });
        }
    }
    group.finish();
    // `--profile-time` (perf record on one benchmark): the table would pollute the profile.
    if !std::env::args().any(|a| a == "--profile-time") {
        table();
    }
}

fn table() {
    let bw = copy_bandwidth();
    println!(
        "\nSTREAM-like copy: {:.2} GB/s (one core, CPU time)",
        bw / 1e9
    );
    println!(
        "{:>8} {:>8} {:>12} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "tets", "kind", "cpu µs/step", "steps/s", "kB/step", "GB/s", "of copy", "nl/lin"
    );
    // nl/lin: time over the linear model's (lin+vp's for the rows with the penalty).
    for cells in SIZES {
        let mut models: Vec<(&str, TensorMass, usize)> = kinds()
            .into_iter()
            .map(|(kind, nonlinear, params, of)| (kind, model(cells, nonlinear, params), of))
            .collect();
        for (_, m, _) in &mut models {
            m.step(DT).expect("first step");
        }
        // Interleaved rounds: a burst of load hits every kind alike; keep each one's best.
        let mut best = vec![Real::INFINITY; models.len()];
        for _ in 0..5 {
            for ((_, m, _), b) in models.iter_mut().zip(&mut best) {
                *b = b.min(seconds_per_step(m, 0.15));
            }
        }
        for ((kind, m, of), s) in models.iter().zip(&best) {
            let bytes = m.system().step_traffic_bytes() as Real;
            let label = if *kind == "hybrid" {
                format!(
                    "hyb{:.0}%",
                    100.0 * m.system().nonlinear_count() as Real / m.system().alive_count() as Real
                )
            } else {
                kind.to_string()
            };
            println!(
                "{:>8} {:>8} {:>12.1} {:>10.0} {:>10.0} {:>10.2} {:>10.3} {:>10.2}",
                5 * cells.pow(3),
                label,
                s * 1e6,
                1.0 / s,
                bytes / 1e3,
                bytes / s / 1e9,
                bytes / s / bw,
                s / best[*of]
            );
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .with_measurement(ThreadCpuTime)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .sample_size(20);
    targets = bench
}
criterion_main!(benches);
