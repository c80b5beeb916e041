//! Sliding contact checked against contact mechanics: Hertz's force law for a sphere pressed
//! into a block, frictionless and Coulomb sliding on a flat block, the force direction on a
//! curved surface, and a plane pressing a whole face (uniaxial compression). The
//! comparisons of the kinds that hold a contact along its normal are in `normal_holds.rs`.
//!
//! The blocks are graded: fine (about half a millimetre) where the probe touches, coarse far
//! away, so a block much larger than the contact stays small enough to solve in seconds.

mod sliding;

use sliding::*;
use tissue::interact::{Instrument, InstrumentKind};
use tissue::math::{Real, Vec3};
use tissue::mesh::MeshData;
use tissue::mesh::generate::{BoxSplit, box_tets};

const R: Real = 0.005;

/// Presses a probe of radius R at the top centre to each depth, one static step each; the
/// force along +z (the tissue pushes the probe up) at each depth.
fn hertz_curve(
    kind: &str,
    params: &str,
    cells: usize,
    nu: Real,
    depths: &[Real],
    dt: Real,
) -> Vec<Real> {
    hertz_curve_on(&block(L, H, cells, &|_| 0.0), kind, params, nu, depths, dt)
}

/// `hertz_curve` on a given block (its top at z = H).
fn hertz_curve_on(
    mesh: &MeshData,
    kind: &str,
    params: &str,
    nu: Real,
    depths: &[Real],
    dt: Real,
) -> Vec<Real> {
    let top_z = mesh
        .vertices
        .iter()
        .map(|p| p.z)
        .fold(Real::NEG_INFINITY, Real::max);
    let params: toml::Table = toml::from_str(params).unwrap();
    let mut sim = sim_on_floor(model_with(kind, mesh, nu, params));
    sim.set_max_contact_iterations(60);
    let top = Vec3::new(0.0, 0.0, top_z + R);
    // Hertz's contact is frictionless.
    let probe = Instrument::new("probe", InstrumentKind::Probe, R, path(&[(0.0, top)]))
        .unwrap()
        .with_friction(0.0)
        .unwrap();
    sim.add_instrument(probe);
    // Static models solve each depth at once; dynamic ones settle for 0.3 s per depth.
    let steps = if sim.model().info().is_static {
        1
    } else {
        (0.3 / dt).round() as usize
    };
    let mut forces = Vec::new();
    for &d in depths {
        sim.set_instrument_position(0, Some(top - Vec3::Z * d))
            .unwrap();
        let mut force = Vec3::ZERO;
        for _ in 0..steps {
            force = sim.step(dt).unwrap().forces[0];
        }
        forces.push(force.z);
    }
    forces
}

fn print_hertz(kind: &str, depths: &[Real], forces: &[Real], nu: Real) -> Real {
    eprintln!("| {kind} δ mm | F N | Hertz N | gap |");
    eprintln!("|---|---|---|---|");
    let mut worst: Real = 0.0;
    for (d, f) in depths.iter().zip(forces) {
        let h = hertz(nu, R, *d);
        let gap = f / h - 1.0;
        worst = worst.max(gap.abs());
        eprintln!(
            "| {:.2} | {:.5} | {:.5} | {:+.1}% |",
            d * 1e3,
            f,
            h,
            100.0 * gap
        );
    }
    worst
}

#[test]
fn hertz_coarse_fem_static() {
    // Linear tetrahedra, 16 cells: 0.6 mm at the contact, whose radius √(Rδ) is 1.6 to
    // 2.2 mm. Linear tetrahedra this coarse are stiff: measured +23% to +24% over Hertz
    // (quadratic ones on the same kind of block: `hertz_refined`, within 5%). Checked here:
    // the exponent 3/2 (the ratios of the forces), and the gap within its measured band.
    let nu = 0.3;
    let depths = [0.5e-3, 0.75e-3, 1.0e-3];
    let forces = hertz_curve("fem-static", "", 16, nu, &depths, 1.0);
    let worst = print_hertz("fem-static P1, 16 cells", &depths, &forces, nu);
    assert!(worst < 0.30, "coarse Hertz gap {worst}");
    let exponent = (forces[2] / forces[0]).ln() / (depths[2] / depths[0]).ln();
    eprintln!("exponent {exponent:.3}");
    assert!((exponent - 1.5).abs() < 0.05, "{exponent}");
}

