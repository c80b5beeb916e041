//! Sliding contact checked against contact mechanics: Hertz's force law for a sphere pressed
//! into a block, frictionless and Coulomb sliding on a flat block, the force direction on a
//! curved surface, and a plane pressing a whole face (uniaxial compression).
//!
//! The blocks are graded: fine (about half a millimetre) where the probe touches, coarse far
//! away, so a block much larger than the contact stays small enough to solve in seconds.

use tissue::error::SimError;
use tissue::interact::{Constraints, Instrument, InstrumentKind, Keyframe, Loads, Trajectory};
use tissue::material::Material;
use tissue::math::{Mat3, Real, Vec3};
use tissue::mesh::MeshData;
use tissue::mesh::generate::{BoxSplit, box_tets};
use tissue::model::registry::{BuildInput, build};
use tissue::model::{
    ContactSurface, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView, VolumeView,
};
use tissue::sim::Simulation;

const E: Real = 3000.0;

/// A block [−l, l]² × [0, h] on a fixed floor, `cells` cells across (half as many deep),
/// graded toward the top centre: x = l (α s + (1 − α) s³), s ∈ [−1, 1], and the same
/// toward the top in z. `lift(x)` raises the top surface (a curved block), fading to the
/// floor.
fn block(l: Real, h: Real, cells: usize, lift: &dyn Fn(Real) -> Real) -> MeshData {
    let mut mesh = box_tets(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 1.0),
        [cells, cells, cells / 2],
        BoxSplit::Six,
    );
    let alpha = 0.25;
    let grade = |s: Real| alpha * s + (1.0 - alpha) * s * s * s;
    for p in &mut mesh.vertices {
        let (x, y) = (l * grade(p.x), l * grade(p.y));
        // 1 − grade(1 − z): fine at the top.
        let t = 1.0 - grade(1.0 - p.z);
        *p = Vec3::new(x, y, h * t + t * lift(x));
    }
    MeshData::from_tets(&mesh)
}

fn model(kind: &str, mesh: &MeshData, nu: Real) -> Box<dyn tissue::model::Deformable> {
    model_with(kind, mesh, nu, toml::Table::new())
}

fn model_with(
    kind: &str,
    mesh: &MeshData,
    nu: Real,
    params: toml::Table,
) -> Box<dyn tissue::model::Deformable> {
    let mut material = Material::new(E, nu).unwrap();
    material.damping = 20.0;
    let input = BuildInput {
        mesh,
        source: "graded block",
        material,
        params: &params,
    };
    build(kind, &input).unwrap()
}

/// The simulation with the floor (z = 0) fixed.
fn sim_on_floor(model: Box<dyn tissue::model::Deformable>) -> Simulation {
    let fixed: Vec<u32> = (0..model.rest_surface().len() as u32)
        .filter(|&v| model.rest_surface()[v as usize].z < 1e-9)
        .collect();
    Simulation::new(model, fixed, Loads::default()).unwrap()
}

fn path(keys: &[(Real, Vec3)]) -> Trajectory {
    Trajectory::new(
        keys.iter()
            .map(|&(t, p)| Keyframe {
                t,
                position: p.to_array(),
            })
            .collect(),
    )
    .unwrap()
}

/// Hertz: F = 4/3 · E/(1 − ν²) · √R · δ^{3/2}.
fn hertz(nu: Real, r: Real, depth: Real) -> Real {
    4.0 / 3.0 * E / (1.0 - nu * nu) * r.sqrt() * depth.powf(1.5)
}

const L: Real = 0.02;
const H: Real = 0.02;
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

/// The sliding probe: large against its indentation (contact radius √(R δ) = 2.4 mm, a/R =
/// 0.12), so that its surface is nearly flat over the contact and μN along the surface is
/// μN sideways within 1%.
const SLIDE_R: Real = 0.02;
const SLIDE_DEPTH: Real = 3e-4;

/// Presses the probe into the flat block, then moves it 3 mm along +x; the force at each
/// step of the move.
fn slide(kind: &str, friction: Real, dt: Real) -> Vec<Vec3> {
    slide_on(kind, friction, dt, 16)
}

/// `slide` on a block of `cells` cells across.
fn slide_on(kind: &str, friction: Real, dt: Real, cells: usize) -> Vec<Vec3> {
    slide_of(kind, friction, dt, cells, false).0
}

