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
        Vec3::new(l * self.eps * n.x, l * self.eps * n.y, (l + 2.0 * mu) * self.eps * n.z)
    }
}

/// Fixes the equator of a sphere, prescribes the exact field on the cap z > 0.6 R and loads
/// the rest with the exact tractions; returns the worst displacement error relative to the
/// largest displacement, and the worst cap reaction error relative to the largest reaction.
fn uniaxial_errors(subdivisions: u32) -> (Real, Real) {
    let s = sphere(subdivisions);
    let field = Uniaxial { eps: 0.01 };
    let mut model = Bem::new(&s, material(), BemParams::default()).unwrap();
    let rest = model.rest_surface().to_vec();
    let normals: Vec<Vec3> = rest.iter().map(|p| p.normalize()).collect();
    let fixed: Vec<u32> = (0..rest.len() as u32).filter(|&v| rest[v as usize].z.abs() < 1e-12).collect();
    let cap: Vec<u32> = (0..rest.len() as u32).filter(|&v| rest[v as usize].z > 0.03).collect();
    let c = Constraints {
        fixed: fixed.clone(),
        prescribed: cap
            .iter()
            .map(|&v| Prescribed { vertex: v, position: rest[v as usize] + field.u(rest[v as usize]) })
            .collect(),
    };
    model.set_constraints(&c).unwrap();
    let areas = model.areas().to_vec();
    let point_loads = (0..rest.len())
        .filter(|&v| !fixed.contains(&(v as u32)) && !cap.contains(&(v as u32)))
        .map(|v| (v as u32, field.traction(normals[v]) * areas[v]))
        .collect();
    model.set_loads(&Loads { gravity: Vec3::ZERO, point_loads }).unwrap();
    model.step(0.01).unwrap();
    let du = model
        .surface()
        .positions
        .iter()
        .zip(&rest)
        .map(|(p, r)| (*p - *r - field.u(*r)).length())
        .fold(0.0, Real::max);
    let umax = rest.iter().map(|r| field.u(*r).length()).fold(0.0, Real::max);
    let reactions = model.reactions().prescribed;
    let (mut dr, mut rmax) = (0.0 as Real, 0.0 as Real);
    for (k, &v) in cap.iter().enumerate() {
        let exact = -field.traction(normals[v as usize]) * areas[v as usize];
        dr = dr.max((reactions[k] - exact).length());
        rmax = rmax.max(exact.length());
    }
    (du / umax, dr / rmax)
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
fn linear_field_satisfies_h_u_equals_g_p() {
    // The exact uniaxial field makes H U − G P small, and smaller on a finer mesh.
    let field = Uniaxial { eps: 0.01 };
    let mut last = Real::INFINITY;
    for sub in [1, 2] {
        let s = sphere(sub);
        let m = Bem::new(&s, material(), BemParams::default()).unwrap();
        let inf = m.system().influence();
        let n = inf.dofs();
        let u: Vec<Real> = s.vertices.iter().flat_map(|x| field.u(*x).to_array()).collect();
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
    eprintln!("uniaxial sphere, 162 vertices: displacement error {du:.3e}, reaction error {dr:.3e}");
    assert!(du < 0.02, "{du}");
    assert!(dr < 0.1, "{dr}");
}

#[test]
fn woodbury_equals_a_fresh_inversion() {
    let s = sphere(1);
    let mut m = Bem::new(&s, material(), BemParams::default()).unwrap();
    let rest = m.rest_surface().to_vec();
    let fixed: Vec<u32> = (0..rest.len() as u32).filter(|&v| rest[v as usize].z < -0.03).collect();
    let press = |vs: &[u32]| Constraints {
        fixed: fixed.clone(),
        prescribed: vs
            .iter()
            .map(|&v| Prescribed { vertex: v, position: rest[v as usize] * 0.99 })
            .collect(),
    };
    let top: Vec<u32> = (0..rest.len() as u32).filter(|&v| rest[v as usize].z > 0.02).collect();
    assert!(top.len() >= 10 && fixed.len() >= 3);
    for set in [&top[..3], &top[..10], &top[4..7]] {
        m.set_constraints(&press(set)).unwrap();
        let sys = m.system();
        let mut mask = sys.fixed().to_vec();
        for &v in set {
            mask[v as usize] = true;
        }
        let fresh = sys.reordered(&mask).partial_piv_lu().inverse();
        let updated = sys.explicit_inverse().unwrap();
        let rel = (&updated - &fresh).norm_l2() / fresh.norm_l2();
        eprintln!("woodbury with {} contacts: relative difference {rel:.2e}", set.len());
        assert!(rel < 1e-8, "{rel}");
    }
    assert_eq!(m.system().factorizations, 1);
    assert_eq!(m.system().woodbury_updates, 3);
}

