//! Incisions in the BEM: the groove's geometry, and the bordered system against a fresh
//! assembly and factorisation of the cut surface.

use super::cut::{OPENING, incise};
use super::tests::{material, sphere};
use super::*;
use crate::interact::{Constraints, Loads, Prescribed};
use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;
use crate::mesh::check::check_surface;
use crate::model::{CutInfo, CutPath, Deformable};

/// A blade 3 cm deep in z swept along x across the top of the 5 cm sphere, at y = `y`.
fn blade(y: Real, x0: Real, x1: Real) -> CutPath {
    CutPath {
        start: [Vec3::new(x0, y, 0.02), Vec3::new(x0, y, 0.08)],
        end: [Vec3::new(x1, y, 0.02), Vec3::new(x1, y, 0.08)],
    }
}

/// Every directed edge once and its reverse once: closed and consistently oriented.
fn assert_closed_oriented(s: &SurfaceMesh) {
    let mut directed = std::collections::HashMap::new();
    for t in &s.triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *directed.entry((a, b)).or_insert(0) += 1;
        }
    }
    for (&(a, b), &c) in &directed {
        assert_eq!(c, 1, "edge {a}->{b} used {c} times");
        assert_eq!(directed.get(&(b, a)), Some(&1), "edge {a}->{b} has no twin");
    }
    let problems = check_surface(s);
    assert!(problems.is_empty(), "{problems:?}");
    assert!(s.signed_volume() > 0.0);
}

#[test]
fn an_incision_opens_a_closed_oriented_groove_and_keeps_old_vertices() {
    let s = sphere(3);
    let cut = incise(&s, &blade(0.001, -0.03, 0.03), OPENING)
        .unwrap()
        .unwrap();
    let n0 = s.vertices.len();
    // Two ends, and two lips and a floor per interior crossing.
    assert_eq!(cut.added_vertices % 3, 2, "{}", cut.added_vertices);
    let interior = (cut.added_vertices - 2) / 3;
    assert!(interior >= 3, "{interior}");
    assert_eq!(cut.surface.vertices.len(), n0 + cut.added_vertices);
    assert_eq!(&cut.surface.vertices[..n0], &s.vertices[..]);
    assert_closed_oriented(&cut.surface);
    // The chain has interior + 1 triangles, plus the two beyond its ends.
    assert_eq!(cut.removed_triangles, interior + 3);
    // Each removed chain triangle becomes three, each end triangle two; each wall has
    // 2 (interior − 1) + 2 triangles.
    let added = 3 * (interior + 1) + 4 + 2 * (2 * interior);
    assert_eq!(
        cut.surface.triangles.len(),
        s.triangles.len() - cut.removed_triangles + added
    );
    // The groove removes material and lies below the top.
    let (v0, v1) = (s.signed_volume(), cut.surface.signed_volume());
    assert!(v1 < v0 && v1 > 0.95 * v0, "{v0} {v1}");
    // Lips are on the original edges (on the sphere's chords): inside the sphere.
    for p in &cut.surface.vertices[n0..] {
        assert!(p.length() <= 0.05 + 1e-12);
    }
    // A sweep that crosses nothing is no cut.
    assert!(
        incise(&s, &blade(0.001, 0.2, 0.3), OPENING)
            .unwrap()
            .is_none()
    );
}

/// Fixed bottom, the top pushed by a contact ring and the two sides of the cut plane pulled
/// apart by point loads (1 mN each on the vertices near the cut).
fn problem(rest: &[Vec3]) -> (Constraints, Loads) {
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z < -0.04)
        .collect();
    let prescribed = (0..rest.len() as u32)
        .filter(|&v| {
            let p = rest[v as usize];
            p.x > 0.025 && p.z > 0.035
        })
        .map(|v| Prescribed {
            vertex: v,
            position: rest[v as usize] - Vec3::Z * 1e-3,
        })
        .collect();
    let point_loads = (0..rest.len() as u32)
        .filter(|&v| {
            let p = rest[v as usize];
            p.z > 0.03 && p.x.abs() < 0.015 && p.y.abs() > 0.004 && p.y.abs() < 0.02
        })
        .map(|v| (v, Vec3::Y * 1e-3 * rest[v as usize].y.signum()))
        .collect();
    (
        Constraints { fixed, prescribed },
        Loads {
            gravity: Vec3::ZERO,
            point_loads,
        },
    )
}

/// The model on `s` with the problem posed on the uncut sphere's vertices `rest`.
fn build(s: &SurfaceMesh, rest: &[Vec3]) -> Bem {
    let mut model = Bem::new(s, material(), BemParams::default()).unwrap();
    let (c, l) = problem(rest);
    model.set_constraints(&c).unwrap();
    model.set_loads(&l).unwrap();
    model.step(0.01).unwrap();
    model
}

