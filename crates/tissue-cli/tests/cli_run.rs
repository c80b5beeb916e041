//! The `tissue` binary: `run` on scene files, `demo`, and errors naming what is wrong.

use std::path::PathBuf;
use std::process::Command;

fn tissue() -> Command {
    Command::new(env!("CARGO_BIN_EXE_tissue"))
}

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(rel)
}

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn unknown_key_in_a_scene_fails_naming_it() {
    let dir = tmp("unknown_key");
    let text = std::fs::read_to_string(repo("scenes/liver-probe.toml"))
        .unwrap()
        .replace("dt = 0.01", "dt = 0.01\nstep_size = 0.02")
        .replace("../assets", &repo("assets").display().to_string());
    let scene = dir.join("bad.toml");
    std::fs::write(&scene, text).unwrap();
    let out = tissue()
        .arg("run")
        .arg(&scene)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("step_size") && err.contains("bad.toml"),
        "{err}"
    );
    assert!(err.contains("line 33"), "{err}");
}

/// `tissue run` says when a fine contact surface is too coarse for a frictionless probe
/// (`Simulation::contact_warnings`), naming the `visual_levels` that fixes it: the shipped
/// liver at `visual_levels = 0` (the 5 mm probe on 2 mm edges), not as shipped (1).
#[test]
fn run_warns_of_a_fine_surface_too_coarse_for_the_probe() {
    let dir = tmp("fine_warning");
    let shipped = std::fs::read_to_string(repo("scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &repo("assets").display().to_string())
        .replace("duration = 1.0", "duration = 0.02");
    for (k, warned) in [(0, true), (1, false)] {
        let scene = dir.join(format!("k{k}.toml"));
        let text = shipped.replace("\nvisual_levels = 1 ", &format!("\nvisual_levels = {k} "));
        std::fs::write(&scene, text).unwrap();
        let out = tissue()
            .arg("run")
            .arg(&scene)
            .arg("--out")
            .arg(dir.join(format!("out{k}")))
            .output()
            .unwrap();
        assert!(out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            err.contains("warning:") && err.contains("give [mesh] visual_levels = 1"),
            warned,
            "k = {k}: {err}"
        );
    }
}

#[test]
fn missing_scene_file_is_named() {
    let out = tissue()
        .args(["run", "no/such/scene.toml", "--quiet"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no/such/scene.toml"), "{err}");
}

#[test]
fn demo_prints_its_scene() {
    let out = tissue().args(["demo", "--print-scene"]).output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        text,
        std::fs::read_to_string(repo("scenes/liver-probe.toml")).unwrap()
    );
}

#[test]
fn run_writes_frames_pvd_forces_and_summary() {
    let dir = tmp("liver_run");
    let out = tissue()
        .arg("run")
        .arg(repo("scenes/liver-probe.toml"))
        .arg("--out")
        .arg(&dir)
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // 100 steps, a frame every 10 plus the first: 11 frames.
    for k in 0..11 {
        assert!(
            dir.join(format!("frames/frame_{k:05}.vtu")).is_file(),
            "frame {k}"
        );
    }
    assert!(!dir.join("frames/frame_00011.vtu").exists());
    let pvd = std::fs::read_to_string(dir.join("scene.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 11);
    let csv = std::fs::read_to_string(dir.join("forces.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "t,fx,fy,fz");
    assert_eq!(lines.len(), 1 + 101, "header, t = 0, then one row per step");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    for key in [
        "model",
        "steps",
        "wall_seconds",
        "steps_per_second",
        "initial_volume",
        "final_volume",
        "max_displacement",
        "max_instrument_force",
    ] {
        assert!(s.get(key).is_some(), "summary lacks {key}");
    }
    assert_eq!(s["model"], "fem-static");
    assert_eq!(s["steps"], 100);
    assert!(s["max_instrument_force"].as_f64().unwrap() > 0.0);
    // Liver volume 36.561 cm³ = 3.6561e-5 m³.
    assert!((s["initial_volume"].as_f64().unwrap() - 3.6561e-5).abs() < 1e-8);
    assert!(s.get("error").is_none());
}

#[test]
fn demo_runs() {
    let out = tissue().arg("demo").output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("fem-static") && text.contains("max probe force"),
        "{text}"
    );
}

#[test]
fn failing_step_names_step_and_keeps_outputs() {
    // fem-static cannot cut: the scalpel's first step fails.
    let dir = tmp("failing_step");
    let text = std::fs::read_to_string(repo("scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &repo("assets").display().to_string())
        .replace(
            "kind = \"probe\"",
            "kind = \"scalpel\"\ndirection = [0.0, 1.0, 0.0]\nlength = 0.01",
        )
        // A scalpel takes no `contact` (the probe's line; its comment stays a comment).
        .replace("contact = \"sticking\"", "")
        .replace("radius = 0.005                # m", "");
    let scene = dir.join("cut.toml");
    std::fs::write(&scene, text).unwrap();
    let out = tissue()
        .arg("run")
        .arg(&scene)
        .arg("--out")
        .arg(dir.join("out"))
        .arg("--quiet")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("step 1 (from t = 0 s)") && err.contains("cutting"),
        "{err}"
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/summary.json")).unwrap())
            .unwrap();
    assert!(s["error"].as_str().unwrap().contains("cutting"));
    assert_eq!(s["steps"], 0);
    // The first frame and the t = 0 row were written before the failure.
    assert!(dir.join("out/frames/frame_00000.vtu").is_file());
    let pvd = std::fs::read_to_string(dir.join("out/scene.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 1);
    let csv = std::fs::read_to_string(dir.join("out/forces.csv")).unwrap();
    assert_eq!(csv.lines().count(), 2);
}