#[test]
#[ignore = "refined blocks, minutes: cargo test --release -p tissue --test sliding_contact hertz_refined -- --ignored --nocapture"]
fn hertz_refined() {
    let nu = 0.3;
    let depths = [0.5e-3, 0.75e-3, 1.0e-3];
    // Quadratic tetrahedra against Hertz.
    let forces = hertz_curve("fem-static", "order = \"quadratic\"", 16, nu, &depths, 1.0);
    let worst = print_hertz("fem-static P2, 16 cells", &depths, &forces, nu);
    // Measured +5.7%, +6.7%, +4.3% (issue 20 asks 5%: open). Part of it is the block, not
    // the elements: 2 cm thick under a contact radius of 1.6-2.2 mm is a layer about nine
    // contact radii deep, a few percent stiffer than Hertz's half-space.
    assert!(worst < 0.08, "fem-static P2: Hertz gap {worst}");
    // A dynamic kind after settling equals the static solution on the same mesh (linear
    // tetrahedra, which is what the dynamic kinds have).
    let fixed = hertz_curve("fem-static", "", 16, nu, &depths, 1.0);
    let settled = hertz_curve("fem-semi-implicit", "", 16, nu, &depths, 0.005);
    print_hertz("fem-static P1, 16 cells", &depths, &fixed, nu);
    print_hertz(
        "fem-semi-implicit, 16 cells, settled",
        &depths,
        &settled,
        nu,
    );
    for (a, b) in fixed.iter().zip(&settled) {
        assert!((b / a - 1.0).abs() < 0.02, "static {a} N, settled {b} N");
    }
}

/// Node coordinates 0..=n from 0 to `length`: `uniform` cells of size `fine` first, then
/// cells growing by a constant ratio (found by bisection) to reach `length` exactly.
fn fine_then_geometric(n: usize, uniform: usize, fine: Real, length: Real) -> Vec<Real> {
    let rest = n - uniform;
    let span = length - fine * uniform as Real;
    let reach = |r: Real| (1..=rest).map(|k| fine * r.powi(k as i32)).sum::<Real>();
    let (mut lo, mut hi) = (1.0, 10.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if reach(mid) < span {
            lo = mid
        } else {
            hi = mid
        }
    }
    let r = 0.5 * (lo + hi);
    let mut x = vec![0.0];
    for k in 0..n {
        let size = if k < uniform {
            fine
        } else {
            fine * r.powi((k + 1 - uniform) as i32)
        };
        x.push(x[k] + size);
    }
    x[n] = length;
    x
}

/// A block [−l, l]² × [0, h] whose cells are `fine` wide over the top centre (`uniform`
/// cells each side of it, and as many layers down), growing geometrically beyond: the
/// contact zone stays uniformly fine however large the block.
fn contact_block(l: Real, h: Real, cells: usize, uniform: usize, fine: Real) -> MeshData {
    let mut mesh = box_tets(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 1.0),
        [cells, cells, cells / 2],
        BoxSplit::Six,
    );
    let half = cells / 2;
    let across = fine_then_geometric(half, uniform, fine, l);
    let down = fine_then_geometric(half, uniform, fine, h);
    let side = |s: Real| {
        let i = (s.abs() * half as Real).round() as usize;
        s.signum() * across[i.min(half)]
    };
    for p in &mut mesh.vertices {
        let k = ((1.0 - p.z) * half as Real).round() as usize;
        *p = Vec3::new(side(p.x), side(p.y), h - down[k.min(half)]);
    }
    MeshData::from_tets(&mesh)
}

#[test]
#[ignore = "a deep block, about 8 minutes: cargo test --release --workspace --test sliding_contact hertz_deep_block -- --ignored --nocapture"]
fn hertz_deep_block() {
    // The 2 cm block is a layer about nine contact radii deep on a fixed floor, stiffer
    // than Hertz's half-space (Dimitriadis et al. 2002 put a bonded layer at about
    // +0.88 a/h at ν = 0.3: +9% here). An 8 cm block is 37 contact radii deep. Its cells
    // must be uniform over the whole contact (a cubic grading fine at the centre left
    // 2 mm cells at the rim, and the force jumped by ±10 % as nodes came into contact):
    // 0.4 mm over 2.4 mm, growing geometrically beyond (`contact_block`).
    let nu = 0.3;
    let depths = [0.5e-3, 0.75e-3, 1.0e-3];
    let runs: Vec<(usize, Real)> = std::env::var("HERTZ_RUNS")
        .ok()
        .map(|v| {
            v.split(',')
                .filter_map(|r| {
                    let (c, h) = r.split_once(':')?;
                    Some((c.parse().ok()?, h.parse::<Real>().ok()? * 1e-3))
                })
                .collect()
        })
        .unwrap_or_else(|| vec![(24, 0.4e-3)]);
    for (cells, fine) in runs {
        // 2.4 mm of uniform cells around the contact (its radius is at most 2.2 mm).
        let uniform = (2.4e-3 / fine - 1e-9).ceil() as usize;
        let mesh = contact_block(0.08, 0.08, cells, uniform, fine);
        let forces = hertz_curve_on(
            &mesh,
            "fem-static",
            "order = \"quadratic\"",
            nu,
            &depths,
            1.0,
        );
        let worst = print_hertz(
            &format!("fem-static P2, 8 cm block, {cells} cells"),
            &depths,
            &forces,
            nu,
        );
        // Measured at 24 cells, 0.4 mm: +3.0 %, +3.8 %, +4.0 % (the issue asks 5 %).
        assert!(worst < 0.05, "{cells} cells, {fine} m: Hertz gap {worst}");
    }
}