/// max |a − b| / max |b| over displacements, and over reactions.
fn gaps(a: &Bem, b: &Bem) -> (Real, Real) {
    let da = a.static_displacements();
    let db = b.static_displacements();
    let rel = |x: &[Vec3], y: &[Vec3]| {
        let scale = y.iter().map(|v| v.length()).fold(0.0, Real::max);
        let worst = x
            .iter()
            .zip(y)
            .map(|(p, q)| (*p - *q).length())
            .fold(0.0, Real::max);
        worst / scale
    };
    let (ra, rb) = (a.reactions(), b.reactions());
    let react_a: Vec<Vec3> = ra.fixed.iter().chain(ra.prescribed).copied().collect();
    let react_b: Vec<Vec3> = rb.fixed.iter().chain(rb.prescribed).copied().collect();
    (rel(&da, &db), rel(&react_a, &react_b))
}

#[test]
fn bordering_equals_a_fresh_assembly_over_three_cuts() {
    let s = sphere(2);
    let mut bordered = build(&s, &s.vertices);
    let mut reassembled = build(&s, &s.vertices);
    let blades = [
        blade(0.001, -0.03, 0.02),
        blade(-0.012, -0.025, 0.02),
        blade(0.014, -0.03, 0.015),
    ];
    for (i, b) in blades.iter().enumerate() {
        let info = bordered.cut(b).unwrap();
        assert!(info.added_vertices > 0, "cut {i}: {info:?}");
        assert_eq!(info.topology_version, i as u32 + 1);
        assert_eq!(reassembled.incise(b, CutUpdate::Reassembly).unwrap(), info);
        let cut_surface = SurfaceMesh::new(
            bordered.rest_surface().to_vec(),
            bordered.surface().triangles.to_vec(),
        );
        assert_closed_oriented(&cut_surface);
        bordered.step(0.01).unwrap();
        reassembled.step(0.01).unwrap();
        // The bordered H and G are the re-assembled ones, entry for entry.
        let (ib, ir) = (
            bordered.system().influence(),
            reassembled.system().influence(),
        );
        assert!(ib == ir, "cut {i}: H or G differ");
        let (du, dr) = gaps(&bordered, &reassembled);
        // Against a model built afresh, whose far rows re-sum their diagonals: they differ
        // by the quadrature error of the groove's T* integral (1.1e-9 measured).
        let fresh = build(&cut_surface, &s.vertices);
        let (fu, fr) = gaps(&bordered, &fresh);
        let rank = bordered.system().last_border_rank();
        eprintln!(
            "cut {i}: {} unknowns, rank {rank:?}; vs re-assembly: displacements {du:e}, \
             reactions {dr:e}; vs Bem::new: {fu:e}, {fr:e}",
            bordered.system().dofs()
        );
        assert!(du < 1e-6 && dr < 1e-6, "cut {i}: {du:e} {dr:e}");
        assert!(fu < 1e-8 && fr < 1e-8, "cut {i}: {fu:e} {fr:e}");
        // One factorisation (when the constraints were first set), then only bordering.
        assert_eq!(bordered.system().factorizations, 1);
        assert_eq!(bordered.system().borderings(), i + 1);
    }
}

#[test]
fn a_pulled_incision_opens() {
    let s = sphere(2);
    let mut model = build(&s, &s.vertices);
    let n0 = s.vertices.len();
    let info = model.cut(&blade(0.001, -0.03, 0.02)).unwrap();
    model.step(0.01).unwrap();
    let rest = model.rest_surface().to_vec();
    let now = model.surface().positions.to_vec();
    // New vertices: an end, then (lip, lip, floor) per interior crossing, then an end.
    let interior = (info.added_vertices - 2) / 3;
    let scale = model
        .static_displacements()
        .iter()
        .fold(0.0, |m: Real, u| m.max(u.length()));
    let mut widening = Vec::new();
    for j in 0..interior {
        let (a, b) = (n0 + 1 + 3 * j, n0 + 2 + 3 * j);
        widening.push((now[a] - now[b]).length() - (rest[a] - rest[b]).length());
    }
    let mean = widening.iter().sum::<Real>() / interior as Real;
    eprintln!("lip widening {widening:?}, largest displacement {scale:e}");
    assert!(widening.iter().all(|&w| w > 0.0), "{widening:?}");
    assert!(mean > 0.05 * scale, "{mean:e} vs {scale:e}");
}

