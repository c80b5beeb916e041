//! Contacts held along the instrument's normal only (`Deformable::set_constraints_along`),
//! checked across kinds: independent implementations of the same linear model agree, a
//! different discretisation lands where it should, and every kind that holds along normals
//! is measured against the relaxation of its targets (`sliding::Relaxed`): solves per step,
//! pulling contacts, reactions off their normals. The 8-cell block slide and the shipped
//! coarse liver pressed by a frictionless probe.

mod sliding;

use sliding::*;
use tissue::math::{Real, Vec3};
use tissue::sim::Simulation;

/// Two independent normal-only holds agree: `fem-condensed` holds each frictionless contact
/// along the probe's normal only and solves it with its surface compliance (one small dense
/// solve per contact set), `fem-static` adds one row nᵀu = nᵀd per contact to its sparse
/// solve through the Schur complement (`fem::system`). Same linear FEM on the same mesh: the
/// same forces at every step of the slide, to 1e-6 (measured 5e-15). 8 cells: the condensed
/// block's dense compliance stays small.
#[test]
fn normal_only_contact_on_the_compliance_agrees_with_fem_static() {
    let exact = slide_on("fem-condensed", 0.0, 0.05, 8);
    let relaxed = slide_on("fem-static", 0.0, 0.05, 8);
    assert_eq!(exact.len(), relaxed.len());
    let mut worst: Real = 0.0;
    for (a, b) in exact.iter().zip(&relaxed) {
        let gap = (*a - *b).length() / b.z;
        worst = worst.max(gap);
        eprintln!(
            "fem-condensed {a:.5} (|Ft|/Fn {:.1e}), fem-static {b:.5} (|Ft|/Fn {:.1e}): gap {gap:.1e}",
            tangential(*a) / a.z,
            tangential(*b) / b.z
        );
        // The sideways part left is the coarse mesh's (8 cells: measured 1.7%, alike for
        // both; 0.4% at 16 cells in `frictionless_probe_slides_without_drag`).
        assert!(a.z > 0.0);
        assert!(tangential(*a) < 0.03 * a.z, "{a}");
    }
    eprintln!("worst gap {worst:.2e}");
    assert!(worst < 1e-6, "{worst}");
}

/// The worst |a − b| / b_z over a slide's steps.
fn worst_gap(a: &[Vec3], b: &[Vec3]) -> Real {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(a, b)| (*a - *b).length() / b.z)
        .fold(0.0, Real::max)
}

/// `fem-precomputed-tensors` holds each frictionless contact along the probe's normal only
/// and solves it in the contact forces with its tensors (`solve::along`, an LU), as
/// `fem-condensed` does with its compliance (a Cholesky): the same linear FEM on the same
/// 8-cell block, so the same forces at every step of the slide, to 1e-6; and fewer solves a
/// step than the relaxation of its targets (`Relaxed`).
#[test]
fn normal_only_contact_on_the_tensors_agrees_with_fem_condensed() {
    let (tensors, solves) = slide_of("fem-precomputed-tensors", 0.0, 0.05, 8, false);
    let (relaxed, relaxed_solves) = slide_of("fem-precomputed-tensors", 0.0, 0.05, 8, true);
    let condensed = slide_on("fem-condensed", 0.0, 0.05, 8);
    let (gap, relaxed_gap) = (
        worst_gap(&tensors, &condensed),
        worst_gap(&relaxed, &condensed),
    );
    eprintln!(
        "tensors along normals vs fem-condensed: worst gap {gap:.2e}, {solves} solves a step \
         at most; relaxed: gap {relaxed_gap:.2e}, {relaxed_solves} solves"
    );
    for f in &tensors {
        assert!(f.z > 0.0 && tangential(*f) < 0.03 * f.z, "{f}");
    }
    assert!(gap < 1e-6, "{gap}");
    assert!(solves < relaxed_solves, "{solves} vs {relaxed_solves}");
}

