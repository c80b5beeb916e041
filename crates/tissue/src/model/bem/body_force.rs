//! Gravity in the BEM without a volume integral, by a particular solution.
//!
//! A uniform body force b (N/m³, ρg) enters the boundary integral equation through a domain
//! integral that a surface-only model cannot evaluate. Instead, the displacement is split as
//! u = u_p + u_h, where u_p is any field that balances b inside the body and u_h solves the
//! homogeneous problem, the one H and G already describe. For each component k,
//!   u_p,k = −b_k (x_k − o_k)² / (2(λ + 2μ))
//! has the uniaxial strain ε_kk = −b_k (x_k − o_k) / (λ + 2μ) and stress
//! σ = Σ_k ε_kk (λ I + 2μ e_k e_kᵀ), whose divergence is −b: it balances gravity exactly,
//! and it is linear in b. The homogeneous part then sees the boundary data shifted by the
//! particular field: a fixed vertex holds u_h = −u_p, a free surface carries the traction
//! −t_p = −σ n, a contact holds u_h = u* − u_p. Since σ is linear in x and n is constant
//! on each triangle, t_p is exact per triangle corner (one value per corner, not per
//! vertex, so sharp edges keep their two normals).
//!
//! In the reordered system (fixed columns exchanged) this is one more right-hand side,
//!   A₀ x_g = −Σ_{known corners} G_{τ,a} t_p(a, τ) + H_{:,F} u_p,F,
//! solved once per gravity and fixed set; contacts then act through the Woodbury update as
//! before, with their targets shifted by −u_p.

use crate::error::SimError;
use crate::math::{Real, Vec3};

use super::assembly::Geometry;
use super::model::Bem;
use super::system::{BemSystem, not_factored};

/// The particular solution of a uniform body force, about an origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct BodyForce {
    /// The body force per volume, N/m³.
    pub b: Vec3,
    /// Where u_p vanishes (any point does; the centroid keeps the numbers small).
    pub origin: Vec3,
    lambda: Real,
    mu: Real,
}

impl BodyForce {
    pub fn new(b: Vec3, origin: Vec3, lambda: Real, mu: Real) -> Self {
        Self {
            b,
            origin,
            lambda,
            mu,
        }
    }

    /// ε_kk per component (the strain is diagonal).
    fn strain(&self, x: Vec3) -> Vec3 {
        -self.b * (x - self.origin) / (self.lambda + 2.0 * self.mu)
    }

    /// u_p at `x`, in m.
    pub fn displacement(&self, x: Vec3) -> Vec3 {
        let s = x - self.origin;
        -self.b * s * s / (2.0 * (self.lambda + 2.0 * self.mu))
    }

    /// t_p = σ_p n at `x` on a surface with outward normal `n`, in Pa.
    pub fn traction(&self, x: Vec3, n: Vec3) -> Vec3 {
        let e = self.strain(x);
        self.lambda * (e.x + e.y + e.z) * n + 2.0 * self.mu * e * n
    }

    /// The particular traction at each corner of each triangle (with that triangle's
    /// normal).
    pub fn corner_tractions(&self, geo: &Geometry) -> Vec<[Vec3; 3]> {
        geo.elements
            .iter()
            .map(|e| e.corners.map(|x| self.traction(x, e.normal)))
            .collect()
    }

    /// ∫ φ_v t_p dA over the triangles each vertex's unknown traction acts on
    /// (`supports[e][a]`: corner a of element e belongs to its vertex's support), in N:
    /// what the particular field adds to a support's reaction. Exact: t_p is linear on a
    /// triangle, and ∫ φ_a t = A/12 (2 t_a + t_b + t_c).
    pub fn support_forces(&self, geo: &Geometry, supports: &[[bool; 3]]) -> Vec<Vec3> {
        let mut out = vec![Vec3::ZERO; geo.vertices.len()];
        for (e, el) in geo.elements.iter().enumerate() {
            let t = el.corners.map(|x| self.traction(x, el.normal));
            let area = 0.5 * el.jac;
            for a in 0..3 {
                if supports.get(e).is_some_and(|s| s[a]) {
                    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
                    out[el.nodes[a]] += area / 12.0 * (2.0 * t[a] + t[b] + t[c]);
                }
            }
        }
        out
    }
}

