//! Checks of the BEM against invariants, exact elastic fields and a fresh inversion.

use faer::linalg::solvers::DenseSolveCore;

use super::*;
use crate::interact::{Constraints, Loads, Prescribed};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;
use crate::mesh::generate::icosphere;
use crate::model::Deformable;

pub(super) const E: Real = 3000.0;
pub(super) const NU: Real = 0.3;

pub(super) fn material() -> Material {
    Material::new(E, NU).unwrap()
}

pub(super) fn sphere(subdivisions: u32) -> SurfaceMesh {
    icosphere(Vec3::ZERO, 0.05, subdivisions)
}

/// Uniaxial strain ε along z: u = ε z e_z, σ = λε I + 2με e_z e_z. Zero on z = 0.
pub(super) struct Uniaxial {
    pub eps: Real,
}

impl Uniaxial {
    pub fn u(&self, x: Vec3) -> Vec3 {
        Vec3::new(0.0, 0.0, self.eps * x.z)
    }
    pub fn traction(&self, n: Vec3) -> Vec3 {
        let m = material();
        let (l, mu) = (m.lambda(), m.mu());
        Vec3::new(
            l * self.eps * n.x,
            l * self.eps * n.y,
            (l + 2.0 * mu) * self.eps * n.z,
        )
    }
}

/// Fixes the equator of a sphere, prescribes the exact field on the cap z > 0.6 R and loads
/// the rest with the exact tractions; returns the worst displacement error relative to the
/// largest displacement, and the worst cap reaction error relative to the largest reaction.
/// The exact uniaxial field: the cap (z > 3 cm) held at it, the equator fixed, the other
/// vertices loaded with its traction. With `rims`, the contacts' free side is traction-free
/// unless loaded, so the cap is loaded too (then the cap's own unknown traction is ~0) and
/// the reaction error is measured against zero.
fn uniaxial_errors_with(subdivisions: u32, rims: bool) -> (Real, Real) {
    let s = sphere(subdivisions);
    let field = Uniaxial { eps: 0.01 };
    let params = BemParams {
        discontinuous_contacts: rims,
        ..BemParams::default()
    };
    let mut model = Bem::new(&s, material(), params).unwrap();
    let rest = model.rest_surface().to_vec();
    let normals: Vec<Vec3> = rest.iter().map(|p| p.normalize()).collect();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z.abs() < 1e-12)
        .collect();
    let cap: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z > 0.03)
        .collect();
    let c = Constraints {
        fixed: fixed.clone(),
        prescribed: cap
            .iter()
            .map(|&v| Prescribed {
                vertex: v,
                position: rest[v as usize] + field.u(rest[v as usize]),
            })
            .collect(),
    };
    model.set_constraints(&c).unwrap();
    let areas = model.areas().to_vec();
    let point_loads = (0..rest.len())
        .filter(|&v| !fixed.contains(&(v as u32)) && (rims || !cap.contains(&(v as u32))))
        .map(|v| (v as u32, field.traction(normals[v]) * areas[v]))
        .collect();
    model
        .set_loads(&Loads {
            gravity: Vec3::ZERO,
            point_loads,
        })
        .unwrap();
    model.step(0.01).unwrap();
    let du = model
        .surface()
        .positions
        .iter()
        .zip(&rest)
        .map(|(p, r)| (*p - *r - field.u(*r)).length())
        .fold(0.0, Real::max);
    let umax = rest
        .iter()
        .map(|r| field.u(*r).length())
        .fold(0.0, Real::max);
    let reactions = model.reactions().prescribed;
    let (mut dr, mut rmax) = (0.0 as Real, 0.0 as Real);
    for (k, &v) in cap.iter().enumerate() {
        let exact = -field.traction(normals[v as usize]) * areas[v as usize];
        let expected = if rims { Vec3::ZERO } else { exact };
        dr = dr.max((reactions[k] - expected).length());
        rmax = rmax.max(exact.length());
    }
    (du / umax, dr / rmax)
}

fn uniaxial_errors(subdivisions: u32) -> (Real, Real) {
    uniaxial_errors_with(subdivisions, false)
}

