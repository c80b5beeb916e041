//! Frictionless contacts that only push on `linked-volumes` and `spline` (issue 20): each
//! model holds a frictionless contact along the instrument's normal and only while it pushes
//! (`Deformable::contacts_push_only`), as the kinds on the shared integrator do, instead of
//! the relaxation of targets held in all three directions (`sliding::Relaxed`, "before").
//!
//! The physics checked: no contact ever pulls; a held press gives a steady force; and a
//! frictionless contact keeps no memory of the path: pressed at A and slid to B, the tissue
//! settles where a press straight down at B leaves it (the equilibrium is unique without
//! friction), which a sticking contact, dragging the surface along, does not.

mod sliding;

use sliding::*;
use tissue::interact::{Instrument, InstrumentKind};
use tissue::math::{Real, Vec3};
use tissue::scene::Scene;
use tissue::sim::Simulation;

/// What a run gave at each step: time, force on the probe, and the worst pull of a contact
/// (its reaction along the instrument's outward normal, relative to |F|; positive pulls).
struct Step {
    t: Real,
    force: Vec3,
    pull: Real,
}

fn run(sim: &mut Simulation, end: Real, dt: Real) -> Vec<Step> {
    let mut out = Vec::new();
    while sim.time() < end - 1e-9 {
        let r = sim.step(dt).unwrap();
        let probe = &sim.instruments()[0];
        let shape = probe.shape().unwrap();
        let size = r.forces[0].length().max(1e-300);
        let pull = probe
            .contacts()
            .iter()
            .zip(probe.contact_reactions())
            .map(|(k, g)| g.dot(k.normal(&shape, probe.position())) / size)
            .fold(0.0, Real::max);
        out.push(Step {
            t: r.time,
            force: r.forces[0],
            pull,
        });
    }
    out
}

/// The largest change of the force between steps over (from, to], relative to the last force.
fn jump(h: &[Step], from: Real, to: Real) -> Real {
    let w: Vec<&Step> = h
        .iter()
        .filter(|s| s.t > from && s.t <= to + 1e-9)
        .collect();
    let last = w.last().unwrap().force.length();
    w.windows(2)
        .map(|p| (p[1].force - p[0].force).length() / last)
        .fold(0.0, Real::max)
}

fn force_at(h: &[Step], t: Real) -> Vec3 {
    h.iter().rfind(|s| s.t <= t + 1e-9).unwrap().force
}

const DEPTH: Real = 3e-4;

fn top(x: Real) -> Vec3 {
    Vec3::new(x, 0.0, H + SLIDE_R)
}

/// `linked-volumes` (16 voxels along the block, 2.5 mm) on the 8-cell block, implicit
/// Euler at 1 ms, a 20 mm probe: pressed 0.3 mm at x = −1.5 mm, held, slid 1 mm along x,
/// held 0.6 s (the mass damping, α = 20/s, takes the slowest modes down by e^−α·t/2 = 0.25 %
/// in that time), lifted (path A); and pressed straight down at x = −0.5 mm and held (B).
fn linked_volumes(relaxed: bool, slid: bool) -> Vec<Step> {
    let mesh = block(L, H, 8, &|_| 0.0);
    let built = model("linked-volumes", &mesh, 0.3);
    let mut sim = sim_on_floor(if relaxed {
        Box::new(Relaxed(built))
    } else {
        built
    });
    let (a, b) = (top(-1.5e-3), top(-0.5e-3));
    let down = -Vec3::Z * DEPTH;
    let keys = if slid {
        vec![
            (0.0, a),
            (0.3, a + down),
            (0.6, a + down),
            (0.9, b + down),
            (1.5, b + down),
            (1.6, b + Vec3::Z * 2e-3),
            (1.7, b + Vec3::Z * 2e-3),
        ]
    } else {
        vec![(0.0, b), (0.3, b + down), (1.5, b + down)]
    };
    let end = keys.last().unwrap().0;
    let probe = Instrument::new("probe", InstrumentKind::Probe, SLIDE_R, path(&keys))
        .unwrap()
        .with_friction(0.0)
        .unwrap();
    sim.add_instrument(probe);
    run(&mut sim, end, 1e-3)
}