/// `bem` holds each frictionless contact along the probe's normal only, solved with its
/// pre-inverted response (`BemSystem::solve_along`), on the 8-cell block's surface. It
/// pushes nearly straight down while sliding, matches its own relaxation (`Relaxed`) to the
/// relaxation's tolerance in fewer solves, and with the probe centred reads Hertz's force
/// within 15 % (measured +9.8 %; the 2 cm layer on its fixed floor is stiffer than a
/// half-space). `fem-static`'s linear tetrahedra on the same block are much stiffer (+66 %
/// of Hertz at 8 cells, +22 % at 16: `hertz_coarse_fem_static`): the two differ by
/// `fem-static`'s coarse-mesh stiffness (measured 35 % apart), not by the contact.
#[test]
fn normal_only_contact_on_bem_is_close_to_hertz() {
    let (bem, solves) = slide_of("bem", 0.0, 0.05, 8, false);
    let (relaxed, relaxed_solves) = slide_of("bem", 0.0, 0.05, 8, true);
    let reference = slide_on("fem-static", 0.0, 0.05, 8);
    let (gap, relaxed_gap) = (worst_gap(&bem, &reference), worst_gap(&bem, &relaxed));
    let mut sideways: Real = 0.0;
    for (a, b) in bem.iter().zip(&reference) {
        sideways = sideways.max(tangential(*a) / a.z);
        eprintln!(
            "bem {a:.5} (|Ft|/Fn {:.1e}), fem-static {b:.5}",
            tangential(*a) / a.z
        );
    }
    // The step with the probe centred (x from −1.5 to +1.5 mm over the slide).
    let centred = bem.len() / 2 - 1;
    let f_hertz = hertz(0.3, SLIDE_R, SLIDE_DEPTH);
    let (to_hertz, fem_to_hertz) = (
        bem[centred].z / f_hertz - 1.0,
        reference[centred].z / f_hertz - 1.0,
    );
    eprintln!(
        "bem along normals: centred {:.5} N, {to_hertz:+.3} of Hertz ({f_hertz:.5} N; \
         fem-static {fem_to_hertz:+.3}); worst gap to fem-static {gap:.2e}, |Ft|/Fn at most \
         {sideways:.1e}, {solves} solves a step at most; vs its relaxation: \
         {relaxed_gap:.2e} ({relaxed_solves} solves)",
        bem[centred].z
    );
    for f in &bem {
        assert!(f.z > 0.0, "{f}");
    }
    assert!(sideways < 0.03, "{sideways}");
    assert!(to_hertz.abs() < 0.15, "{to_hertz}");
    assert!(fem_to_hertz > to_hertz, "{fem_to_hertz} vs {to_hertz}");
    assert!(relaxed_gap < 0.01, "{relaxed_gap}");
    assert!(solves < relaxed_solves, "{solves} vs {relaxed_solves}");
}

/// What a frictionless press of the coarse liver showed (`coarse_liver_press`).
struct LiverPress {
    force: Vec3,
    contacts: usize,
    most_solves: usize,
    /// Solves over all steps, and the steps.
    solves: usize,
    steps: usize,
    all_converged: bool,
    /// The largest pull of a contact along its normal, relative to the probe force.
    worst_pull: Real,
    /// The largest |supports + probe| relative to the probe force.
    worst_balance: Real,
    /// The largest angle between a contact's reaction and its normal, in rad.
    worst_angle: Real,
    /// The probe force along +y (out of the liver) at each back-off step.
    backed_off: Vec<Real>,
}

/// The shipped coarse liver (edges about 1 cm, `liver-fem-condensed.toml` with `kind`) under
/// a frictionless 2 cm probe (larger than the edges, so that the contact is resolved by the
/// mesh's vertices) pressed 8 mm, then backed off 0.2 mm in three directions and returned.
fn coarse_liver_press(kind: &str) -> LiverPress {
    coarse_liver_press_with(kind, false)
}

/// `coarse_liver_press`, the model wrapped in `Relaxed` when `relaxed`.
fn coarse_liver_press_with(kind: &str, relaxed: bool) -> LiverPress {
    liver_press_on("liver-fem-condensed.toml", kind, relaxed)
}

