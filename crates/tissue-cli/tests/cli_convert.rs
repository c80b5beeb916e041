//! `tissue mesh convert` says what it dropped, and its counts are those of the written file.

use std::path::PathBuf;
use std::process::Command;

fn repo(rel: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join(rel)
}

fn convert(input: &str, output: &str) -> String {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cli_convert");
    std::fs::create_dir_all(&dir).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_tissue"))
        .args(["mesh", "convert"])
        .arg(repo(input))
        .arg(dir.join(output))
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn lossy_conversions_say_what_they_dropped() {
    // liver.msh: 181 vertices, 596 tetrahedra; OBJ keeps its 140-vertex boundary.
    let obj = convert("assets/meshes/liver.msh", "liver.obj");
    assert!(obj.contains("140 vertices, 276 triangles"), "{obj}");
    assert!(!obj.contains("596 tetrahedra\n"), "{obj}");
    assert!(
        obj.contains("dropped") && obj.contains("596 of 596 tetrahedra"),
        "{obj}"
    );
    // The PLY's 79 fixed vertices have no place in VTK.
    let vtk = convert("assets/meshes/wound_deformable.ply", "wound.vtk");
    assert!(
        vtk.contains("1476 tetrahedra") && vtk.contains("79 of 79 fixed vertices"),
        "{vtk}"
    );
    // Nothing lost, nothing said.
    let msh = convert("assets/meshes/liver.msh", "liver.vtu");
    assert!(
        msh.contains("181 vertices, 596 tetrahedra") && !msh.contains("dropped"),
        "{msh}"
    );
}
