//! Frictionless contact on `hybrid` (issue 20): the pre-computed rest holds a contact along
//! its normal only while it pushes (an active set of rows of its condensed response,
//! settled within the step), the tensor-mass region by the integrator's push-only
//! projection. Checked against physics on the graded block of `sliding/` (4 × 4 × 2 cm,
//! E = 3 kPa, ν = 0.3, α = 20/s, floor fixed; a 20 mm probe pressed 0.3 mm):
//!
//! - pressed on the rest and held: no contact pulls at any step, and the settled force is
//!   `fem-static`'s on the same mesh (the rest is linear FEM, the region linear
//!   tensor-mass: one linear elastic model, so one equilibrium); the supports balance it;
//! - slid sideways and held: the sideways force stays what the discrete surface gives
//!   (`fem-static`'s own share while sliding) and the slid state is that of a straight press
//!   at the end point (a frictionless contact keeps no memory of its path);
//! - the probe across the interface: contacts on both parts at once, both only pushing.

mod sliding;

use sliding::*;
use tissue::interact::{Instrument, InstrumentKind};
use tissue::math::{Real, Vec3};
use tissue::sim::Simulation;

/// What a run gave at each step: time, force on the probe, the worst pull of a contact
/// (its reaction along the instrument's outward normal, relative to |F|; positive pulls),
/// and the probe's contacts on the rest (label 0) and on the region.
struct Step {
    t: Real,
    force: Vec3,
    pull: Real,
    on_rest: usize,
    on_region: usize,
}

fn run(sim: &mut Simulation, end: Real, dt: Real) -> Vec<Step> {
    let mut out = Vec::new();
    while sim.time() < end - 1e-9 {
        let r = sim.step(dt).unwrap();
        let probe = &sim.instruments()[0];
        let shape = probe.shape().unwrap();
        let size = r.forces[0].length().max(1e-300);
        let labels = sim.model().vertex_labels();
        let (mut on_rest, mut on_region) = (0, 0);
        let mut pull: Real = 0.0;
        for (k, g) in probe.contacts().iter().zip(probe.contact_reactions()) {
            pull = pull.max(g.dot(k.normal(&shape, probe.position())) / size);
            if *g == Vec3::ZERO {
                continue; // handed over near the probe, not touching
            }
            match labels.as_ref().map(|l| l[k.vertex as usize]) {
                Some(0) => on_rest += 1,
                Some(_) => on_region += 1,
                None => {}
            }
        }
        out.push(Step {
            t: r.time,
            force: r.forces[0],
            pull,
            on_rest,
            on_region,
        });
    }
    out
}

fn force_at(h: &[Step], t: Real) -> Vec3 {
    h.iter().rfind(|s| s.t <= t + 1e-9).unwrap().force
}

fn top(x: Real) -> Vec3 {
    Vec3::new(x, 0.0, H + SLIDE_R)
}

const CELLS: usize = 8;
const DT: Real = 1e-3;

/// The hybrid on the block with the region `region` (a `cut_region` table), linear
/// tensor-mass in it (the rest is linear FEM: together one linear elastic model).
fn hybrid_sim(region: &str) -> Simulation {
    hybrid_sim_on(region, CELLS)
}

/// `hybrid_sim` on a block of `cells` cells across.
fn hybrid_sim_on(region: &str, cells: usize) -> Simulation {
    let mesh = block(L, H, cells, &|_| 0.0);
    let params: toml::Table =
        toml::from_str(&format!("cut_region = {region}\nnonlinear = false")).unwrap();
    sim_on_floor(model_with("hybrid", &mesh, 0.3, params))
}

/// A small region in a top corner, away from the probe: the probe presses the rest.
const CORNER: &str = "{ sphere = { center = [0.02, 0.02, 0.02], radius = 0.008 } }";
/// The half x > 0: the interface is the plane x = 0, under the probe.
const HALF: &str = "{ box = { min = [0.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] } }";

/// A frictionless probe along `keys` on `sim`.
fn press(mut sim: Simulation, keys: &[(Real, Vec3)]) -> (Vec<Step>, Simulation) {
    let end = keys.last().unwrap().0;
    let probe = Instrument::new("probe", InstrumentKind::Probe, SLIDE_R, path(keys)).unwrap();
    sim.add_instrument(probe);
    let h = run(&mut sim, end, DT);
    (h, sim)
}

/// `fem-static`'s force on the same mesh, the probe pressed 0.3 mm at `x`.
fn fem_static_at(x: Real) -> Vec3 {
    let mesh = block(L, H, CELLS, &|_| 0.0);
    let sim = sim_on_floor(model("fem-static", &mesh, 0.3));
    let down = top(x) - Vec3::Z * SLIDE_DEPTH;
    let (h, _) = press(sim, &[(0.0, top(x)), (0.1, down), (0.2, down)]);
    h.last().unwrap().force
}