#[test]
fn h_annihilates_rigid_translations() {
    let s = sphere(2);
    let m = Bem::new(&s, material(), BemParams::default()).unwrap();
    let inf = m.system().influence();
    let n = inf.dofs();
    let hmax = inf.h.iter().fold(0.0 as Real, |a, v| a.max(v.abs()));
    for r in 0..n {
        for k in 0..3 {
            let sum: Real = (0..n / 3).map(|j| inf.h_at(r, 3 * j + k)).sum();
            assert!(sum.abs() < 1e-10 * hmax, "row {r} axis {k}: {sum:e}");
        }
    }
}

#[test]
fn h_annihilates_rigid_rotations() {
    // A small rotation u = ω × x is linear on every flat triangle and carries no traction, so
    // H u = 0 holds for the discretised surface exactly: what is left is quadrature error
    // (the rigid-body diagonal makes translations exact by construction, rotations are not).
    let s = sphere(2);
    let m = Bem::new(&s, material(), BemParams::default()).unwrap();
    let inf = m.system().influence();
    let n = inf.dofs();
    let omega = Vec3::new(0.3, -0.5, 0.8);
    let u: Vec<Real> = s
        .vertices
        .iter()
        .flat_map(|x| omega.cross(*x).to_array())
        .collect();
    let (mut res, mut scale) = (0.0 as Real, 0.0 as Real);
    for r in 0..n {
        let terms = (0..n).map(|c| inf.h_at(r, c) * u[c]);
        res = res.max(terms.clone().sum::<Real>().abs());
        scale = scale.max(terms.fold(0.0, |a, t| a.max(t.abs())));
    }
    let rel = res / scale;
    eprintln!("rigid rotation, 162 vertices: max |H u| / max |H_rc u_c| = {rel:.3e}");
    assert!(rel < 1e-8, "{rel:e}");
}

#[test]
fn linear_field_satisfies_h_u_equals_g_p() {
    // The exact uniaxial field makes H U − G P small, and smaller on a finer mesh.
    let field = Uniaxial { eps: 0.01 };
    let mut last = Real::INFINITY;
    for sub in [1, 2] {
        let s = sphere(sub);
        let m = Bem::new(&s, material(), BemParams::default()).unwrap();
        let inf = m.system().influence();
        let n = inf.dofs();
        let u: Vec<Real> = s
            .vertices
            .iter()
            .flat_map(|x| field.u(*x).to_array())
            .collect();
        let p: Vec<Real> = s
            .vertices
            .iter()
            .flat_map(|x| field.traction(x.normalize()).to_array())
            .collect();
        let (mut res, mut scale) = (0.0 as Real, 0.0 as Real);
        for r in 0..n {
            let hu: Real = (0..n).map(|c| inf.h_at(r, c) * u[c]).sum();
            let gp: Real = (0..n).map(|c| inf.g_at(r, c) * p[c]).sum();
            res = res.max((hu - gp).abs());
            scale = scale.max(hu.abs());
        }
        let rel = res / scale;
        eprintln!("subdivisions {sub}: max |HU - GP| / max |HU| = {rel:.3e}");
        assert!(rel < 0.6 * last, "{rel} after {last}");
        last = rel;
    }
    assert!(last < 0.05, "{last}");
}

#[test]
fn uniaxial_strain_is_recovered() {
    let (du, dr) = uniaxial_errors(2);
    eprintln!(
        "uniaxial sphere, 162 vertices: displacement error {du:.3e}, reaction error {dr:.3e}"
    );
    assert!(du < 0.02, "{du}");
    assert!(dr < 0.1, "{dr}");
}

#[test]
fn uniaxial_strain_is_recovered_with_contact_rims() {
    // The rim rule takes the free side of a contact's rim as the loads make it: with the
    // field's traction loaded on the cap too, the cap holds the field with ~no reaction of
    // its own, as accurately as the continuous rule recovers it.
    let (du, dr) = uniaxial_errors_with(2, true);
    let (du_hat, _) = uniaxial_errors(2);
    eprintln!(
        "uniaxial sphere with contact rims, 162 vertices: displacement error {du:.3e} \
         (continuous rule {du_hat:.3e}), reaction {dr:.3e} of the field's"
    );
    assert!(du < 0.02, "{du}");
    assert!(dr < 0.1, "{dr}");
}