#[test]
fn frictionless_probe_slides_without_drag() {
    let forces = slide("fem-static", 0.0, 0.05);
    for f in &forces {
        eprintln!(
            "frictionless: F = {f:.4}, |Ft|/Fn = {:.4}",
            tangential(*f) / f.z
        );
    }
    for f in &forces {
        assert!(f.z > 0.0);
        assert!(tangential(*f) < 0.01 * f.z, "{f}");
    }
}

#[test]
fn coulomb_probe_drags_mu_times_the_push_while_sliding() {
    let mu = 0.3;
    let forces = slide("fem-static", mu, 0.05);
    for f in &forces {
        eprintln!("mu 0.3: F = {f:.4}, |Ft|/Fn = {:.4}", tangential(*f) / f.z);
    }
    // The first steps stick (the tangential force builds up), then it slides at μN,
    // resisting the motion (the probe moves +x, the tissue pushes it back, −x).
    let sliding: Vec<&Vec3> = forces
        .iter()
        .filter(|f| tangential(**f) > 0.9 * mu * f.z)
        .collect();
    assert!(sliding.len() >= forces.len() / 2, "it should slide");
    for f in &sliding {
        assert!(f.x < 0.0, "{f}");
        assert!((tangential(**f) / f.z - mu).abs() < 0.05 * mu, "{f}");
    }
    for f in &forces {
        assert!(tangential(*f) <= mu * f.z * 1.05, "{f}");
    }
}

#[test]
fn coulomb_probe_sticks_below_the_bound() {
    // A sideways move too small to reach μN: the tangential force stays below it and the
    // centre of the contact keeps its points of the probe (the rim, where the pressure falls
    // to zero, slips a little: Cattaneo and Mindlin's partial slip).
    let mesh = block(L, H, 16, &|_| 0.0);
    let mut sim = sim_on_floor(model("fem-static", &mesh, 0.3));
    sim.set_max_contact_iterations(60);
    let down = Vec3::new(0.0, 0.0, H + SLIDE_R - SLIDE_DEPTH);
    let probe = Instrument::new(
        "probe",
        InstrumentKind::Probe,
        SLIDE_R,
        path(&[(0.0, down), (1.0, down + Vec3::X * 2e-5)]),
    )
    .unwrap()
    .with_friction(0.3)
    .unwrap();
    sim.add_instrument(probe);
    sim.step(0.5).unwrap();
    let before: Vec<_> = sim.instruments()[0].contacts().to_vec();
    let p0 = sim.instruments()[0].position();
    let r = sim.step(0.5).unwrap();
    let f = r.forces[0];
    let inst = &sim.instruments()[0];
    let shift = inst.position() - p0;
    eprintln!("stick: F = {f:.4}, |Ft|/Fn = {:.4}", tangential(f) / f.z);
    assert!(tangential(f) < 0.3 * f.z && f.x < 0.0, "{f}");
    let a = (SLIDE_R * SLIDE_DEPTH).sqrt();
    let mut centre = 0;
    let mut held = 0;
    for k in inst.contacts() {
        let Some(b) = before.iter().find(|b| b.vertex == k.vertex) else {
            continue;
        };
        let off = k.target - inst.position();
        let slid = (k.target - b.target - shift).length();
        held += usize::from(slid < 1e-12);
        if off.x.hypot(off.y) < 0.5 * a {
            centre += 1;
            assert!(
                slid < 0.05 * shift.length(),
                "vertex {} slid {slid} m",
                k.vertex
            );
        }
    }
    let count = inst.contacts().len();
    eprintln!("stick: {held} of {count} contacts kept their point of the probe");
    assert!(centre >= 3, "{centre} contacts in the centre");
    // The rim was left at the cone by the press itself (Spence's radial slip under a pure
    // normal load), so it slips at any sideways load: measured 13 of 30 held.
    assert!(3 * held >= count, "{held} of {count} stuck");
}