/// Pressed 0.3 mm at x = −0.5 mm on the rest over 0.3 s and held to 1 s: no contact pulls at
/// any step, the held force is `fem-static`'s within 1 % (the slowest mode left after the
/// 0.7 s hold decays as e^(−α t / 2) = e^(−7) ≈ 1e-3 with α = 20/s; the region's lumped
/// masses and tensor-mass stiffness change the path to it, not the equilibrium), and the
/// supports hold what the probe pushes, within 1 % of it.
#[test]
fn hybrid_press_on_the_rest_pushes_only_and_settles_on_fem_static() {
    let b = top(-0.5e-3);
    let down = b - Vec3::Z * SLIDE_DEPTH;
    let (h, sim) = press(hybrid_sim(CORNER), &[(0.0, b), (0.3, down), (1.0, down)]);
    let reference = fem_static_at(-0.5e-3);
    let held = h.last().unwrap().force;
    let balance = (held + sim.fixed_reaction_total()).length() / held.length();
    let worst_pull = h.iter().map(|s| s.pull).fold(0.0, Real::max);
    let pulls = h.iter().filter(|s| s.force.z < 0.0).count();
    let on_rest = h.iter().map(|s| s.on_rest).max().unwrap();
    let on_region = h.iter().map(|s| s.on_region).max().unwrap();
    let info = sim.model().info();
    let detail = |k: &str| {
        info.details
            .iter()
            .find(|(n, _)| n == k)
            .map(|(_, v)| v.clone())
            .unwrap_or_default()
    };
    eprintln!(
        "hybrid press on the rest: held {held} against fem-static {reference} ({:+.2e}), supports + probe {balance:.1e} of |F|, worst contact pull {worst_pull:.1e}, steps pulling {pulls}, contacts on the rest {on_rest}, on the region {on_region}, solves {}, capped steps {}",
        (held.z - reference.z) / reference.z,
        detail("rest_contact_solves"),
        detail("rest_contact_capped_steps"),
    );
    assert!(on_rest > 0 && on_region == 0, "{on_rest} {on_region}");
    assert!(worst_pull <= 1e-12, "{worst_pull}");
    assert_eq!(pulls, 0);
    assert!(
        (held - reference).length() < 0.01 * reference.z,
        "{held} against {reference}"
    );
    assert!(balance < 0.01, "{balance}");
    assert_eq!(detail("rest_contact_capped_steps"), "0");
}

/// The sideways share |F_t|/F_n over `(from, to]`, at most.
fn sideways(h: &[Step], from: Real, to: Real) -> Real {
    h.iter()
        .filter(|s| s.t > from && s.t <= to + 1e-9)
        .map(|s| tangential(s.force) / s.force.z)
        .fold(0.0, Real::max)
}

/// The slide: pressed 0.3 mm at x = −1.5 mm over 0.3 s, held to 0.6 s, slid 1 mm along x to
/// x = −0.5 mm by 0.9 s (3.3 mm/s), held to 1.5 s.
fn slide_keys() -> Vec<(Real, Vec3)> {
    let down = -Vec3::Z * SLIDE_DEPTH;
    let (a, b) = (top(-1.5e-3), top(-0.5e-3));
    vec![
        (0.0, a),
        (0.3, a + down),
        (0.6, a + down),
        (0.9, b + down),
        (1.5, b + down),
    ]
}

/// Slid frictionless on the rest: no contact pulls at any step; while sliding the sideways
/// force is no more than the discrete surface gives with `fem-static`'s exact normal holds
/// along the same path (its share, plus 0.2 % of the normal force for the motion: the
/// mass damping drags the moving dimple); slid and held, the force is that of the straight
/// press at the end point (`fem-static`'s there, which the straight hybrid press meets to
/// 3e-8 above) within 0.5 %: a frictionless contact keeps no memory of its path.
#[test]
fn hybrid_slide_on_the_rest_is_frictionless_and_forgets_its_path() {
    let (h, _) = press(hybrid_sim(CORNER), &slide_keys());
    let mesh = block(L, H, CELLS, &|_| 0.0);
    let (fs, _) = press(sim_on_floor(model("fem-static", &mesh, 0.3)), &slide_keys());
    let straight = fem_static_at(-0.5e-3);
    let held = force_at(&h, 1.5);
    let memory = (held - straight).length() / straight.z;
    let share = sideways(&h, 0.65, 0.9);
    let share_static = sideways(&fs, 0.65, 0.9);
    let worst_pull = h.iter().map(|s| s.pull).fold(0.0, Real::max);
    let pulls = h.iter().filter(|s| s.force.z < 0.0).count();
    eprintln!(
        "hybrid slide on the rest: |Ft|/Fn sliding {share:.4} (fem-static {share_static:.4}), slid and held {held} against a straight press {straight} ({memory:.1e}), worst contact pull {worst_pull:.1e}, steps pulling {pulls}"
    );
    assert!(worst_pull <= 1e-12, "{worst_pull}");
    assert_eq!(pulls, 0);
    assert!(
        share <= share_static + 2e-3,
        "{share} against {share_static}"
    );
    assert!(memory < 5e-3, "{held} against {straight}");
}