/// Wall time of one incision, bordered and by re-assembly, on the 642-vertex sphere:
/// `cargo test --release --offline -p tissue cut_speed -- --ignored --nocapture`.
#[test]
#[ignore]
fn cut_speed() {
    let s = sphere(3);
    let t = std::time::Instant::now();
    let mut a = build(&s, &s.vertices);
    let precompute = t.elapsed().as_secs_f64();
    let mut b = build(&s, &s.vertices);
    let cut = blade(0.001, -0.03, 0.02);
    a.incise(&cut, CutUpdate::Bordering).unwrap();
    b.incise(&cut, CutUpdate::Reassembly).unwrap();
    a.step(0.01).unwrap();
    b.step(0.01).unwrap();
    let (du, dr) = gaps(&a, &b);
    eprintln!(
        "642-vertex sphere: precompute {precompute:.2} s; cut by bordering {:.3} s (rank {:?}, \
         {} unknowns), by re-assembly {:.3} s; gaps {du:e} {dr:e}",
        a.system().last_cut_seconds,
        a.system().last_border_rank(),
        a.system().dofs(),
        b.system().last_cut_seconds,
    );
    assert!(du < 1e-6 && dr < 1e-6);
}

/// One bordered incision on the 2194-vertex liver against its pre-computation:
/// `cargo test --release --offline -p tissue cut_speed_liver -- --ignored --nocapture`.
#[test]
#[ignore = "slow: pre-computation on the 2194-vertex liver (a minute or more)"]
fn cut_speed_liver() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../assets/meshes/liver-smooth.obj"
    );
    let data = crate::io::read(path).unwrap();
    let mut surface = data.surface_mesh().unwrap();
    surface.vertices.iter_mut().for_each(|p| *p *= 0.01);
    let t = std::time::Instant::now();
    let mut bem = Bem::new(&surface, material(), BemParams::default()).unwrap();
    let rest = bem.rest_surface().to_vec();
    let n = rest.len();
    let by = |f: &dyn Fn(&Vec3) -> Real| {
        (0..n)
            .min_by(|&a, &b| f(&rest[a]).total_cmp(&f(&rest[b])))
            .unwrap() as u32
    };
    let fixed = vec![by(&|p| p.x), by(&|p| -p.x), by(&|p| p.z)];
    bem.set_constraints(&Constraints::fixed(fixed)).unwrap();
    let precompute = t.elapsed().as_secs_f64();
    let down = Vec3::new(0.0, -0.04, 0.0);
    let (p0, p1) = (Vec3::new(0.025, 0.06, 0.005), Vec3::new(0.0, 0.06, 0.005));
    let info = bem
        .cut(&CutPath {
            start: [p0, p0 + down],
            end: [p1, p1 + down],
        })
        .unwrap();
    bem.step(0.01).unwrap();
    eprintln!(
        "liver-smooth: {n} vertices, precompute {precompute:.1} s; one cut ({info:?}) by \
         bordering {:.2} s, rank {:?}, {} unknowns after",
        bem.system().last_cut_seconds,
        bem.system().last_border_rank(),
        bem.system().dofs()
    );
    assert_eq!(bem.system().factorizations, 1);
}

/// In real time the system's update runs on a worker: the cut returns at once, the model
/// answers steps on the uncut surface meanwhile, a second stroke waits its turn, and what
/// lands equals the synchronous incisions to the last bit.
#[test]
fn a_real_time_incision_lands_from_the_background_as_the_synchronous_one() {
    let s = sphere(2);
    let mut now = build(&s, &s.vertices);
    let mut later = build(&s, &s.vertices);
    later.set_real_time(true);
    let uncut = later.surface().positions.to_vec();
    let triangles0 = later.surface().triangles.len();
    let blades = [blade(0.001, -0.03, 0.02), blade(-0.012, -0.025, 0.02)];
    for b in &blades {
        assert!(now.cut(b).unwrap().added_vertices > 0);
        let queued = later.cut(b).unwrap();
        assert_eq!(
            queued,
            CutInfo::default(),
            "a real-time cut returns before it lands"
        );
    }
    // Until it lands the model steps on the uncut surface, and says what it computes.
    assert!(later.background().is_some_and(|s| s.contains("incision")));
    later.step(0.01).unwrap();
    assert_eq!(later.surface().triangles.len(), triangles0);
    assert_eq!(later.surface().positions, &uncut[..]);
    let info = later.wait_for_incisions().unwrap();
    assert_eq!(info.topology_version, 2);
    assert!(later.background().is_none());
    now.step(0.01).unwrap();
    later.step(0.01).unwrap();
    assert_eq!(later.surface().triangles, now.surface().triangles);
    assert_eq!(later.surface().positions, now.surface().positions);
    assert_eq!(gaps(&later, &now), (0.0, 0.0));
    assert_eq!(later.system().borderings(), 2);
    assert_eq!(later.system().factorizations, 1);
}