/// `linked-volumes`: no contact pulls at any step; the held press is steady (the force
/// changes by less than 0.1 % a step); slid 1 mm and held, the force is the straight
/// press's at the new place within 5 % (measured 3.4 %: an element is held along the mean
/// normal of the vertices near the instrument it carries, not only those touching it, and
/// that tilt keeps a little memory of the path; the normal of the touching vertices alone
/// cut it to 0.8 % but made the held force jump by 2.4 % a step as vertices touched and
/// left); lifted, nothing is held. "Before" (the relaxation of targets held in full,
/// `Relaxed`) with `PUSH_ONLY_BEFORE` set: a contact pulling 2.9 times the probe force, 223
/// of 1700 steps pulling the probe in, forces 5 times apart after the two paths.
#[test]
fn linked_volumes_frictionless_contact_pushes_only_and_forgets_its_path() {
    let slid = linked_volumes(false, true);
    let straight = linked_volumes(false, false);
    let worst_pull = slid.iter().map(|s| s.pull).fold(0.0, Real::max);
    let pulls = slid.iter().filter(|s| s.force.z < 0.0).count();
    let held_jump = jump(&slid, 0.45, 0.6);
    let again_jump = jump(&slid, 1.35, 1.5);
    let (fa, fb) = (force_at(&slid, 1.5), force_at(&straight, 1.5));
    let memory = (fa - fb).length() / fb.z;
    let sliding = slid
        .iter()
        .filter(|s| s.t > 0.65 && s.t <= 0.9)
        .map(|s| tangential(s.force) / s.force.z)
        .fold(0.0, Real::max);
    eprintln!(
        "linked-volumes along normals: held {:.5} N (jump {held_jump:.1e} of it a step), slid and held {fa:.5} against {fb:.5} straight ({memory:.2e}), |Ft|/Fn sliding {sliding:.3}, worst contact pull {worst_pull:.1e}, steps pulling {pulls}",
        force_at(&slid, 0.6).z
    );
    // `PUSH_ONLY_BEFORE`: also the relaxation of targets held in full (before), 6 s more.
    if std::env::var("PUSH_ONLY_BEFORE").is_ok() {
        let before = linked_volumes(true, true);
        let before_straight = linked_volumes(true, false);
        eprintln!(
            "linked-volumes relaxed (before): held {:.5} N (jump {:.1e}), slid and held {:.5} against {:.5} straight, worst contact pull {:.1e}, steps pulling {}",
            force_at(&before, 0.6).z,
            jump(&before, 0.45, 0.6),
            force_at(&before, 1.5),
            force_at(&before_straight, 1.5),
            before.iter().map(|s| s.pull).fold(0.0, Real::max),
            before.iter().filter(|s| s.force.z < 0.0).count(),
        );
    }
    assert!(worst_pull <= 1e-12, "{worst_pull}");
    assert_eq!(pulls, 0);
    assert!(force_at(&slid, 0.6).z > 0.0);
    assert!(
        held_jump < 1e-3 && again_jump < 1e-3,
        "{held_jump} {again_jump}"
    );
    assert!(memory < 0.05, "{fa} against {fb}");
    let lifted = slid.last().unwrap();
    assert_eq!(lifted.force, Vec3::ZERO);
}

fn repo(rel: &str) -> String {
    format!("{}/../../{rel}", env!("CARGO_MANIFEST_DIR"))
}

/// The shipped sheet (`sheet-spline.toml`: a 6 cm square spline shell, edges held, 5 mm
/// probe) with `contact`, the probe pressed 3 mm at x = 27 mm, held, slid to x = 33 mm and
/// held to 2 s (`slid`), or pressed straight down at 33 mm and held.
fn sheet(contact: &str, slid: bool) -> Vec<Step> {
    let text = std::fs::read_to_string(repo("scenes/sheet-spline.toml")).unwrap();
    let keys = if slid {
        "[ { t = 0.0, position = [0.027, 0.03, 0.0052] }, { t = 0.5, position = [0.027, 0.03, 0.0022] }, { t = 0.8, position = [0.027, 0.03, 0.0022] }, { t = 1.2, position = [0.033, 0.03, 0.0022] }, { t = 2.0, position = [0.033, 0.03, 0.0022] } ]"
    } else {
        "[ { t = 0.0, position = [0.033, 0.03, 0.0052] }, { t = 0.5, position = [0.033, 0.03, 0.0022] }, { t = 2.0, position = [0.033, 0.03, 0.0022] } ]"
    };
    let start = text.find("path = [").unwrap();
    let end = start + text[start..].find("]\n").unwrap() + 1;
    let text = format!(
        "{}contact = \"{contact}\"\npath = {keys}{}",
        &text[..start],
        &text[end..]
    );
    let dir = repo("scenes");
    let scene = Scene::from_toml(
        &text,
        std::path::Path::new(&dir),
        std::path::Path::new("sheet-spline.toml"),
    )
    .unwrap();
    let mut sim = scene.build().unwrap();
    let out = run(&mut sim, 2.0, scene.run.dt);
    if slid {
        // Settled: the supports hold what the probe pushes.
        let balance = out.last().unwrap().force + sim.fixed_reaction_total();
        let f = out.last().unwrap().force.length();
        eprintln!(
            "sheet, {contact}: supports + probe {:.2e} N of {f:.4} N",
            balance.length()
        );
    }
    out
}

/// `spline`: a frictionless contact is a penalty spring along the normal that only pushes
/// (`spline::system`): no contact pulls; slid and held, the sheet settles where a straight
/// press at the new place leaves it, within 2 % (a sticking contact keeps the drag it built
/// up: printed beside it).
#[test]
fn spline_frictionless_contact_pushes_only_and_forgets_its_path() {
    let slid = sheet("sliding", true);
    let straight = sheet("sliding", false);
    let worst_pull = slid.iter().map(|s| s.pull).fold(0.0, Real::max);
    let (fa, fb) = (force_at(&slid, 2.0), force_at(&straight, 2.0));
    let memory = (fa - fb).length() / fb.z;
    // `PUSH_ONLY_BEFORE`: the same with sticking contact (measured 2.9e-2).
    let sticking = std::env::var("PUSH_ONLY_BEFORE").is_ok().then(|| {
        (force_at(&sheet("sticking", true), 2.0) - force_at(&sheet("sticking", false), 2.0))
            .length()
            / fb.z
    });
    eprintln!(
        "sheet spline, frictionless: held {:.5} N, slid and held {fa:.5} against {fb:.5} straight ({memory:.2e}; sticking {sticking:?}), worst contact pull {worst_pull:.1e}, held jump {:.1e}",
        force_at(&slid, 0.8).z,
        jump(&slid, 1.8, 2.0)
    );
    assert!(worst_pull <= 1e-12, "{worst_pull}");
    assert!(slid.iter().all(|s| s.force.z >= 0.0));
    assert!(fb.z > 1e-3, "{fb}");
    assert!(memory < 0.02, "{fa} against {fb}");
}
