//! The run of record of issue 24: every dynamic kind steps the shipped liver (liver.msh,
//! 1,400-odd tetrahedra; E = 5 kPa, ν = 0.4, ρ = 1000, mass damping 20 /s, a probe pressing
//! the top) at the user's dt = 1 ms (haptics) and 1/60 s (a screen) with
//! `substeps = "auto"` chosen by the model, with no error; and `spline` on the shipped tube at 1 ms with its default integrator, whose probe
//! force must be the one implicit Euler finds at the same step. The probe touches the shipped
//! smooth surface cut once (`visual_levels = 1`), as in the demo scene: on the coarse
//! surface's vertices alone the frictionless probe slid between them and off the organ before
//! 1 s (every kind's force 0 at the end, `fem-static`'s 3.6e-4 N). The quick variants cover
//! 0.1 s at 1 ms, 0.2 s at 1/60 s and the tube's first 0.2 s; the full second is ignored (it prints the table of
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

fn scene(kind: &str, duration: f64, dt: f64) -> Scene {
    let text = format!(
        r#"
[mesh]
file = "../assets/meshes/liver.msh"
scale = 0.01
visual = "../assets/meshes/liver-smooth.obj"
visual_levels = 1

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
dt = {dt}
"#
    );
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    Scene::from_toml(&text, &base, Path::new("liver-1ms.toml")).expect("scene parses")
}

/// Runs `kind` for `duration` s at steps of `dt`; returns (probe force magnitude at the end,
/// the most substeps a step took, process CPU seconds).
fn run(kind: &str, duration: f64, dt: f64) -> (f64, u32, f64) {
    let s = scene(kind, duration, dt);
    let cpu = tissue::benchmark::beam::process_cpu_seconds();
    let mut sim = s.build().unwrap_or_else(|e| panic!("{kind}: {e}"));
    let steps = (duration / dt).round() as usize;
    let mut most = 0;
    for k in 1..=steps {
        let r = sim
            .step(dt)
            .unwrap_or_else(|e| panic!("{kind}: step {k}: {e}"));
        most = most.max(r.info.substeps);
    }
    let cpu = tissue::benchmark::beam::process_cpu_seconds() - cpu;
    let f = sim.instrument_forces()[0].length();
    assert!(f.is_finite(), "{kind}: force {f}");
    (f, most, cpu)
}

fn check(duration: f64, dt: f64) {
    eprintln!("the liver for {duration} s at dt = {dt:.4e} s");
    let (f_static, _, _) = run("fem-static", duration, dt);
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
        let (f, substeps, cpu) = run(kind, duration, dt);
        eprintln!("{kind:24} {substeps:>9} {cpu:>9.2} {f:>12.4e}");
        if !IMPLICIT.contains(&kind) {
            // The liver's stable explicit step is below 1 ms at 5 kPa: the model splits it.
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

/// `spline` on the shipped tube for `duration` s at 1 ms with `integrator` (None: the
/// model's default, implicit Euler, as the scene's own at 5 ms). Returns the probe force at
/// the end and the most substeps a step took.
fn spline_tube(duration: f64, integrator: Option<&str>) -> (tissue::math::Vec3, u32) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/tube-spline.toml");
    let text = std::fs::read_to_string(&path).expect("tube scene");
    let line = integrator.map_or(String::new(), |i| format!("integrator = \"{i}\""));
    // Sticking, as this comparison was measured: a frictionless probe (the default) on the
    // spline under an explicit scheme reads 0 N here (docs/contact.md, "Not done").
    let text = text
        .replace(
            "kind = \"probe\"",
            "kind = \"probe\"\ncontact = \"sticking\"",
        )
        .replace("integrator = \"implicit-euler\"", &line)
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
    let name = format!("spline (tube, {})", integrator.unwrap_or("default"));
    eprintln!("{name:24} {most:>9} {cpu:>9.2} {:>12.4e}", f.x);
    (f, most)
}

/// The tube pushes the probe back out, and an explicit scheme (symplectic Euler, the spline's
/// default before implicit Euler) reports the force the same model reports under implicit
/// Euler at the same step (independent integrators; the
/// probe moves 6 µm a step, slowly enough for both to be quasi-static). Before the spline's
/// spring targets moved over the step, the explicit run reported −0.029 N at 1 s (pulling
/// the probe in) against implicit Euler's +0.0079 N: see `model::spline::system`.
fn check_tube(duration: f64) {
    let (f, most) = spline_tube(duration, Some("symplectic-euler"));
    let (reference, _) = spline_tube(duration, Some("implicit-euler"));
    // The probe presses from +x (its path runs from x = 14.5 to 8.5 mm; the wall is at
    // x = 10 mm, first touched at t ≈ 0.08 s): the tissue pushes it along +x.
    assert!(reference.x > 0.0, "implicit Euler: {reference}");
    assert!(
        f.x > 0.0,
        "spline (symplectic Euler) pulls the probe in: {f}"
    );
    // Measured: 0.05% at 0.3 s.
    assert!(
        (f.x / reference.x - 1.0).abs() < 0.02,
        "symplectic Euler {} N against implicit Euler {} N",
        f.x,
        reference.x
    );
    let lateral = (f.y * f.y + f.z * f.z).sqrt();
    assert!(lateral <= 1e-3 * f.length(), "spline: probe force {f}");
    assert!(most >= 2, "the tube's stable step is below 1 ms: {most}");
}

#[test]
fn every_explicit_kind_runs_the_liver_at_1ms_quick() {
    check(0.1, 1e-3);
}

#[test]
fn every_dynamic_kind_runs_the_liver_at_60hz_quick() {
    // A screen's frame: 0.2 s is 12 steps of 1/60 s, each split by the explicit kinds.
    check(0.2, 1.0 / 60.0);
}

#[test]
fn spline_pushes_the_probe_back_at_1ms_with_an_explicit_integrator_quick() {
    // 0.2 s: contact from 0.08 s, 0.7 mm deep at the end (~3 CPU s for both runs).
    check_tube(0.2);
}

#[test]
#[ignore = "1 s of eleven models at 1 ms and at 1/60 s, and the tube: minutes in release"]
fn every_explicit_kind_runs_the_liver_at_1ms_for_one_second() {
    check(1.0, 1e-3);
    check(1.0, 1.0 / 60.0);
    check_tube(1.0);
}
