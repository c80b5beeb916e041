//! Scenes whose body is a medical image (`[image]`): the shipped brain (NIfTI, linked
//! volumes) and hip-muscle (MetaImage, ChainMail) scenes build the lattice the image selects,
//! regions select marching-surface vertices, the probe feels the tissue push back, and
//! every mistake in an `[image]` scene is an error naming the scene file and the key.

use std::path::{Path, PathBuf};

use tissue::image::read_image;
use tissue::interact::Region;
use tissue::math::Vec3;
use tissue::scene::Scene;
use tissue::voxel::{from_image_threshold, keep_largest};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(rel)
}

fn scene(name: &str) -> Scene {
    Scene::load(repo(&format!("scenes/{name}"))).unwrap_or_else(|e| panic!("{e}"))
}

/// A scene read from text, as if it were `scenes/test.toml`.
fn from_text(text: &str) -> Result<Scene, String> {
    Scene::from_toml(text, &repo("scenes"), Path::new("scenes/test.toml"))
        .map_err(|e| e.to_string())
}

const BRAIN: &str = r#"
[image]
file = "../assets/images/anatomical.nii"
threshold = [6000.0, 40000.0]
stride = 2
[material]
young_modulus = 3000.0
poisson_ratio = 0.3
[model]
kind = "linked-volumes"
[[fixed]]
box = { min = [0.0, -0.1, -0.1], max = [0.2, 0.1, -0.0135] }
[run]
duration = 0.1
dt = 0.01
"#;

#[test]
fn the_brain_scene_builds_the_lattice_the_image_selects_and_pushes_the_probe_up() {
    let s = scene("brain-linked-volumes.toml");
    // The same selection made by hand: threshold, every 2nd voxel, largest part.
    let image = read_image(repo("assets/images/anatomical.nii"), 1.0).unwrap();
    let mut grid = from_image_threshold(&image, 6000.0, 40000.0, 2).unwrap();
    let kept = keep_largest(&mut grid);
    assert_eq!(grid.dims, [17, 21, 13]);
    assert_eq!(grid.spacing, Vec3::splat(0.004));
    let body = s.load_body().unwrap();
    assert_eq!(body.grid.as_ref().unwrap().labels, grid.labels);

    let mut sim = s.build().unwrap();
    assert_eq!(sim.model().kind(), "linked-volumes");
    assert_eq!(sim.model().info().nodes, kept);
    // The fixed box selects exactly the marching-surface vertices inside it (the surface
    // drawn is the model's, identical to the one the body carries).
    let rest = sim.model().rest_surface().to_vec();
    assert_eq!(rest, body.mesh.vertices);
    let in_box = Region::Box {
        min: [0.0, -0.1, -0.1],
        max: [0.2, 0.1, -0.0135],
    }
    .select(&rest);
    assert!(!in_box.is_empty());
    assert_eq!(sim.fixed(), in_box.as_slice());

    let mut force = Vec3::ZERO;
    for _ in 0..20 {
        let r = sim.step(s.run.dt).unwrap();
        force = r.forces[0];
        assert!(
            sim.model()
                .surface()
                .positions
                .iter()
                .all(|p| p.is_finite())
        );
    }
    // After 20 steps the probe is 1.6 mm into the top: the tissue pushes it up.
    assert!(force.z > 1e-4, "{force}");
    assert!(sim.fixed_reaction_total().z < 0.0);
}

#[test]
fn the_hip_muscle_scene_pushes_the_probe_back_out() {
    let s = scene("pelvis-chainmail.toml");
    let mut sim = s.build().unwrap();
    assert_eq!(sim.model().kind(), "chainmail");
    let grid = s.load_body().unwrap().grid.unwrap();
    // Every 6th of 221 x 271 x 69 voxels, spacing (0.78125, 0.78125, 2.46876) mm x 6.
    assert_eq!(grid.dims, [37, 46, 12]);
    assert!((grid.spacing.x - 0.0046875).abs() < 1e-12);
    assert!((grid.spacing.z - 0.01481256).abs() < 1e-9);
    assert_eq!(sim.model().info().nodes, grid.occupied());
    let mut deepest = Vec3::ZERO;
    for _ in 0..s.run.step_count() {
        let r = sim.step(s.run.dt).unwrap();
        if (r.time - 0.5).abs() < 1e-9 {
            deepest = r.forces[0];
        }
    }
    // Pressed along -y into the back of the muscle, the probe is pushed back along +y.
    assert!(deepest.y > 1e-2, "{deepest}");
}