/// The probe across the interface (the region is the half x > 0, the probe pressed at
/// x = 0 and held): contacts on both parts at once, on the rest rows of its condensed
/// response held along their normals, on the region the integrator's projections; none
/// pulls at any step, and the held force is `fem-static`'s (one linear elastic model across
/// the interface) within 1 %, as on the rest alone.
#[test]
fn hybrid_contact_across_the_interface_pushes_only_on_both_parts() {
    let b = top(0.0);
    let down = b - Vec3::Z * SLIDE_DEPTH;
    let (h, _) = press(hybrid_sim(HALF), &[(0.0, b), (0.3, down), (1.0, down)]);
    let reference = fem_static_at(0.0);
    let held = h.last().unwrap().force;
    let both = h
        .iter()
        .filter(|s| s.on_rest > 0 && s.on_region > 0)
        .count();
    let worst_pull = h.iter().map(|s| s.pull).fold(0.0, Real::max);
    let pulls = h.iter().filter(|s| s.force.z < 0.0).count();
    let last = h.last().unwrap();
    eprintln!(
        "hybrid across the interface: held {held} against fem-static {reference} ({:+.2e}), steps with contacts on both parts {both} of {}, at the end {} on the rest and {} on the region, worst contact pull {worst_pull:.1e}, steps pulling {pulls}",
        (held.z - reference.z) / reference.z,
        h.len(),
        last.on_rest,
        last.on_region
    );
    assert!(last.on_rest > 0 && last.on_region > 0);
    assert!(worst_pull <= 1e-12, "{worst_pull}");
    assert_eq!(pulls, 0);
    assert!(
        (held - reference).length() < 0.01 * reference.z,
        "{held} against {reference}"
    );
}

/// The shipped hybrid scenes (`liver-hybrid.toml`, `liver-hybrid-auto.toml`) with the probe
/// frictionless (the scene's `contact = "sticking"` line dropped) or as shipped: per run,
/// the steps touching, the steps where a contact pulls along its normal (a real pull), the
/// steps whose force points along the probe's motion, the force at the end and the largest,
/// and the most contacts on the rest and on the region at once. A study (prints only):
/// `cargo test --release -p tissue --test hybrid_sliding -- --ignored --nocapture`.
#[test]
#[ignore = "study of the shipped scenes: prints a table"]
fn hybrid_shipped_scenes_study() {
    for name in ["liver-hybrid", "liver-hybrid-auto"] {
        for sticking in [true, false] {
            let dir = format!("{}/../../scenes", env!("CARGO_MANIFEST_DIR"));
            let text = std::fs::read_to_string(format!("{dir}/{name}.toml")).unwrap();
            let text: String = text
                .lines()
                .filter(|l| sticking || !l.trim_start().starts_with("contact = \"sticking\""))
                .map(|l| format!("{l}\n"))
                .collect();
            let scene = tissue::scene::Scene::from_toml(
                &text,
                std::path::Path::new(&dir),
                std::path::Path::new(&format!("{name}.toml")),
            )
            .unwrap();
            let mut sim = scene.build().unwrap();
            let p = sim
                .instruments()
                .iter()
                .position(|i| matches!(i.kind(), InstrumentKind::Probe))
                .unwrap();
            let motion = {
                let i = &sim.instruments()[p];
                (i.position_at(scene.run.duration) - i.position_at(0.0)).normalize_or_zero()
            };
            let (mut touching, mut pulling, mut along, mut rest, mut region) = (0, 0, 0, 0, 0);
            let mut largest: Real = 0.0;
            let mut last = Vec3::ZERO;
            let cpu = std::time::Instant::now();
            while sim.time() < scene.run.duration - 1e-9 {
                let r = sim.step(scene.run.dt).unwrap();
                let probe = &sim.instruments()[p];
                let f = r.forces[p];
                let size = f.length().max(1e-300);
                if f != Vec3::ZERO {
                    touching += 1;
                }
                let (mut on_rest, mut on_region) = (0, 0);
                let labels = sim.model().vertex_labels();
                let mut pulls = false;
                if let Some(shape) = probe.shape() {
                    for (k, g) in probe.contacts().iter().zip(probe.contact_reactions()) {
                        pulls |= g.dot(k.normal(&shape, probe.position())) / size > 1e-9;
                        if *g != Vec3::ZERO {
                            match labels.as_ref().map(|l| l[k.vertex as usize]) {
                                Some(0) => on_rest += 1,
                                Some(_) => on_region += 1,
                                None => {}
                            }
                        }
                    }
                }
                pulling += usize::from(pulls);
                along += usize::from(f.dot(motion) > 0.0);
                rest = rest.max(on_rest);
                region = region.max(on_region);
                largest = largest.max(f.length());
                last = f;
            }
            let info = sim.model().info();
            let detail = |k: &str| {
                info.details
                    .iter()
                    .find(|(n, _)| n == k)
                    .map(|(_, v)| v.clone())
                    .unwrap_or_default()
            };
            println!(
                "{name}, {}: {touching} steps touching, {pulling} with a contact pulling, {along} with the force along the motion; at the end {last} N, largest {largest:.4} N; contacts at once: {rest} on the rest, {region} on the region; rest contact solves {}, capped steps {}; {:.1} s",
                if sticking { "sticking" } else { "frictionless" },
                detail("rest_contact_solves"),
                detail("rest_contact_capped_steps"),
                cpu.elapsed().as_secs_f64()
            );
        }
    }
}