#[test]
fn woodbury_equals_a_fresh_inversion() {
    // The continuous rule, whose contact columns are −G as they stand; the rim rule's
    // update equals a dense solve in `bem_validation`.
    let s = sphere(1);
    let mut m = Bem::new(&s, material(), BemParams::continuous()).unwrap();
    let rest = m.rest_surface().to_vec();
    let fixed: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z < -0.03)
        .collect();
    let top: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z > 0.02)
        .collect();
    assert!(top.len() >= 10 && fixed.len() >= 3);
    for set in [&top[..3], &top[..10], &top[4..7]] {
        m.set_constraints(&press(&rest, -0.03, set)).unwrap();
        let sys = m.system();
        // A₀ (fixed tractions discontinuous at the rim) with the contacts' columns −G.
        let (mut a, _) = sys.base_matrix(sys.fixed());
        let g = &sys.influence().g;
        let n = sys.dofs();
        for &v in set {
            for c in 3 * v as usize..3 * v as usize + 3 {
                for r in 0..n {
                    a[(r, c)] = -g[r * n + c];
                }
            }
        }
        let fresh = a.partial_piv_lu().inverse();
        let updated = sys.explicit_inverse().unwrap();
        let rel = (&updated - &fresh).norm_l2() / fresh.norm_l2();
        eprintln!(
            "woodbury with {} contacts: relative difference {rel:.2e}",
            set.len()
        );
        assert!(rel < 1e-8, "{rel}");
    }
    assert_eq!(m.system().factorizations, 1);
    assert_eq!(m.system().woodbury_updates, 3);
}

/// Equator fixed, the north pole pushed 1 mm down.
fn pole_push(m: &Bem) -> Constraints {
    let rest = m.rest_surface();
    let pole = (0..rest.len())
        .max_by(|&a, &b| rest[a].z.total_cmp(&rest[b].z))
        .unwrap();
    Constraints {
        fixed: (0..rest.len() as u32)
            .filter(|&v| rest[v as usize].z.abs() < 1e-12)
            .collect(),
        prescribed: vec![Prescribed {
            vertex: pole as u32,
            position: rest[pole] - Vec3::Z * 1e-3,
        }],
    }
}

#[test]
fn quasi_viscous_steps_follow_eq_13_and_reach_the_static_state() {
    let s = sphere(1);
    let mut stat = Bem::new(&s, material(), BemParams::default()).unwrap();
    let c = pole_push(&stat);
    stat.set_constraints(&c).unwrap();
    stat.step(0.01).unwrap();
    let target = stat.surface().positions.to_vec();
    let params = BemParams {
        alpha: 0.05,
        ..BemParams::default()
    };
    let mut visc = Bem::new(&s, material(), params).unwrap();
    assert!(!visc.info().is_static && stat.info().is_static);
    visc.set_constraints(&c).unwrap();
    let dt = 0.01;
    visc.step(dt).unwrap();
    let rest = s.vertices.clone();
    let graph = SurfaceGraph::new(&s.vertices, &s.triangles);
    let d = graph.distances(&[c.prescribed[0].vertex as usize]);
    for v in 0..rest.len() {
        let f = (-0.05 * d[v] / dt).exp();
        let expect = rest[v] + (target[v] - rest[v]) * f;
        assert!(
            (visc.surface().positions[v] - expect).length() < 1e-15,
            "vertex {v}"
        );
    }
    let pole = c.prescribed[0].vertex as usize;
    assert_eq!(visc.surface().positions[pole], c.prescribed[0].position);
    for _ in 0..200 {
        visc.step(dt).unwrap();
    }
    let gap = visc
        .surface()
        .positions
        .iter()
        .zip(&target)
        .map(|(a, b)| (*a - *b).length())
        .fold(0.0, Real::max);
    assert!(gap < 1e-9, "{gap}");
    assert!(visc.step(0.0).is_err());
}

