//! Inputs that once broke a reader (found by `scripts/fuzz.sh`, kept in
//! `fuzz/regressions/TARGET/`) are read again: each gives a result or an error, never a panic.
//! The split of one input into several files (TetGen, detached image data) is the fuzz
//! targets' own (`fuzz/fuzz_targets/`).

use std::path::{Path, PathBuf};

use tissue::image::{metaimage, nifti, nrrd};
use tissue::io::{self, Format, tetgen};
use tissue::scene::Scene;

fn regressions() -> PathBuf {
    PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fuzz/regressions"
    ))
}

/// The input before and after its first 0xFF byte.
fn split_ff(data: &[u8]) -> (&[u8], Vec<u8>) {
    match data.iter().position(|&b| b == 0xFF) {
        Some(k) => (&data[..k], data[k + 1..].to_vec()),
        None => (data, Vec::new()),
    }
}

/// Reads `data` the way fuzz target `target` does; false for an unknown target.
fn read_as(target: &str, data: &[u8]) -> bool {
    let mesh = |f: Format| {
        let _ = io::parse(f, data, Path::new("regression"));
    };
    match target {
        "mesh_obj" => mesh(Format::Obj),
        "mesh_stl" => mesh(Format::Stl),
        "mesh_ply" => mesh(Format::Ply),
        "mesh_msh" => mesh(Format::Msh),
        "mesh_vtk" => mesh(Format::Vtk),
        "mesh_vtu" => mesh(Format::Vtu),
        "mesh_vtp" => mesh(Format::Vtp),
        "mesh_medit" => mesh(Format::Medit),
        "mesh_off" => mesh(Format::Off),
        "mesh_tetgen" => {
            let mut parts = data.splitn(3, |&b| b == 0xFF);
            let (node, ele, face) = (
                parts.next().unwrap_or_default(),
                parts.next().unwrap_or_default(),
                parts.next().unwrap_or_default(),
            );
            if let Ok((mut m, base)) = tetgen::parse_node(node, Path::new("r.node")) {
                let _ = tetgen::parse_ele(ele, Path::new("r.ele"), base, &mut m);
                let _ = tetgen::parse_face(face, Path::new("r.face"), base, &mut m);
            }
        }
        "image_nifti" => {
            let _ = nifti::parse(data, Path::new("r.nii"));
        }
        "image_metaimage" => {
            let (head, tail) = split_ff(data);
            let _ = metaimage::parse_with(head, Path::new("r.mhd"), 0.001, &|_| Ok(tail.clone()));
        }
        "image_nrrd" => {
            let (head, tail) = split_ff(data);
            let _ = nrrd::parse_with(head, Path::new("r.nrrd"), &|_| Ok(tail.clone()));
        }
        "scene_toml" => {
            if let Ok(text) = std::str::from_utf8(data) {
                let _ = Scene::from_toml(text, Path::new("/nonexistent"), Path::new("r.toml"));
            }
        }
        _ => return false,
    }
    true
}

#[test]
fn every_input_the_fuzzers_found_reads_or_errs() {
    let Ok(dirs) = std::fs::read_dir(regressions()) else {
        return;
    };
    let mut replayed = 0;
    for dir in dirs.flatten().filter(|d| d.path().is_dir()) {
        let target = dir.file_name().to_string_lossy().into_owned();
        if target == "viewer_message" {
            continue; // replayed by tissue-cli's view tests
        }
        for file in std::fs::read_dir(dir.path()).unwrap().flatten() {
            let data = std::fs::read(file.path()).unwrap();
            assert!(
                read_as(&target, &data),
                "fuzz/regressions/{target}: no reader for this target; add it to read_as"
            );
            replayed += 1;
        }
    }
    println!("{replayed} regression inputs replayed");
}

#[test]
fn the_replay_knows_every_fuzz_target() {
    let manifest = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fuzz/Cargo.toml"
    ))
    .unwrap();
    for line in manifest.lines() {
        if let Some(name) = line
            .strip_prefix("name = \"")
            .and_then(|l| l.strip_suffix('"'))
            && name != "tissue-fuzz"
            && name != "viewer_message"
        {
            assert!(
                read_as(name, b""),
                "fuzz target {name} has no replay in read_as"
            );
        }
    }
}
