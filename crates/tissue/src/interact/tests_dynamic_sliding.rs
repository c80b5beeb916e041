//! Frictionless sliding contact on the dynamic kinds (issue 20): a probe pressed into a block
//! on a fixed floor, held still, slid sideways, held again. The force on it must be smooth
//! while it is held (no chatter from contacts let go and taken back), never pull, settle to
//! `fem-static`'s answer on the same mesh, and stay along the normal while it slides.

use crate::interact::{Instrument, InstrumentKind, Keyframe, Loads, Trajectory};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::MeshData;
use crate::mesh::generate::{BoxSplit, box_tets};
use crate::model::Deformable;
use crate::model::registry::{BuildInput, build};
use crate::sim::Simulation;

const E: Real = 3000.0;
const L: Real = 0.02;
const H: Real = 0.02;
const R: Real = 0.02;
const DEPTH: Real = 3e-4;
/// Probe path: pressed over [0, PRESS], held to SLIDE, slid 3 mm along +x to HOLD, held to END.
const PRESS: Real = 0.5;
const SLIDE: Real = 1.5;
const HOLD: Real = 2.5;
const END: Real = 3.0;
const SLIDE_X: Real = 3e-3;

/// A block [−l, l]² × [0, h], `cells` across (half as many deep), graded toward the top
/// centre as `tests/sliding_contact.rs`'s block.
pub(crate) fn graded_block(cells: usize) -> MeshData {
    let mut mesh = box_tets(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 1.0),
        [cells, cells, cells / 2],
        BoxSplit::Six,
    );
    let alpha = 0.25;
    let grade = |s: Real| alpha * s + (1.0 - alpha) * s * s * s;
    for p in &mut mesh.vertices {
        let t = 1.0 - grade(1.0 - p.z);
        *p = Vec3::new(L * grade(p.x), L * grade(p.y), H * t);
    }
    MeshData::from_tets(&mesh)
}

fn model(kind: &str, mesh: &MeshData) -> Box<dyn Deformable> {
    let mut material = Material::new(E, 0.3).unwrap();
    material.damping = 20.0;
    let params = toml::Table::new();
    let input = BuildInput {
        mesh,
        source: "graded block",
        material,
        params: &params,
        regions: &[],
    };
    build(kind, &input).unwrap()
}

fn sim(kind: &str, mesh: &MeshData, path: &[(Real, Vec3)]) -> Simulation {
    sim_with(kind, mesh, path, true)
}

/// `sim` with a frictionless probe or a sticking one.
fn sim_with(kind: &str, mesh: &MeshData, path: &[(Real, Vec3)], frictionless: bool) -> Simulation {
    let model = model(kind, mesh);
    let fixed: Vec<u32> = (0..model.rest_surface().len() as u32)
        .filter(|&v| model.rest_surface()[v as usize].z < 1e-9)
        .collect();
    let mut sim = Simulation::new(model, fixed, Loads::default()).unwrap();
    sim.set_max_contact_iterations(60);
    let path = Trajectory::new(
        path.iter()
            .map(|&(t, p)| Keyframe {
                t,
                position: p.to_array(),
            })
            .collect(),
    )
    .unwrap();
    let probe = Instrument::new("probe", InstrumentKind::Probe, R, path).unwrap();
    let probe = if frictionless {
        probe.with_friction(0.0).unwrap()
    } else {
        probe.sticking()
    };
    sim.add_instrument(probe);
    sim
}

fn start() -> Vec3 {
    Vec3::new(-0.0015, 0.0, H + R)
}

fn pressed() -> Vec3 {
    start() - Vec3::Z * DEPTH
}

/// The press, hold, slide, hold path.
fn path() -> Vec<(Real, Vec3)> {
    let slid = pressed() + Vec3::X * SLIDE_X;
    vec![
        (0.0, start()),
        (PRESS, pressed()),
        (SLIDE, pressed()),
        (HOLD, slid),
        (END, slid),
    ]
}

/// What the model's inner solver did over a run (`StepInfo`): iterations per step (mean
/// and most, 0 for a direct solve) and steps it reported capped.
#[derive(Debug, Default)]
struct Solver {
    mean: Real,
    most: usize,
    capped: usize,
}