#[test]
fn reactions_balance_and_follow_the_push() {
    let s = sphere(2);
    let mut m = Bem::new(&s, material(), BemParams::default()).unwrap();
    let c = pole_push(&m);
    m.set_constraints(&c).unwrap();
    m.step(0.01).unwrap();
    let r = m.reactions();
    let probe: Vec3 = r.prescribed.iter().copied().sum();
    let support: Vec3 = r.fixed.iter().copied().sum();
    // Pushed down, the tissue pushes the probe up; the supports take the opposite. The
    // BIE does not impose global equilibrium exactly: it holds to discretisation error.
    assert!(probe.z > 0.0, "{probe}");
    let imbalance = (probe + support).length() / probe.length();
    eprintln!("pole push: probe {probe} N, imbalance {imbalance:.2e}");
    assert!(imbalance < 0.05, "{imbalance}");
    // Linear: twice the push, twice the force.
    let mut c2 = c.clone();
    let rest = m.rest_surface()[c.prescribed[0].vertex as usize];
    c2.prescribed[0].position = rest - Vec3::Z * 2e-3;
    m.set_constraints(&c2).unwrap();
    m.step(0.01).unwrap();
    let probe2: Vec3 = m.reactions().prescribed.iter().copied().sum();
    assert!((probe2 - probe * 2.0).length() < 1e-12 * probe.length());
    assert_eq!(
        m.system().factorizations,
        1,
        "a contact change does not refactorise"
    );
    m.reset();
    assert_eq!(m.surface().positions, m.rest_surface());
}

#[test]
fn bad_input_is_refused_with_its_reason() {
    let s = sphere(1);
    // An open surface.
    let mut open = s.clone();
    open.triangles.pop();
    let e = Bem::new(&open, material(), BemParams::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("not closed"), "{e}");
    // Inward normals.
    let mut inward = s.clone();
    inward.triangles.iter_mut().for_each(|t| t.swap(1, 2));
    let e = Bem::new(&inward, material(), BemParams::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("outward"), "{e}");
    // A triangle pointing at a vertex that does not exist.
    let mut bad = s.clone();
    bad.triangles[3][1] = 999;
    assert!(Bem::new(&bad, material(), BemParams::default()).is_err());
    let mut m = Bem::new(&s, material(), BemParams::default()).unwrap();
    // Solving before any fixed set, too few fixed vertices, a vertex that does not exist.
    assert!(m.step(0.01).is_err());
    assert!(m.set_constraints(&Constraints::fixed(vec![0, 1])).is_err());
    assert!(
        m.set_constraints(&Constraints::fixed(vec![0, 1, 500]))
            .is_err()
    );
    let loads = Loads {
        gravity: Vec3::new(0.0, Real::NAN, -9.81),
        point_loads: vec![],
    };
    let e = m.set_loads(&loads).unwrap_err().to_string();
    assert!(e.contains("gravity"), "{e}");
    let loads = Loads {
        gravity: Vec3::ZERO,
        point_loads: vec![(7, Vec3::NAN)],
    };
    assert!(m.set_loads(&loads).is_err());
    // Unknown or bad settings name themselves.
    let mut params = toml::Table::new();
    params.insert("viscosity".into(), toml::Value::Float(1.0));
    let mesh = crate::mesh::MeshData::from_surface(&s);
    let input = crate::model::BuildInput {
        mesh: &mesh,
        source: "sphere",
        material: material(),
        params: &params,
        regions: &[],
    };
    let e = Bem::from_input(&input).unwrap_err().to_string();
    assert!(e.contains("viscosity"), "{e}");
    let mut negative = toml::Table::new();
    negative.insert("alpha".into(), toml::Value::Float(-1.0));
    let input = crate::model::BuildInput {
        params: &negative,
        ..input
    };
    assert!(
        Bem::from_input(&input)
            .unwrap_err()
            .to_string()
            .contains("alpha")
    );
    // The rim cache's budget from a scene, in MiB; a negative one names the key.
    let mut budget = toml::Table::new();
    budget.insert("rim_cache_mib".into(), toml::Value::Float(1.5));
    let m = Bem::from_input(&crate::model::BuildInput {
        params: &budget,
        ..input
    })
    .unwrap();
    assert_eq!(m.system().rim_cache_budget(), 3 << 19);
    budget.insert("rim_cache_mib".into(), toml::Value::Float(-2.0));
    let e = Bem::from_input(&crate::model::BuildInput {
        params: &budget,
        ..input
    })
    .unwrap_err()
    .to_string();
    assert!(e.contains("rim_cache_mib"), "{e}");
}

#[test]
fn builds_by_kind_from_a_tet_mesh_boundary() {
    use crate::mesh::generate::{BoxSplit, box_tets};
    let tets = box_tets(Vec3::ZERO, Vec3::splat(0.02), [2, 2, 2], BoxSplit::Six);
    let mesh = crate::mesh::MeshData::from_tets(&tets);
    let params = toml::Table::new();
    let input = crate::model::BuildInput {
        mesh: &mesh,
        source: "box",
        material: material(),
        params: &params,
        regions: &[],
    };
    let m = crate::model::build("bem", &input).unwrap();
    assert_eq!(m.kind(), "bem");
    // 27 grid vertices, all but the centre on the boundary; 6 faces × 4 squares × 2 = 48.
    assert_eq!(m.info().surface_vertices, 26);
    assert_eq!(m.surface().triangles.len(), 48);
}