#[test]
fn frictionless_force_on_a_curved_surface_is_along_its_normal() {
    // The top rises as z = H + A sin(πx / 2l); the probe comes straight down at x0 where the
    // slope is about 0.4. The surface normal there is (−z'(x0), 0, 1).
    let a = 0.006;
    let k = std::f64::consts::PI / (2.0 * L);
    let lift = move |x: Real| a * (k * x).sin();
    let mesh = block(L, H, 16, &lift);
    let mut sim = sim_on_floor(model("fem-static", &mesh, 0.3));
    sim.set_max_contact_iterations(60);
    let x0 = 0.004;
    let normal = Vec3::new(-a * k * (k * x0).cos(), 0.0, 1.0).normalize();
    let contact = Vec3::new(x0, 0.0, H + lift(x0));
    let start = contact + normal * R;
    let probe = Instrument::new(
        "probe",
        InstrumentKind::Probe,
        R,
        path(&[(0.0, start), (1.0, start - Vec3::Z * 1e-3)]),
    )
    .unwrap()
    .with_friction(0.0)
    .unwrap();
    sim.add_instrument(probe);
    let mut f = Vec3::ZERO;
    for _ in 0..10 {
        f = sim.step(0.1).unwrap().forces[0];
    }
    let angle = f
        .normalize()
        .dot(normal)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let push_angle = f.normalize().dot(Vec3::Z).acos().to_degrees();
    eprintln!(
        "curved: F = {f:.4}, {angle:.2}° from the surface normal ({:.1}° from the push)",
        push_angle
    );
    assert!(angle < 5.0, "{angle}°");
}

#[test]
fn a_plane_pressing_the_top_is_uniaxial_compression() {
    // ν = 0: the fixed floor does not hold the block sideways, so a frictionless plane
    // pushing the top down by d gives F = E A d / h exactly (linear FEM is exact for it).
    let mesh = block(L, H, 8, &|_| 0.0);
    let mut sim = sim_on_floor(model("fem-static", &mesh, 0.0));
    let d = 2e-4;
    let plane = Instrument::new(
        "table",
        InstrumentKind::Plane { normal: -Vec3::Z },
        0.01,
        path(&[(0.0, Vec3::new(0.0, 0.0, H - d))]),
    )
    .unwrap()
    .with_friction(0.0)
    .unwrap();
    sim.add_instrument(plane);
    let r = sim.step(1.0).unwrap();
    let f = r.forces[0];
    let exact = E * (2.0 * L) * (2.0 * L) * d / H;
    eprintln!("plane: F = {f:.6}, E A d / h = {exact:.5e}");
    assert!((f.z - exact).abs() < 1e-6 * exact, "{f}");
    assert!(tangential(f) < 1e-6 * exact);
}

#[test]
fn a_capsule_lying_on_the_block_pushes_straight_down() {
    let mesh = block(L, H, 12, &|_| 0.0);
    let mut sim = sim_on_floor(model("fem-static", &mesh, 0.3));
    sim.set_max_contact_iterations(60);
    let r = 0.003;
    let tip = Vec3::new(-0.008, 0.0, H + r - 5e-4);
    let shaft = Instrument::new(
        "shaft",
        InstrumentKind::Capsule {
            axis: Vec3::X,
            length: 0.016,
        },
        r,
        path(&[(0.0, tip)]),
    )
    .unwrap()
    .with_friction(0.0)
    .unwrap();
    sim.add_instrument(shaft);
    let rep = sim.step(1.0).unwrap();
    let f = rep.forces[0];
    eprintln!("capsule: F = {f:.5}, {} contacts", rep.contacts[0]);
    assert!(rep.contacts[0] > 10);
    assert!(f.z > 0.0 && tangential(f) < 0.01 * f.z, "{f}");
    // Every contact pushes (no adhesion) and lies on the capsule.
    let inst = &sim.instruments()[0];
    let shape = inst.shape().unwrap();
    for (k, f) in inst.contacts().iter().zip(inst.contact_reactions()) {
        let c = shape.closest(inst.position(), k.target, Vec3::ZERO);
        assert!(c.depth.abs() < 1e-12);
        assert!(f.dot(c.normal) <= 1e-9 * rep.forces[0].length(), "{f}");
    }
}

