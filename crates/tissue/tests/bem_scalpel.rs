//! A scalpel drawn across the BEM liver at an interactive frame rate: each frame's sweep is
//! shorter than the surface's edges, so the model joins consecutive sweeps until they open
//! a groove.

use tissue::Material;
use tissue::interact::Constraints;
use tissue::math::{Real, Vec3};
use tissue::model::bem::{Bem, BemParams};
use tissue::model::{CutPath, Deformable};

const LIVER_OBJ: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.obj");

fn liver() -> Bem {
    let mut surface = tissue::io::read(LIVER_OBJ).unwrap().surface_mesh().unwrap();
    surface.vertices.iter_mut().for_each(|p| *p *= 0.01);
    let mut bem = Bem::new(
        &surface,
        Material::new(3000.0, 0.3).unwrap(),
        BemParams::default(),
    )
    .unwrap();
    // The ligament patches of scenes/liver-bem-cut.toml.
    let anchors = [
        Vec3::new(-0.0064, 0.0235, 0.0257),
        Vec3::new(-0.0405, 0.0059, 0.0204),
        Vec3::new(-0.0296, 0.0194, -0.0165),
    ];
    let fixed = bem
        .rest_surface()
        .iter()
        .enumerate()
        .filter(|(_, p)| anchors.iter().any(|a| (**p - *a).length() < 0.01))
        .map(|(v, _)| v as u32)
        .collect();
    bem.set_constraints(&Constraints {
        fixed,
        prescribed: Vec::new(),
    })
    .unwrap();
    bem
}

/// The blade of scenes/liver-bem-cut.toml: 4 cm down from the tip at `p`.
fn blade(p: Vec3) -> [Vec3; 2] {
    [p, p - Vec3::Y * 0.04]
}

/// The scene's stroke, carried on until the blade has left the liver.
fn tip(s: Real) -> Vec3 {
    Vec3::new(0.025, 0.06, 0.005).lerp(Vec3::new(-0.1, 0.06, 0.005), s)
}

#[test]
fn a_stroke_of_short_sweeps_opens_one_groove_when_the_blade_leaves() {
    let mut whole = liver();
    let once = whole
        .cut(&CutPath {
            start: blade(tip(0.0)),
            end: blade(tip(1.0)),
        })
        .unwrap();
    assert!(once.added_vertices > 0);

    let mut framed = liver();
    let frames = 100;
    let mut opened = Vec::new();
    for k in 0..frames {
        let (s0, s1) = (k as Real / frames as Real, (k + 1) as Real / frames as Real);
        let info = framed
            .cut(&CutPath {
                start: blade(tip(s0)),
                end: blade(tip(s1)),
            })
            .unwrap();
        if info.added_vertices > 0 {
            opened.push((k, info.added_vertices));
        }
    }
    eprintln!(
        "one sweep adds {} vertices; {frames} frames (1.25 mm each) open {opened:?}",
        once.added_vertices
    );
    // One groove, when the blade left the liver, the same as the stroke cut at once.
    assert_eq!(opened.len(), 1, "{opened:?}");
    assert_eq!(opened[0].1, once.added_vertices);
    assert!(
        opened[0].0 < frames - 1,
        "opened on leaving, before the stroke's end"
    );
    let (a, b) = (framed.rest_surface(), whole.rest_surface());
    assert_eq!(a.len(), b.len());
    let worst = a
        .iter()
        .zip(b)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, Real::max);
    assert!(worst < 1e-12, "same groove: {worst}");
    // The model still solves after its cut.
    framed.step(0.01).unwrap();
}

#[test]
fn a_new_stroke_closes_the_pending_one() {
    // A third of the stroke in short sweeps, still in the tissue: nothing opens yet.
    let mut model = liver();
    for k in 0..30 {
        let (s0, s1) = (k as Real / 100.0, (k + 1) as Real / 100.0);
        let info = model
            .cut(&CutPath {
                start: blade(tip(s0)),
                end: blade(tip(s1)),
            })
            .unwrap();
        assert_eq!(info.added_vertices, 0, "frame {k}");
    }
    // A sweep elsewhere (the scalpel lifted and put down again) opens the pending stroke.
    let elsewhere = Vec3::new(0.0, 0.0, 0.3);
    let third = model
        .cut(&CutPath {
            start: blade(elsewhere),
            end: blade(elsewhere + Vec3::X * 0.001),
        })
        .unwrap();
    let mut reference = liver();
    let at_once = reference
        .cut(&CutPath {
            start: blade(tip(0.0)),
            end: blade(tip(0.3)),
        })
        .unwrap();
    assert!(at_once.added_vertices > 0);
    assert_eq!(third.added_vertices, at_once.added_vertices);
    assert_eq!(third.topology_version, 1);
}
