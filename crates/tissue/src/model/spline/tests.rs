//! Tests of the spline model against analytic results: Kirchhoff's clamped plate, the
//! thin-walled cylinder, rigid motions, finite differences of the energy.

use super::*;
use crate::material::Material;
use crate::math::{Mat3, Real, Vec3, flatten};
use crate::solve::CgWorkspace;

/// A deterministic pseudo-random displacement in [−1, 1]³ per point.
fn wiggle(n: usize, seed: u64) -> Vec<Vec3> {
    let mut s = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((s >> 11) as Real / (1u64 << 53) as Real) * 2.0 - 1.0
    };
    (0..n).map(|_| Vec3::new(next(), next(), next())).collect()
}

fn material(e: Real, nu: Real) -> Material {
    Material::new(e, nu).unwrap()
}

fn curved_tube() -> (SplineSurface, ShellEnergy) {
    let s = SplineSurface::tube(0.01, 0.04, 8, 6).unwrap();
    let e = ShellEnergy::new(&s, &material(1e5, 0.3), 1e-3).unwrap();
    (s, e)
}

#[test]
fn forces_are_the_exact_gradient() {
    for (surf, energy) in [curved_tube(), {
        let s = SplineSurface::flat_patch(0.05, 0.03, 6, 5).unwrap();
        let e = ShellEnergy::new(&s, &material(2e4, 0.45), 2e-3).unwrap();
        (s, e)
    }] {
        let x: Vec<Vec3> = surf
            .control
            .iter()
            .zip(wiggle(surf.control.len(), 3))
            .map(|(p, d)| *p + 2e-3 * d)
            .collect();
        let mut f = vec![Vec3::ZERO; x.len()];
        let w = energy.add_forces(&x, &mut f);
        assert!((w - energy.energy(&x)).abs() <= 1e-14 * w.abs());
        let h = 1e-7;
        let scale = f.iter().map(|v| v.abs().max_element()).fold(0.0, Real::max);
        for i in 0..x.len() {
            for c in 0..3 {
                let mut xp = x.clone();
                let mut xm = x.clone();
                xp[i][c] += h;
                xm[i][c] -= h;
                let fd = -(energy.energy(&xp) - energy.energy(&xm)) / (2.0 * h);
                assert!(
                    (fd - f[i][c]).abs() < 1e-6 * scale,
                    "node {i} axis {c}: {fd} vs {}",
                    f[i][c]
                );
            }
        }
    }
}

#[test]
fn rigid_motion_costs_nothing() {
    let (surf, energy) = curved_tube();
    let r = Mat3::from_axis_angle(Vec3::new(0.3, -0.5, 0.8).normalize(), 1.1);
    let t = Vec3::new(0.2, -0.1, 0.05);
    let x: Vec<Vec3> = surf.control.iter().map(|p| r * *p + t).collect();
    // Scale: the energy of a 1% stretch.
    let stretched: Vec<Vec3> = surf.control.iter().map(|p| *p * 1.01).collect();
    let reference = energy.energy(&stretched);
    assert!(reference > 0.0);
    assert!(
        energy.energy(&x) < 1e-20 * reference.max(1.0),
        "{}",
        energy.energy(&x)
    );
    let mut f = vec![Vec3::ZERO; x.len()];
    energy.add_forces(&x, &mut f);
    let fmax = f.iter().map(|v| v.length()).fold(0.0, Real::max);
    assert!(fmax < 1e-9, "{fmax}");
}

