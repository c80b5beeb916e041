//! The haptic loop on the liver: the local linear model anchored on full simulation updates
//! predicts the full model's force near the anchor, and a device emulator driving the scene's
//! probe over UDP feels the liver at 1 kHz.

use std::path::Path;

use tissue::Vec3;
use tissue::haptic::{
    HapticConfig, HapticLoop, LocalContact, Pose, UdpBridge, run_coupled, run_emulator,
    step_coupled,
};
use tissue::scene::Scene;

fn liver() -> (Scene, tissue::sim::Simulation) {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenes/liver-probe.toml"
    ));
    let scene = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    let sim = scene.build().unwrap_or_else(|e| panic!("{e}"));
    (scene, sim)
}

/// The shipped scene on its visual vertices alone (`visual_levels = 0`): the probe is held
/// between them and the force grows smoothly with depth. On the scene's surface cut once the
/// organ slides off the probe in small jumps as it is pressed (the force along the press
/// drops by up to 3.5 mN within a 0.1 mm step, docs/contact.md "The shipped liver's fine
/// surface resolved"), and a secant taken across one predicts worse than holding the force
/// (measured at 7 mm: 1.7e-3 N against 4.0e-3 N; at k = 2, 4.7e-3 against 4.4e-3): the
/// local model's prediction is checked where the force is smooth.
fn liver_on_visual_vertices() -> tissue::sim::Simulation {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"));
    assert!(text.contains("\nvisual_levels = 1 "));
    let dir = std::env::temp_dir().join(format!("tissue-haptic-liver-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("liver-k0.toml");
    std::fs::write(
        &path,
        text.replace("\nvisual_levels = 1 ", "\nvisual_levels = 0 "),
    )
    .unwrap();
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    scene.build().unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn local_model_predicts_the_full_force_near_the_anchor() {
    let mut sim = liver_on_visual_vertices();
    let lp = HapticLoop::start(HapticConfig::default()).unwrap_or_else(|e| panic!("{e}"));
    let h = lp.handle();
    // 7 mm into the top of the liver (the scene's path ends 10 mm in).
    let x0 = Vec3::new(-0.005, 0.0485, 0.0067);
    let d = 2e-4;
    let mut force_at = |x: Vec3| {
        h.set_pose(Pose {
            position: x,
            ..Pose::default()
        });
        let r = step_coupled(&mut sim, 0, &h, 0.01).unwrap_or_else(|e| panic!("{e}"));
        r.forces[0]
    };
    // Come down gradually, as a hand does (a 7 mm jump would put the surface behind the
    // probe's centre).
    for k in 0..=14 {
        force_at(Vec3::new(-0.005, 0.0555 - 0.0005 * k as f64, 0.0067));
    }
    // Pressing further in, as the loop's own estimate sees it: anchor, one secant, then a
    // prediction 0.5 mm deeper. (Sideways moves are left out: with one vertex under a 5 mm
    // probe the static contact set flips, and with it the force; the 3D estimate is checked
    // on a smooth field in the unit tests.)
    let mut local = LocalContact::new(1e6, 100.0);
    local.update(x0, force_at(x0), true);
    let x1 = x0 - d * Vec3::Y;
    let f1 = force_at(x1);
    local.update(x1, f1, true);
    let target = x1 - 2.5 * d * Vec3::Y;
    let f_true = force_at(target);
    let f_pred = local.force_at(target);
    let err_linear = (f_pred - f_true).length();
    let err_hold = (f1 - f_true).length();
    println!(
        "force {:.5} N; local model error {:.2e} N, zero-order hold error {:.2e} N; K_yy {:.3} N/m",
        f_true.length(),
        err_linear,
        err_hold,
        local.stiffness().y_axis.y
    );
    assert!(f_true.y > 0.05, "the liver pushes the probe up: {f_true:?}");
    // Linear elasticity: the linear model is near exact, holding the last force is not.
    // The frictionless probe on the smooth liver's points takes more points as it goes in
    // (the patch grows, Hertz-like), so the force curves and the secant is first order:
    // measured 0.037 of the hold's error (with the sticking probe's fixed contact set it
    // was below 0.01).
    assert!(err_linear < 0.1 * err_hold, "{err_linear} vs {err_hold}");
    assert!(err_hold > 1e-3);
    // Pressing in is resisted: the vertical stiffness is negative (force drops going up).
    assert!(local.stiffness().y_axis.y < -1.0);
    lp.stop();
}

#[test]
fn emulated_device_feels_the_liver_through_the_loop() {
    let (scene, mut sim) = liver();
    let lp = HapticLoop::start(HapticConfig::default()).unwrap_or_else(|e| panic!("{e}"));
    let h = lp.handle();
    let start = Vec3::new(-0.005, 0.0555, 0.0067);
    h.set_pose(Pose {
        position: start,
        ..Pose::default()
    });
    let bridge =
        UdpBridge::start(([127, 0, 0, 1], 0).into(), h.clone()).unwrap_or_else(|e| panic!("{e}"));
    let target = bridge.local_addr();
    // Press 8 mm down over 0.8 s, then hold.
    let device = std::thread::spawn(move || {
        run_emulator(target, 1.2, 1000.0, &|t: f64| {
            start - Vec3::new(0.0, 0.01 * t.min(0.8), 0.0)
        })
    });
    let coupling = run_coupled(&mut sim, 0, &h, scene.run.dt, 1.25);
    let rep = device
        .join()
        .unwrap_or_else(|_| panic!("emulator panicked"))
        .unwrap_or_else(|e| panic!("{e}"));
    bridge.stop();
    let stats = lp.stop();
    println!("{stats:?}\n{coupling:?}\n{rep:?}");
    assert_eq!(coupling.errors, 0);
    assert!(coupling.steps >= 50, "{coupling:?}");
    assert_eq!(rep.poses_sent, 1200);
    // That the loop answered, not how punctually: rates, percentiles and missed deadlines are
    // measured by `tissue haptic-bench` on a quiet machine. Here the four threads share CI's
    // two cores with the other tests, and a count near 1,200 failed one run in five.
    assert!(rep.forces_received >= rep.poses_sent / 2, "{rep:?}");
    // Held 8 mm in: the last force felt is the full model's force there, pushing up.
    let f_full = sim.instruments()[0].force();
    assert!(f_full.y > 0.01, "{f_full:?}");
    assert!(
        (rep.last_force - f_full).length() < 0.05 * f_full.length(),
        "device {:?} vs model {f_full:?}",
        rep.last_force
    );
    assert!(stats.ticks >= 500, "{stats:?}");
}