/// The shipped liver scene with its fine surface (`[mesh] visual`), fem-static, the probe
/// frictionless: contacts are found on the 2194 fine vertices and solved on them exactly.
#[test]
fn fine_liver_surface_holds_the_probe_out_and_the_supports_balance() {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"));
    let dir = std::env::temp_dir().join(format!("tissue-fine-liver-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("fine.toml");
    std::fs::write(&path, text).unwrap();
    let scene = tissue::scene::Scene::load(&path).unwrap();
    let mut sim = scene.build().unwrap();
    // The smooth liver's 2194 vertices and its edges' midpoints (`visual_levels = 1`).
    assert_eq!(sim.fine_surface().unwrap().0.len(), 8770);
    for _ in 0..scene.run.step_count() {
        sim.step(scene.run.dt).unwrap();
    }
    let inst = &sim.instruments()[0];
    let (c, r) = (inst.position(), inst.radius());
    let (_, fine) = sim.fine_surface().unwrap();
    let deepest = fine
        .iter()
        .map(|p| r - p.distance(c))
        .fold(Real::NEG_INFINITY, Real::max);
    let f = inst.force();
    let balance = f + sim.fixed_reaction_total();
    eprintln!(
        "fine liver: F = {f:.5} N on {} coarse vertices, deepest fine vertex {deepest:.2e} m \
         inside, balance {:.1e} N",
        inst.contacts().len(),
        balance.length()
    );
    // The probe goes down (−y): the liver pushes it up.
    assert!(f.y > 0.0, "{f}");
    // No fine vertex left inside the probe beyond rounding; static: the fixed vertices take
    // what the probe gives.
    assert!(deepest < 1e-6 * r, "{deepest}");
    assert!(balance.length() < 1e-6 * f.length(), "{balance}");
}

/// The shipped liver with its fine surface and a frictionless probe pressed 1 cm, fem-static,
/// stepped at 1/60 s, 10 ms and 1 ms: a static frictionless equilibrium depends on where the
/// probe is, not on the steps that brought it there, so the three end forces agree. The fine
/// points are held exactly (`interact::fine_points`: one complementarity problem per solve,
/// the planes moved to the points until they stop); the per-vertex planes they replaced
/// carried the contact from step to step and gave 0.0904 / 0.0958 / 0.1135 N. Also: every
/// step's contact loop converged (within 400 solves), no point pulls, and the supports
/// balance the probe (the points' loads on held vertices included).
#[test]
fn a_fine_surface_static_press_gives_one_force_at_any_step() {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let base = std::fs::read_to_string(format!("{root}/scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"));
    let dir = std::env::temp_dir().join(format!("tissue-fine-dt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut ends = Vec::new();
    for dt in [1.0 / 60.0, 0.01, 0.001] {
        let path = dir.join(format!("dt-{dt}.toml"));
        std::fs::write(&path, base.replace("dt = 0.01 ", &format!("dt = {dt} "))).unwrap();
        let scene = tissue::scene::Scene::load(&path).unwrap();
        assert_eq!(scene.run.dt, dt);
        let mut sim = scene.build().unwrap();
        // At 1 ms a few steps need more than the scene's 64 solves on the surface cut once
        // (`visual_levels = 1`; measured: 4 steps over 64, 2 over 128, 1 over 256, none over
        // 400, against at most 51 at the scene's 10 ms): the loop's rare slow steps, reported
        // in docs/contact.md, not a different equilibrium.
        sim.set_max_contact_iterations(400);
        let mut solves = 0;
        for _ in 0..scene.run.step_count() {
            let rep = sim.step(dt).unwrap();
            assert!(
                rep.contact_converged,
                "t = {}: the contact loop capped",
                rep.time
            );
            assert!(
                rep.forces[0].y >= 0.0,
                "t = {}: pulls {}",
                rep.time,
                rep.forces[0]
            );
            solves += rep.contact_iterations;
        }
        let inst = &sim.instruments()[0];
        assert!(inst.contacts().is_empty() && !inst.fine_points().is_empty());
        assert!(inst.point_pushes().iter().all(|&l| l >= 0.0));
        let f = inst.force();
        let balance = f + sim.fixed_reaction_total();
        eprintln!(
            "dt = {dt:.5} s: F = {f:.6} N, |F| = {:.6} N, {:.1}° off the push, {} points \
             pushed, {:.2} solves per step, balance {:.1e} N",
            f.length(),
            f.angle_between(Vec3::Y).to_degrees(),
            inst.point_pushes().iter().filter(|&&l| l > 0.0).count(),
            solves as Real / scene.run.step_count() as Real,
            balance.length()
        );
        assert!(balance.length() < 1e-6 * f.length(), "{balance}");
        ends.push(f);
    }
    for f in &ends[1..] {
        assert!(
            (*f - ends[0]).length() < 1e-4 * ends[0].length(),
            "{f} {}",
            ends[0]
        );
    }
}

/// The shipped liver with its fine surface (`visual`) and a frictionless probe pressed 1 cm
/// and drawn back along the same path, for the static kinds: every step's force pushes (the
/// tissue never pulls the probe in), each contact's reaction lies along its face normal
/// (frictionless: held along the normal only), no fine vertex ends inside the probe, and the
/// way back retraces the way in (a frictionless static equilibrium does not depend on the
/// path: the force at 0.9 s and at 1.1 s, where the probe is at the same place, agree).
/// Before face contacts were carried with a retreating probe, the pressed faces sprang back
/// past the probe's centre in one solve and the liver pulled the probe down, 0.085 N at the
/// end; held in full, a tangential reaction 38 % of the push. `fem-condensed` and
/// `fem-precomputed-tensors` hold the same points with their compliance: fem-static's peak.
#[test]
fn fine_liver_surface_pressed_and_drawn_back_pushes_only_and_retraces() {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let base = std::fs::read_to_string(format!("{root}/scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace(
            "{ t = 1.0, position = [-0.005, 0.0455, 0.0067] } ]",
            "{ t = 1.0, position = [-0.005, 0.0455, 0.0067] },\n \
             { t = 2.0, position = [-0.005, 0.0555, 0.0067] } ]",
        )
        .replace("duration = 1.0", "duration = 2.0");
    let dir = std::env::temp_dir().join(format!("tissue-fine-back-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut peaks: Vec<(&str, Vec3)> = Vec::new();
    for kind in ["fem-static", "fem-condensed", "fem-precomputed-tensors"] {
        let path = dir.join(format!("{kind}.toml"));
        std::fs::write(
            &path,
            base.replace("kind = \"fem-static\"", &format!("kind = \"{kind}\"")),
        )
        .unwrap();
        let scene = tissue::scene::Scene::load(&path).unwrap();
        let mut sim = scene.build().unwrap();
        let mut forces = Vec::new();
        let mut deepest: Real = Real::NEG_INFINITY;
        let mut worst_tangential: Real = 0.0;
        let mut capped = 0;
        let (mut worst_gap, mut exact_points): (Real, usize) = (0.0, 0);
        for _ in 0..scene.run.step_count() {
            let rep = sim.step(scene.run.dt).unwrap();
            let inst = &sim.instruments()[0];
            forces.push(inst.force());
            // A step whose contact loop reached its cap says so (its set was still
            // changing: a face's normal moved after the last solve); checked on the others.
            if !rep.contact_converged {
                capped += 1;
                continue;
            }
            for (k, f) in inst.contacts().iter().zip(inst.contact_reactions()) {
                let n = k
                    .face
                    .expect("contacts on the fine surface are face contacts");
                worst_tangential = worst_tangential.max((*f - n * f.dot(n)).length());
            }
            // Held exactly on the fine points: no push is negative, and every pushed point
            // rests on its plane.
            let fine_now = sim.fine_surface().unwrap().1;
            for (p, &l) in inst.fine_points().iter().zip(inst.point_pushes()) {
                assert!(l >= 0.0, "a fine point pulls: {l}");
                let gap = p
                    .contact
                    .normal
                    .dot(fine_now[p.fine as usize] - p.contact.target);
                if l > 0.0 {
                    worst_gap = worst_gap.max(gap.abs());
                }
                exact_points += 1;
            }
            let (c, r) = (inst.position(), inst.radius());
            let (_, fine) = sim.fine_surface().unwrap();
            deepest = fine
                .iter()
                .map(|p| r - p.distance(c))
                .fold(deepest, Real::max);
        }
        let peak = forces[99];
        let pulls = forces.iter().filter(|f| f.y < -1e-9).count();
        let (before, after) = (forces[89], forces[109]);
        eprintln!(
            "{kind}: peak {peak:.5} N ({:.1}° off the push), 0.9 s {before:.5}, 1.1 s {after:.5}, \
             end {:.5}, pulling steps {pulls}, worst tangential {worst_tangential:.1e} N, \
             deepest fine vertex {deepest:.1e} m, {capped} capped steps, {exact_points} fine \
             point contacts, worst gap of a pushed point {worst_gap:.1e} m",
            peak.angle_between(Vec3::Y).to_degrees(),
            forces[199]
        );
        assert_eq!(pulls, 0);
        assert!(
            worst_tangential <= 1e-9 * peak.length(),
            "{worst_tangential}"
        );
        assert!(deepest < 1e-6 * r_probe(), "{deepest}");
        // Held exactly on the fine points, the way back retraces the way in (to the contact
        // loop's tolerance).
        assert!(
            (before - after).length() <= 1e-4 * peak.length(),
            "{before} {after}"
        );
        // Back where it first touched, the probe carries less than a tenth of the peak.
        assert!(
            forces[199].length() < 0.1 * peak.length(),
            "{}",
            forces[199]
        );
        peaks.push((kind, peak));
    }
    // The pre-computed kinds solve the same points with the same linear model's response
    // (their compliance, `solve::points`): fem-static's peak.
    for (kind, peak) in &peaks[1..] {
        let d = (*peak - peaks[0].1).length() / peaks[0].1.length();
        eprintln!("{kind}: peak vs fem-static {d:.1e} relative");
        assert!(d < 1e-6, "{kind}: {peak} vs {}", peaks[0].1);
    }
}

fn r_probe() -> Real {
    0.005
}

/// `bem` on the shipped liver with its fine surface, a frictionless probe pressed 1 cm
/// through `Simulation`: the points are solved exactly on its unsymmetric response (before
/// Murty's rule in `solve::points::refine`, step 45 failed: a 9-point set cycled). Every
/// step solves complementary (none reported capped), no push is negative, every pushed
/// point rests on its plane, the probe is pushed back.
#[test]
fn bem_holds_the_fine_liver_surface_on_its_points() {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace("kind = \"fem-static\"", "kind = \"bem\"");
    let dir = std::env::temp_dir().join(format!("tissue-fine-bem-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bem.toml");
    std::fs::write(&path, text).unwrap();
    let scene = tissue::scene::Scene::load(&path).unwrap();
    let mut sim = scene.build().unwrap();
    let (mut worst_gap, mut points, mut pushed): (Real, usize, usize) = (0.0, 0, 0);
    for _ in 0..scene.run.step_count() {
        let rep = sim.step(scene.run.dt).unwrap();
        assert!(!rep.info.capped, "a step kept the symmetric part's answer");
        let inst = &sim.instruments()[0];
        let fine_now = sim.fine_surface().unwrap().1;
        for (p, &l) in inst.fine_points().iter().zip(inst.point_pushes()) {
            assert!(l >= 0.0, "a fine point pulls: {l}");
            if l > 0.0 {
                let gap = p
                    .contact
                    .normal
                    .dot(fine_now[p.fine as usize] - p.contact.target);
                worst_gap = worst_gap.max(gap.abs());
                pushed += 1;
            }
            points += 1;
        }
    }
    let force = sim.instruments()[0].force();
    eprintln!(
        "bem: force at 1 cm {force:.5} N ({:.5} N), {points} fine point contacts, {pushed} \
         pushed, worst gap of a pushed point {worst_gap:.1e} m",
        force.length()
    );
    assert!(force.y > 0.0, "{force}");
    assert!(pushed > 0 && worst_gap < 1e-9, "{worst_gap}");
}

/// The static loop's planes moved by Aitken's acceleration (the default) against one plain
/// round at a time (`Simulation::set_accelerated_planes(false)`): two ways to the same fixed
/// point. The shipped liver with its fine surface, fem-static, a frictionless probe pressed
/// 1 cm at 1/60 s: every step's force agrees to the loops' stop (each plane still by 1e-4
/// of the probe, 0.5 µm) and the accelerated loop takes fewer solves. Measured on the
/// visual vertices alone: 258 → 228 solves over the 60 steps, forces to 1e-4 of the largest;
/// on the scene's surface cut once (`visual_levels = 1`, session 20): 464 → 354 solves,
/// forces to 1.1e-4 at step 5 (a point entering the set there); on a stuffed liver's own
/// boundary cut in nine, 200 → 125 solves (`stuffed_indentation`'s study).
#[test]
fn accelerated_planes_reach_the_plain_loops_forces_in_fewer_solves() {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace("dt = 0.01 ", &format!("dt = {} ", 1.0 / 60.0));
    let dir = std::env::temp_dir().join(format!("tissue-aitken-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("press.toml");
    std::fs::write(&path, text).unwrap();
    let scene = tissue::scene::Scene::load(&path).unwrap();
    let run = |accelerated: bool| {
        let mut sim = scene.build().unwrap();
        sim.set_accelerated_planes(accelerated);
        let mut solves = 0;
        let mut forces = Vec::new();
        for _ in 0..scene.run.step_count() {
            let r = sim.step(scene.run.dt).unwrap();
            assert!(r.contact_converged, "t = {}", r.time);
            solves += r.contact_iterations;
            forces.push(r.forces[0]);
        }
        (forces, solves)
    };
    let (plain, plain_solves) = run(false);
    let (fast, fast_solves) = run(true);
    eprintln!("solves: plain {plain_solves}, accelerated {fast_solves}");
    let top = plain.iter().fold(0.0, |a: Real, f| a.max(f.length()));
    let worst = plain
        .iter()
        .zip(&fast)
        .map(|(a, b)| (*a - *b).length() / top)
        .fold(0.0, Real::max);
    eprintln!("forces agree to {worst:.2e} of the largest");
    for (k, (a, b)) in plain.iter().zip(&fast).enumerate() {
        assert!((*a - *b).length() < 2e-4 * top, "step {k}: {a} against {b}");
    }
    assert!(
        fast_solves < plain_solves,
        "{fast_solves} >= {plain_solves}"
    );
}

/// `[mesh] visual_levels = k` cuts the visual surface flat into 4^k triangles per triangle
/// before tying it to the model: on the shipped liver (the smooth surface's edges about 2 mm
/// near the probe's path, the probe's radius 5 mm) the probe pressed 1 cm is held by points
/// on the visual faces as well as its vertices. Checked: the fine surface has 4^k times the
/// triangles; no fine point ends inside the probe; every step's loop converges within the
/// scene's cap (64; measured at most 5, 51 and 19 solves a step at k = 0, 1, 2); the force
/// converges as the points get finer (k = 0, 1, 2: measured |F| 0.1121, 0.0844, 0.0843 N,
/// the vector changing by 65 % and 0.44 % of it; k = 3 moves it 0.32 % more, 64 times the
/// points, left out for time): the visual vertices alone hold the probe a third too hard, so the shipped scene
/// says `visual_levels = 1`, whose force is within 1 % of k = 2's. The warning
/// (`Simulation::contact_warnings`, `interact::slip::FINE_RATIO`) is given at k = 0, naming
/// `visual_levels = 1`, and not at k = 1 or 2. And the key is refused without a `visual`, or
/// beyond its bound, naming itself.
#[test]
fn visual_levels_put_contact_points_on_the_visual_faces() {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let base = std::fs::read_to_string(format!("{root}/scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"));
    assert!(base.contains("visual = ") && base.contains("\nvisual_levels = 1 "));
    let dir = std::env::temp_dir().join(format!("tissue-visual-levels-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let with = |k: u32, text: &str| {
        let path = dir.join(format!("levels-{k}.toml"));
        std::fs::write(
            &path,
            text.replacen(
                "\nvisual_levels = 1 ",
                &format!("\nvisual_levels = {k} "),
                1,
            ),
        )
        .unwrap();
        tissue::scene::Scene::load(&path)
    };
    let mut ends = Vec::new();
    for k in 0..=2 {
        let scene = with(k, &base).unwrap();
        let mut sim = scene.build().unwrap();
        assert_eq!(
            sim.fine_surface().unwrap().0.triangles.len(),
            4384 << (2 * k)
        );
        let warnings = sim.contact_warnings();
        if k == 0 {
            assert!(
                warnings.len() == 1 && warnings[0].contains("visual_levels = 1"),
                "{warnings:?}"
            );
        } else {
            assert!(warnings.is_empty(), "k = {k}: {warnings:?}");
        }
        assert_eq!(sim.max_contact_iterations(), 64);
        let mut most = 0;
        for _ in 0..scene.run.step_count() {
            let r = sim.step(scene.run.dt).unwrap();
            assert!(r.contact_converged, "k = {k}, t = {}", r.time);
            most = most.max(r.contact_iterations);
        }
        eprintln!("k = {k}: at most {most} solves a step");
        let inst = &sim.instruments()[0];
        let (c, r) = (inst.position(), inst.radius());
        let deepest = sim
            .fine_surface()
            .unwrap()
            .1
            .iter()
            .map(|p| r - p.distance(c))
            .fold(Real::NEG_INFINITY, Real::max);
        assert!(deepest < 1e-6 * r, "k = {k}: {deepest}");
        eprintln!("visual_levels {k}: F = {:.6} N", inst.force());
        ends.push(inst.force());
    }
    let (d01, d12) = (
        (ends[1] - ends[0]).length() / ends[2].length(),
        (ends[2] - ends[1]).length() / ends[2].length(),
    );
    eprintln!("changes {:.2} %, {:.2} %", 100.0 * d01, 100.0 * d12);
    assert!(d12 < 0.1 * d01 && d12 < 0.01, "{d01} {d12}");
    let no_visual = base
        .lines()
        .filter(|l| !l.starts_with("visual ="))
        .collect::<Vec<_>>()
        .join("\n");
    let e = with(1, &no_visual).err().unwrap().to_string();
    assert!(e.contains("visual_levels"), "{e}");
    let e = with(9, &base).err().unwrap().to_string();
    assert!(e.contains("visual_levels = 9"), "{e}");
}