/// The 2-subdivision sphere as a `Simulation` (bottom fixed, real time or not) with a
/// scalpel 6 cm long crossing the top along x from −3 to +2 cm over `sweep` seconds.
fn sphere_with_scalpel(real_time: bool, sweep: Real) -> crate::sim::Simulation {
    use crate::interact::{Instrument, InstrumentKind, Keyframe, Trajectory};
    let s = sphere(2);
    let fixed: Vec<u32> = (0..s.vertices.len() as u32)
        .filter(|&v| s.vertices[v as usize].z < -0.04)
        .collect();
    let mut model = Bem::new(&s, material(), BemParams::default()).unwrap();
    model.set_real_time(real_time);
    let mut sim = crate::sim::Simulation::new(Box::new(model), fixed, Loads::default()).unwrap();
    let key = |t: Real, x: Real| Keyframe {
        t,
        position: [x, 0.001, 0.02],
    };
    let path = Trajectory::new(vec![key(0.0, -0.03), key(sweep, 0.02)]).unwrap();
    let scalpel = InstrumentKind::Scalpel {
        direction: Vec3::Z,
        length: 0.06,
    };
    sim.add_instrument(Instrument::new("scalpel", scalpel, 0.001, path).unwrap());
    sim
}

/// Through `Simulation`: a scalpel crosses the top in real time, the steps go on while the
/// incision is computed, and once it lands (at the start of a step) the surface, the
/// contact search and the probe's force are those of the same scene stepped synchronously.
#[test]
fn a_simulation_in_real_time_steps_on_while_the_incision_is_computed() {
    use crate::interact::{Instrument, InstrumentKind, Keyframe, Trajectory};
    let run = |real_time: bool| {
        let mut sim = sphere_with_scalpel(real_time, 0.01);
        let probe = Trajectory::new(vec![
            Keyframe {
                t: 0.0,
                position: [0.03, 0.0, 0.06],
            },
            Keyframe {
                t: 0.05,
                position: [0.03, 0.0, 0.0445],
            },
        ])
        .unwrap();
        sim.add_instrument(
            Instrument::new("probe", InstrumentKind::Probe, 0.01, probe)
                .unwrap()
                .sticking(),
        );
        sim
    };
    let mut sync = run(false);
    let mut rt = run(true);
    let (mut sync_steps, mut rt_steps) = (0, 0);
    // The scalpel crosses the top in the first step: the synchronous run cuts there.
    sync.step(0.01).unwrap();
    sync_steps += 1;
    assert_eq!(sync.topology_version(), 1);
    // The real-time run steps on until the worker's incision lands (a wall-clock bound
    // only guards against a hang).
    let start = std::time::Instant::now();
    while rt.topology_version() == 0 && start.elapsed().as_secs() < 120 {
        rt.step(0.01).unwrap();
        rt_steps += 1;
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    assert_eq!(rt.topology_version(), 1, "the incision landed");
    assert!(
        rt_steps >= 2,
        "the first step answered on the uncut surface"
    );
    // Past the probe's path end (t = 0.05 s), both at the same place.
    while sync_steps < 8 || sync_steps < rt_steps + 2 {
        sync.step(0.01).unwrap();
        sync_steps += 1;
    }
    while rt_steps < sync_steps {
        rt.step(0.01).unwrap();
        rt_steps += 1;
    }
    assert_eq!(
        rt.model().surface().triangles,
        sync.model().surface().triangles
    );
    let (fs, fr) = (sync.instruments()[1].force(), rt.instruments()[1].force());
    assert!(fs.length() > 0.0, "the probe touches");
    assert!((fs - fr).length() <= 1e-9 * fs.length(), "{fs:?} {fr:?}");
}

/// A stroke whose blade is still inside when the scalpel is taken away (a viewer cut that
/// ends on the organ) opens at the next step, as the same stroke leaving the tissue does.
#[test]
fn a_stroke_held_when_the_scalpel_goes_opens_at_the_next_step() {
    // Ten short sweeps across the top, the blade inside the whole time.
    let mut sim = sphere_with_scalpel(false, 0.1);
    for _ in 0..10 {
        sim.step(0.01).unwrap();
    }
    assert_eq!(
        sim.topology_version(),
        0,
        "the stroke is held while the blade is in"
    );
    let triangles = sim.model().surface().triangles.len();
    sim.remove_instrument(0);
    sim.step(0.01).unwrap();
    assert_eq!(sim.topology_version(), 1);
    // The same groove as the whole stroke cut at once.
    let whole = incise(
        &sphere(2),
        &CutPath {
            start: [Vec3::new(-0.03, 0.001, 0.02), Vec3::new(-0.03, 0.001, 0.08)],
            end: [Vec3::new(0.02, 0.001, 0.02), Vec3::new(0.02, 0.001, 0.08)],
        },
        OPENING,
    )
    .unwrap()
    .unwrap();
    assert!(sim.model().surface().triangles.len() > triangles);
    assert_eq!(
        sim.model().surface().triangles,
        &whole.surface.triangles[..]
    );
}
