//! fem-condensed against fem-static on the liver and a box; shared fixtures for the
//! pre-computed tensors' tests.

use std::cell::RefCell;

use super::*;
use crate::interact::{Constraints, Loads, Prescribed};
use crate::math::testing::{central_jacobian, max_entry};
use crate::mesh::generate::{BoxSplit, box_tets};
use crate::model::testing::shifted_entries_force;
use crate::model::{Deformable, Reactions};

pub(crate) const LIVER: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");

pub(crate) fn liver_material() -> Material {
    Material::new(3000.0, 0.3).unwrap()
}

/// The liver in metres, its linear `fem-static` (the reference) and the fixed set of these
/// tests: file vertices 3, 39, 64 as surface vertices (the nearest surface vertex if
/// interior).
pub(crate) fn liver_static() -> (TetMesh, FemStatic, Vec<u32>) {
    let mut mesh = crate::io::read(LIVER).unwrap().tet_mesh(LIVER).unwrap();
    mesh.vertices.iter_mut().for_each(|v| *v *= 0.01);
    let fem = FemStatic::new(&mesh, liver_material(), Order::Linear).unwrap();
    let nodes = fem.surface_nodes();
    let rest = fem.rest_nodes();
    let fixed = [3usize, 39, 64]
        .iter()
        .map(|&v| {
            (0..nodes.len() as u32)
                .min_by(|&a, &b| {
                    let d = |s: u32| (rest[nodes[s as usize] as usize] - rest[v]).length();
                    d(a).total_cmp(&d(b))
                })
                .unwrap()
        })
        .collect();
    (mesh, fem, fixed)
}

/// Cutting is refused: the pre-computation holds for one topology only.
pub(crate) fn assert_cannot_cut(model: &mut dyn Deformable) {
    let blade = crate::model::CutPath {
        start: [Vec3::ZERO; 2],
        end: [Vec3::X; 2],
    };
    assert!(matches!(
        model.cut(&blade),
        Err(SimError::Unsupported { .. })
    ));
}

/// A small deterministic generator (LCG), uniform in [0, 1).
pub(crate) struct Rng(u64);
impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(6364136223846793005).wrapping_add(1))
    }
    pub fn next(&mut self) -> Real {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as Real / (1u64 << 53) as Real
    }
}

/// `count` distinct non-fixed surface vertices pushed by random displacements up to `amp`.
pub(crate) fn random_constraints(
    rest: &[Vec3],
    fixed: &[u32],
    count: usize,
    amp: Real,
    rng: &mut Rng,
) -> Constraints {
    let mut c = Constraints::fixed(fixed.to_vec());
    while c.prescribed.len() < count {
        let v = (rng.next() * rest.len() as Real) as u32;
        if fixed.contains(&v) || c.prescribed.iter().any(|p| p.vertex == v) {
            continue;
        }
        let d = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5) * 2.0 * amp;
        c.prescribed.push(Prescribed {
            vertex: v,
            position: rest[v as usize] + d,
        });
    }
    c
}

pub(crate) fn loads(point_vertex: u32) -> Loads {
    Loads {
        gravity: Vec3::new(0.0, 0.0, -9.81),
        point_loads: vec![(point_vertex, Vec3::new(0.01, -0.02, 0.005))],
    }
}

fn detail(m: &FemCondensed, name: &str) -> String {
    let info = m.info();
    let found = info.details.iter().find(|(k, _)| k == name);
    found.map(|(_, v)| v.clone()).unwrap_or_default()
}

fn max_abs(v: impl Iterator<Item = Real>) -> Real {
    v.fold(0.0, |m, x| m.max(x.abs()))
}

