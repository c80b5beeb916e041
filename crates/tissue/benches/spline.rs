//! Speed of the `spline` model (one core; criterion reports thread CPU time per iteration):
//! - one step of a tube of 32 × 64 control points (r = 1 cm, length 10 cm, h = 1 mm,
//!   E = 50 kPa, ν = 0.45, ρ = 1000, α = 10/s, ends clamped, started squeezed 2%) with each shared
//!   integrator: explicit schemes at dt = 5e-5 s (below their stability limit), implicit
//!   Euler at dt = 1e-3 s with 25 CG iterations;
//! - one tessellation of that tube at the rendering resolution (3 segments per knot span:
//!   96 × 184 = 17 664 vertices).
//!
//! Run: `cargo bench --offline -p tissue --bench spline -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::Criterion;
use tissue::Material;
use tissue::integrate::Scheme;
use tissue::math::Vec3;
use tissue::model::Deformable;
use tissue::model::spline::{SplineModel, SplineParams, SplineSurface, Tessellation};

#[path = "support/cpu_time.rs"]
mod cpu_time;

fn tube_model(scheme: Scheme) -> SplineModel {
    let mut material = Material::new(5.0e4, 0.45).expect("material");
    material.damping = 10.0;
    let params = SplineParams {
        integrator: scheme,
        clamp_ends: true,
        cg_iterations: Some(25),
        ..SplineParams::default()
    };
    let rest = SplineSurface::tube(0.01, 0.1, 32, 64).expect("tube");
    let mut m = SplineModel::new(rest, material, params).expect("model");
    // Start squeezed 2% into an ellipse, at rest: the wall rings and the damping calms it.
    // (Not gravity from rest: the total energy would start at zero and the integrators'
    // relative blow-up guard refuses explicit Euler's first step.)
    let x: Vec<Vec3> = m
        .rest_shape()
        .control
        .iter()
        .map(|p| Vec3::new(p.x * 1.02, p.y * 0.98, p.z))
        .collect();
    let v = vec![Vec3::ZERO; x.len()];
    m.set_state(&x, &v).expect("state");
    m
}

fn bench(c: &mut Criterion<cpu_time::ThreadCpuTime>) {
    let mut group = c.benchmark_group("spline");
    group.sample_size(10);
    for scheme in Scheme::ALL {
        let dt = if scheme == Scheme::ImplicitEuler {
            1e-3
        } else {
            5e-5
        };
        let mut m = tube_model(scheme);
        group.bench_function(format!("tube_32x64_step_{}", scheme.name()), |b| {
            b.iter(|| black_box(m.step(dt).expect("step")))
        });
    }
    let rest = SplineSurface::tube(0.01, 0.1, 32, 64).expect("tube");
    let mut tess = Tessellation::new(&rest, 3);
    let mut out = vec![Vec3::ZERO; tess.len()];
    group.bench_function(
        format!("tube_32x64_tessellate_{}_vertices", tess.len()),
        |b| b.iter(|| tess.apply(black_box(&rest.control), &mut out)),
    );
    group.finish();
}

cpu_time::cpu_time_main!(bench);
