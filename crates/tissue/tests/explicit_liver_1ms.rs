//! The run of record of issue 24: every dynamic kind steps the shipped liver (liver.msh,
//! 1,400-odd tetrahedra; E = 5 kPa, ν = 0.4, ρ = 1000, mass damping 20 /s, a probe pressing
//! the top) at the user's dt = 1 ms with `substeps = "auto"` chosen by the model, with no
//! error; and `spline` on the shipped tube at 1 ms with its default integrator. The quick
//! variants cover 0.1 s (the tube 0.02 s); the full second is ignored (it prints the table of
//! `docs/performance.md`: kind, substeps, CPU time, force).
//! Physics beside it: tensor-mass (Cotin's tensors, symplectic Euler) and fem-explicit
//! (assembled K, central differences) are the same linear FEM with the same lumped masses,
//! so two independent implementations must report the same probe force; after the full
//! second (the probe moves at 1 cm/s, the damping relaxes in 0.05 s) the linear kinds'
//! force is the static one, `fem-static`'s at the same probe position.

use std::path::Path;

use tissue::scene::Scene;

const KINDS: [&str; 10] = [
    "fem-explicit",
    "tensor-mass",
    "tensor-mass-nonlinear",
    "spring-mass",
    "simplex-spring-mass",
    "volumetric-spring-mass",
    "fem-semi-implicit",
    "fem-corotational",
    "linked-volumes",
    "hybrid",
];

/// Kinds whose substeps are their own business (implicit: one solve per step).
const IMPLICIT: [&str; 4] = [
    "fem-semi-implicit",
    "fem-corotational",
    "linked-volumes",
    "hybrid",
];

/// The linear-FEM kinds whose settled force must be fem-static's.
const LINEAR: [&str; 3] = ["fem-explicit", "tensor-mass", "fem-semi-implicit"];

fn scene(kind: &str, duration: f64) -> Scene {
    let text = format!(
        r#"
[mesh]
file = "../assets/meshes/liver.msh"
scale = 0.01

[material]
young_modulus = 5000.0
poisson_ratio = 0.4
density = 1000.0
damping = 20.0

[model]
kind = "{kind}"

[[fixed]]
name = "ligaments"
file_vertices = [3, 39, 64]

[[instrument]]
kind = "probe"
radius = 0.005
path = [ {{ t = 0.0, position = [-0.005, 0.0555, 0.0067] }},
         {{ t = 1.0, position = [-0.005, 0.0455, 0.0067] }} ]

[run]
duration = {duration}
dt = 0.001
"#
    );
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    Scene::from_toml(&text, &base, Path::new("liver-1ms.toml")).expect("scene parses")
}

/// Runs `kind` for `duration` s at 1 ms; returns (probe force magnitude at the end, the
/// most substeps a step took, process CPU seconds).
fn run(kind: &str, duration: f64) -> (f64, u32, f64) {
    let s = scene(kind, duration);
    let cpu = tissue::benchmark::beam::process_cpu_seconds();
    let mut sim = s.build().unwrap_or_else(|e| panic!("{kind}: {e}"));
    let steps = (duration / 1e-3).round() as usize;
    let mut most = 0;
    for k in 1..=steps {
        let r = sim
            .step(1e-3)
            .unwrap_or_else(|e| panic!("{kind}: step {k}: {e}"));
        most = most.max(r.info.substeps);
    }
    let cpu = tissue::benchmark::beam::process_cpu_seconds() - cpu;
    let f = sim.instrument_forces()[0].length();
    assert!(f.is_finite(), "{kind}: force {f}");
    (f, most, cpu)
}

fn check(duration: f64) {
    let (f_static, _, _) = run("fem-static", duration);
    eprintln!(
        "{:24} {:>9} {:>9} {:>12}",
        "kind", "substeps", "CPU s", "force N"
    );
    eprintln!(
        "{:24} {:>9} {:>9} {f_static:>12.4e}",
        "fem-static", "-", "-"
    );
    let mut forces = Vec::new();
    for kind in KINDS {
        let (f, substeps, cpu) = run(kind, duration);
        eprintln!("{kind:24} {substeps:>9} {cpu:>9.2} {f:>12.4e}");
        if !IMPLICIT.contains(&kind) {
            // The liver's stable explicit step is below 1 ms at 5 kPa: the model split it.
            assert!(substeps >= 2, "{kind}: {substeps}");
        }
        forces.push(f);
    }
    // Same linear FEM, independent implementations and integrators: same force to 1%
    // (measured: 0.05%).
    let (fem, tensor) = (forces[0], forces[1]);
    assert!(fem > 0.0, "the probe pressed nothing");
    assert!(
        (tensor / fem - 1.0).abs() < 0.01,
        "tensor-mass {tensor} vs fem-explicit {fem}"
    );
    if duration >= 1.0 {
        // Settled: the linear kinds' force is the static one to 2%.
        for (kind, f) in KINDS.iter().zip(&forces) {
            if LINEAR.contains(kind) {
                assert!(
                    (f / f_static - 1.0).abs() < 0.02,
                    "{kind}: {f} N against fem-static's {f_static} N"
                );
            }
        }
    }
}

/// `spline` on the shipped tube at 1 ms with its default integrator (the scene's own is
/// implicit Euler at 5 ms): it substeps by itself and pushes back on the probe.
fn spline_tube(duration: f64) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/tube-spline.toml");
    let text = std::fs::read_to_string(&path).expect("tube scene");
    let text = text
        .replace("integrator = \"implicit-euler\"", "")
        .replace("dt = 0.005", "dt = 0.001")
        .replace("duration = 1.0", &format!("duration = {duration}"));
    let s = Scene::from_toml(&text, path.parent().unwrap(), &path).expect("scene parses");
    let cpu = tissue::benchmark::beam::process_cpu_seconds();
    let mut sim = s.build().expect("spline builds");
    let mut most = 0;
    for k in 1..=(duration / 1e-3).round() as usize {
        let r = sim
            .step(1e-3)
            .unwrap_or_else(|e| panic!("spline: step {k}: {e}"));
        most = most.max(r.info.substeps);
    }
    let cpu = tissue::benchmark::beam::process_cpu_seconds() - cpu;
    let f = sim.instrument_forces()[0];
    eprintln!(
        "spline (tube)            {most:>9} {cpu:>9.2} {:>12.4e}",
        f.length()
    );
    // Runs to its end with finite, symmetric forces. Its force is NOT yet checked against
    // the scene's own implicit Euler at 5 ms (+7.9e-3 N along x at 1 s, pushing the probe
    // back), which this explicit run does not reproduce (−2.9e-2 N at 1 s, negative from
    // the first contact at 0.15 s and smooth from step to step, so not a ringing penalty
    // spring seen at one instant): an open defect, see docs/performance.md.
    let lateral = (f.y * f.y + f.z * f.z).sqrt();
    assert!(
        f.is_finite() && lateral <= 1e-3 * f.length() + 1e-12,
        "spline: probe force {f}"
    );
    assert!(most >= 1);
}

#[test]
fn every_explicit_kind_runs_the_liver_at_1ms_quick() {
    check(0.1);
}

#[test]
fn spline_runs_the_tube_at_1ms_with_its_default_integrator_quick() {
    // 20 steps (the whole second costs ~7 CPU s; its own scene runs implicit Euler at 5 ms).
    spline_tube(0.02);
}

#[test]
#[ignore = "1 s of eleven models and the tube: a few minutes in release"]
fn every_explicit_kind_runs_the_liver_at_1ms_for_one_second() {
    check(1.0);
    spline_tube(1.0);
}
