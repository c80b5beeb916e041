//! Kelvin's fundamental solution of 3D linear elastostatics: the displacement U* and the
//! traction T* at a field point y caused by a unit point force at a source point x in an
//! infinite body. Both are 3×3 tensors indexed [load direction][component].
//!
//! With r = y − x, R = |r|, r̂ = r / R and the outward normal n at y:
//! U*_lk = [(3 − 4ν) δ_lk + r̂_l r̂_k] / (16 π μ (1 − ν) R)
//! T*_lk = −[∂R/∂n ((1 − 2ν) δ_lk + 3 r̂_l r̂_k) − (1 − 2ν)(r̂_l n_k − r̂_k n_l)] / (8 π (1 − ν) R²)
//! U* is O(1/R) (weakly singular on the source's own elements); T* is O(1/R²).

use std::f64::consts::PI;

use crate::math::{Real, Vec3};

/// The constants of the kernels for one material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kelvin {
    /// 1 / (16 π μ (1 − ν)).
    cu: Real,
    /// 1 / (8 π (1 − ν)).
    ct: Real,
    /// 3 − 4ν.
    a: Real,
    /// 1 − 2ν.
    b: Real,
}

impl Kelvin {
    /// Kernels for shear modulus `mu` (Pa) and Poisson's ratio `nu` (checked by `Material`).
    pub fn new(mu: Real, nu: Real) -> Self {
        Self {
            cu: 1.0 / (16.0 * PI * mu * (1.0 - nu)),
            ct: 1.0 / (8.0 * PI * (1.0 - nu)),
            a: 3.0 - 4.0 * nu,
            b: 1.0 - 2.0 * nu,
        }
    }

    /// U*(x, y) for r = y − x ≠ 0, in m/N.
    #[inline]
    pub fn u(&self, r: Vec3) -> [[Real; 3]; 3] {
        let len = r.length();
        let d = r / len;
        let s = self.cu / len;
        let mut out = [[0.0; 3]; 3];
        for l in 0..3 {
            for k in 0..3 {
                let delta = if l == k { self.a } else { 0.0 };
                out[l][k] = s * (delta + d[l] * d[k]);
            }
        }
        out
    }

    /// T*(x, y) for r = y − x ≠ 0 and the unit outward normal `n` at y, in 1/m².
    #[inline]
    pub fn t(&self, r: Vec3, n: Vec3) -> [[Real; 3]; 3] {
        let len2 = r.length_squared();
        let len = len2.sqrt();
        let d = r / len;
        let drdn = d.dot(n);
        let s = -self.ct / len2;
        let mut out = [[0.0; 3]; 3];
        for l in 0..3 {
            for k in 0..3 {
                let delta = if l == k { self.b } else { 0.0 };
                out[l][k] =
                    s * (drdn * (delta + 3.0 * d[l] * d[k]) - self.b * (d[l] * n[k] - d[k] * n[l]));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MU: Real = 1000.0;
    const NU: Real = 0.3;

    fn lame() -> Real {
        2.0 * MU * NU / (1.0 - 2.0 * NU)
    }

    /// Displacement gradient ∂U*_lk/∂y_m by central differences.
    fn grad(k: &Kelvin, r: Vec3, l: usize) -> [[Real; 3]; 3] {
        let h = 1e-5;
        let mut g = [[0.0; 3]; 3];
        for m in 0..3 {
            let mut e = Vec3::ZERO;
            e[m] = h;
            let (p, q) = (k.u(r + e), k.u(r - e));
            for c in 0..3 {
                g[c][m] = (p[l][c] - q[l][c]) / (2.0 * h);
            }
        }
        g
    }

    #[test]
    fn t_is_the_traction_of_u() {
        // T* must be σ(U*)·n with Hooke's law applied to U*'s strain.
        let k = Kelvin::new(MU, NU);
        let r = Vec3::new(0.3, -0.2, 0.5);
        let n = Vec3::new(0.2, 0.9, -0.4).normalize();
        let t = k.t(r, n);
        for (l, tl) in t.iter().enumerate() {
            let g = grad(&k, r, l);
            let div = g[0][0] + g[1][1] + g[2][2];
            for (c, &tlc) in tl.iter().enumerate() {
                let mut tc = 0.0;
                for m in 0..3 {
                    let delta = if c == m { 1.0 } else { 0.0 };
                    let sigma = lame() * div * delta + MU * (g[c][m] + g[m][c]);
                    tc += sigma * n[m];
                }
                assert!((tc - tlc).abs() < 1e-6 * tlc.abs().max(1e-3), "{l}{c}");
            }
        }
    }

    #[test]
    fn u_satisfies_navier() {
        // μ ∇²u + (λ + μ) ∇(∇·u) = 0 away from the source, by second differences.
        let k = Kelvin::new(MU, NU);
        let r = Vec3::new(0.4, 0.1, -0.3);
        let h = 1e-3;
        for l in 0..3 {
            let at = |p: Vec3| k.u(p)[l];
            let mut lap = [0.0; 3];
            let mut graddiv = [0.0; 3];
            for m in 0..3 {
                let mut e = Vec3::ZERO;
                e[m] = h;
                let (p, c, q) = (at(r + e), at(r), at(r - e));
                for i in 0..3 {
                    lap[i] += (p[i] - 2.0 * c[i] + q[i]) / (h * h);
                }
                for j in 0..3 {
                    let mut f = Vec3::ZERO;
                    f[j] = h;
                    let d = |a: Vec3, b: Vec3| (at(r + a + b)[j] - at(r + a - b)[j]) / (2.0 * h);
                    graddiv[m] += (d(e, f) - d(-e, f)) / (2.0 * h);
                }
            }
            let scale = k.u(r)[l][l] / (r.length_squared());
            for i in 0..3 {
                let res = MU * lap[i] + (lame() + MU) * graddiv[i];
                assert!(res.abs() < 1e-4 * MU * scale, "{l} {i}: {res}");
            }
        }
    }

    #[test]
    fn u_is_symmetric_and_reciprocal() {
        let k = Kelvin::new(MU, NU);
        let r = Vec3::new(0.1, 0.7, -0.2);
        let (a, b) = (k.u(r), k.u(-r));
        for l in 0..3 {
            for c in 0..3 {
                assert_eq!(a[l][c], a[c][l]);
                assert!((a[l][c] - b[l][c]).abs() < 1e-18);
            }
        }
    }
}
