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

/// A 3D Slicer-style segmentation: a ball "tumour" (label 2) inside a ball "liver" (label 1),
/// 40³ voxels of 1 mm, one layer, raw.
fn nested_balls_seg_nrrd() -> Vec<u8> {
    let n = 40usize;
    let c = (n as f64 - 1.0) / 2.0;
    let mut data = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r = ((i as f64 - c).powi(2) + (j as f64 - c).powi(2) + (k as f64 - c).powi(2))
                    .sqrt();
                data.push(if r < 7.0 {
                    2u8
                } else if r < 16.0 {
                    1
                } else {
                    0
                });
            }
        }
    }
    let mut out = format!(
        "NRRD0004\ntype: uchar\ndimension: 3\nspace: left-posterior-superior\n\
         sizes: {n} {n} {n}\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n\
         kinds: domain domain domain\nencoding: raw\nspace origin: (0,0,0)\n\
         Segment0_ID:=Segment_1\nSegment0_Name:=liver\nSegment0_LabelValue:=1\n\
         Segment0_Layer:=0\nSegment1_ID:=Segment_2\nSegment1_Name:=tumour\n\
         Segment1_LabelValue:=2\nSegment1_Layer:=0\n\n"
    )
    .into_bytes();
    out.extend(data);
    out
}

#[test]
fn a_segmentation_is_inspected_and_meshed_by_segment_names() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cli_image_seg");
    std::fs::create_dir_all(&dir).unwrap();
    let seg = dir.join("balls.seg.nrrd");
    std::fs::write(&seg, nested_balls_seg_nrrd()).unwrap();
    let out = inspect(&["--json"], seg.clone());
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["segments"][1]["name"], "tumour");
    assert_eq!(v["segments"][1]["label"], 2.0);
    let mesh = dir.join("balls.vtu");
    let run = |labels: &str| {
        Command::new(env!("CARGO_BIN_EXE_tissue"))
            .args(["mesh", "tetrahedralize"])
            .arg(&seg)
            .arg(&mesh)
            // --force: names are tested here, not the guarantees (docs/meshing.md, "Several
            // labels" and "Labels keep their volume").
            .args([
                "--labels", labels, "--size", "0.002", "--smooth", "0", "--force",
            ])
            .output()
            .unwrap()
    };
    let out = run("liver,tumour");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let m = tissue::io::read(&mesh).unwrap();
    let mut tags: Vec<i32> = m.tet_tags.clone();
    tags.sort_unstable();
    tags.dedup();
    assert_eq!(tags, vec![1, 2]);
    // The tumour's tetrahedra hold its voxel volume: a ball of radius ~7 mm.
    let tumour: f64 = m
        .tets
        .iter()
        .zip(&m.tet_tags)
        .filter(|(_, t)| **t == 2)
        .map(|(t, _)| {
            let p = t.map(|i| m.vertices[i as usize]);
            ((p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]) / 6.0).abs()
        })
        .sum();
    let ball = 4.0 / 3.0 * std::f64::consts::PI * 0.007f64.powi(3);
    assert!((tumour / ball - 1.0).abs() < 0.25, "{tumour} vs {ball}");
    let out = run("liver,spleen");
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("balls.seg.nrrd") && e.contains("spleen") && e.contains("liver, tumour"),
        "{e}"
    );
}

/// `--close` and `--open` (the ball filters a scene declares with `tet_close`, `tet_open`):
/// four bundles 1 × 1 × 2 mm voxels parted by cracks one voxel wide, with a strand one voxel
/// thick, become one body (the cracks' 720 voxels filled, the strand's 3 removed), the JSON
/// report says so, and a negative radius is refused with its name.
#[test]
fn ball_filters_are_asked_for_reported_and_a_bad_radius_is_named() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cli_image_balls");
    std::fs::create_dir_all(&dir).unwrap();
    let (nx, ny, nz) = (28usize, 28usize, 16usize);
    let mut raw = vec![0u8; nx * ny * nz];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let block = (4..24).contains(&i) && (4..24).contains(&j) && (2..14).contains(&k);
                let crack = [9, 14, 19].contains(&j);
                let strand = (24..27).contains(&i) && j == 12 && k == 8;
                if block && !crack || strand {
                    raw[i + nx * (j + ny * k)] = 1;
                }
            }
        }
    }
    std::fs::write(dir.join("bundles.raw"), raw).unwrap();
    let header = dir.join("bundles.mhd");
    std::fs::write(
        &header,
        "ObjectType = Image\nNDims = 3\nDimSize = 28 28 16\nElementSpacing = 1 1 2\n\
         Position = 0 0 0\nElementType = MET_UCHAR\nElementDataFile = bundles.raw\n",
    )
    .unwrap();
    let run = |close: &str| {
        Command::new(env!("CARGO_BIN_EXE_tissue"))
            .args(["mesh", "tetrahedralize"])
            .arg(&header)
            .arg(dir.join("bundles.vtu"))
            .args(["--threshold", "1,1", "--size", "0.004", "--smooth", "0"])
            .args(["--open-close", "0", "--open", "0.0015", "--json", "--force"])
            .arg(format!("--close={close}"))
            .output()
            .unwrap()
    };
    let out = run("0.0015");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let c = &v["cleaning"];
    assert_eq!(
        (
            &c["closed_voxels"],
            &c["opened_voxels"],
            &c["parts_dropped"],
            &c["voxels_after"]
        ),
        (&720.into(), &3.into(), &0.into(), &4800.into()),
        "{v}"
    );
    let out = run("-0.001");
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("closing radius") && e.contains("-0.001"), "{e}");
}
