//! The shared integrator's implicit Euler holds an instrument's push-only contacts inside its
//! solve (`integrate::implicit`, `integrate::contact::HeldContacts`): on the shipped liver,
//! pressed by the demo scene's frictionless probe at the haptic loop's step and at the
//! screen's, no step stops at its solver's cap, and two preconditioners reach the same state.

use tissue::math::Real;
use tissue::scene::Scene;

/// `scenes/liver-probe.toml` (its smooth surface, a frictionless probe pressed 1 cm over
/// 1 s) with mass damping 20 1/s, `[model]` lines `model` and the step `dt`, run `seconds`:
/// the last probe force, N, and the steps that stopped at a cap (solver or contact set).
fn press_liver(model: &str, dt: Real, seconds: Real) -> (tissue::math::Vec3, usize) {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace("density = 1000.0", "density = 1000.0\ndamping = 20.0")
        .replace("kind = \"fem-static\"", model)
        .replace("dt = 0.01 ", &format!("dt = {dt} "));
    let dir = std::env::temp_dir().join(format!("tissue-ie-contacts-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{}-{dt}.toml", model.len()));
    std::fs::write(&path, text).unwrap();
    let scene = Scene::load(&path).unwrap();
    assert_eq!(scene.run.dt, dt);
    let mut sim = scene.build().unwrap();
    let (mut last, mut capped) = (tissue::math::Vec3::ZERO, 0);
    let steps = (seconds / dt).round() as usize;
    for _ in 0..steps {
        let rep = sim.step(dt).unwrap();
        capped += usize::from(rep.info.capped);
        last = rep.forces[0];
    }
    (last, capped)
}

/// Held in the solve, the contacts are part of the CG's system: its filter zeroes the held
/// particles' rows as well as the contacts' normals, and its tolerance is relative to what
/// drives the free part (the contacts' known motion, when the load is round-off at rest).
/// Before both, `linked-volumes` on this scene stopped 990 of 1000 steps at 1 ms and 60 of
/// 60 at 1/60 s at the 1000-iteration cap (worst relative residual 7.3e6 and 3.8e11).
/// Block-Jacobi (`linked-volumes`' default) and the factorised rest matrix reach the same
/// force to the CG's tolerance.
#[test]
fn the_liver_pressed_under_implicit_euler_never_stops_at_a_cap() {
    for (dt, seconds) in [(1.0 / 60.0, 1.0), (1e-3, 0.3)] {
        let (f_blocks, capped_blocks) = press_liver("kind = \"linked-volumes\"", dt, seconds);
        let (f_rest, capped_rest) = press_liver(
            "kind = \"linked-volumes\"\npreconditioner = \"rest-factor\"",
            dt,
            seconds,
        );
        let (f_tm, capped_tm) = press_liver(
            "kind = \"tensor-mass\"\nintegrator = \"implicit-euler\"",
            dt,
            seconds,
        );
        eprintln!(
            "dt {dt:.5} s: linked-volumes block-Jacobi {f_blocks:.6} N ({capped_blocks} capped), \
             rest factor {f_rest:.6} N ({capped_rest}); tensor-mass {f_tm:.6} N ({capped_tm})"
        );
        assert_eq!(
            (capped_blocks, capped_rest, capped_tm),
            (0, 0, 0),
            "dt {dt}"
        );
        assert!(
            f_blocks.length() > 1e-3 && f_tm.length() > 1e-3,
            "the probe touches"
        );
        let off = (f_blocks - f_rest).length() / f_rest.length();
        assert!(off < 1e-4, "dt {dt}: {f_blocks} against {f_rest}");
    }
}