#[test]
fn fixed_tractions_act_only_on_fully_fixed_triangles() {
    // A0's column of a fixed vertex must be −G assembled over the fixed triangles alone
    // (an independent assembly of that sub-surface), except for a point support, which
    // keeps all its triangles; the support areas tile the floor.
    use crate::mesh::generate::{BoxSplit, box_tets};
    let tets = box_tets(
        Vec3::ZERO,
        Vec3::new(0.04, 0.04, 0.02),
        [4, 4, 2],
        BoxSplit::Six,
    );
    let s = crate::mesh::MeshData::from_tets(&tets)
        .surface_mesh()
        .unwrap();
    let mut m = Bem::new(&s, material(), BemParams::default()).unwrap();
    let rest = m.rest_surface().to_vec();
    let n = rest.len();
    let mut fixed: Vec<bool> = rest.iter().map(|p| p.z < 1e-9).collect();
    // A point support on the top face.
    let point = (0..n)
        .find(|&v| (rest[v] - Vec3::new(0.01, 0.02, 0.02)).length() < 1e-9)
        .unwrap();
    fixed[point] = true;
    let c = Constraints::fixed((0..n as u32).filter(|&v| fixed[v as usize]).collect());
    m.set_constraints(&c).unwrap();
    let sys = m.system();
    let (a, area) = sys.base_matrix(&fixed);
    let elements: Vec<_> = s
        .triangles
        .iter()
        .filter_map(|&t| assembly::Element::new(&s.vertices, t))
        .collect();
    let floor: Vec<_> = elements
        .iter()
        .copied()
        .filter(|e| e.nodes.iter().all(|&v| fixed[v] && v != point))
        .collect();
    let kelvin = Kelvin::new(material().mu(), NU);
    let sub = assembly::assemble(&s.vertices, &floor, &kelvin, &|_| {});
    let inf = sys.influence();
    let dofs = 3 * n;
    let gmax = inf.g.iter().fold(0.0 as Real, |a, v| a.max(v.abs()));
    let mut worst: Real = 0.0;
    let mut rim_changed: Real = 0.0;
    for (v, &is_fixed) in fixed.iter().enumerate() {
        for k in 0..3 {
            let c = 3 * v + k;
            for r in 0..dofs {
                let expect = if v == point {
                    -inf.g_at(r, c)
                } else if is_fixed {
                    -sub.g_at(r, c)
                } else {
                    inf.h_at(r, c)
                };
                worst = worst.max((a[(r, c)] - expect).abs());
                if is_fixed && v != point {
                    rim_changed = rim_changed.max((a[(r, c)] + inf.g_at(r, c)).abs());
                }
            }
        }
    }
    eprintln!(
        "fixed-set columns vs a sub-surface assembly: {:.2e}; rim share {:.2e} (of max |G| {gmax:.2e})",
        worst / gmax,
        rim_changed / gmax
    );
    assert!(worst < 1e-12 * gmax, "{worst:e}");
    assert!(
        rim_changed > 0.01 * gmax,
        "the floor's rim triangles were dropped"
    );
    let floor_area: Real = (0..n).filter(|&v| v != point).map(|v| area[v]).sum();
    assert!((floor_area - 0.04 * 0.04).abs() < 1e-15, "{floor_area}");
    // The point support's traction acts on all its triangles: its tributary area.
    assert!((area[point] - m.areas()[point]).abs() < 1e-18);
    assert_eq!(m.system().support_area(point), Some(area[point]));
}