/// The slide of `hybrid_slide_on_the_rest_is_frictionless_and_forgets_its_path` on the
/// 16-cell block, where `fem-static`'s sideways share while sliding is 0.4 % (the 8-cell
/// surface's facets give 1.7 %): the hybrid's share, beside `fem-static`'s on the same mesh.
/// A study (prints only; about a minute).
#[test]
#[ignore = "study: the slide on the 16-cell block"]
fn hybrid_slide_on_the_finer_block_study() {
    let cpu = std::time::Instant::now();
    let (h, _) = press(hybrid_sim_on(CORNER, 16), &slide_keys());
    let hybrid_s = cpu.elapsed().as_secs_f64();
    let mesh = block(L, H, 16, &|_| 0.0);
    let (fs, _) = press(sim_on_floor(model("fem-static", &mesh, 0.3)), &slide_keys());
    let pulls = h.iter().filter(|s| s.force.z < 0.0).count();
    let worst_pull = h.iter().map(|s| s.pull).fold(0.0, Real::max);
    println!(
        "16 cells: |Ft|/Fn sliding {:.4} (fem-static {:.4}); held after the slide {} (fem-static {}); worst contact pull {worst_pull:.1e}, steps pulling {pulls}; hybrid {hybrid_s:.1} s",
        sideways(&h, 0.65, 0.9),
        sideways(&fs, 0.65, 0.9),
        force_at(&h, 1.5),
        force_at(&fs, 1.5),
    );
}

/// `liver-hybrid-auto.toml` with the smooth liver as its contact surface (`visual`): the
/// probe presses the liver toward the scalpel's path, and the region grown ahead of the blade
/// must cover the tetrahedra the blade meets where they are now, not only where they were at
/// rest: before, the cut was refused at 0.57 s ("within one element of the region's
/// border"). The scene runs to its end and the blade cuts.
#[test]
fn the_auto_region_grows_over_what_the_pressed_liver_brings_under_the_blade() {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-hybrid-auto.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"));
    let text = text.replacen(
        "[mesh]\n",
        &format!("[mesh]\nvisual = \"{root}/assets/meshes/liver-smooth.obj\"\n"),
        1,
    );
    let base = std::path::Path::new(&root).join("scenes/liver-hybrid-auto.toml");
    let scene = tissue::scene::Scene::from_toml(&text, base.parent().unwrap(), &base).unwrap();
    let mut sim = scene.build().unwrap();
    assert!(sim.fine_surface().is_some());
    let triangles = sim.model().surface().triangles.len();
    for k in 0..scene.run.step_count() {
        sim.step(scene.run.dt)
            .unwrap_or_else(|e| panic!("step {k}: {e}"));
    }
    assert_ne!(
        sim.model().surface().triangles.len(),
        triangles,
        "the blade cut nothing"
    );
}

