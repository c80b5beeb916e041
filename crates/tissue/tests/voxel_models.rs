//! The voxel models' example scenes run end to end: the probe feels the liver push back,
//! the scalpel cuts ChainMail links, and both models stay finite.

use tissue::math::Vec3;
use tissue::scene::Scene;

fn scene(name: &str) -> Scene {
    let path = format!("{}/../../scenes/{name}", env!("CARGO_MANIFEST_DIR"));
    Scene::load(&path).unwrap()
}

#[test]
fn chainmail_scene_presses_and_cuts() {
    let s = scene("liver-chainmail.toml");
    let mut sim = s.build().unwrap();
    assert_eq!(sim.model().kind(), "chainmail");
    let links = sim.model().info().elements;
    let mut deepest = Vec3::ZERO;
    for _ in 0..s.run.step_count() {
        let r = sim.step(s.run.dt).unwrap();
        if (r.time - 0.45).abs() < 1e-9 {
            deepest = r.forces[0];
        }
        assert!(
            sim.model()
                .surface()
                .positions
                .iter()
                .all(|p| p.is_finite())
        );
    }
    // Pressed down, the tissue pushes the probe up.
    assert!(deepest.y > 1e-3, "{deepest}");
    // The scalpel removed links.
    let after = sim.model().info().elements;
    assert!(after < links, "{after} of {links}");
}

#[test]
fn linked_volumes_scene_pushes_back() {
    let s = scene("liver-linked-volumes.toml");
    let mut sim = s.build().unwrap();
    assert_eq!(sim.model().kind(), "linked-volumes");
    let mut last = Vec3::ZERO;
    for _ in 0..s.run.step_count() {
        last = sim.step(s.run.dt).unwrap().forces[0];
    }
    assert!(last.y > 1e-3, "{last}");
    let held: Vec3 = sim.fixed_reaction_total();
    // The supports hold the body down against the probe (dynamic, so not an exact balance).
    assert!(held.y < 0.0, "{held}");
}