#[test]
fn a_scene_built_model_assembles_on_first_constraints_and_reports_progress() {
    use std::sync::{Arc, Mutex};
    let s = sphere(1);
    let mesh = crate::mesh::MeshData::from_surface(&s);
    // The deprecated `progress` key is still accepted (and ignored).
    let mut params = toml::Table::new();
    params.insert("progress".into(), toml::Value::Boolean(true));
    let input = crate::model::BuildInput {
        mesh: &mesh,
        source: "sphere",
        material: material(),
        params: &params,
        regions: &[],
    };
    let mut deferred = crate::model::build("bem", &input).unwrap();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let sink = seen.clone();
    let counter = seen.clone();
    deferred.set_progress(crate::model::Progress::new(move |stage, f| {
        sink.lock().unwrap().push((stage.to_string(), f))
    }));
    assert!(seen.lock().unwrap().is_empty(), "nothing assembled yet");
    let mut eager = Bem::new(&s, material(), BemParams::default()).unwrap();
    let c = pole_push(&eager);
    deferred.set_constraints(&c).unwrap();
    eager.set_constraints(&c).unwrap();
    deferred.step(0.01).unwrap();
    eager.step(0.01).unwrap();
    assert_eq!(deferred.surface().positions, eager.surface().positions);
    assert_eq!(
        deferred.reactions().prescribed,
        eager.reactions().prescribed
    );
    let seen = seen.lock().unwrap();
    let last = |stage: &str| {
        seen.iter()
            .filter(|(s, _)| s.contains(stage))
            .map(|&(_, f)| f)
            .next_back()
    };
    assert_eq!(last("assembling"), Some(1.0), "{seen:?}");
    assert_eq!(last("factorising"), Some(1.0), "{seen:?}");
    // A second set of constraints with the same fixed set neither assembles nor factorises.
    let before = seen.len();
    drop(seen);
    deferred.set_constraints(&c).unwrap();
    assert_eq!(counter.lock().unwrap().len(), before);
}

#[test]
fn discontinuous_contacts_keep_woodbury_exact() {
    // With the contacts' tractions discontinuous at their rim, the Woodbury inverse must
    // equal a fresh inversion of the reordered matrix whose constrained columns (fixed and
    // contacts) are −G restricted to fully constrained triangles.
    let s = sphere(1);
    let params = BemParams {
        discontinuous_contacts: true,
        ..BemParams::default()
    };
    let mut m = Bem::new(&s, material(), params).unwrap();
    let rest = m.rest_surface().to_vec();
    let top: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z > 0.02)
        .collect();
    for set in [&top[..10], &top[..], &top[4..7]] {
        m.set_constraints(&press(&rest, -0.03, set)).unwrap();
        let sys = m.system();
        let mut mask = sys.fixed().to_vec();
        for &v in set {
            mask[v as usize] = true;
        }
        let (a, area) = sys.base_matrix(&mask);
        let fresh = a.partial_piv_lu().inverse();
        let updated = sys.explicit_inverse().unwrap();
        let rel = (&updated - &fresh).norm_l2() / fresh.norm_l2();
        // The contacts' areas: what turns their tractions into the probe force.
        for &v in set {
            assert_eq!(sys.support_area(v as usize), Some(area[v as usize]));
        }
        let full: Real = set.iter().map(|&v| m.areas()[v as usize]).sum();
        let inner: Real = set.iter().map(|&v| area[v as usize]).sum();
        eprintln!(
            "discontinuous contacts, {} contacts: relative difference {rel:.2e}, traction area {inner:.3e} of {full:.3e} m²",
            set.len()
        );
        assert!(rel < 1e-8, "{rel}");
        if set.len() == top.len() {
            assert!(inner < 0.9 * full, "the rim triangles were dropped");
        }
    }
    assert_eq!(m.system().factorizations, 1);
}

/// The vertices below `z_fixed` held, `vs` pushed 0.5 mm toward the centre.
pub(super) fn press(rest: &[Vec3], z_fixed: Real, vs: &[u32]) -> Constraints {
    Constraints {
        fixed: (0..rest.len() as u32)
            .filter(|&v| rest[v as usize].z < z_fixed)
            .collect(),
        prescribed: vs
            .iter()
            .map(|&v| Prescribed {
                vertex: v,
                position: rest[v as usize] * 0.99,
            })
            .collect(),
    }
}

/// One step under `c`: positions, reactions and tractions.
pub(super) fn step(m: &mut Bem, c: &Constraints) -> (Vec<Vec3>, Vec<Vec3>, Vec<Vec3>) {
    m.set_constraints(c).unwrap();
    m.step(0.01).unwrap();
    (
        m.surface().positions.to_vec(),
        m.reactions().prescribed.to_vec(),
        m.tractions().to_vec(),
    )
}

