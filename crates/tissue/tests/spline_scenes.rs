//! The `spline` scenes load, run, and balance: at the end of a slow, damped press the supports
//! hold what the probe pushes.

use tissue::Real;
use tissue::scene::Scene;

fn repo(rel: &str) -> String {
    format!("{}/../../{rel}", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn sheet_scene_supports_balance_the_probe() {
    let s = Scene::load(repo("scenes/sheet-spline.toml")).unwrap();
    let mut sim = s.build().unwrap();
    assert_eq!(sim.model().kind(), "spline");
    assert_eq!(sim.fixed().len(), 84);
    for _ in 0..s.run.step_count() {
        sim.step(s.run.dt).unwrap();
    }
    let probe = sim.instrument_forces()[0];
    // Pressed down, the sheet pushes the probe up.
    assert!(probe.z > 1e-3, "{probe}");
    // The press is slow and damped: inertia and damping forces are a small part.
    let balance = probe + sim.fixed_reaction_total();
    assert!(
        balance.length() < 0.05 * probe.length(),
        "{balance} vs {probe}"
    );
}

#[test]
fn tube_scene_runs_and_pushes_back() {
    let s = Scene::load(repo("scenes/tube-spline.toml")).unwrap();
    let mut sim = s.build().unwrap();
    let steps = 60; // to t = 0.3 s: the probe is 1.3 mm into the wall
    for _ in 0..steps {
        sim.step(s.run.dt).unwrap();
    }
    let f = sim.instrument_forces()[0];
    let lateral: Real = (f.y * f.y + f.z * f.z).sqrt();
    assert!(f.x > 0.0 && lateral < 1e-3 * f.x, "{f}");
}

/// A user's spline scene that names no integrator, with the default frictionless probe, at a
/// haptic step: the tube pushes the probe back (implicit Euler is the default; under the old
/// default, symplectic Euler, a frictionless probe read 0 N here with the probe 1 mm into the
/// wall), along the probe's axis, as hard as the scene's own implicit Euler at 5 ms to a
/// few per cent (the probe moves 6 mm/s: both quasi-static).
#[test]
fn a_default_spline_pushes_a_frictionless_probe_back_at_1ms() {
    let path = repo("scenes/tube-spline.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let base = std::path::Path::new(&path);
    let run = |text: &str, dt: Real| {
        let s = Scene::from_toml(text, base.parent().unwrap(), base).unwrap();
        let mut sim = s.build().unwrap();
        assert_eq!(sim.instruments()[0].friction(), Some(0.0));
        for _ in 0..(0.3 / dt).round() as usize {
            sim.step(dt).unwrap();
        }
        sim.instrument_forces()[0]
    };
    let default = text
        .lines()
        .filter(|l| !l.starts_with("integrator"))
        .map(|l| format!("{l}\n"))
        .collect::<String>();
    let f = run(&default, 1e-3);
    let reference = run(&text, 5e-3);
    eprintln!("default spline at 1 ms: {f}; the scene's implicit Euler at 5 ms: {reference}");
    assert!(f.x > 0.0, "{f}");
    let lateral: Real = (f.y * f.y + f.z * f.z).sqrt();
    assert!(lateral <= 1e-2 * f.x, "{f}");
    assert!((f.x / reference.x - 1.0).abs() < 0.05, "{f} {reference}");
}