/// The same press on the shipped scene `file` (its probe and `[contact]` lines as in
/// `liver-fem-condensed.toml`), the model of `kind`.
fn liver_press_on(file: &str, kind: &str, relaxed: bool) -> LiverPress {
    static RUN: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/{file}"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace("\"fem-condensed\"", &format!("\"{kind}\""))
        // Frictionless (the default; the shipped scene asks for sticking, its 5 mm probe
        // slipping between the coarse vertices: this press uses a 2 cm probe).
        .replace("contact = \"sticking\"", "contact = \"sliding\"")
        .replace("max_iterations = 8", "max_iterations = 50")
        .replace("radius = 0.005", "radius = 0.02")
        .replace("0.0555, 0.0067", "0.0705, 0.0067")
        .replace("0.0455, 0.0067", "0.0625, 0.0067");
    // The mesh's own vertices: a fine surface the scene gives (`visual`) is left out.
    let text: String = text
        .lines()
        .filter(|l| !l.starts_with("visual"))
        .map(|l| format!("{l}\n"))
        .collect();
    // Three point supports have no fully fixed triangle for the BEM's discontinuous rule,
    // and with it a contact released for pulling leaves its neighbours' tractions on fewer
    // triangles: the continuous rule where the scene does not choose (see the bem test).
    let text = if text.contains("discontinuous_contacts") {
        text
    } else {
        text.replace(
            "kind = \"bem\"\n",
            "kind = \"bem\"\ndiscontinuous_contacts = false\n",
        )
    };
    // One file per press: tests run on threads side by side.
    let run = RUN.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!(
        "tissue-sliding-liver-{kind}-{}-{run}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("sliding.toml");
    std::fs::write(&path, text).unwrap();
    let scene = tissue::scene::Scene::load(&path).unwrap();
    let body = scene.load_body().unwrap();
    let material = scene.material_for(&body).unwrap();
    let mut built = scene
        .build_model(kind, &body, material, &scene.model_params)
        .unwrap();
    if relaxed {
        built = Box::new(Relaxed(built));
    }
    let mut sim = scene.build_with_model(built, &body.mesh).unwrap();
    assert_eq!(sim.model().kind(), kind);
    assert_eq!(sim.instruments()[0].friction(), Some(0.0));
    let mut out = LiverPress {
        force: Vec3::ZERO,
        contacts: 0,
        most_solves: 0,
        solves: 0,
        steps: 0,
        all_converged: true,
        worst_pull: 0.0,
        worst_balance: 0.0,
        worst_angle: 0.0,
        backed_off: Vec::new(),
    };
    let check = |sim: &Simulation, r: &tissue::sim::StepReport, out: &mut LiverPress| {
        out.most_solves = out.most_solves.max(r.contact_iterations);
        out.solves += r.contact_iterations;
        out.steps += 1;
        out.all_converged &= r.contact_converged;
        let inst = &sim.instruments()[0];
        let f = inst.force();
        let scale = f.length().max(1e-30);
        let balance = (f + sim.fixed_reaction_total()).length() / scale;
        out.worst_balance = out.worst_balance.max(balance);
        let shape = inst.shape().unwrap();
        for (k, r) in inst.contacts().iter().zip(inst.contact_reactions()) {
            let n = k.normal(&shape, inst.position());
            out.worst_angle = out
                .worst_angle
                .max(r.cross(n).length() / r.length().max(1e-300));
            out.worst_pull = out.worst_pull.max(r.dot(n) / scale);
        }
    };
    for _ in 0..scene.run.step_count() {
        let r = sim.step(scene.run.dt).unwrap();
        check(&sim, &r, &mut out);
    }
    out.force = sim.instruments()[0].force();
    out.contacts = sim.instruments()[0].contacts().len();
    let deep = sim.instruments()[0].position();
    for d in [
        Vec3::new(0.0, 2e-4, 0.0),
        Vec3::new(2e-4, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 2e-4),
        Vec3::ZERO,
    ] {
        sim.set_instrument_position(0, Some(deep + d)).unwrap();
        let r = sim.step(0.01).unwrap();
        out.backed_off.push(r.forces[0].y);
        check(&sim, &r, &mut out);
    }
    eprintln!(
        "{file}, frictionless probe, {kind}{}: F = {:.5} N at 8 mm, {} contacts, at \
         most {} solves a step ({} in {} steps, all converged: {}), worst pull {:.1e} of F, \
         balance {:.1e}, reactions within {:.1e} rad of their normals, backing off F_y = \
         {:.5?}",
        if relaxed { " (relaxed)" } else { "" },
        out.force,
        out.contacts,
        out.most_solves,
        out.solves,
        out.steps,
        out.all_converged,
        out.worst_pull,
        out.worst_balance,
        out.worst_angle,
        out.backed_off
    );
    out
}

/// `fem-condensed` holds each frictionless contact along the probe's normal only and solves
/// it with its compliance: every step converges, the supports take what the probe gives, no
/// contact pulls and every reaction is along its normal.
#[test]
fn coarse_liver_frictionless_probe_on_the_compliance_pushes_and_balances() {
    let out = coarse_liver_press("fem-condensed");
    assert!(out.force.y > 0.0 && out.contacts >= 3, "{}", out.force);
    assert!(out.all_converged);
    assert!(out.worst_balance < 1e-9, "{}", out.worst_balance);
    assert!(out.worst_pull <= 1e-9, "{}", out.worst_pull);
    assert!(out.worst_angle < 1e-5, "{}", out.worst_angle);
    assert!(
        out.backed_off.iter().all(|&f| f > 0.0),
        "{:?}",
        out.backed_off
    );
}

