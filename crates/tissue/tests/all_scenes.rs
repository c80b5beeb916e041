//! Every scene shipped in `scenes/` builds and runs with its own dt, every step accepted by
//! the plausibility backstop. The quick test runs the first steps of each (a few for the
//! static models, whose steps are solves); `every_scene_runs_to_its_end` (ignored, minutes)
//! runs them all to the end of their duration:
//! `cargo test --release -p tissue --test all_scenes -- --ignored --nocapture`.

use std::path::PathBuf;

use tissue::scene::Scene;

fn scene_files() -> Vec<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes"));
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 20, "{} scenes", files.len());
    files
}

/// Scenes left to the ignored full run: building `liver-bem.toml` (dense BEM on the smooth
/// liver's surface) takes minutes on a shared 2-core machine.
const SLOW: &[&str] = &["liver-bem.toml"];

/// Runs each scene (but `skip`) for at most `steps(total, is_static)` steps; the failures, one line each.
fn run_all(skip: &[&str], steps: impl Fn(u64, bool) -> u64) -> Vec<String> {
    let mut failures = Vec::new();
    for file in scene_files() {
        if file
            .file_name()
            .is_some_and(|n| skip.iter().any(|s| n == *s))
        {
            continue;
        }
        let start = std::time::Instant::now();
        let name = file.file_name().map(|n| n.to_string_lossy().into_owned());
        let name = name.unwrap_or_default();
        let result = Scene::load(&file)
            .map_err(|e| e.to_string())
            .and_then(|s| Ok((s.build().map_err(|e| e.to_string())?, s)));
        let (mut sim, scene) = match result {
            Ok(x) => x,
            Err(e) => {
                failures.push(format!("{name}: does not build: {e}"));
                continue;
            }
        };
        let n = steps(scene.run.step_count(), sim.model().info().is_static);
        for _ in 0..n {
            if let Err(e) = sim.step(scene.run.dt) {
                failures.push(format!("{name}: {e}"));
                break;
            }
        }
        eprintln!(
            "{name}: {} steps of {} ({:.1} s wall, machine shared)",
            sim.steps(),
            scene.run.step_count(),
            start.elapsed().as_secs_f64()
        );
    }
    failures
}

#[test]
fn every_scene_builds_and_takes_its_first_steps() {
    let failures = run_all(SLOW, |total, is_static| {
        total.min(if is_static { 1 } else { 5 })
    });
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
#[ignore = "minutes: every shipped scene to its end"]
fn every_scene_runs_to_its_end() {
    let failures = run_all(&[], |total, _| total);
    assert!(failures.is_empty(), "{failures:#?}");
}
