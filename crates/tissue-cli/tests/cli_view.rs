//! `tissue view` and `tissue haptic-bench` as a user runs them: a `--viewer-dir` missing
//! its page says what is missing; the built-in page is served from any folder with the
//! token; the bench prints the loop's figures as JSON.

use std::path::PathBuf;
use std::process::Command;

fn tissue() -> Command {
    Command::new(env!("CARGO_BIN_EXE_tissue"))
}

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(rel)
}

#[test]
fn a_viewer_dir_without_three_says_what_is_missing() {
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
    assert!(err.contains("vendor/three"), "{err}");

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

/// A GET with the given Host; the status line and the body's length.
fn get(port: u16, path: &str) -> (String, usize) {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap_or_else(|e| panic!("{e}"));
    write!(s, "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n")
        .unwrap_or_else(|e| panic!("{e}"));
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let text = String::from_utf8_lossy(&out);
    let status = text.lines().next().unwrap_or("").to_string();
    let body = text.split_once("\r\n\r\n").map_or(0, |(_, b)| b.len());
    (status, body)
}

#[test]
fn the_built_in_page_is_served_from_an_empty_folder() {
    use std::io::BufRead;
    let empty = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("view_empty_folder");
    let _ = std::fs::remove_dir_all(&empty);
    std::fs::create_dir_all(&empty).unwrap_or_else(|e| panic!("{e}"));
    let mut child = tissue()
        .arg("view")
        .arg(repo("scenes/liver-probe.toml"))
        .args(["--port", "0"])
        .env_remove("TISSUE_VIEWER_DIR")
        .current_dir(&empty)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap_or_else(|e| panic!("{e}"));
    let mut line = String::new();
    if let Some(out) = child.stdout.take() {
        let _ = std::io::BufReader::new(out).read_line(&mut line);
    }
    // "tissue view: http://127.0.0.1:PORT/?token=HEX  (Ctrl-C stops)"
    let url = line.split_whitespace().nth(2).unwrap_or("").to_string();
    let port: u16 = url
        .split(':')
        .nth(2)
        .and_then(|p| p.split('/').next())
        .and_then(|p| p.parse().ok())
        .unwrap_or(0);
    let token = url.split("?token=").nth(1).unwrap_or("").to_string();
    let results = [
        get(port, &format!("/?token={token}")),
        get(port, &format!("/vendor/three/three.core.js?token={token}")),
        get(port, "/"),
    ];
    let _ = child.kill();
    let _ = child.wait();
    assert_eq!(token.len(), 64, "{line}");
    assert!(
        results[0].0.contains("200") && results[0].1 > 1000,
        "{results:?}"
    );
    assert!(
        results[1].0.contains("200") && results[1].1 > 100_000,
        "{results:?}"
    );
    assert!(results[2].0.contains("403"), "{results:?}");
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
