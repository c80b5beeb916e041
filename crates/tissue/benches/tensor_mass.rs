//! Steps per second of `tensor-mass` and `tensor-mass-nonlinear` on one core, for box meshes
//! of about 5k, 20k and 80k tetrahedra (`box_tets`, 5-split, a 10 cm cube), E = 3 kPa,
//! ν = 0.45, mass damping 5/s, symplectic Euler (the default), dt = 1e-4 s, one face
//! clamped, from a stretched start so that every term is non-zero.
//!
//! Non-linear: the tensor form (default) and the element form (`form = "elements"`).
//!
//! After criterion's groups it prints a table: steps/s, the model's estimate of bytes moved
//! per step (`TensorSystem::step_traffic_bytes`), the bandwidth that implies, and its ratio
//! to a STREAM-like copy measured in the same run; plus the hybrid model with about a tenth
//! of the tetrahedra non-linear. Goals: linear ≥ 300 steps/s at 20k tets; non-linear /
//! linear ≤ 3. The machine is shared (2 cores, other jobs): numbers vary by ~10-20 %.
//!
//! Run: `cargo bench --offline -p tissue --bench tensor_mass -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
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

/// Bytes/s of a copy of 2 × 64 MiB (read + write counted), best of 5.
fn copy_bandwidth() -> Real {
    let n = 8 << 20;
    let src: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let mut dst = vec![0.0f64; n];
    let mut best = Real::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        dst.copy_from_slice(black_box(&src));
        black_box(&mut dst);
        best = best.min(t.elapsed().as_secs_f64());
    }
    (2 * 8 * n) as Real / best
}

fn steps_per_second(m: &mut TensorMass) -> Real {
    let t = Instant::now();
    let mut k = 0u32;
    while t.elapsed() < Duration::from_millis(700) {
        m.step(DT).expect("step");
        k += 1;
    }
    k as Real / t.elapsed().as_secs_f64()
}

const SIZES: [usize; 3] = [10, 16, 25];

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("tensor_mass");
    let elements = TensorMassParams {
        form: NonlinearForm::Elements,
        ..Default::default()
    };
    for cells in SIZES {
        for (kind, nonlinear, params) in [
            ("linear", false, TensorMassParams::default()),
            ("stvk_tensors", true, TensorMassParams::default()),
            ("stvk_elements", true, elements.clone()),
        ] {
            let mut m = model(cells, nonlinear, params);
            let name = format!("{kind}_{}_tets_step", 5 * cells * cells * cells);
            group.bench_function(name, |b| b.iter(|| black_box(m.step(DT).expect("step"))));
        }
    }
    group.finish();

    let bw = copy_bandwidth();
    println!("\nSTREAM-like copy: {:.2} GB/s (one core)", bw / 1e9);
    println!(
        "{:>8} {:>8} {:>12} {:>12} {:>12} {:>10} {:>10}",
        "tets", "kind", "steps/s", "kB/step", "GB/s", "of copy", "nl/lin"
    );
    for cells in SIZES {
        let mut lin_rate = 0.0;
        for (kind, nonlinear, params) in [
            ("linear", false, TensorMassParams::default()),
            ("stvk-t", true, TensorMassParams::default()),
            ("stvk-e", true, elements.clone()),
            (
                "hybrid",
                true,
                TensorMassParams {
                    strain_threshold: 0.33,
                    ..Default::default()
                },
            ),
        ] {
            let mut m = model(cells, nonlinear, params);
            m.step(DT).expect("first step");
            let rate = steps_per_second(&mut m);
            let bytes = m.system().step_traffic_bytes() as Real;
            if !nonlinear {
                lin_rate = rate;
            }
            let label = if kind == "hybrid" {
                format!(
                    "hyb{:.0}%",
                    100.0 * m.system().nonlinear_count() as Real / m.system().alive_count() as Real
                )
            } else {
                kind.to_string()
            };
            println!(
                "{:>8} {:>8} {:>12.0} {:>12.0} {:>12.2} {:>10.3} {:>10.2}",
                5 * cells * cells * cells,
                label,
                rate,
                bytes / 1e3,
                bytes * rate / 1e9,
                bytes * rate / bw,
                lin_rate / rate
            );
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        .sample_size(20);
    targets = bench
}
criterion_main!(benches);