/// Relative difference of surface displacements and of reactions between two models.
pub(crate) fn compare(a: &dyn Deformable, b: &dyn Deformable) -> (Real, Real) {
    let rest = b.rest_surface();
    let (pa, pb) = (a.surface().positions, b.surface().positions);
    let du = max_abs(pa.iter().zip(pb).flat_map(|(x, y)| (*x - *y).to_array()));
    let scale_u = max_abs(pb.iter().zip(rest).flat_map(|(x, r)| (*x - *r).to_array()));
    let (ra, rb) = (a.reactions(), b.reactions());
    let flat = |r: Reactions<'_>| -> Vec<Real> {
        r.fixed
            .iter()
            .chain(r.prescribed)
            .flat_map(|v| v.to_array())
            .collect()
    };
    let (fa, fb) = (flat(ra), flat(rb));
    assert_eq!(fa.len(), fb.len());
    let dr = max_abs(fa.iter().zip(&fb).map(|(x, y)| x - y));
    let scale_r = max_abs(fb.iter().copied());
    (du / scale_u, dr / scale_r)
}

/// Applies the same constraints and loads to every model and steps them.
pub(crate) fn apply(models: &mut [&mut dyn Deformable], c: &Constraints, l: &Loads) {
    for m in models.iter_mut() {
        m.set_loads(l).unwrap();
        m.set_constraints(c).unwrap();
        m.step(0.0).unwrap();
    }
}

/// Σ reactions = Σ applied loads (gravity ρ g V plus point loads).
pub(crate) fn check_balance(m: &dyn Deformable, applied: Vec3) {
    let r = m.reactions();
    let total: Vec3 = r.fixed.iter().chain(r.prescribed).copied().sum();
    let scale = r
        .fixed
        .iter()
        .chain(r.prescribed)
        .fold(applied.length(), |s, v| s.max(v.length()));
    assert!(
        (total - applied).length() <= 1e-9 * scale,
        "{}: {total} vs {applied}",
        m.kind()
    );
}

pub(crate) fn applied_load(fem: &FemStatic, l: &Loads) -> Vec3 {
    let v: Real = (0..fem.linear_mesh().tets.len())
        .map(|e| fem.linear_mesh().tet_volume(e))
        .sum();
    l.gravity * fem.material().density * v + l.point_loads.iter().map(|p| p.1).sum::<Vec3>()
}

#[test]
fn liver_matches_fem_static_for_random_contact_sets() {
    let (mesh, mut reference, fixed) = liver_static();
    let calls = RefCell::new(Vec::new());
    let mut model = FemCondensed::new_with_progress(&mesh, liver_material(), &fixed, &|f| {
        calls.borrow_mut().push(f)
    })
    .unwrap();
    let calls = calls.into_inner();
    assert_eq!(
        calls.len(),
        137,
        "one progress call per free surface vertex"
    );
    assert!(calls.windows(2).all(|w| w[0] < w[1]) && calls.last() == Some(&1.0));
    assert_eq!(model.compliance().nrows(), 3 * 137);
    let rest = reference.rest_surface().to_vec();
    let mut rng = Rng::new(7);
    let l = loads(fixed[0] + 1);
    for count in [1, 3, 10, 25] {
        let c = random_constraints(&rest, &fixed, count, 2e-3, &mut rng);
        apply(&mut [&mut reference, &mut model], &c, &l);
        let (du, dr) = compare(&model, &reference);
        assert!(du < 1e-8 && dr < 1e-8, "{count} contacts: {du:e} {dr:e}");
        check_balance(&model, applied_load(&reference, &l));
        let interior = model.interior_displacements().unwrap();
        let u = reference.displacements();
        let scale = max_abs(u.iter().copied());
        let diff = max_abs(
            interior
                .iter()
                .flat_map(|v| v.to_array())
                .zip(u)
                .map(|(a, b)| a - b),
        );
        assert!(diff < 1e-8 * scale, "interior: {diff:e}");
    }
    // A new fixed set is condensed again, the same one is not.
    assert_eq!(detail(&model, "rebuilds"), "1");
    let mut c = random_constraints(&rest, &fixed, 5, 1e-3, &mut rng);
    model.set_constraints(&c).unwrap();
    assert_eq!(detail(&model, "rebuilds"), "1");
    c.fixed.push(c.prescribed[0].vertex);
    apply(&mut [&mut reference, &mut model], &c, &l);
    assert_eq!(detail(&model, "rebuilds"), "2");
    assert_eq!(model.compliance().nrows(), 3 * 136);
    let (du, dr) = compare(&model, &reference);
    assert!(du < 1e-8 && dr < 1e-8, "after rebuild: {du:e} {dr:e}");
}