/// The same press on `fem-static`, which holds the contacts along their normals in its
/// sparse solve: the same forces as the compliance to 1e-6 (measured 6e-15), with no
/// pulling contact and every reaction along its normal. (With the relaxation it used
/// before, contacts held in all three directions, the forces agreed within 9.2e-4 but the
/// steps took the 50-solve cap and left contacts pulling a quarter of the probe force.)
#[test]
fn coarse_liver_fem_static_normal_holds_agree_with_the_compliance() {
    let exact = coarse_liver_press("fem-condensed");
    let sparse = coarse_liver_press("fem-static");
    let gap = (exact.force - sparse.force).length() / exact.force.length();
    eprintln!("force gap {gap:.2e}");
    assert!(gap < 1e-6, "{gap}");
    assert!(sparse.all_converged);
    assert!(sparse.worst_balance < 1e-9, "{}", sparse.worst_balance);
    assert!(sparse.worst_pull <= 1e-9, "{}", sparse.worst_pull);
    assert!(sparse.worst_angle < 1e-5, "{}", sparse.worst_angle);
}

/// `fem-precomputed-tensors` on the same press: its contacts held along their normals and
/// solved with its tensors give `fem-condensed`'s forces to 1e-6, with no pulling contact,
/// every reaction along its normal and the supports balancing the probe; the relaxation of
/// its targets, measured alongside (`Relaxed`), takes more solves and leaves pulls.
#[test]
fn coarse_liver_frictionless_probe_on_the_tensors_pushes_and_balances() {
    let exact = coarse_liver_press("fem-condensed");
    let tensors = coarse_liver_press("fem-precomputed-tensors");
    let relaxed = coarse_liver_press_with("fem-precomputed-tensors", true);
    let gap = (exact.force - tensors.force).length() / exact.force.length();
    eprintln!("force gap to fem-condensed {gap:.2e}");
    assert!(gap < 1e-6, "{gap}");
    assert!(tensors.all_converged);
    assert!(tensors.worst_balance < 1e-9, "{}", tensors.worst_balance);
    assert!(tensors.worst_pull <= 1e-9, "{}", tensors.worst_pull);
    assert!(tensors.worst_angle < 1e-5, "{}", tensors.worst_angle);
    assert!(tensors.backed_off.iter().all(|&f| f > 0.0));
    assert!(tensors.solves < relaxed.solves);
}

/// `bem` on the same press (the tetrahedra's boundary; the tractions continuous across the
/// contact rim, see `coarse_liver_press`): contacts held along their normals and solved
/// with the pre-inverted response, no pulling contact, every reaction along its normal, in
/// fewer solves than the relaxation of its targets (`Relaxed`), which leaves pulls and
/// sideways reactions; its force within 5 % of `fem-condensed`'s on the same surface
/// (measured 3.1 %: two discretisations). The supports balance the probe only as well as
/// the collocation's tractions at three point supports integrate (18 % here, the same with
/// the relaxation: the BEM's, not the contact's), so that is not checked.
#[test]
fn coarse_liver_frictionless_probe_on_bem_pushes_along_the_normals() {
    let exact = coarse_liver_press("fem-condensed");
    let bem = coarse_liver_press("bem");
    let relaxed = coarse_liver_press_with("bem", true);
    let gap = (exact.force - bem.force).length() / exact.force.length();
    eprintln!("force gap to fem-condensed {gap:.2e}");
    assert!(bem.force.y > 0.0 && bem.contacts >= 3, "{}", bem.force);
    assert!(bem.all_converged);
    assert!(bem.worst_pull <= 1e-9, "{}", bem.worst_pull);
    assert!(bem.worst_angle < 1e-5, "{}", bem.worst_angle);
    assert!(bem.backed_off.iter().all(|&f| f > 0.0));
    assert!(bem.solves < relaxed.solves);
    assert!(gap < 0.05, "{gap}");
}

/// The shipped smooth liver (`liver-bem.toml`: 2194 surface vertices, ligament patches
/// fixed, contact tractions discontinuous at the rim) under the same frictionless 2 cm
/// probe, held along the normals and relaxed. A study (the BEM's pre-computation takes
/// about 40 s per run): `cargo test --release -p tissue --test normal_holds
/// smooth_liver_bem_study -- --ignored --nocapture`.
#[test]
#[ignore = "two BEM builds on the 2194-vertex liver, minutes"]
fn smooth_liver_bem_study() {
    let along = liver_press_on("liver-bem.toml", "bem", false);
    let relaxed = liver_press_on("liver-bem.toml", "bem", true);
    let gap = (along.force - relaxed.force).length() / along.force.length();
    eprintln!("smooth liver, bem: along normals against the relaxation: force gap {gap:.2e}");
}