/// (time, force, contacts) at every step, and what the solver did.
fn run(kind: &str, mesh: &MeshData, dt: Real) -> (Vec<(Real, Vec3, usize)>, Solver) {
    // `DYNAMIC_SLIDE_STICKING`: sticking contact instead, for comparison.
    let sticking = std::env::var("DYNAMIC_SLIDE_STICKING").is_ok();
    let mut sim = sim_with(kind, mesh, &path(), !sticking);
    let mut out = Vec::new();
    let mut solver = Solver::default();
    while sim.time() < END - 1e-9 {
        let r = sim.step(dt).unwrap();
        out.push((r.time, r.forces[0], r.contacts[0]));
        solver.mean += r.info.iterations as Real;
        solver.most = solver.most.max(r.info.iterations);
        solver.capped += usize::from(r.info.capped);
        if r.info.capped && std::env::var("DYNAMIC_SLIDE_TRACE").is_ok() {
            let details = sim.model().info().details;
            let solves = details.iter().find(|(k, _)| k == "contact_solves");
            eprintln!(
                "  capped at {:.3} s: {} iterations, residual {:.2e}, {solves:?}",
                r.time, r.info.iterations, r.info.residual
            );
        }
    }
    solver.mean /= out.len().max(1) as Real;
    (out, solver)
}

/// `fem-static`'s force with the probe at `at` (pressed there in a few static steps).
fn settled(mesh: &MeshData, at: Vec3) -> Vec3 {
    let mut sim = sim("fem-static", mesh, &[(0.0, start()), (1.0, at)]);
    let mut f = Vec3::ZERO;
    for _ in 0..10 {
        f = sim.step(0.1).unwrap().forces[0];
    }
    f
}

/// What a window of the history shows.
#[derive(Debug)]
struct Window {
    /// Range of the push (force along +z), N.
    low: Real,
    high: Real,
    /// Largest change of the force between steps, N.
    jump: Real,
    /// Largest |F_t| / F_z.
    tangential: Real,
    /// Steps where the probe is pulled (F_z < 0).
    pulls: usize,
    /// Range of the contact count.
    contacts: (usize, usize),
}

fn window(h: &[(Real, Vec3, usize)], from: Real, to: Real) -> Window {
    let mut w = Window {
        low: Real::INFINITY,
        high: Real::NEG_INFINITY,
        jump: 0.0,
        tangential: 0.0,
        pulls: 0,
        contacts: (usize::MAX, 0),
    };
    let mut last: Option<Vec3> = None;
    for &(t, f, n) in h
        .iter()
        .filter(|(t, _, _)| *t > from + 1e-9 && *t <= to + 1e-9)
    {
        let _ = t;
        w.low = w.low.min(f.z);
        w.high = w.high.max(f.z);
        if let Some(l) = last {
            w.jump = w.jump.max((f - l).length());
        }
        last = Some(f);
        let ft = Vec3::new(f.x, f.y, 0.0).length();
        if f.z > 0.0 {
            w.tangential = w.tangential.max(ft / f.z);
        }
        w.pulls += usize::from(f.z < 0.0);
        w.contacts = (w.contacts.0.min(n), w.contacts.1.max(n));
    }
    w
}

fn report(kind: &str, dt: Real, cells: usize, h: &[(Real, Vec3, usize)], reference: [Real; 2]) {
    // The second halves of the two holds (settled) and the slide.
    let held = window(h, 1.0, SLIDE);
    let slid = window(h, SLIDE + 0.1, HOLD);
    let after = window(h, HOLD + 0.25, END);
    let last_held = h
        .iter()
        .rfind(|(t, _, _)| *t <= SLIDE + 1e-9)
        .map_or(0.0, |x| x.1.z);
    eprintln!(
        "{kind:>22} dt {:.1} ms {cells:>2} cells | held Fz {:.5}-{:.5} (static {:.5}, end {:+.1}%) jump {:.1e} ({:.1}%) pulls {} contacts {:?} | slide Fz {:.5}-{:.5} jump {:.1e} Ft/Fn {:.3} pulls {} | held again Fz {:.5}-{:.5} (static {:.5}) jump {:.1e} pulls {}",
        dt * 1e3,
        held.low,
        held.high,
        reference[0],
        100.0 * (last_held / reference[0] - 1.0),
        held.jump,
        100.0 * held.jump / reference[0],
        held.pulls,
        held.contacts,
        slid.low,
        slid.high,
        slid.jump,
        slid.tangential,
        slid.pulls,
        after.low,
        after.high,
        reference[1],
        after.jump,
        after.pulls,
    );
}

