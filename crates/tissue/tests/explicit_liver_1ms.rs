//! The run of record of issue 24: every explicit dynamic kind steps the shipped liver
//! (liver.msh, 1,400-odd tetrahedra; E = 5 kPa, ν = 0.4, ρ = 1000, mass damping 20 /s, a
//! probe pressing the top) at the user's dt = 1 ms with `substeps = "auto"` chosen by the
//! model, with no error. The quick variant covers 0.1 s; the full second is ignored.
//! Physics beside it: tensor-mass (Cotin's tensors, symplectic Euler) and fem-explicit
//! (assembled K, central differences) are the same linear FEM with the same lumped masses,
//! so two independent implementations must report the same probe force.

use std::path::Path;

use tissue::scene::Scene;

const KINDS: [&str; 7] = [
    "fem-explicit",
    "tensor-mass",
    "tensor-mass-nonlinear",
    "spring-mass",
    "simplex-spring-mass",
    "volumetric-spring-mass",
    "fem-semi-implicit",
];

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
/// most substeps a step took).
fn run(kind: &str, duration: f64) -> (f64, u32) {
    let s = scene(kind, duration);
    let mut sim = s.build().unwrap_or_else(|e| panic!("{kind}: {e}"));
    let steps = (duration / 1e-3).round() as usize;
    let mut most = 0;
    for k in 1..=steps {
        let r = sim
            .step(1e-3)
            .unwrap_or_else(|e| panic!("{kind}: step {k}: {e}"));
        most = most.max(r.info.substeps);
    }
    let f = sim.instrument_forces()[0].length();
    assert!(f.is_finite(), "{kind}: force {f}");
    (f, most)
}

fn check(duration: f64) {
    let mut forces = Vec::new();
    for kind in KINDS {
        let (f, substeps) = run(kind, duration);
        eprintln!("{kind:24} probe force {f:.4e} N, up to {substeps} substeps per 1 ms step");
        if kind != "fem-semi-implicit" {
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
}

#[test]
fn every_explicit_kind_runs_the_liver_at_1ms_quick() {
    check(0.1);
}

#[test]
#[ignore = "1 s of seven models: about a minute in release"]
fn every_explicit_kind_runs_the_liver_at_1ms_for_one_second() {
    check(1.0);
}