/// A 10 × 2 × 2-cell beam of 10 × 2 × 2 cm, its material, its linear `fem-static` and the
/// surface vertices at x = 0 (the clamp).
fn clamped_beam(split: BoxSplit) -> (TetMesh, Material, FemStatic, Vec<u32>) {
    let mesh = box_tets(Vec3::ZERO, Vec3::new(0.1, 0.02, 0.02), [10, 2, 2], split);
    let material = Material::new(5000.0, 0.4).unwrap();
    let reference = FemStatic::new(&mesh, material, Order::Linear).unwrap();
    let rest = reference.rest_surface();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].x < 1e-9)
        .collect();
    assert_eq!(fixed.len(), 9);
    (mesh, material, reference, fixed)
}

/// A 10 × 2 × 2-cell beam clamped at x = 0 under random contacts and loads: `build` (a
/// surface-response model, given the mesh, material and fixed set) against `fem-static`.
pub(crate) fn box_matches_fem_static_with<M: Deformable>(
    split: BoxSplit,
    seed: u64,
    load_vertex: u32,
    counts: [usize; 2],
    build: impl Fn(&TetMesh, Material, &[u32]) -> M,
) {
    let (mesh, material, mut reference, fixed) = clamped_beam(split);
    let rest = reference.rest_surface().to_vec();
    let mut model = build(&mesh, material, &fixed);
    let mut rng = Rng::new(seed);
    let l = loads(load_vertex);
    for count in counts {
        let c = random_constraints(&rest, &fixed, count, 1e-3, &mut rng);
        apply(&mut [&mut reference, &mut model], &c, &l);
        let (du, dr) = compare(&model, &reference);
        assert!(du < 1e-8 && dr < 1e-8, "{count}: {du:e} {dr:e}");
        check_balance(&model, applied_load(&reference, &l));
    }
}

/// `prescribed_stiffness` of a surface-response model on the clamped beam against central
/// differences of `fem-static`'s reactions (an independent implementation): two instruments
/// (entries 0..5 and the rest), a vertex given to both, loads on.
pub(crate) fn stiffness_matches_fem_static_differences_with<M: Deformable>(
    build: impl Fn(&TetMesh, Material, &[u32]) -> M,
) {
    let (mesh, material, mut reference, fixed) = clamped_beam(BoxSplit::Six);
    let rest = reference.rest_surface().to_vec();
    let mut model = build(&mesh, material, &fixed);
    let mut c = random_constraints(&rest, &fixed, 9, 1e-3, &mut Rng::new(5));
    let mut repeat = c.prescribed[2];
    repeat.position += Vec3::splat(1e-4);
    c.prescribed.push(repeat);
    let l = loads(20);
    apply(&mut [&mut reference, &mut model], &c, &l);
    let k = model.prescribed_stiffness(0..5).unwrap();
    assert!(model.prescribed_stiffness(0..100).is_none());
    // fem-static keeps the loads `apply` gave it; only the targets of entries 0..5 move.
    let fd = central_jacobian(1e-5, |shift| {
        shifted_entries_force(&mut reference, &c, 5, shift)
    });
    let gap = max_entry(k - fd) / max_entry(fd);
    eprintln!(
        "{}: stiffness gap to fem-static differences {gap:.1e}",
        model.kind()
    );
    assert!(gap <= 1e-6, "{k:?} vs {fd:?}");
}

#[test]
fn stiffness_matches_fem_static_differences() {
    stiffness_matches_fem_static_differences_with(|mesh, material, fixed| {
        FemCondensed::new(mesh, material, fixed).unwrap()
    });
}

#[test]
fn box_matches_fem_static() {
    box_matches_fem_static_with(BoxSplit::Six, 11, 20, [2, 8], |mesh, material, fixed| {
        FemCondensed::new(mesh, material, fixed).unwrap()
    });
}