/// The study: every dynamic kind at 1 ms (tensor-mass also at 0.2 ms) on 8- and 16-cell
/// blocks. `DYNAMIC_SLIDE_KINDS=kind,kind` and `DYNAMIC_SLIDE_CELLS=8,16` narrow it;
/// `DYNAMIC_SLIDE_TRACE` prints the force early in the hold and every step the model
/// reported capped; `DYNAMIC_SLIDE_STICKING` runs sticking contact instead.
#[test]
#[ignore = "study, a minute or more: cargo test --release -p tissue --lib dynamic_sliding_study -- --ignored --nocapture"]
fn dynamic_sliding_study() {
    let kinds = std::env::var("DYNAMIC_SLIDE_KINDS").unwrap_or_else(|_| {
        "fem-static,tensor-mass,tensor-mass-nonlinear,volumetric-spring-mass,fem-semi-implicit,fem-explicit,fem-corotational"
            .into()
    });
    let cells = std::env::var("DYNAMIC_SLIDE_CELLS").unwrap_or_else(|_| "8,16".into());
    let dts = std::env::var("DYNAMIC_SLIDE_DT").unwrap_or_else(|_| "0.001".into());
    for c in cells
        .split(',')
        .filter_map(|c| c.trim().parse::<usize>().ok())
    {
        let mesh = graded_block(c);
        let reference = [
            settled(&mesh, pressed()).z,
            settled(&mesh, pressed() + Vec3::X * SLIDE_X).z,
        ];
        for kind in kinds.split(',').map(str::trim) {
            for dt in dts.split(',').filter_map(|d| d.trim().parse::<Real>().ok()) {
                let (h, solver) = run(kind, &mesh, dt);
                report(kind, dt, c, &h, reference);
                if solver.most > 0 {
                    eprintln!(
                        "{kind:>22} inner solver: {:.1} iterations a step on average, {} at most, {} steps capped",
                        solver.mean, solver.most, solver.capped
                    );
                }
                if std::env::var("DYNAMIC_SLIDE_TRACE").is_ok() {
                    for (t, f, n) in h.iter().filter(|(t, _, _)| *t > 1.0 && *t < 1.1) {
                        eprintln!("  t {t:.4} F {f:.6} contacts {n}");
                    }
                }
            }
        }
    }
}

