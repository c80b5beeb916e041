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

/// Every directed edge of the drawn triangles has exactly one opposite twin (closed,
/// oriented) and no triangle repeats a vertex.
fn assert_closed(triangles: &[[u32; 3]]) {
    use std::collections::HashMap;
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for &[a, b, c] in triangles {
        assert!(a != b && b != c && a != c);
        for e in [(a, b), (b, c), (c, a)] {
            *directed.entry(e).or_insert(0) += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!((n, directed.get(&(b, a)).copied()), (1, Some(1)), "{a}-{b}");
    }
}

#[test]
fn linked_volumes_cut_scene_cuts_springs_and_draws_a_closed_surface() {
    let s = scene("liver-linked-volumes-cut.toml");
    let mut sim = s.build().unwrap();
    assert_eq!(sim.model().kind(), "linked-volumes");
    let springs = sim.model().info().elements;
    assert_closed(sim.model().surface().triangles);
    let mut pressed = Vec3::ZERO;
    for _ in 0..s.run.step_count() {
        let r = sim.step(s.run.dt).unwrap();
        if (r.time - 0.8).abs() < 1e-9 {
            pressed = r.forces[1];
        }
        let surface = sim.model().surface();
        assert!(surface.positions.iter().all(|p| p.is_finite()));
    }
    let after = sim.model().info().elements;
    assert!(after + 100 < springs, "{after} of {springs}");
    // The cuts re-connected the surface: the simulation saw the topology change.
    assert!(sim.topology_version() > 0);
    assert_closed(sim.model().surface().triangles);
    // Pressed down next to the cut, the tissue still pushes the probe up.
    assert!(pressed.y > 1e-3, "{pressed}");
}

#[test]
fn chainmail_scene_surface_stays_closed_through_the_cut() {
    let s = scene("liver-chainmail.toml");
    let mut sim = s.build().unwrap();
    for _ in 0..s.run.step_count() {
        sim.step(s.run.dt).unwrap();
    }
    assert_closed(sim.model().surface().triangles);
}
