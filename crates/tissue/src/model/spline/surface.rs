//! Tensor-product cubic B-spline surfaces S(u, v) = Σ_ij N_i(u) M_j(v) P_ij over [0, 1]²,
//! each parameter clamped (an open edge) or periodic (a closed direction: the circumference
//! of a tube), with first and second derivatives.
//!
//! Control point (i, j) is stored at i + nu·j (u runs fastest). A `Stencil` is what one
//! parameter point needs: the 4 × 4 control indices and the one-dimensional functions of
//! each parameter, from which the 16 weights of S and of its derivatives are formed on the
//! fly (storing 96 weights per quadrature point would cost more memory traffic than the
//! products cost time).

use crate::error::SimError;
use crate::math::{Real, Vec3, is_finite_vec};

use super::basis::{Basis, BasisValues, KnotKind};

/// Largest control net accepted (nu · nv): its quadrature data alone takes about 7 kB per
/// control point, so this bounds a model near 0.5 GB.
pub const MAX_CONTROL_POINTS: usize = 1 << 16;

/// Refuses nets larger than `MAX_CONTROL_POINTS` before anything is allocated for them.
pub fn check_net_size(nu: usize, nv: usize) -> Result<(), SimError> {
    match nu.checked_mul(nv) {
        Some(n) if n <= MAX_CONTROL_POINTS => Ok(()),
        _ => Err(SimError::BadParameter {
            name: "control",
            value: format!("[{nu}, {nv}]"),
            reason: format!("at most {MAX_CONTROL_POINTS} control points in all"),
        }),
    }
}

/// Which derivative of S a stencil weight belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Deriv {
    Value = 0,
    U = 1,
    V = 2,
    UU = 3,
    VV = 4,
    UV = 5,
}

/// The control points and basis functions that determine S near one parameter point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stencil {
    pub u: BasisValues,
    pub v: BasisValues,
    /// Control points per u row (to form indices).
    pub nu: u32,
}

impl Stencil {
    /// Control index of local node k = a + 4b (a along u, b along v).
    #[inline]
    pub fn node(&self, k: usize) -> usize {
        (self.u.index[k % 4] + self.nu * self.v.index[k / 4]) as usize
    }

    /// The 16 weights of one derivative of S.
    #[inline]
    pub fn weights(&self, d: Deriv) -> [Real; 16] {
        let (du, dv) = match d {
            Deriv::Value => (0, 0),
            Deriv::U => (1, 0),
            Deriv::V => (0, 1),
            Deriv::UU => (2, 0),
            Deriv::VV => (0, 2),
            Deriv::UV => (1, 1),
        };
        let (a, b) = (&self.u.n[du], &self.v.n[dv]);
        std::array::from_fn(|k| a[k % 4] * b[k / 4])
    }

    /// All six weight sets, in `Deriv` order.
    #[inline]
    pub fn all_weights(&self) -> [[Real; 16]; 6] {
        [
            Deriv::Value,
            Deriv::U,
            Deriv::V,
            Deriv::UU,
            Deriv::VV,
            Deriv::UV,
        ]
        .map(|d| self.weights(d))
    }

    /// Σ_k w_k x[node k] for one derivative.
    #[inline]
    pub fn combine(&self, x: &[Vec3], w: &[Real; 16]) -> Vec3 {
        let mut s = Vec3::ZERO;
        for (k, wk) in w.iter().enumerate() {
            s += *wk * x[self.node(k)];
        }
        s
    }
}

/// A cubic B-spline surface with its control net.
#[derive(Clone, Debug, PartialEq)]
pub struct SplineSurface {
    pub u: Basis,
    pub v: Basis,
    /// Control points, index i + nu·j.
    pub control: Vec<Vec3>,
}

impl SplineSurface {
    /// A surface over the given bases; `control` must hold nu·nv finite points.
    pub fn new(u: Basis, v: Basis, control: Vec<Vec3>) -> Result<Self, SimError> {
        if v.kind() == KnotKind::Periodic && u.kind() != KnotKind::Periodic {
            // One convention keeps tessellation and fitting simple: the closed direction is u.
            return Err(SimError::BadParameter {
                name: "control",
                value: "periodic v".into(),
                reason: "the closed (periodic) direction must be u".into(),
            });
        }
        check_net_size(u.count(), v.count())?;
        let expected = u.count() * v.count();
        if control.len() != expected || !control.iter().all(|p| is_finite_vec(*p)) {
            return Err(SimError::BadParameter {
                name: "control",
                value: format!("{} points", control.len()),
                reason: format!(
                    "needs {} x {} = {expected} finite control points",
                    u.count(),
                    v.count()
                ),
            });
        }
        Ok(Self { u, v, control })
    }

    /// A flat clamped patch over [0, a] × [0, b] in the z = 0 plane. With uniform clamped
    /// knots a grid of Greville points reproduces the plane with S(u, v) = (a u, b v, 0).
    pub fn flat_patch(a: Real, b: Real, nu: usize, nv: usize) -> Result<Self, SimError> {
        let (bu, bv) = (Basis::clamped(nu)?, Basis::clamped(nv)?);
        let (gu, gv) = (greville(&bu), greville(&bv));
        let control = (0..nv)
            .flat_map(|j| {
                let (gu, y) = (&gu, b * gv[j]);
                (0..nu).map(move |i| Vec3::new(a * gu[i], y, 0.0))
            })
            .collect();
        Self::new(bu, bv, control)
    }