/// The property issue 20 asked for, on the 8-cell block at 1 ms: pressed 0.3 mm and held,
/// the dynamic kinds (on the shared integrator, `fem-explicit`, `fem-semi-implicit` and
/// `fem-corotational`) give a force that no longer changes between steps (below 0.1 % of
/// it, against jumps of 17 times it before on `tensor-mass`), that never pulls at any
/// contact, and that (the kinds with the same linear elasticity as `fem-static`) is
/// `fem-static`'s to 0.5 % (`fem-corotational`, the same elasticity in rotated frames, to
/// COROTATIONAL_GAP); slid 1 mm, the sideways force stays at `fem-static`'s on this mesh
/// (2.1 % of the push; 0.4 % at 16 cells in the study); lifted off, the probe is let go:
/// no force and no contact held.
#[test]
fn held_probe_force_on_dynamic_kinds_is_smooth_pushes_and_matches_fem_static() {
    let mesh = graded_block(8);
    let reference = settled(&mesh, pressed()).z;
    let slid = pressed() + Vec3::X * 1e-3;
    let lifted = slid + Vec3::Z * (DEPTH + 2e-3);
    let path = [
        (0.0, start()),
        (0.3, pressed()),
        (0.6, pressed()),
        (0.9, slid),
        (1.0, lifted),
    ];
    for (kind, gap_bound) in [
        ("tensor-mass", Some(5e-3)),
        ("volumetric-spring-mass", None),
        ("fem-explicit", Some(5e-3)),
        ("fem-semi-implicit", Some(5e-3)),
        ("fem-corotational", Some(COROTATIONAL_GAP)),
    ] {
        let mut sim = sim(kind, &mesh, &path);
        let mut last: Option<Vec3> = None;
        while sim.time() < 1.1 - 1e-9 {
            let r = sim.step(1e-3).unwrap();
            let f = r.forces[0];
            let probe = &sim.instruments()[0];
            for (k, g) in probe.contacts.iter().zip(probe.contact_reactions()) {
                let shape = probe.shape().unwrap();
                let push = -g.dot(k.normal(&shape, probe.position));
                assert!(push >= 0.0, "{kind} at {:.3} s: contact pulls {g}", r.time);
            }
            assert!(f.z >= 0.0, "{kind} at {:.3} s: {f}", r.time);
            // Held from 0.3 s: after a few decay times of the damping (α = 20/s).
            if r.time > 0.45 && r.time <= 0.6 + 1e-9 {
                if let Some(l) = last {
                    let jump = (f - l).length();
                    assert!(jump < 1e-3 * f.z, "{kind} at {:.3} s: {l} -> {f}", r.time);
                }
                last = Some(f);
                if let Some(bound) = gap_bound.filter(|_| r.time > 0.5) {
                    let gap = (f.z / reference - 1.0).abs();
                    assert!(gap < bound, "{kind}: {} against {reference}", f.z);
                }
            }
            if r.time > 0.65 && r.time <= 0.9 + 1e-9 {
                let ft = Vec3::new(f.x, f.y, 0.0).length();
                assert!(ft < 0.03 * f.z, "{kind} at {:.3} s: {f}", r.time);
            }
            if r.time > 1.05 {
                assert_eq!(
                    (f, r.contacts[0]),
                    (Vec3::ZERO, 0),
                    "{kind} at {:.3} s",
                    r.time
                );
            }
        }
    }
}

/// `fem-corotational`'s held force against `fem-static`'s at the 0.3 mm press: linear
/// elasticity in each element's rotated frame, which differs from linear FEM by the
/// rotations the press gives the elements under the probe. Measured −1.47 % at 8 cells and
/// −2.26 % at 16, the geometric non-linearity `fem-static` leaves out: it vanishes with the
/// press (`corotational_gap_study`: −0.10 % and −0.23 % at 10 µm;
/// `fem_corotational_settles_on_fem_static_as_the_press_gets_small`).
const COROTATIONAL_GAP: Real = 3e-2;

/// A probe jumping onto a resting `fem-explicit` block (the viewer's first point after the
/// probe is parked): parked 0.1 mm above the top, the organ at rest (energy 0), then 1 mm
/// into it in one step. The step is work put in, not a blow-up (the growth test's
/// reference, `fem::dynamic`): accepted with sticking and with frictionless contact, and
/// the held probe then pushes.
#[test]
fn fem_explicit_takes_a_probe_jumping_onto_it_from_rest() {
    let mesh = graded_block(8);
    for frictionless in [false, true] {
        let parked = Vec3::new(0.0, 0.0, H + R + 1e-4);
        let path = [(0.0, parked), (1.0, parked)];
        let mut sim = sim_with("fem-explicit", &mesh, &path, frictionless);
        for _ in 0..20 {
            let r = sim.step(1e-3).unwrap();
            assert_eq!(r.forces[0], Vec3::ZERO);
        }
        let deep = parked - Vec3::Z * 1.1e-3;
        sim.set_instrument_position(0, Some(deep)).unwrap();
        let mut f = Vec3::ZERO;
        for step in 0..200 {
            let r = sim.step(1e-3);
            let Ok(r) = r else {
                panic!("frictionless {frictionless}, step {step} after the jump: {r:?}");
            };
            f = r.forces[0];
        }
        assert!(f.z > 0.0, "frictionless {frictionless}: {f}");
    }
}