#[test]
fn stiffness_product_matches_force_differences_at_rest_and_is_symmetric() {
    let (surf, mut energy) = curved_tube();
    energy.prepare(&surf.control);
    let n = surf.control.len();
    let (a, b) = (wiggle(n, 7), wiggle(n, 8));
    let mut ka = vec![Vec3::ZERO; n];
    let mut kb = vec![Vec3::ZERO; n];
    energy.product(&a, &mut ka);
    energy.product(&b, &mut kb);
    let dot = |p: &[Vec3], q: &[Vec3]| p.iter().zip(q).map(|(x, y)| x.dot(*y)).sum::<Real>();
    let (ab, ba) = (dot(&b, &ka), dot(&a, &kb));
    assert!((ab - ba).abs() < 1e-10 * ab.abs().max(1e-30));
    // At rest the Gauss–Newton stiffness is the Hessian: compare with −Δf/Δx.
    let h = 1e-7;
    let f_at = |s: Real| {
        let x: Vec<Vec3> = surf
            .control
            .iter()
            .zip(&a)
            .map(|(p, d)| *p + s * *d)
            .collect();
        let mut f = vec![Vec3::ZERO; n];
        energy.add_forces(&x, &mut f);
        f
    };
    let (fp, fm) = (f_at(h), f_at(-h));
    let scale = ka.iter().map(|v| v.length()).fold(0.0, Real::max);
    for i in 0..n {
        let fd = -(fp[i] - fm[i]) / (2.0 * h);
        assert!(fd.distance(ka[i]) < 1e-5 * scale, "{i}: {fd} vs {}", ka[i]);
    }
    // The diagonal is the diagonal of the product.
    let mut diag = vec![Vec3::ZERO; n];
    energy.diagonal(&mut diag);
    for (i, c) in [(0, 0), (5, 1), (17, 2), (n - 1, 0)] {
        let mut e = vec![Vec3::ZERO; n];
        e[i][c] = 1.0;
        let mut ke = vec![Vec3::ZERO; n];
        energy.product(&e, &mut ke);
        assert!((ke[i][c] - diag[i][c]).abs() < 1e-10 * diag[i][c].abs());
    }
}

/// Static equilibrium under a dead load by Newton iterations on the Gauss–Newton stiffness
/// (Jacobi-preconditioned CG). `held[3i + c]` holds that coordinate at its start value.
pub(super) fn static_solve(
    energy: &mut ShellEnergy,
    x: &mut [Vec3],
    held: &[bool],
    load: &[Vec3],
) -> Real {
    let n = x.len();
    let mut cg = CgWorkspace::new(3 * n);
    let mut residual = Real::INFINITY;
    for _ in 0..20 {
        let mut f = load.to_vec();
        energy.add_forces(x, &mut f);
        let b: Vec<Real> = flatten(&f)
            .iter()
            .zip(held)
            .map(|(v, h)| if *h { 0.0 } else { *v })
            .collect();
        let load_norm = flatten(load).iter().map(|v| v * v).sum::<Real>().sqrt();
        residual = b.iter().map(|v| v * v).sum::<Real>().sqrt() / load_norm;
        if residual < 1e-9 {
            break;
        }
        energy.prepare(x);
        let mut diag = vec![Vec3::ZERO; n];
        energy.diagonal(&mut diag);
        let inv: Vec<Real> = flatten(&diag)
            .iter()
            .zip(held)
            .map(|(d, h)| if *h || *d <= 0.0 { 0.0 } else { 1.0 / d })
            .collect();
        let mut dx = vec![0.0; 3 * n];
        let mut tmp = vec![Vec3::ZERO; n];
        let mut out = vec![Vec3::ZERO; n];
        cg.solve(
            |p, y| {
                for (t, c) in tmp.iter_mut().zip(p.chunks_exact(3)) {
                    *t = Vec3::new(c[0], c[1], c[2]);
                }
                out.iter_mut().for_each(|o| *o = Vec3::ZERO);
                energy.product(&tmp, &mut out);
                y.copy_from_slice(flatten(&out));
            },
            &inv,
            &b,
            &mut dx,
            20_000,
            1e-12,
        );
        for (xi, d) in x.iter_mut().zip(dx.chunks_exact(3)) {
            *xi += Vec3::new(d[0], d[1], d[2]);
        }
    }
    residual
}