/// `slide_on`, the model wrapped in `Relaxed` when `relaxed`; also the most solves a step
/// took.
fn slide_of(
    kind: &str,
    friction: Real,
    dt: Real,
    cells: usize,
    relaxed: bool,
) -> (Vec<Vec3>, usize) {
    let mesh = block(L, H, cells, &|_| 0.0);
    let built = model(kind, &mesh, 0.3);
    let mut sim = sim_on_floor(if relaxed {
        Box::new(Relaxed(built))
    } else {
        built
    });
    sim.set_max_contact_iterations(60);
    let top = Vec3::new(-0.0015, 0.0, H + SLIDE_R);
    let down = top - Vec3::Z * SLIDE_DEPTH;
    let probe = Instrument::new(
        "probe",
        InstrumentKind::Probe,
        SLIDE_R,
        path(&[(0.0, top), (0.5, down), (1.5, down + Vec3::X * 3e-3)]),
    )
    .unwrap()
    .with_friction(friction)
    .unwrap();
    sim.add_instrument(probe);
    let mut forces = Vec::new();
    let mut most_solves = 0;
    let mut t = 0.0;
    while t < 1.5 - 1e-9 {
        let r = sim.step(dt).unwrap();
        t = r.time;
        most_solves = most_solves.max(r.contact_iterations);
        if t > 0.5 + 1e-9 {
            forces.push(r.forces[0]);
            eprintln!(
                "t {t:.2}: {} solves, slide residual {:.1e}, {} contacts",
                r.contact_iterations, r.slide_residual, r.contacts[0]
            );
        }
    }
    (forces, most_solves)
}

/// A model with the default `Deformable::set_constraints_along` (every contact held in all
/// three directions, false returned): `Simulation` slides its frictionless contacts by the
/// relaxation of their targets, as the compliance kinds did before they held them along
/// their normals. What the exact holds are measured against.
struct Relaxed(Box<dyn Deformable>);

impl Deformable for Relaxed {
    fn kind(&self) -> &'static str {
        self.0.kind()
    }
    fn surface(&self) -> SurfaceView<'_> {
        self.0.surface()
    }
    fn rest_surface(&self) -> &[Vec3] {
        self.0.rest_surface()
    }
    fn volume(&self) -> Option<VolumeView<'_>> {
        self.0.volume()
    }
    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        self.0.set_constraints(c)
    }
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        self.0.set_loads(loads)
    }
    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        self.0.step(dt)
    }
    fn reactions(&self) -> Reactions<'_> {
        self.0.reactions()
    }
    fn reset(&mut self) {
        self.0.reset()
    }
    fn prescribed_stiffness(&self, entries: std::ops::Range<usize>) -> Option<Mat3> {
        self.0.prescribed_stiffness(entries)
    }
    fn set_contact_reach(&mut self, reach: Option<&[(Vec3, Real)]>) {
        self.0.set_contact_reach(reach)
    }
    fn contact_surface(&self) -> ContactSurface<'_> {
        self.0.contact_surface()
    }
    fn info(&self) -> ModelInfo {
        self.0.info()
    }
}

fn tangential(f: Vec3) -> Real {
    Vec3::new(f.x, f.y, 0.0).length()
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

/// The shipped liver scene with its fine surface (`[mesh] visual`), fem-static: contacts are
/// found on the 2194 fine vertices and handed to the coarse surface by the map's weights.
#[test]
fn fine_liver_surface_holds_the_probe_out_and_the_supports_balance() {
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-probe.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace(
            "scale = 0.01",
            &format!("scale = 0.01\nvisual = \"{root}/assets/meshes/liver-smooth.obj\""),
        );
    let dir = std::env::temp_dir().join(format!("tissue-fine-liver-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("fine.toml");
    std::fs::write(&path, text).unwrap();
    let scene = tissue::scene::Scene::load(&path).unwrap();
    let mut sim = scene.build().unwrap();
    assert_eq!(sim.fine_surface().unwrap().0.len(), 2194);
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
    let root = format!("{}/../..", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(format!("{root}/scenes/liver-fem-condensed.toml"))
        .unwrap()
        .replace("../assets", &format!("{root}/assets"))
        .replace("\"fem-condensed\"", &format!("\"{kind}\""))
        .replace(
            "kind = \"probe\"",
            "kind = \"probe\"\ncontact = \"sliding\"",
        )
        .replace("max_iterations = 8", "max_iterations = 50")
        // Three point supports have no fully fixed triangle for the BEM's discontinuous
        // rule, and with it a contact released for pulling leaves its neighbours' tractions
        // on fewer triangles: the continuous rule (see the bem test below).
        .replace(
            "kind = \"bem\"",
            "kind = \"bem\"\ndiscontinuous_contacts = false",
        )
        .replace("radius = 0.005", "radius = 0.02")
        .replace("0.0555, 0.0067", "0.0705, 0.0067")
        .replace("0.0455, 0.0067", "0.0625, 0.0067");
    let dir = std::env::temp_dir().join(format!(
        "tissue-sliding-liver-{kind}-{}",
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
        "coarse liver, frictionless probe, {kind}{}: F = {:.5} N at 8 mm, {} contacts, at \
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