/// `fem-corotational` on the 16-cell block (the study's finer mesh, where `fem-static`'s
/// own sideways force while sliding is 0.4 % of the push), at a 5 ms step (implicit Euler):
/// pressed 0.3 mm and held, its force settles on `fem-static`'s within COROTATIONAL_GAP
/// (−2.26 %, the geometric non-linearity);
/// slid 1 mm sideways, the tangential force stays below 1 % of the push (frictionless); no
/// contact pulls at any step.
#[test]
fn fem_corotational_holds_and_slides_frictionless_on_the_finer_block() {
    let mesh = graded_block(16);
    let reference = settled(&mesh, pressed()).z;
    let slid = pressed() + Vec3::X * 1e-3;
    let path = [
        (0.0, start()),
        (0.3, pressed()),
        (0.6, pressed()),
        (0.9, slid),
    ];
    let mut sim = sim("fem-corotational", &mesh, &path);
    let (mut held, mut worst_ft): (Option<Real>, Real) = (None, 0.0);
    while sim.time() < 0.9 - 1e-9 {
        let r = sim.step(5e-3).unwrap();
        assert!(!r.info.capped, "at {:.3} s: {:?}", r.time, r.info);
        let f = r.forces[0];
        let probe = &sim.instruments()[0];
        let shape = probe.shape().unwrap();
        for (k, g) in probe.contacts.iter().zip(probe.contact_reactions()) {
            let push = -g.dot(k.normal(&shape, probe.position));
            assert!(push >= 0.0, "at {:.3} s: contact pulls {g}", r.time);
        }
        if r.time > 0.6 - 1e-9 && r.time < 0.6 + 1e-9 {
            held = Some(f.z);
        }
        if r.time > 0.65 {
            worst_ft = worst_ft.max(Vec3::new(f.x, f.y, 0.0).length() / f.z);
        }
    }
    let held = held.unwrap();
    eprintln!(
        "fem-corotational, 16 cells, 5 ms: held {held:.6} N (fem-static {reference:.6} N, {:+.2} %), |F_t|/F_n at most {:.2} % while sliding",
        100.0 * (held / reference - 1.0),
        100.0 * worst_ft
    );
    assert!(
        (held / reference - 1.0).abs() < COROTATIONAL_GAP,
        "{held} vs {reference}"
    );
    assert!(worst_ft < 0.01, "{worst_ft}");
}

/// `fem-corotational`'s held force over `fem-static`'s, less one, pressed `depth` on the
/// `cells` block (over 0.3 s, held to 0.6 s, 5 ms steps).
fn corotational_gap(cells: usize, depth: Real) -> Real {
    let mesh = graded_block(cells);
    let at = start() - Vec3::Z * depth;
    let reference = settled(&mesh, at).z;
    let path = [(0.0, start()), (0.3, at), (0.6, at)];
    let mut sim = sim("fem-corotational", &mesh, &path);
    let mut f = Vec3::ZERO;
    while sim.time() < 0.6 - 1e-9 {
        f = sim.step(5e-3).unwrap().forces[0];
    }
    f.z / reference - 1.0
}

/// The gap between `fem-corotational`'s held force and `fem-static`'s against the press,
/// on the 8- and 16-cell blocks.
#[test]
#[ignore = "study, half a minute: cargo test --release -p tissue --lib corotational_gap_study -- --ignored --nocapture"]
fn corotational_gap_study() {
    for cells in [8, 16] {
        for depth in [3e-4, 1e-4, 3e-5, 1e-5] {
            let gap = corotational_gap(cells, depth);
            eprintln!(
                "{cells} cells, depth {:.3} mm: corotational / fem-static − 1 = {:+.3} %",
                depth * 1e3,
                100.0 * gap
            );
        }
    }
}

/// Small deformation: the held force of `fem-corotational` goes to `fem-static`'s as the
/// press gets small (8 cells: −1.47 % at 0.3 mm, −0.31 % at 0.03 mm), so what is left at
/// 0.3 mm is the geometric non-linearity linear FEM leaves out, not the contact.
#[test]
fn fem_corotational_settles_on_fem_static_as_the_press_gets_small() {
    let (deep, shallow) = (corotational_gap(8, 3e-4), corotational_gap(8, 3e-5));
    assert!(shallow.abs() < 5e-3, "{shallow}");
    assert!(shallow.abs() < deep.abs() / 3.0, "{shallow} vs {deep}");
}
