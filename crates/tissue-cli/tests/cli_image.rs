//! `tissue mesh inspect` on volume images: NIfTI and MetaImage report their grid and values.

use std::path::PathBuf;
use std::process::Command;

fn image(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/images")).join(name)
}

fn inspect(args: &[&str], file: PathBuf) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tissue"))
        .args(["mesh", "inspect"])
        .arg(file)
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn inspect_nii_json_reports_the_grid_and_values() {
    let out = inspect(&["--json"], image("anatomical.nii"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["dims"], serde_json::json!([33, 41, 25]));
    assert_eq!(v["value_type"], "int16");
    assert_eq!(v["byte_order"], "big");
    assert_eq!(v["min"], -610.0);
    assert_eq!(v["max"], 30393.0);
    assert_eq!(v["zeros"], 0);
    assert_eq!(v["negatives"], 26);
    let dx = v["spacing"][0].as_f64().unwrap();
    assert!((dx - 0.002).abs() < 1e-12, "{dx}");
}

#[test]
fn inspect_mhd_text_reports_dims_type_and_zeros() {
    let out = inspect(&[], image("pelvis_f.mhd"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("221 × 271 × 69 = 4132479 voxels"), "{text}");
    assert!(text.contains("uint8"), "{text}");
    assert!(text.contains("0 .. 226"), "{text}");
    assert!(text.contains("zeros:   476587 (11.53 %)"), "{text}");
}

#[test]
fn inspect_gzipped_nifti_fails_with_the_reason() {
    let out = inspect(&[], PathBuf::from("brain.nii.gz"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("brain.nii.gz"), "{err}");
}