/// A probe that starts inside the demo liver (`liver-probe.toml` as `hybrid`, the probe
/// from (−20.0, 26.0, 18.0) mm to one radius past the smooth surface in 0.3 s, 10 ms steps)
/// puts two new frictionless contacts on the rest at the first step: the coupling then has
/// a stiff mode at the interface that the warm re-measure misses, and the region's
/// explicit step at the measured 15 substeps diverges. The integrator retries a refused
/// step with more substeps; doubling the stiffness margin per retry reached 42 substeps
/// and still diverged (found by random presses, it blew the viewer's hybrid up at random);
/// quadrupling it reaches 60, which holds. The run must go to its end, every force finite.
#[test]
fn hybrid_survives_a_probe_that_starts_inside_the_liver() {
    let dir = format!("{}/../../scenes", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{dir}/liver-probe.toml")).unwrap();
    let mut out = String::new();
    let mut in_model = false;
    let mut skip_path = false;
    for l in text.lines() {
        let t = l.trim_start();
        if t.starts_with('[') {
            in_model = t.starts_with("[model]");
        }
        if in_model && t.starts_with("kind =") {
            out.push_str("kind = \"hybrid\"\n");
            continue;
        }
        if t.starts_with("path = [") {
            skip_path = true;
            out.push_str(
                "path = [ { t = 0.0, position = [-0.0200368, 0.0260494, 0.018043] },\n\
                 { t = 0.3, position = [-0.0191033, 0.0312656, 0.00840351] } ]\n",
            );
        }
        if skip_path {
            skip_path = !t.ends_with("] } ]") && !t.ends_with("}]");
            continue;
        }
        out.push_str(l);
        out.push('\n');
    }
    assert!(out.contains("kind = \"hybrid\"") && out.contains("0.0260494"));
    let scene = tissue::scene::Scene::from_toml(
        &out,
        std::path::Path::new(&dir),
        std::path::Path::new("liver-probe-hybrid.toml"),
    )
    .unwrap();
    let mut sim = scene.build().unwrap();
    let mut largest: Real = 0.0;
    while sim.time() < 0.6 - 1e-9 {
        let r = sim
            .step(0.01)
            .unwrap_or_else(|e| panic!("at t = {}: {e}", sim.time()));
        for f in &r.forces {
            assert!(f.is_finite(), "at t = {}: {f}", sim.time());
            largest = largest.max(f.length());
        }
    }
    // Push-only contact: the tissue pushes the probe back against its press, never along it.
    let press = (Vec3::new(-0.0191033, 0.0312656, 0.00840351)
        - Vec3::new(-0.0200368, 0.0260494, 0.018043))
    .normalize();
    let last = sim.step(0.01).unwrap();
    let against = -last.forces[0].dot(press);
    eprintln!(
        "largest probe force over 0.6 s: {largest:.4} N; at the end {:.4} N against the press",
        against
    );
    assert!(largest > 0.0, "the probe must touch the liver");
    assert!(
        against > 0.0,
        "the probe force must oppose its press: {against}"
    );
}

/// The demo liver (`liver-probe.toml`: the 1 cm liver, its smooth surface as the contact
/// surface, ligaments held, a 5 mm frictionless probe) as `hybrid`, the probe on `path` (a
/// TOML array of keyframes).
fn demo_liver_hybrid(path: &str) -> Simulation {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = format!(
        "[mesh]\nfile = \"{root}/assets/meshes/liver.msh\"\nscale = 0.01\n\
         visual = \"{root}/assets/meshes/liver-smooth.obj\"\n\
         [material]\nyoung_modulus = 3000.0\npoisson_ratio = 0.3\ndensity = 1000.0\n\
         [model]\nkind = \"hybrid\"\n\
         [[fixed]]\nname = \"ligaments\"\nfile_vertices = [3, 39, 64]\n\
         [[instrument]]\nkind = \"probe\"\nradius = 0.005\npath = {path}\n\
         [run]\nduration = 1.0\ndt = 0.01\n"
    );
    let base = std::path::Path::new(&root).join("scenes/liver-probe.toml");
    let scene = tissue::scene::Scene::from_toml(&text, base.parent().unwrap(), &base).unwrap();
    scene.build().unwrap()
}

/// The viewer releasing its probe: a press into the demo liver (a random vertex's press
/// that diverged, `udr16`), held, then the probe moved 0.3 m away within one 10 ms step.
/// The rest's frictionless contacts that pushed at the end of the last step were guessed
/// held with targets on the probe's new place; the region's step diverged before the pull
/// could be seen after it (session 18 took the step again without them, said as capped).
/// Now a contact whose force pulls where the step starts is let go before the step: the
/// run goes on, no step is capped, and the probe holds nothing after the lift.
#[test]
fn hybrid_lets_go_of_a_probe_lifted_away_within_one_step() {
    let mut sim = demo_liver_hybrid(
        "[ { t = 0.0, position = [-0.048077, 0.00555944, -0.00719626] },\n\
         { t = 0.3, position = [-0.0404262, 0.0124708, -0.00336242] },\n\
         { t = 0.5, position = [-0.0404262, 0.0124708, -0.00336242] },\n\
         { t = 0.51, position = [0.0, 0.3, 0.0] } ]",
    );
    let (mut held, mut lift, mut capped) = (0.0 as Real, 0.0 as Real, Vec::new());
    while sim.time() < 0.7 - 1e-9 {
        let r = sim
            .step(0.01)
            .unwrap_or_else(|e| panic!("at t = {}: {e}", sim.time()));
        assert!(r.forces[0].is_finite(), "at t = {}", r.time);
        if r.info.capped {
            capped.push(r.time);
        }
        if r.time < 0.5 + 1e-9 {
            held = r.forces[0].length();
        } else if r.time < 0.51 + 1e-9 {
            // The lift's own step: the push of the planes it started with (0.48 mN of the
            // 0.125 N held with main at 756577c merged; 0 on 74b582c), a mean over the step.
            lift = r.forces[0].length();
        } else {
            assert_eq!(r.forces[0], Vec3::ZERO, "at t = {}: after the lift", r.time);
        }
    }
    eprintln!(
        "probe force before the lift {held:.4} N, in the lift's step {lift:.2e} N; capped \
         steps at {capped:?}"
    );
    assert!(lift < 0.01 * held, "{lift} N in the lift's step");
    assert!(held > 1e-3, "the probe must press the liver: {held} N");
    assert!(capped.is_empty(), "capped steps at {capped:?}");
}

/// `tissue compare --quick`'s deep press on `hybrid` (the liver, the probe of half the
/// organ's height pressed 9.9 mm over 0.15 s by a smooth ramp, then held, `DT` = 1 ms
/// steps, no mass damping, kinetic damping: velocities zeroed at each kinetic-energy peak,
/// none with `NOSTOP`), traced step by step from `FROM` s for `STEPS` steps: the probe
/// force, the kinetic energy, each touching contact (R: on the rest, G: on the region;
/// vertex, push in N) and the four surface vertices that moved most in the step (label:
/// 0 rest, 1 the region's border, 2 the region; how far from the probe's surface). With
/// `PLANES`, each face plane: its vertex's distance in front of it at the step's end and
/// start (µm; `*`: it pushed). With `FREEZE` = t, from t on the model steps by itself under
/// the last planes the simulation placed (none placed again). `T_END` ends the run (1.5 s).
/// A study (prints only): `FROM=1.2 STEPS=4 cargo test --release -p tissue --test
/// hybrid_sliding deep_press_trace -- --ignored --nocapture`; docs/hybrid.md, "Session 19"
/// and "Session 20".
#[test]
#[ignore = "study: traces the comparison's deep press on hybrid"]
fn hybrid_deep_press_trace_study() {
    use tissue::compare::drive::{ContactLaw, smooth_ramp, touching_probe};
    use tissue::compare::{Organ, Scenario};
    use tissue::material::Material;
    let var = |k: &str, d: Real| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let mut mesh = tissue::io::read(format!("{root}/assets/meshes/liver.msh")).unwrap();
    for v in &mut mesh.vertices {
        *v *= 0.01;
    }
    let material = Material::new(3000.0, 0.3).unwrap();
    let organ = Organ::new(mesh, "liver".into(), material, 0.0, 800).unwrap();
    let sc = Scenario::of(&organ.mesh).unwrap();
    let model = organ.build("hybrid", material).unwrap();
    let mut sim = touching_probe(model, &sc, ContactLaw::FineSurface).unwrap();
    let (dt, ramp) = (var("DT", 1e-3), 0.15);
    let (from, steps) = (var("FROM", 0.9), var("STEPS", 12.0) as usize);
    let end = var("T_END", 1.5);
    let top = sc.probe() + Vec3::Y * sc.probe_radius;
    let (mut last, mut peak, mut stops) = (0.0, 0.0 as Real, 0);
    let mut prev: Vec<Vec3> = sim.model().surface().positions.to_vec();
    let mut k = 0;
    while (k as Real + 1.0) * dt < end + 1e-9 {
        k += 1;
        let t = k as Real * dt;
        let f = smooth_ramp(t / ramp);
        sim.set_instrument_position(0, Some(top - Vec3::Y * (f * sc.deep)))
            .unwrap();
        let trace = t >= from && t < from + steps as Real * dt;
        if trace {
            prev = sim.model().surface().positions.to_vec();
        }
        let freeze = var("FREEZE", 1e9);
        if t > freeze + 0.5 * dt {
            // The planes as the last simulation step placed them, held for good.
            let info = sim.model_mut().step(dt).unwrap();
            let e = sim.model().kinetic_energy().unwrap_or(0.0);
            peak = peak.max(e);
            let stopped =
                std::env::var("NOSTOP").is_err() && e < last && sim.model_mut().stop_motion();
            if stopped {
                stops += 1;
                last = 0.0;
            } else {
                last = e;
            }
            let f: Vec3 = sim.model().reactions().prescribed.iter().copied().sum();
            if trace {
                println!(
                    "t {t:.4} F {:.5e} KE {e:.3e} KE/peak {:.2e}{} stops {stops} substeps {} (frozen)",
                    -f.y,
                    e / peak.max(1e-300),
                    if stopped { " (stopped)" } else { "" },
                    info.substeps
                );
            }
            continue;
        }
        let r = sim.step(dt).unwrap();
        let e = sim.model().kinetic_energy().unwrap_or(0.0);
        peak = peak.max(e);
        let stopped = std::env::var("NOSTOP").is_err() && e < last && sim.model_mut().stop_motion();
        if stopped {
            stops += 1;
            last = 0.0;
        } else {
            last = e;
        }
        if trace {
            let probe = &sim.instruments()[0];
            let shape = probe.shape().unwrap();
            let labels = sim.model().vertex_labels();
            let held: Vec<String> = probe
                .contacts()
                .iter()
                .zip(probe.contact_reactions())
                .filter(|(_, g)| **g != Vec3::ZERO)
                .map(|(c, g)| {
                    let part = labels.as_ref().map_or(9, |l| l[c.vertex as usize]);
                    format!(
                        "{}{}:{:.2e}",
                        if part == 0 { "R" } else { "G" },
                        c.vertex,
                        -g.dot(c.normal(&shape, probe.position()))
                    )
                })
                .collect();
            let now = sim.model().surface().positions.to_vec();
            if std::env::var("PLANES").is_ok() {
                // Each plane: its vertex's distance in front of it at the step's end (µm)
                // and how far the plane sits from the vertex's place at the step's start.
                let planes: Vec<String> = probe
                    .contacts()
                    .iter()
                    .zip(probe.contact_reactions())
                    .filter_map(|(c, g)| {
                        let n = c.face?;
                        let v = c.vertex as usize;
                        Some(format!(
                            "{v}:end{:+.2}/start{:+.2}um{}",
                            1e6 * n.dot(now[v] - c.target),
                            1e6 * n.dot(prev[v] - c.target),
                            if *g == Vec3::ZERO { "" } else { "*" }
                        ))
                    })
                    .collect();
                println!("   planes: {}", planes.join(" "));
            }
            let mut moved: Vec<(Real, usize)> = now
                .iter()
                .zip(&prev)
                .map(|(a, b)| (a - b).length())
                .enumerate()
                .map(|(i, d)| (d, i))
                .collect();
            moved.sort_by(|a, b| b.0.total_cmp(&a.0));
            let c = sim.instruments()[0].position();
            let most: Vec<String> = moved[..4]
                .iter()
                .map(|&(d, i)| {
                    format!(
                        "v{i}[{}] {:.2}mm (from probe {:.1}mm)",
                        labels.as_ref().map_or(9, |l| l[i]),
                        1e3 * d,
                        1e3 * ((now[i] - c).length() - sc.probe_radius)
                    )
                })
                .collect();
            println!("   moved most: {}", most.join(", "));
            let d = sim.model().info().details;
            let solves = d
                .iter()
                .find(|(k, _)| k == "rest_contact_solves")
                .map_or("", |(_, v)| v.as_str());
            println!(
                "t {t:.4} F {:.5e} KE {e:.3e} KE/peak {:.2e}{} stops {stops} substeps {} solves [{solves}] held {}",
                r.forces[0].y,
                e / peak.max(1e-300),
                if stopped { " (stopped)" } else { "" },
                r.info.substeps,
                held.join(" ")
            );
        }
    }
}

/// The comparison's deep press on the linear hybrid (`nonlinear = false`: linear
/// tensor-mass in the region, the rest linear FEM: one linear elastic model), settled by the
/// comparison's kinetic damping at 1 ms under its contact planes as the simulation placed
/// them at 0.5 s (held from then on: the planes' own placement each step keeps a mode the
/// stops cannot drain, docs/hybrid.md "Session 20"). It comes to rest (the kinetic energy
/// under 1e-8 of the ramp's peak over at least the last 50 steps of 2 s: 547; it did before
/// the half kick after a stop too, 393), and so does the default St Venant–Kirchhoff region
/// (which without the half kick grew under the same frozen planes: the regression), and its
/// settled force is `fem-static`'s on the same mesh held on the same planes (those that
/// push at the end, along their normals: 3) within 1e-4 (9.9e-6 measured): the static
/// answer of its own parts, with no plane that does not push passed by `fem-static`'s
/// answer by more than 1 µm (none is).
#[test]
fn hybrid_deep_press_settles_by_kinetic_damping_on_fem_static_under_its_planes() {
    use tissue::compare::drive::{ContactLaw, smooth_ramp, touching_probe};
    use tissue::compare::{Organ, Scenario};
    use tissue::interact::{Constraints, Prescribed};
    use tissue::material::Material;
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let mut mesh = tissue::io::read(format!("{root}/assets/meshes/liver.msh")).unwrap();
    for v in &mut mesh.vertices {
        *v *= 0.01;
    }
    let material = Material::new(3000.0, 0.3).unwrap();
    let organ = Organ::new(mesh, "liver".into(), material, 0.0, 800).unwrap();
    let sc = Scenario::of(&organ.mesh).unwrap();
    // The deep press to 0.5 s through the simulation, then the model alone under those
    // planes to 2 s, kinetic damping throughout; returns the simulation and how many steps
    // at the end the kinetic energy stayed under 1e-8 of its peak.
    let settle = |params: &str| {
        let params: toml::Table = toml::from_str(params).unwrap();
        let model = organ.build_with("hybrid", material, &params).unwrap();
        let mut sim = touching_probe(model, &sc, ContactLaw::FineSurface).unwrap();
        let (dt, ramp, freeze, end) = (1e-3, 0.15, 0.5, 2.0);
        let top = sc.probe() + Vec3::Y * sc.probe_radius;
        let (mut last, mut peak, mut quiet) = (0.0, 0.0 as Real, 0);
        let steps = (end / dt) as usize;
        for k in 1..=steps {
            let t = k as Real * dt;
            if t <= freeze + 0.5 * dt {
                let f = smooth_ramp(t / ramp);
                sim.set_instrument_position(0, Some(top - Vec3::Y * (f * sc.deep)))
                    .unwrap();
                sim.step(dt).unwrap();
            } else {
                sim.model_mut().step(dt).unwrap();
            }
            let e = sim.model().kinetic_energy().unwrap();
            peak = peak.max(e);
            quiet = if t > freeze && e <= 1e-8 * peak {
                quiet + 1
            } else {
                0
            };
            if e < last && sim.model_mut().stop_motion() {
                last = 0.0;
            } else {
                last = e;
            }
        }
        (sim, quiet)
    };
    // The default, St Venant-Kirchhoff region: at rest too (before the half kick after a
    // stop its kinetic energy grew to 0.2 of the peak under the same frozen planes).
    let (_, quiet) = settle("");
    println!("nonlinear: {quiet} quiet steps at the end");
    assert!(
        quiet >= 50,
        "nonlinear, not at rest: {quiet} quiet steps at the end"
    );
    let (sim, quiet) = settle("nonlinear = false");
    println!("linear: {quiet} quiet steps at the end");
    assert!(quiet >= 50, "not at rest: {quiet} quiet steps at the end");
    let force: Vec3 = sim.model().reactions().prescribed.iter().copied().sum();
    // The planes (the probe's contacts, the model's prescribed entries in that order):
    // those that push at the end held along their normals on fem-static.
    let reactions = sim.model().reactions().prescribed.to_vec();
    let contacts = sim.instruments()[0].contacts();
    assert_eq!(reactions.len(), contacts.len());
    let planes: Vec<(u32, Vec3, Vec3, bool)> = contacts
        .iter()
        .zip(&reactions)
        .map(|(c, g)| {
            let n = c.face.expect("a face plane of the fine surface");
            (c.vertex, c.target, n, *g != Vec3::ZERO)
        })
        .collect();
    let mut fem = organ.build("fem-static", material).unwrap();
    // The same surface vertices, numbered as each model numbers its surface.
    let rest = fem.rest_surface().to_vec();
    let of = |v: u32| -> u32 {
        let p = sim.model().rest_surface()[v as usize];
        rest.iter()
            .position(|q| *q == p)
            .expect("the same rest surface") as u32
    };
    assert_eq!(rest.len(), sim.model().rest_surface().len());
    let pushing: Vec<_> = planes.iter().filter(|p| p.3).collect();
    assert!(pushing.len() >= 2, "{planes:?}");
    let held = Constraints {
        fixed: sc.fixed(&rest),
        prescribed: pushing
            .iter()
            .map(|p| Prescribed {
                vertex: of(p.0),
                position: p.1,
            })
            .collect(),
    };
    let normals: Vec<Option<Vec3>> = pushing.iter().map(|p| Some(p.2)).collect();
    assert!(fem.set_constraints_along(&held, &normals).unwrap());
    fem.step(1.0).unwrap();
    let reference: Vec3 = fem.reactions().prescribed.iter().copied().sum();
    let off = (force - reference).length() / reference.length();
    let s = fem.surface().positions;
    let passed = planes
        .iter()
        .filter(|p| !p.3)
        .map(|p| -p.2.dot(s[of(p.0) as usize] - p.1))
        .fold(0.0, Real::max);
    println!(
        "hybrid {force:?} N, fem-static {reference:?} N: {:.2e} apart; {} planes pushed, \
         the others passed by at most {:.2e} m",
        off,
        pushing.len(),
        passed
    );
    assert!(off < 1e-4, "{off}");
    assert!(passed < 1e-6, "{passed}");
}