    /// A tube of `radius` along z from 0 to `length`: periodic around (u), clamped along (v).
    /// The control polygon of each ring is scaled so that the surface passes through the
    /// circle at the control angles (a uniform periodic cubic maps a regular n-gon of radius
    /// R onto a curve of radius R (2 + cos(2π/n))/3 at its nodes).
    pub fn tube(radius: Real, length: Real, nu: usize, nv: usize) -> Result<Self, SimError> {
        let (bu, bv) = (Basis::periodic(nu)?, Basis::clamped(nv)?);
        let gv = greville(&bv);
        let step = std::f64::consts::TAU / nu as Real;
        let r = radius * 3.0 / (2.0 + step.cos());
        let control = (0..nv)
            .flat_map(|j| {
                let z = length * gv[j];
                // P_i carries the most weight (4/6) at t = (i − 1)/n: put it at that angle.
                (0..nu).map(move |i| {
                    let a = step * (i as Real - 1.0);
                    Vec3::new(r * a.cos(), r * a.sin(), z)
                })
            })
            .collect();
        Self::new(bu, bv, control)
    }

    pub fn nu(&self) -> usize {
        self.u.count()
    }

    pub fn nv(&self) -> usize {
        self.v.count()
    }

    /// The stencil at (s, t) ∈ [0, 1]².
    pub fn stencil(&self, s: Real, t: Real) -> Stencil {
        Stencil {
            u: self.u.eval(s),
            v: self.v.eval(t),
            nu: self.nu() as u32,
        }
    }

    /// S(s, t) for the given control points (the surface's own, or a deformed net).
    pub fn point_with(&self, x: &[Vec3], s: Real, t: Real) -> Vec3 {
        let st = self.stencil(s, t);
        st.combine(x, &st.weights(Deriv::Value))
    }

    pub fn point(&self, s: Real, t: Real) -> Vec3 {
        self.point_with(&self.control, s, t)
    }

    /// S and its derivatives at (s, t), in `Deriv` order.
    pub fn derivatives(&self, s: Real, t: Real) -> [Vec3; 6] {
        let st = self.stencil(s, t);
        st.all_weights().map(|w| st.combine(&self.control, &w))
    }
}

/// Greville abscissae (knot averages): control points placed there reproduce linear functions.
pub fn greville(b: &Basis) -> Vec<Real> {
    let n = b.count();
    match b.kind() {
        KnotKind::Periodic => (0..n)
            .map(|i| ((i as Real - 1.0) / n as Real).rem_euclid(1.0))
            .collect(),
        KnotKind::Clamped => {
            let m = (n - 3) as Real;
            // Knots 0,0,0,0,1/m,…; Greville i = (t_{i+1} + t_{i+2} + t_{i+3}) / 3.
            let knot = |k: usize| ((k as Real - 3.0) / m).clamp(0.0, 1.0);
            (0..n)
                .map(|i| (knot(i + 1) + knot(i + 2) + knot(i + 3)) / 3.0)
                .collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_patch_reproduces_the_plane_and_its_derivatives() {
        let s = SplineSurface::flat_patch(2.0, 3.0, 6, 5).unwrap();
        for &(a, b) in &[(0.0, 0.0), (0.3, 0.7), (1.0, 1.0), (0.55, 0.12)] {
            let d = s.derivatives(a, b);
            assert!(d[0].distance(Vec3::new(2.0 * a, 3.0 * b, 0.0)) < 1e-13);
            assert!(d[1].distance(Vec3::new(2.0, 0.0, 0.0)) < 1e-12);
            assert!(d[2].distance(Vec3::new(0.0, 3.0, 0.0)) < 1e-12);
            for (k, dk) in d.iter().enumerate().skip(3) {
                assert!(dk.length() < 1e-10, "{k} {dk:?}");
            }
        }
    }

    #[test]
    fn tube_passes_near_its_circle_and_closes() {
        let (r, n) = (0.01, 16);
        let s = SplineSurface::tube(r, 0.1, n, 6).unwrap();
        // At the control angles the ring lies on the circle exactly.
        for i in 0..n {
            let t = i as Real / n as Real;
            let p = s.point(t, 0.4);
            assert!(
                ((p.x * p.x + p.y * p.y).sqrt() - r).abs() < 1e-15 * 10.0,
                "{i}"
            );
            let a = std::f64::consts::TAU * t;
            assert!((p.y.atan2(p.x) - a).sin().abs() < 1e-12);
            assert!((p.z - 0.04).abs() < 1e-15);
        }
        // Between them the cubic stays within 0.1% of the radius for 16 points.
        let p = s.point(0.5 / n as Real, 0.5);
        assert!(((p.x * p.x + p.y * p.y).sqrt() - r).abs() < 1e-3 * r);
        // Closed: S and its derivatives at u = 0 and u = 1 agree.
        let (a, b) = (s.derivatives(0.0, 0.3), s.derivatives(1.0 - 1e-13, 0.3));
        for k in 0..6 {
            assert!(a[k].distance(b[k]) < 1e-9 * (1.0 + a[k].length()), "{k}");
        }
    }
}