/// Centre deflection of a clamped square plate (side a, thickness h) under a uniform
/// pressure q, relative to Kirchhoff's w = 0.0012653 q a⁴ / D (Timoshenko & Woinowsky-Krieger,
/// table 35).
fn clamped_plate_ratio(n: usize) -> Real {
    let (a, h, e, nu) = (0.1, 1e-3, 1e6, 0.3);
    let surf = SplineSurface::flat_patch(a, a, n, n).unwrap();
    let mut energy = ShellEnergy::new(&surf, &material(e, nu), h).unwrap();
    let d = e * h * h * h / (12.0 * (1.0 - nu * nu));
    // Deflection 1% of the thickness: the linear (Kirchhoff) regime.
    let expected = 0.01 * h;
    let q = expected * d / (0.001_265_3 * a.powi(4));
    let load = energy.area_load(|_, _| Vec3::new(0.0, 0.0, -q));
    // Clamped: the two outer rows of control points on every edge (position and slope).
    let held: Vec<bool> = (0..n * n)
        .flat_map(|k| {
            let (i, j) = (k % n, k / n);
            let edge = i < 2 || j < 2 || i >= n - 2 || j >= n - 2;
            [edge; 3]
        })
        .collect();
    let mut x = surf.control.clone();
    let res = static_solve(&mut energy, &mut x, &held, &load);
    assert!(res < 1e-8, "static solve residual {res}");
    let w = -surf.point_with(&x, 0.5, 0.5).z;
    w / expected
}

#[test]
fn clamped_plate_matches_kirchhoff() {
    let r = clamped_plate_ratio(12);
    assert!((r - 1.0).abs() < 0.05, "w / w_Kirchhoff = {r}");
}

#[test]
#[ignore = "convergence study; prints numbers"]
fn convergence_studies() {
    for n in [6, 8, 10, 12, 16, 20] {
        let r = clamped_plate_ratio(n);
        println!("clamped plate, control {n} x {n}: w / w_Kirchhoff = {r:.5}");
    }
    for (a, b) in [(8, 5), (12, 7), (16, 9), (24, 13)] {
        let r = inflated_tube_ratio(a, b);
        println!("inflated tube, control {a} x {b}: dr / dr_thin-walled = {r:.5}");
    }
}

/// Radial growth of a free-ended tube under internal pressure p, relative to the thin-walled
/// cylinder Δr = p R² / (E h) (hoop stress p R / h, no axial stress), corrected for the
/// bending stiffness of the wall: ×1 / (1 + h² / (12 (1 − ν²) R²)).
fn inflated_tube_ratio(nu_ctrl: usize, nv_ctrl: usize) -> Real {
    let (r, l, h, e, nu, p) = (0.01, 0.04, 5e-4, 1e5, 0.3, 1.0);
    let surf = SplineSurface::tube(r, l, nu_ctrl, nv_ctrl).unwrap();
    let mut energy = ShellEnergy::new(&surf, &material(e, nu), h).unwrap();
    let load = energy.area_load(|_, n| p * n);
    // Remove the rigid motions without restraining the expansion: the middle ring keeps its
    // z (symmetry), the control points at 0 and π keep y, the one at π/2 keeps x.
    let mut held = vec![false; 3 * surf.control.len()];
    let mid = nv_ctrl / 2;
    for i in 0..nu_ctrl {
        held[3 * (i + nu_ctrl * mid) + 2] = true;
    }
    for (i, c) in [(1, 1), (1 + nu_ctrl / 2, 1), (1 + nu_ctrl / 4, 0)] {
        held[3 * (i + nu_ctrl * mid) + c] = true;
    }
    let mut x = surf.control.clone();
    let res = static_solve(&mut energy, &mut x, &held, &load);
    assert!(res < 1e-8, "static solve residual {res}");
    let expected = p * r * r / (e * h) / (1.0 + h * h / (12.0 * (1.0 - nu * nu) * r * r));
    let radial = |pt: Vec3| (pt.x * pt.x + pt.y * pt.y).sqrt();
    let k = 16;
    let growth = (0..k)
        .map(|i| {
            let t = i as Real / k as Real;
            radial(surf.point_with(&x, t, 0.5)) - radial(surf.point(t, 0.5))
        })
        .sum::<Real>()
        / k as Real;
    growth / expected
}

#[test]
fn inflated_tube_matches_thin_walled_cylinder() {
    let ratio = inflated_tube_ratio(16, 9);
    assert!((ratio - 1.0).abs() < 0.01, "Δr / Δr_thin-walled = {ratio}");
}
