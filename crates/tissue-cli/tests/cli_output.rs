//! Standard output that goes away: a reader that closed its end (`tissue models | head -c0`)
//! ends the command quietly with status 0; a full disk (`> /dev/full`) is an error naming
//! standard output. Neither panics.

use std::path::PathBuf;
use std::process::{Command, Output, Stdio};

fn tissue() -> Command {
    Command::new(env!("CARGO_BIN_EXE_tissue"))
}

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(rel)
}

/// Runs `tissue args` with stdout a pipe whose reading end is already closed: every write
/// fails with EPIPE (no race with a reader that may or may not have read yet).
fn into_closed_pipe(args: &[&str]) -> Output {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    tissue()
        .args(args)
        .stdout(Stdio::from(writer))
        .stderr(Stdio::piped())
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_closed_pipe_ends_quietly() {
    let liver = repo("assets/meshes/liver.msh");
    let liver = liver.to_str().unwrap();
    for args in [
        vec!["models"],
        vec!["demo", "--print-scene"],
        vec!["mesh", "inspect", liver, "--json"],
        vec!["mesh", "inspect", liver],
    ] {
        let o = into_closed_pipe(&args);
        let err = stderr(&o);
        assert!(
            o.status.success() && !err.contains("panicked") && err.is_empty(),
            "{args:?}: {:?} {err}",
            o.status
        );
    }
}

#[cfg(target_os = "linux")]
#[test]
fn a_full_disk_is_an_error_not_a_panic() {
    let Ok(full) = std::fs::File::create("/dev/full") else {
        return; // no /dev/full in this container: nothing to test
    };
    for args in [vec!["models"], vec!["demo", "--print-scene"]] {
        let o = tissue()
            .args(&args)
            .stdout(Stdio::from(full.try_clone().unwrap()))
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("writing to standard output") && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    }
}
