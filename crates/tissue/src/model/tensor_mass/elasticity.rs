//! The elasticity tensor ℂ shared by the linear and the St Venant–Kirchhoff tensor-mass
//! models, and the rest data of one tetrahedron.
//!
//! Both models derive from the energy density ψ = ½ E:ℂ:E, with E the Green strain (its
//! linearisation ε for `tensor-mass`). ℂ is isotropic (Lamé λ, μ) plus an optional
//! transversely isotropic fibre part along a unit direction a (Picinbono et al. 2003):
//! ψ_fibre = (λ_f/2)(aᵀEa)² + μ_f |Ea|², which stiffens stretch along the fibre and the
//! shears that involve it. ℂ is only ever applied to symmetric matrices, so it is stored as
//! its constants and applied as a function.

use crate::math::{Mat3, Real, Vec3};
use crate::model::fem::element_linear::shape_gradients;

/// ℂ as a map on symmetric 3×3 matrices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Elasticity {
    pub lambda: Real,
    pub mu: Real,
    /// Unit fibre direction, or zero for an isotropic material.
    pub fibre: Vec3,
    /// Extra Lamé-like constants along the fibre, in Pa.
    pub fibre_lambda: Real,
    pub fibre_mu: Real,
}

impl Elasticity {
    pub fn isotropic(lambda: Real, mu: Real) -> Self {
        Self {
            lambda,
            mu,
            fibre: Vec3::ZERO,
            fibre_lambda: 0.0,
            fibre_mu: 0.0,
        }
    }

    /// The same constants with a fibre along `direction` (normalised; zero disables it).
    pub fn with_fibre(mut self, direction: Vec3, fibre_lambda: Real, fibre_mu: Real) -> Self {
        self.fibre = direction.normalize_or_zero();
        self.fibre_lambda = fibre_lambda;
        self.fibre_mu = fibre_mu;
        self
    }

    pub fn has_fibre(&self) -> bool {
        self.fibre != Vec3::ZERO && (self.fibre_lambda != 0.0 || self.fibre_mu != 0.0)
    }

    /// ℂ : s for a symmetric s (the second Piola–Kirchhoff stress of a strain s).
    #[inline]
    pub fn apply(&self, s: Mat3) -> Mat3 {
        let tr = s.x_axis.x + s.y_axis.y + s.z_axis.z;
        let mut out = s * (2.0 * self.mu);
        out.x_axis.x += self.lambda * tr;
        out.y_axis.y += self.lambda * tr;
        out.z_axis.z += self.lambda * tr;
        if self.has_fibre() {
            out += self.apply_fibre(s);
        }
        out
    }

    /// The fibre part of ℂ : s alone.
    #[inline]
    pub fn apply_fibre(&self, s: Mat3) -> Mat3 {
        let a = self.fibre;
        let sa = s * a;
        let saa = outer(sa, a);
        outer(a, a) * (self.fibre_lambda * a.dot(sa)) + (saa + saa.transpose()) * self.fibre_mu
    }
}

/// u vᵀ.
#[inline]
pub fn outer(u: Vec3, v: Vec3) -> Mat3 {
    Mat3::from_cols(u * v.x, u * v.y, u * v.z)
}

/// (u vᵀ + v uᵀ) / 2.
#[inline]
pub fn sym_outer(u: Vec3, v: Vec3) -> Mat3 {
    let m = outer(u, v);
    (m + m.transpose()) * 0.5
}

/// Σ_ij a_ij b_ij.
#[inline]
pub fn ddot(a: &Mat3, b: &Mat3) -> Real {
    a.x_axis.dot(b.x_axis) + a.y_axis.dot(b.y_axis) + a.z_axis.dot(b.z_axis)
}

/// What a tetrahedron keeps of its rest shape: the gradients of its barycentric shape
/// functions and its volume (positive: meshes are validated before building).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TetRest {
    pub gradients: [Vec3; 4],
    pub volume: Real,
}

impl TetRest {
    pub fn new(corners: &[Vec3; 4]) -> Option<Self> {
        let (gradients, volume) = shape_gradients(corners)?;
        Some(Self {
            gradients,
            volume: volume.abs(),
        })
    }

    /// The displacement gradient H = Σ_a u_a g_aᵀ of corner displacements `u`.
    #[inline]
    pub fn displacement_gradient(&self, u: &[Vec3; 4]) -> Mat3 {
        let g = &self.gradients;
        let mut h = outer(u[0], g[0]);
        for a in 1..4 {
            h += outer(u[a], g[a]);
        }
        h
    }
}