/// Which triangle corners carry an unknown support traction for the fixed set `fixed`: a
/// fixed vertex's traction acts on its fully fixed triangles, or on all of them for a point
/// or line support (`Geometry::traction_supports`); every other corner has known traction.
pub(super) fn support_corners(geo: &Geometry, fixed: &[bool]) -> Vec<[bool; 3]> {
    let (rim, _) = geo.traction_supports(fixed);
    geo.elements
        .iter()
        .enumerate()
        .map(|(e, el)| {
            std::array::from_fn(|a| {
                let v = el.nodes[a];
                fixed.get(v).copied().unwrap_or(false)
                    && !rim.get(v).is_some_and(|r| r.contains(&(e, a)))
            })
        })
        .collect()
}

/// The right-hand side of the homogeneous problem for `force` with the fixed set `fixed`:
/// −Σ G_{τ,a} t_p over the corners with known traction, plus H_{:,F} u_p,F (the fixed
/// vertices hold u_h = −u_p). `h` is H, row-major 3n × 3n.
pub(super) fn right_hand_side(
    force: &BodyForce,
    geo: &Geometry,
    h: &[Real],
    fixed: &[bool],
) -> Vec<Real> {
    let n = geo.vertices.len();
    let supports = support_corners(geo, fixed);
    let mut known: Vec<[Vec3; 3]> = force.corner_tractions(geo);
    for (t, s) in known.iter_mut().zip(&supports) {
        for a in 0..3 {
            t[a] = if s[a] { Vec3::ZERO } else { -t[a] };
        }
    }
    let mut rhs = geo.g_times_corner_tractions(&known);
    let dofs = 3 * n;
    let u_fixed: Vec<(usize, Vec3)> = (0..n)
        .filter(|&v| fixed.get(v).copied().unwrap_or(false))
        .map(|v| (v, force.displacement(geo.vertices[v])))
        .collect();
    for (r, out) in rhs.iter_mut().enumerate() {
        let row = &h[r * dofs..(r + 1) * dofs];
        for &(v, u) in &u_fixed {
            *out += row[3 * v] * u.x + row[3 * v + 1] * u.y + row[3 * v + 2] * u.z;
        }
    }
    rhs
}

/// The particular field of the current gravity and the homogeneous response to it, for
/// one factorisation (fixed set and surface).
pub(super) struct GravityResponse {
    pub force: BodyForce,
    /// A₀⁻¹ of `right_hand_side`: free displacements and fixed tractions of u_h.
    pub x: Vec<Real>,
    /// `BodyForce::support_forces` for the fixed set.
    pub support: Vec<Vec3>,
    /// What it was computed for: the gravity, the factorisation count and the cut count.
    key: (Vec3, usize, u32),
}

impl Bem {
    /// The gravity response for the current gravity and factorisation, computed when either
    /// changed: one sweep of G over the surface and one solve with A₀'s LU, O(n²).
    pub(super) fn gravity_response(&mut self) -> Result<Option<&GravityResponse>, SimError> {
        if self.gravity == Vec3::ZERO || !self.system.is_factored() {
            self.body = None;
            return Ok(None);
        }
        let key = (self.gravity, self.system.factorizations, self.cuts);
        if self.body.as_ref().is_none_or(|b| b.key != key) {
            let geo = self
                .system
                .geometry()
                .ok_or_else(|| SimError::Unsupported {
                    model: "bem",
                    operation: "gravity",
                    reason: "the system has no surface geometry".into(),
                })?;
            let n = geo.vertices.len();
            let origin = geo.vertices.iter().fold(Vec3::ZERO, |a, &v| a + v) / n.max(1) as Real;
            let force = BodyForce::new(
                self.gravity * self.material.density,
                origin,
                self.material.lambda(),
                self.material.mu(),
            );
            let fixed = self.system.fixed();
            let mut x = right_hand_side(&force, geo, &self.system.inf.h, fixed);
            let support = force.support_forces(geo, &support_corners(geo, fixed));
            self.system.solve_base(&mut x)?;
            if let Some(v) = x.iter().position(|v| !v.is_finite()) {
                return Err(SimError::NotPositiveDefinite {
                    row: v / 3,
                    hint: "the gravity response is not finite".into(),
                });
            }
            self.body = Some(GravityResponse {
                force,
                x,
                support,
                key,
            });
        }
        Ok(self.body.as_ref())
    }
}

