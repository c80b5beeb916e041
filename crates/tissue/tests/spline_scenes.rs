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
