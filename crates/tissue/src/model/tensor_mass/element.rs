//! Per-element quantities computed directly from the deformation gradient: the plain St
//! Venant–Kirchhoff force (the cross-check of the tensor form, and the energy of the
//! blow-up guard), its tangent product (for implicit schemes), the linear energy, the
//! displacement-gradient measure of the hybrid switch, and the volume-conservation penalty.
//!
//! StVK: F = I + H, E = ½(FᵀF − I), S = ℂ:E, first Piola–Kirchhoff stress P = F S, and the
//! force on corner a is −V P g_a. Its derivative along a displacement δ is
//! δP = δF S + F (ℂ : sym(Fᵀ δF)).
//!
//! Volume penalty (Picinbono et al. 2003 add one to stop soft tissue from losing volume):
//! energy (κ/2)(V − V₀)²/V₀ per tetrahedron, force −κ (V − V₀)/V₀ ∂V/∂x_a, with κ in Pa.

use crate::math::{Mat3, Real, Vec3, tet_signed_volume};

use super::elasticity::{Elasticity, TetRest, ddot};

#[inline]
fn green(h: &Mat3) -> Mat3 {
    (h.transpose() * *h + *h + h.transpose()) * 0.5
}

/// Forces of the St Venant–Kirchhoff energy on the corners, for corner displacements `u`.
#[inline]
pub fn stvk_forces(rest: &TetRest, el: &Elasticity, u: &[Vec3; 4]) -> [Vec3; 4] {
    let h = rest.displacement_gradient(u);
    let s = el.apply(green(&h));
    let p = (Mat3::IDENTITY + h) * s * (-rest.volume);
    rest.gradients.map(|g| p * g)
}

/// `stvk_forces` and the energy V ψ(E) = ½ V E:S in one pass.
#[inline]
pub fn stvk_forces_energy(rest: &TetRest, el: &Elasticity, u: &[Vec3; 4]) -> ([Vec3; 4], Real) {
    let h = rest.displacement_gradient(u);
    let e = green(&h);
    let s = el.apply(e);
    let p = (Mat3::IDENTITY + h) * s * (-rest.volume);
    (
        rest.gradients.map(|g| p * g),
        0.5 * rest.volume * ddot(&e, &s),
    )
}

/// V ψ(E) of the St Venant–Kirchhoff energy.
pub fn stvk_energy(rest: &TetRest, el: &Elasticity, u: &[Vec3; 4]) -> Real {
    let e = green(&rest.displacement_gradient(u));
    0.5 * rest.volume * ddot(&e, &el.apply(e))
}

/// V ψ(ε) of the linearised energy.
pub fn linear_energy(rest: &TetRest, el: &Elasticity, u: &[Vec3; 4]) -> Real {
    let h = rest.displacement_gradient(u);
    let e = (h + h.transpose()) * 0.5;
    0.5 * rest.volume * ddot(&e, &el.apply(e))
}

/// (∂f/∂u) δ with the sign flipped (the tangent stiffness times δ), per corner.
pub fn stvk_tangent_product(
    rest: &TetRest,
    el: &Elasticity,
    u: &[Vec3; 4],
    du: &[Vec3; 4],
) -> [Vec3; 4] {
    let h = rest.displacement_gradient(u);
    let dh = rest.displacement_gradient(du);
    let f = Mat3::IDENTITY + h;
    let s = el.apply(green(&h));
    let fd = f.transpose() * dh;
    let ds = el.apply((fd + fd.transpose()) * 0.5);
    let dp = (dh * s + f * ds) * rest.volume;
    rest.gradients.map(|g| dp * g)
}

/// The Frobenius norm of the displacement gradient H = ∂u/∂X: the measure of the hybrid
/// switch. Not the Green strain: the linear force is right only while both the strain and
/// the rotation are small, and a rotated element has no Green strain at all. Measured by
/// the Green strain, a tetrahedron turned 0.3 rad stayed linear, pushed back with the ghost
/// force of a large stretch (a rigid motion must give none), and every switch in and out of
/// the non-linear set changed the element's energy by that ghost's energy, a pump the
/// energy guard has to catch. With |H| below the threshold ε the linear force differs from
/// St Venant–Kirchhoff's by O(ε²) relative, so a switch does too.
#[inline]
pub fn gradient_norm(rest: &TetRest, u: &[Vec3; 4]) -> Real {
    let h = rest.displacement_gradient(u);
    ddot(&h, &h).sqrt()
}

/// ∂V/∂x_a of a tetrahedron's signed volume.
#[inline]
pub fn volume_gradient(x: &[Vec3; 4]) -> [Vec3; 4] {
    let (e1, e2, e3) = (x[1] - x[0], x[2] - x[0], x[3] - x[0]);
    let g1 = e2.cross(e3) / 6.0;
    let g2 = e3.cross(e1) / 6.0;
    let g3 = e1.cross(e2) / 6.0;
    [-(g1 + g2 + g3), g1, g2, g3]
}

/// Volume-penalty forces of one tetrahedron of rest volume `v0` and stiffness `kappa`.
#[inline]
pub fn volume_forces(x: &[Vec3; 4], v0: Real, kappa: Real) -> [Vec3; 4] {
    let v = tet_signed_volume(x[0], x[1], x[2], x[3]);
    let s = -kappa * (v - v0) / v0;
    volume_gradient(x).map(|g| g * s)
}

/// Volume-penalty energy of one tetrahedron.
pub fn volume_energy(x: &[Vec3; 4], v0: Real, kappa: Real) -> Real {
    let v = tet_signed_volume(x[0], x[1], x[2], x[3]);
    0.5 * kappa * (v - v0) * (v - v0) / v0
}