#[test]
fn a_missing_image_names_the_scene_and_the_image() {
    let text = BRAIN.replace("anatomical.nii", "no-such-brain.nii");
    let s = from_text(&text).unwrap();
    let e = s.build().err().unwrap().to_string();
    assert!(e.contains("scenes/test.toml"), "{e}");
    assert!(
        e.contains("no-such-brain.nii") && e.contains("no such file"),
        "{e}"
    );
    assert!(e.contains("[image]") && e.contains("line 2"), "{e}");
}

#[test]
fn bad_image_keys_are_named() {
    let cases: &[(&str, &str, &[&str])] = &[
        (
            "threshold = [6000.0, 40000.0]",
            "threshold = [40000.0, 6000.0]",
            &["line 2", "[image] threshold", "lo <= hi"],
        ),
        (
            "threshold = [6000.0, 40000.0]",
            "threshold = [6000.0]",
            &["threshold"],
        ),
        (
            "threshold = [6000.0, 40000.0]",
            "labels = [1.0]\nthreshold = [6000.0, 40000.0]",
            &["exactly one of `threshold"],
        ),
        (
            "threshold = [6000.0, 40000.0]",
            "labels = [\"liver\"]",
            &[
                "labels",
                "`liver` is a segment name",
                "only NRRD segmentations",
            ],
        ),
        ("stride = 2", "stride = 0", &["stride = 0"]),
        (
            "stride = 2",
            "stride = 2\nscale = 0.001",
            &["scale applies to MetaImage"],
        ),
        (
            "stride = 2",
            "stride = 2\nspacing = [0.002, 0.0, 0.002]",
            &["spacing"],
        ),
        ("stride = 2", "stride = 2\nthreshhold = 1", &["threshhold"]),
        ("anatomical.nii", "anatomical.png", &["not an image format"]),
        (
            "kind = \"linked-volumes\"",
            "kind = \"fem-static\"",
            &["[model]", "fem-static", "cannot be built from an [image]"],
        ),
        (
            "kind = \"linked-volumes\"",
            "kind = \"linked-volumes\"\nresolution = 12",
            &["[model]", "`resolution` does not apply"],
        ),
        (
            "box = { min = [0.0, -0.1, -0.1], max = [0.2, 0.1, -0.0135] }",
            "file_vertices = [1, 2]",
            &["[[fixed]] 1", "file_vertices", "an [image] body has none"],
        ),
        (
            "[material]\nyoung_modulus = 3000.0\npoisson_ratio = 0.3\n",
            "",
            &["needs a [material]"],
        ),
        (
            "[image]",
            "[mesh]\nfile = \"../assets/meshes/liver.obj\"\n[image]",
            &["both [mesh] and [image]"],
        ),
    ];
    for (from, to, wanted) in cases {
        assert!(BRAIN.contains(from), "{from}");
        let text = BRAIN.replacen(from, to, 1);
        let e = from_text(&text)
            .err()
            .unwrap_or_else(|| panic!("{to}: accepted"));
        assert!(e.contains("scenes/test.toml"), "{e}");
        for w in *wanted {
            assert!(e.contains(w), "{to}: `{w}` not in: {e}");
        }
    }
    let none = BRAIN.replace("[image]", "[imagery]");
    assert!(from_text(&none).is_err());
    let neither = BRAIN.split("[material]").nth(1).unwrap();
    let e = from_text(&format!("[material]{neither}")).err().unwrap();
    assert!(
        e.contains("needs [mesh]") && e.contains("or [image]"),
        "{e}"
    );
}

