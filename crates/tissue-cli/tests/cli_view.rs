//! `tissue view` and `tissue haptic-bench` as a user runs them: a missing page says which
//! script to run; the bench prints the loop's figures as JSON.

use std::path::PathBuf;
use std::process::Command;

fn tissue() -> Command {
    Command::new(env!("CARGO_BIN_EXE_tissue"))
}

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(rel)
}

#[test]
fn view_without_three_names_the_setup_script() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("view_no_three");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
    std::fs::write(dir.join("index.html"), "x").unwrap_or_else(|e| panic!("{e}"));
    let out = tissue()
        .args([
            "view",
            "scenes/liver-probe.toml",
            "--port",
            "0",
            "--viewer-dir",
        ])
        .arg(&dir)
        .current_dir(repo(""))
        .output()
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("scripts/setup-viewer.sh"), "{err}");

    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap_or_else(|e| panic!("{e}"));
    let out = tissue()
        .args(["view", "scenes/liver-probe.toml", "--viewer-dir"])
        .arg(&empty)
        .current_dir(repo(""))
        .output()
        .unwrap_or_else(|e| panic!("{e}"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("index.html"), "{err}");
}

#[test]
fn haptic_bench_prints_the_loop_figures() {
    let out = tissue()
        .args([
            "haptic-bench",
            "scenes/liver-probe.toml",
            "--seconds",
            "1",
            "--json",
        ])
        .current_dir(repo(""))
        .output()
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("{e}"));
    for key in [
        "rate_hz",
        "p50_us",
        "p99_us",
        "missed_deadlines",
        "max_force",
    ] {
        assert!(v.get(key).is_some_and(|x| x.is_number()), "{key} in {v}");
    }
    // 1 s at 1 kHz; loose bounds for a shared CI machine.
    let ticks = v["ticks"].as_u64().unwrap_or(0);
    assert!((800..=1100).contains(&ticks), "{v}");
    // The scripted path presses the liver: the device felt a force.
    assert!(v["max_force"].as_f64().unwrap_or(0.0) > 0.01, "{v}");
    let bad = tissue()
        .args(["haptic-bench", "scenes/liver-probe.toml", "--seconds", "-1"])
        .current_dir(repo(""))
        .output()
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(!bad.status.success());
}