/// The sphere's top vertices (z > 0.025), highest first.
pub(super) fn top(rest: &[Vec3]) -> Vec<u32> {
    let mut top: Vec<u32> = (0..rest.len() as u32)
        .filter(|&v| rest[v as usize].z > 0.025)
        .collect();
    top.sort_by(|&a, &b| rest[b as usize].z.total_cmp(&rest[a as usize].z));
    top
}

/// Equator-and-below fixed, the given vertices pushed 0.5 mm toward the centre, one step.
fn press_step(m: &mut Bem, vs: &[u32]) -> (Vec<Vec3>, Vec<Vec3>, Vec<Vec3>) {
    let rest = m.rest_surface().to_vec();
    step(m, &press(&rest, -0.03, vs))
}

#[test]
fn rim_cache_hits_equal_cold_computations() {
    // W̃ sums the cached q in the order a cold computation does, so a contact set reached
    // through the cache gives the same bits as one solved from scratch.
    let s = sphere(2);
    let params = BemParams {
        discontinuous_contacts: true,
        ..BemParams::default()
    };
    let rest = s.vertices.clone();
    let top = top(&rest);
    assert!(top.len() >= 24, "{}", top.len());
    let (first, second) = (&top[..16], &top[6..24]);
    let mut warm = Bem::new(&s, material(), params).unwrap();
    let cold_first = press_step(&mut warm, first);
    let (solved, hits) = warm.system().rim_cache_counts();
    assert_eq!(hits, 0);
    let partly = press_step(&mut warm, second);
    let (solved2, hits2) = warm.system().rim_cache_counts();
    eprintln!(
        "rim pairs: first set {solved} solved; second set {} solved, {hits2} from the cache",
        solved2 - solved
    );
    assert!(hits2 > 0 && solved2 > solved, "{solved2} {hits2}");
    let mut fresh = Bem::new(&s, material(), params).unwrap();
    assert!(
        press_step(&mut fresh, second) == partly,
        "partly cached != cold"
    );
    // One more vertex: the contacts whose rims did not change keep their columns, and the
    // result is still the cold one's.
    let mut grown = Bem::new(&s, material(), params).unwrap();
    press_step(&mut grown, &top[..16]);
    let before = grown.system().rim_contacts_reused();
    let grown_result = press_step(&mut grown, &top[..17]);
    assert!(grown.system().rim_contacts_reused() > before);
    let mut cold = Bem::new(&s, material(), params).unwrap();
    assert!(
        press_step(&mut cold, &top[..17]) == grown_result,
        "reused != cold"
    );
    assert_eq!(cold.system().rim_contacts_reused(), 0);
    // Entirely from the cache: nothing solved.
    assert!(press_step(&mut warm, first) == cold_first, "cached != cold");
    assert_eq!(warm.system().rim_cache_counts().0, solved2);
    // Without a cache (budget 0) every change is cold, with the same result.
    let mut uncached = Bem::new(&s, material(), params).unwrap();
    uncached.set_rim_cache_budget(0);
    press_step(&mut uncached, first);
    assert!(press_step(&mut uncached, second) == partly);
    assert_eq!(uncached.system().rim_cache_usage(), (0, 0));
    // Warming ahead: every pair of the second set's vertices, then no miss.
    let mut ahead = Bem::new(&s, material(), params).unwrap();
    press_step(&mut ahead, &top[..1]);
    let warmed = ahead.warm_contact_rims(&second.iter().map(|&v| v as usize).collect::<Vec<_>>());
    let before = ahead.system().rim_cache_counts().0;
    assert!(press_step(&mut ahead, second) == partly);
    assert_eq!(
        ahead.system().rim_cache_counts().0,
        before,
        "{warmed} warmed"
    );
    // Warming the rings around the current patch covers the next, shifted patch.
    let mut near = Bem::new(&s, material(), params).unwrap();
    press_step(&mut near, first);
    let around = near.warm_contact_rims_near(2);
    let before = near.system().rim_cache_counts().0;
    assert!(press_step(&mut near, second) == partly);
    assert_eq!(
        near.system().rim_cache_counts().0,
        before,
        "{around} warmed"
    );
    let (bytes, pairs) = ahead.system().rim_cache_usage();
    assert_eq!(bytes, pairs * 3 * 3 * rest.len() * 8);
    // The option switched on a built model: the same contact model, no re-factorisation.
    let mut switched = Bem::new(&s, material(), BemParams::continuous()).unwrap();
    let continuous = press_step(&mut switched, second);
    switched.set_discontinuous_contacts(true).unwrap();
    switched.step(0.01).unwrap();
    assert!(switched.surface().positions == &partly.0[..]);
    assert!(continuous.0 != partly.0);
    switched.set_discontinuous_contacts(false).unwrap();
    switched.step(0.01).unwrap();
    assert!(switched.surface().positions == &continuous.0[..]);
    assert_eq!(switched.system().factorizations, 1);
}