#[test]
fn selections_that_find_nothing_name_their_key_when_the_image_is_read() {
    let cases: &[(&str, &str, &[&str])] = &[
        (
            "threshold = [6000.0, 40000.0]",
            "threshold = [50000.0, 60000.0]",
            &["threshold", "-610 to 30393"],
        ),
        (
            "stride = 2",
            "stride = 2\nseed = [1.0, 0.0, 0.0]",
            &["seed", "outside the image"],
        ),
        // The centre of voxel (8, 16, 12) of the 4 mm grid: the midline fissure, CSF.
        (
            "stride = 2",
            "stride = 2\nseed = [0.064, 0.024, 0.032]",
            &["seed", "voxel (8, 16, 12)", "not selected"],
        ),
    ];
    for (from, to, wanted) in cases {
        let s = from_text(&BRAIN.replacen(from, to, 1)).unwrap();
        let e = s.build().err().unwrap().to_string();
        assert!(
            e.contains("scenes/test.toml") && e.contains("anatomical.nii"),
            "{e}"
        );
        for w in *wanted {
            assert!(e.contains(w), "{to}: `{w}` not in: {e}");
        }
    }
    // A seed in tissue keeps the part holding it: here the largest.
    let s =
        from_text(&BRAIN.replacen("stride = 2", "stride = 2\nseed = [0.048, -0.016, 0.032]", 1))
            .unwrap();
    let seeded = s.load_body().unwrap().grid.unwrap();
    let largest = from_text(BRAIN).unwrap().load_body().unwrap().grid.unwrap();
    assert_eq!(seeded.labels, largest.labels);
}

/// The brain image meshed into tetrahedra when `brain-fem-image.toml` is built: a closed
/// 2-manifold boundary (where the stuffed lattice touches itself along edges or at
/// vertices, those tetrahedra are removed: a few with the earlier mesher, none now), every
/// guarantee kept without `tet_force` (since session 17: boundary within h/2 both ways of
/// the input the scene declares, its opening-closing of 2 voxels said in the report, volume
/// within 1 % of the cleaned voxels' and of the voxels before cleaning; until then the
/// boundary was 0.595 h), and a surface kind (`bem`, which refuses a non-manifold surface)
/// builds on it and pushes the probe up.
#[test]
fn the_brain_image_becomes_a_manifold_tet_organ_a_surface_kind_builds_on() {
    let s = scene("brain-fem-image.toml");
    let body = s.load_body().unwrap();
    let tets = body.mesh.tet_mesh("brain").unwrap();
    assert!(
        tets.tets.len() > 8_000 && tets.tets.len() < 10_000,
        "{}",
        tets.tets.len()
    );
    let surface = tissue::mesh::boundary::boundary_surface(&tets).surface;
    let mut edges = std::collections::HashMap::new();
    for t in &surface.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    assert!(
        edges.values().all(|&n| n == 2),
        "every boundary edge in two triangles"
    );
    let report = s.meshing_report().expect("the scene meshes its image");
    let volume_error = report.volume_error.unwrap();
    assert!(volume_error.abs() < 0.01, "{volume_error}");
    // Session 13's mesher (MESHER_VERSION 5) leaves none there; the earlier one removed a
    // few: either way the repair stays local.
    assert!(report.manifold.removed < 20, "{}", report.manifold.removed);
    assert_eq!(
        (report.manifold.edges_left, report.manifold.vertices_left),
        (0, 0)
    );
    assert!(report.violations().is_empty(), "{report}");
    let h = report.size;
    let resolved = report.resolved_input_to_mesh.unwrap();
    assert!(
        report.mesh_to_input <= 0.5 * h && resolved <= 0.5 * h,
        "{report}"
    );
    let uncleaned = report.uncleaned_volume_error.unwrap();
    assert!(uncleaned.abs() < 0.01, "{report}");
    assert_eq!(report.cleaning.as_ref().map(|c| c.open_close), Some(2));
    assert!(report.min_dihedral_deg >= 10.7 - 1e-9, "{report}");
    assert!(
        report.followed.onto + report.followed.partly > 0,
        "{report}"
    );

    let mut bem = s.clone();
    bem.model_kind = "bem".into();
    let mut sim = bem.build().unwrap();
    for _ in 0..60 {
        sim.step(s.run.dt).unwrap();
    }
    let force: Vec3 = sim.instrument_forces().iter().copied().sum();
    // The probe moves down (−z) into the top of the brain: the tissue pushes it up.
    assert!(
        force.z > 1e-3 && force.z.abs() > 3.0 * force.x.abs().max(force.y.abs()),
        "{force}"
    );
}

