//! The run-level backstop (`interact::plausibility`): an instrument wider than the body is
//! refused when the scene is built, and a run whose state leaves physical plausibility (the
//! issue-21 case: fem-explicit on the liver at dt = 0.01 s, far above its critical 5.6e-4 s)
//! stops with a named error at the last plausible step instead of finishing with 1e42 m.

use std::path::{Path, PathBuf};

use tissue::SimError;
use tissue::interact::plausibility::{DISPLACEMENT_FACTOR, FORCE_FACTOR};
use tissue::scene::Scene;

fn scenes() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes"))
}

/// A shipped scene with text replaced.
fn scene(name: &str, edits: &[(&str, &str)]) -> Result<Scene, String> {
    let path = scenes().join(name);
    let mut text = std::fs::read_to_string(&path).map_err(|e| e.to_string())?;
    for (from, to) in edits {
        assert!(text.contains(from), "{name} has no `{from}`");
        text = text.replace(from, to);
    }
    Scene::from_toml(&text, &scenes(), Path::new(name)).map_err(|e| e.to_string())
}

#[test]
fn an_instrument_wider_than_the_body_is_refused_at_load() {
    let s = scene("liver-probe.toml", &[("radius = 0.005", "radius = 1000.0")]);
    let e = match s.and_then(|s| s.build().map_err(|e| e.to_string())) {
        Ok(_) => String::new(),
        Err(e) => e,
    };
    assert!(
        e.contains("[[instrument]] 1") && e.contains("wider than the body"),
        "{e}"
    );
}

#[test]
fn the_liver_bounds_follow_its_size_and_material() {
    let s = scene("liver-probe.toml", &[]).unwrap_or_else(|e| panic!("{e}"));
    let sim = s.build().unwrap_or_else(|e| panic!("{e}"));
    let b = sim.plausibility();
    // The shipped liver spans about 0.1 m by 0.08 m by 0.05 m.
    assert!((0.08..0.3).contains(&b.size), "{}", b.size);
    assert_eq!(b.max_displacement, DISPLACEMENT_FACTOR * b.size);
    let e = 3000.0;
    assert!((b.max_force - FORCE_FACTOR * e * b.size * b.size).abs() < 1e-9 * b.max_force);
    // Far above what a probe pressing 1 cm measures (below 1 N), far below 1e4 N.
    assert!((10.0..1e4).contains(&b.max_force), "{}", b.max_force);
}

#[test]
fn an_explicit_run_far_above_its_critical_step_stops_plausible() {
    // One forced step per dt: by default the model substeps to its stability limit and runs
    // this scene to its end; the backstop is for a user who forces the count.
    let s = scene(
        "liver-fem-explicit.toml",
        &[
            ("dt = 2e-4", "dt = 1e-2"),
            (
                "kind = \"fem-explicit\"",
                "kind = \"fem-explicit\"\nsubsteps = 1",
            ),
        ],
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let mut sim = s.build().unwrap_or_else(|e| panic!("{e}"));
    let bound = sim.plausibility().clone();
    let mut failure = None;
    for _ in 0..s.run.step_count() {
        let (t, steps) = (sim.time(), sim.steps());
        match sim.step(s.run.dt) {
            Ok(r) => {
                for f in &r.forces {
                    assert!(f.length() <= bound.max_force, "accepted {f}");
                }
            }
            Err(e) => {
                // Not accepted: the clock stays at the last plausible step.
                assert_eq!((sim.time(), sim.steps()), (t, steps));
                failure = Some(e);
                break;
            }
        }
    }
    let e = failure.unwrap_or_else(|| panic!("dt = 0.01 s ran to its end"));
    assert!(
        matches!(e, SimError::Implausible { .. } | SimError::Diverged { .. }),
        "{e}"
    );
    let text = e.to_string();
    assert!(text.contains("step") && text.contains("last"), "{text}");
}