#[test]
fn discontinuous_contacts_follow_an_incision_by_bordering() {
    // After a bordered incision the contact rims are solved through the bordered inverse:
    // no re-factorisation, and the same solution as a re-assembly and fresh factorisation
    // of the cut surface (the tolerance `tests_cut` uses for the default model).
    let s = sphere(2);
    let params = BemParams {
        discontinuous_contacts: true,
        ..BemParams::default()
    };
    let rest = s.vertices.clone();
    let c = Constraints {
        fixed: (0..rest.len() as u32)
            .filter(|&v| rest[v as usize].z < -0.04)
            .collect(),
        prescribed: (0..rest.len() as u32)
            .filter(|&v| rest[v as usize].x > 0.01 && rest[v as usize].z > 0.03)
            .map(|v| Prescribed {
                vertex: v,
                position: rest[v as usize] - Vec3::Z * 1e-3,
            })
            .collect(),
    };
    let blade = |y: Real, x0: Real, x1: Real| crate::model::CutPath {
        start: [Vec3::new(x0, y, 0.02), Vec3::new(x0, y, 0.08)],
        end: [Vec3::new(x1, y, 0.02), Vec3::new(x1, y, 0.08)],
    };
    let mut bordered = Bem::new(&s, material(), params).unwrap();
    let mut reassembled = Bem::new(&s, material(), params).unwrap();
    for m in [&mut bordered, &mut reassembled] {
        m.set_constraints(&c).unwrap();
        m.step(0.01).unwrap();
    }
    for (i, b) in [blade(0.001, -0.03, 0.02), blade(-0.012, -0.025, 0.03)]
        .iter()
        .enumerate()
    {
        bordered.cut(b).unwrap();
        reassembled.incise(b, CutUpdate::Reassembly).unwrap();
        bordered.step(0.01).unwrap();
        reassembled.step(0.01).unwrap();
        let sys = bordered.system();
        assert_eq!(sys.factorizations, 1, "cut {i}: re-factorised");
        assert_eq!(sys.borderings(), i + 1);
        let gap = |a: &[Vec3], b: &[Vec3]| {
            let scale = b.iter().map(|v| v.length()).fold(0.0, Real::max);
            let worst = a
                .iter()
                .zip(b)
                .map(|(p, q)| (*p - *q).length())
                .fold(0.0, Real::max);
            worst / scale
        };
        let du = gap(
            &bordered.static_displacements(),
            &reassembled.static_displacements(),
        );
        let dr = gap(
            bordered.reactions().prescribed,
            reassembled.reactions().prescribed,
        );
        // The Woodbury inverse through the bordered layers and the rim cache equals a fresh
        // inverse of the cut surface's constrained matrix.
        let mut mask = sys.fixed().to_vec();
        for &v in sys.contacts() {
            mask[v] = true;
        }
        let fresh = sys.base_matrix(&mask).0.partial_piv_lu().inverse();
        let rel = (&sys.explicit_inverse().unwrap() - &fresh).norm_l2() / fresh.norm_l2();
        let contact_area: Real = sys
            .contacts()
            .iter()
            .map(|&v| sys.support_area(v).unwrap())
            .sum();
        let tributary: Real = sys.contacts().iter().map(|&v| bordered.areas()[v]).sum();
        eprintln!(
            "cut {i}: vs re-assembly displacements {du:.2e}, probe reactions {dr:.2e}; \
             Woodbury vs fresh inverse {rel:.2e}; contact area {contact_area:.3e} of {tributary:.3e}"
        );
        assert!(du < 1e-6 && dr < 1e-6, "cut {i}: {du:e} {dr:e}");
        assert!(rel < 1e-8, "cut {i}: {rel:e}");
        assert!(contact_area < 0.9 * tributary, "the rims are not in effect");
    }
}