/// The hip muscle meshed into tetrahedra by `pelvis-fem-image.toml` keeps every guarantee
/// without `tet_force` (issue 25, session 18) against the input the scene declares: the
/// muscle's voxels closed by a ball of radius 9 mm (fat between bundles narrower than 18 mm
/// counted in) then opened by one (strands thinner than 18 mm out), which the report says.
/// Until then it was meshed with a blur and broke two promises (boundary 1.08 h, volume
/// −4.15 %). It is one piece with a closed 2-manifold boundary, and the probe pressed into
/// the back of the gluteal muscles is pushed back.
#[test]
fn the_hip_muscle_becomes_one_manifold_tet_organ_that_pushes_the_probe_back() {
    let s = scene("pelvis-fem-image.toml");
    s.load_body().unwrap();
    let report = s.meshing_report().expect("the scene meshes its image");
    assert_eq!(report.pieces.count, 1);
    assert_eq!(
        (report.manifold.edges_left, report.manifold.vertices_left),
        (0, 0)
    );
    assert!(report.violations().is_empty(), "{report}");
    let h = report.size;
    assert!(
        report.mesh_to_input <= 0.5 * h
            && report.resolved_input_to_mesh.is_some_and(|d| d <= 0.5 * h),
        "{report}"
    );
    assert!(
        report.volume_error.is_some_and(|e| e.abs() < 0.01),
        "{report}"
    );
    assert!(report.min_dihedral_deg >= 10.0, "{report}");
    // The filter is said, and what it changed: about a third more voxels than the
    // threshold's part (measured +35.7 % for the mesh against them), beside the guarantee.
    let c = report.cleaning.as_ref().expect("the cleaning is reported");
    assert_eq!((c.close, c.open, c.open_close), (0.009, 0.009, 0));
    assert!(c.closed_voxels > 100_000 && c.opened_voxels > 0, "{c:?}");
    assert!(
        report
            .uncleaned_volume_error
            .is_some_and(|e| (0.25..0.45).contains(&e)),
        "{report}"
    );
    let mut sim = s.build().unwrap();
    let mut peak = Vec3::ZERO;
    for _ in 0..50 {
        sim.step(s.run.dt).unwrap();
        let f: Vec3 = sim.instrument_forces().iter().copied().sum();
        if f.length() > peak.length() {
            peak = f;
        }
    }
    // The probe moves along −y into the muscle: the tissue pushes it back, mostly along +y
    // (the sticking probe on the muscle's sloped back also feels it sideways).
    assert!(
        peak.y > 0.1 && peak.y > peak.x.abs().max(peak.z.abs()),
        "{peak}"
    );
}

/// A sticking probe pressing 8 mm into the brain organ meshed at 7 mm (`brain-fem-image.toml`,
/// here with `fem-semi-implicit`) feels the same force at the end whatever the step, and a
/// force that changes smoothly from step to step. A contact held on the probe's flank, above
/// its equator, used to be dropped while it pushed whenever the probe moved on (it was then
/// outside the moved sphere), sprang into the probe and was taken again a step later: the
/// force halved and doubled every step at dt = 2 ms (jumps of 160 %) and the end force was
/// 0.10 N at 2 ms against 0.16 N at 10 ms.
#[test]
fn a_sticking_probe_on_the_brain_organ_feels_the_same_force_at_any_step() {
    let mut s = scene("brain-fem-image.toml");
    s.model_kind = "fem-semi-implicit".into();
    for inst in &mut s.instruments {
        inst.value.contact = Some("sticking".into());
        inst.value.friction = None;
    }
    let run = |dt: f64| {
        let mut sim = s.build().unwrap();
        let steps = (s.run.duration / dt).round() as usize;
        let mut forces = Vec::with_capacity(steps);
        for _ in 0..steps {
            sim.step(dt).unwrap();
            forces.push(sim.instrument_forces().iter().copied().sum::<Vec3>());
        }
        forces
    };
    let (fine, coarse) = (run(0.002), run(0.01));
    let (a, b) = (fine[fine.len() - 1], coarse[coarse.len() - 1]);
    let gap = (a - b).length() / b.length();
    println!(
        "end force at 2 ms {a}, at 10 ms {b}: {:.2} % apart",
        100.0 * gap
    );
    assert!(b.z > 0.03 && gap < 0.03, "2 ms {a}, 10 ms {b}");
    // From 0.3 s (the probe well in) no step changes the force by more than 3 %.
    let from = fine.len() * 3 / 10;
    let worst = fine[from..]
        .windows(2)
        .map(|w| (w[1] - w[0]).length() / w[0].length())
        .fold(0.0, f64::max);
    println!(
        "largest change of the force in one 2 ms step after 0.3 s: {:.2} %",
        100.0 * worst
    );
    assert!(worst < 0.03, "{worst}");
}