#[test]
fn compliance_is_symmetric_positive_and_inverts_the_condensed_stiffness() {
    let (mesh, _, fixed) = liver_static();
    let model = FemCondensed::new(&mesh, liver_material(), &fixed).unwrap();
    let w = model.compliance();
    let n = w.nrows();
    let scale = max_abs((0..n).map(|i| w[(i, i)]));
    for j in 0..n {
        assert!(w[(j, j)] > 0.0);
        for i in 0..j {
            assert!((w[(i, j)] - w[(j, i)]).abs() <= 1e-10 * scale);
        }
    }
    // The diagonal block of a vertex is the inverse of the force per displacement, and
    // Cauchy-Schwarz holds for an SPD matrix: |W_ij| ≤ sqrt(W_ii W_jj).
    for j in 0..n {
        for i in 0..n {
            assert!(w[(i, j)].abs() <= (w[(i, i)] * w[(j, j)]).sqrt() * (1.0 + 1e-12));
        }
    }
}

#[test]
fn bad_input_is_refused_and_keeps_the_state() {
    let (mesh, fem, fixed) = liver_static();
    let rest = fem.rest_surface().to_vec();
    let mut model = FemCondensed::new(&mesh, liver_material(), &fixed).unwrap();
    let c = random_constraints(&rest, &fixed, 4, 1e-3, &mut Rng::new(3));
    model.set_constraints(&c).unwrap();
    model.step(0.0).unwrap();
    let before = model.surface().positions.to_vec();
    let mut bad = c.clone();
    bad.prescribed[1].position.y = Real::NAN;
    assert!(matches!(
        model.set_constraints(&bad),
        Err(SimError::BadParameter { .. })
    ));
    bad.prescribed[1].position = rest[1];
    bad.prescribed[1].vertex = 10_000;
    assert!(matches!(
        model.set_constraints(&bad),
        Err(SimError::BadConstraint { vertex: 10_000, .. })
    ));
    model.step(0.0).unwrap();
    assert_eq!(model.surface().positions, &before[..]);
    assert_cannot_cut(&mut model);
    let info = model.info();
    assert!(info.is_static && info.memory_bytes > 411 * 411 * 8);
    // Too few fixed vertices: a clear error, the model keeps its condensation.
    assert!(
        model
            .set_constraints(&Constraints::fixed(vec![fixed[0]]))
            .is_err()
    );
    model.set_constraints(&c).unwrap();
    model.step(0.0).unwrap();
    assert_eq!(model.surface().positions, &before[..]);
    // No fixed set yet: stepping says what is missing.
    let mut fresh = FemCondensed::new(&mesh, liver_material(), &[]).unwrap();
    assert!(fresh.step(0.0).is_err());
}

#[test]
fn contact_buffers_grow_only_when_more_contacts_appear() {
    let (mesh, fem, fixed) = liver_static();
    let rest = fem.rest_surface().to_vec();
    let mut model = FemCondensed::new(&mesh, liver_material(), &fixed).unwrap();
    let capacity = |m: &FemCondensed| detail(m, "contact_capacity");
    assert_eq!(capacity(&model), "16");
    let mut rng = Rng::new(5);
    for count in [3, 10, 16, 5] {
        let c = random_constraints(&rest, &fixed, count, 1e-3, &mut rng);
        model.set_constraints(&c).unwrap();
        model.step(0.0).unwrap();
        assert_eq!(capacity(&model), "16");
    }
    let c = random_constraints(&rest, &fixed, 20, 1e-3, &mut rng);
    model.set_constraints(&c).unwrap();
    model.step(0.0).unwrap();
    assert_eq!(capacity(&model), "32");
}

#[test]
fn condensation_reports_its_progress_once_per_free_surface_vertex() {
    use std::sync::{Arc, Mutex};
    let (mesh, fem, fixed) = liver_static();
    let free = fem.rest_surface().len() - fixed.len();
    let mut model = FemCondensed::new(&mesh, liver_material(), &[]).unwrap();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let sink = seen.clone();
    model.set_progress(crate::model::Progress::new(move |_, f| {
        sink.lock().unwrap().push(f)
    }));
    model.set_constraints(&Constraints::fixed(fixed)).unwrap();
    let seen = seen.lock().unwrap();
    assert_eq!(seen.len(), free);
    assert!(seen.windows(2).all(|w| w[0] < w[1]));
    assert_eq!(seen.last().copied(), Some(1.0));
}