impl BemSystem {
    /// rhs ← A₀⁻¹ rhs with the kept LU (and the bordering layers of incisions).
    pub(super) fn solve_base(&self, rhs: &mut [Real]) -> Result<(), SimError> {
        let inverse = self.inverse.as_ref().ok_or_else(not_factored)?;
        if !self.is_factored() || rhs.len() != self.dofs() {
            return Err(not_factored());
        }
        let mut m = faer::Mat::from_fn(rhs.len(), 1, |r, _| rhs[r]);
        inverse.solve_in_place(m.as_mut());
        for (r, out) in rhs.iter_mut().enumerate() {
            *out = m[(r, 0)];
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn force() -> BodyForce {
        // ρ = 1000 kg/m³ under a tilted gravity; E = 3 kPa, ν = 0.3.
        let (e, nu) = (3000.0, 0.3);
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let mu = e / (2.0 * (1.0 + nu));
        BodyForce::new(
            1000.0 * Vec3::new(1.0, -2.0, -9.0),
            Vec3::new(0.01, 0.02, -0.03),
            lambda,
            mu,
        )
    }

    /// σ_p by central differences of u_p (Hooke's law on the numerical strain).
    fn numerical_stress(f: &BodyForce, x: Vec3) -> [[Real; 3]; 3] {
        let h = 1e-4;
        let mut grad = [[0.0; 3]; 3];
        for j in 0..3 {
            let mut d = Vec3::ZERO;
            d[j] = h;
            let du = (f.displacement(x + d) - f.displacement(x - d)) / (2.0 * h);
            for i in 0..3 {
                grad[i][j] = du[i];
            }
        }
        let eps = |i: usize, j: usize| 0.5 * (grad[i][j] + grad[j][i]);
        let tr = eps(0, 0) + eps(1, 1) + eps(2, 2);
        std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                f.lambda * tr * Real::from(u8::from(i == j)) + 2.0 * f.mu * eps(i, j)
            })
        })
    }

    #[test]
    fn particular_field_balances_the_body_force() {
        let f = force();
        let x = Vec3::new(0.03, -0.01, 0.02);
        // div σ + b = 0, by central differences of the numerical stress.
        let h = 1e-3;
        for i in 0..3 {
            let mut div = 0.0;
            for j in 0..3 {
                let mut d = Vec3::ZERO;
                d[j] = h;
                let (sp, sm) = (numerical_stress(&f, x + d), numerical_stress(&f, x - d));
                div += (sp[i][j] - sm[i][j]) / (2.0 * h);
            }
            let scale = f.b.length();
            assert!(
                (div + f.b[i]).abs() < 1e-6 * scale,
                "component {i}: div σ = {div}, b = {}",
                f.b[i]
            );
        }
    }

    #[test]
    fn traction_is_stress_times_normal() {
        let f = force();
        let x = Vec3::new(-0.02, 0.04, 0.01);
        let n = Vec3::new(0.3, -0.5, 0.8).normalize();
        let s = numerical_stress(&f, x);
        let expected = Vec3::new(
            s[0][0] * n.x + s[0][1] * n.y + s[0][2] * n.z,
            s[1][0] * n.x + s[1][1] * n.y + s[1][2] * n.z,
            s[2][0] * n.x + s[2][1] * n.y + s[2][2] * n.z,
        );
        let t = f.traction(x, n);
        assert!(
            (t - expected).length() < 1e-7 * expected.length(),
            "{t} vs {expected}"
        );
        // Vanishes at the origin, linear in the position.
        assert_eq!(f.traction(f.origin, n), Vec3::ZERO);
        assert_eq!(f.displacement(f.origin), Vec3::ZERO);
    }
}
