//! The element integrals against Somigliana's identity: for a linear displacement field u
//! (uniform strain, so uniform stress σ and traction σn on each flat triangle), linear
//! elements represent u and the traction exactly, and
//!   ∫ U* σn dΓ − ∫ T* u dΓ = u(x) inside the body, 0 outside,
//! for any source x off the surface. What is left is quadrature error, for sources as close
//! to a triangle as a cut's lips get.

use super::assembly::{Element, element_integrals};
use super::kelvin::Kelvin;
use super::quadrature::Rules;
use super::tests::{material, sphere};
use crate::math::{Mat3, Real, Vec3};

/// A uniform strain and its stress for `material()`.
fn field() -> (Mat3, Mat3) {
    let m = material();
    let eps = Mat3::from_cols(
        Vec3::new(1e-3, 2e-4, -3e-4),
        Vec3::new(2e-4, -5e-4, 1e-4),
        Vec3::new(-3e-4, 1e-4, 7e-4),
    );
    let tr = eps.x_axis.x + eps.y_axis.y + eps.z_axis.z;
    let sigma = Mat3::IDENTITY * (m.lambda() * tr) + eps * (2.0 * m.mu());
    (eps, sigma)
}

/// Somigliana's right-hand side minus its expected value, for source `x`.
fn residual(x: Vec3, inside: bool, elements: &[Element], kelvin: &Kelvin, rules: &Rules) -> Vec3 {
    let (eps, sigma) = field();
    let mut sum = Vec3::ZERO;
    for e in elements {
        let (he, ge) = element_integrals(usize::MAX, x, e, kelvin, rules, true);
        let t = sigma * e.normal;
        for a in 0..3 {
            let u = eps * e.corners[a];
            for l in 0..3 {
                for k in 0..3 {
                    sum[l] += ge[a][l][k] * t[k] - he[a][l][k] * u[k];
                }
            }
        }
    }
    if inside { sum - eps * x } else { sum }
}

#[test]
fn somigliana_holds_for_sources_near_faces_edges_and_corners() {
    let s = sphere(2);
    let elements: Vec<Element> = s
        .triangles
        .iter()
        .map(|&t| Element::new(&s.vertices, t).unwrap())
        .collect();
    let m = material();
    let kelvin = Kelvin::new(m.mu(), m.poisson_ratio);
    let rules = Rules::new();
    let scale = s
        .vertices
        .iter()
        .map(|&p| (field().0 * p).length())
        .fold(0.0, Real::max);
    let mut worst: Real = 0.0;
    for (which, e) in elements.iter().enumerate().step_by(37) {
        let [a, b, c] = e.corners;
        let spots = [
            (a + b + c) / 3.0,
            0.5 * (a + b),
            a * 0.9 + b * 0.05 + c * 0.05,
        ];
        for spot in spots {
            for ratio in [1e-3, 1e-2, 0.05, 0.2, 0.5, 1.0, 3.0] {
                for side in [1.0, -1.0] {
                    let x = spot + e.normal * (side * ratio * e.size);
                    let r = residual(x, side < 0.0, &elements, &kelvin, &rules).length() / scale;
                    assert!(
                        r < 1e-8,
                        "element {which}, ratio {ratio}, side {side}: {r:e}"
                    );
                    worst = worst.max(r);
                }
            }
        }
    }
    eprintln!("Somigliana residual, worst relative: {worst:e}");
}
