//! Gauss rules on triangles: regular rules whose order grows as the source point nears the
//! element, and a Duffy (collapsed square) rule for an element that contains the source.
//!
//! Both come from Gauss–Legendre on the unit square collapsed onto the triangle. The regular
//! rule's order follows an error estimate (`side_for`); sources too close for one rule get
//! the element split into four, recursively, where they are near (`assembly`). In the
//! singular rule the collapse happens at the source corner, so the Jacobian carries a factor
//! ρ (the distance from the source in the square's first coordinate) that cancels U*'s 1/R
//! and leaves T*'s 1/R² times a shape function that vanishes at the source integrable.

use crate::math::Real;

/// One point of a rule: the shape-function values (N0, N1, N2) at the point and the weight,
/// which already includes the Jacobian relative to twice the triangle's area.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadPoint {
    pub n: [Real; 3],
    pub w: Real,
}

/// Gauss–Legendre points and weights on [0, 1], by Newton's method on P_n.
pub fn gauss_legendre(n: usize) -> Vec<(Real, Real)> {
    let mut out = Vec::with_capacity(n);
    let nf = n as Real;
    for i in 0..n {
        // Chebyshev-like first guess, then Newton on the Legendre recurrence.
        let mut x = (std::f64::consts::PI * (i as Real + 0.75) / (nf + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let kf = k as Real;
                let p2 = ((2.0 * kf - 1.0) * x * p1 - (kf - 1.0) * p0) / kf;
                p0 = p1;
                p1 = p2;
            }
            let p = if n == 0 { 1.0 } else { p1 };
            dp = nf * (x * p - p0) / (x * x - 1.0);
            let step = p / dp;
            x -= step;
            if step.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push((0.5 * (1.0 + x), 0.5 * w));
    }
    out
}

/// A regular rule with m × m points: ξ = u, η = v (1 − u), weights summing to 1/2.
pub fn regular(m: usize) -> Vec<QuadPoint> {
    let g = gauss_legendre(m);
    let mut out = Vec::with_capacity(m * m);
    for &(u, wu) in &g {
        for &(v, wv) in &g {
            let (xi, eta) = (u, v * (1.0 - u));
            out.push(QuadPoint {
                n: [1.0 - xi - eta, xi, eta],
                w: wu * wv * (1.0 - u),
            });
        }
    }
    out
}

/// A Duffy rule with m × m points collapsed at local corner `corner` (0, 1 or 2): the
/// source sits at ρ = 0, and the factor ρ of the Jacobian is in the weights.
pub fn singular(m: usize, corner: usize) -> Vec<QuadPoint> {
    let g = gauss_legendre(m);
    let (a, b) = ((corner + 1) % 3, (corner + 2) % 3);
    let mut out = Vec::with_capacity(m * m);
    for &(rho, wr) in &g {
        for &(s, ws) in &g {
            let mut n = [0.0; 3];
            n[corner] = 1.0 - rho;
            n[a] = rho * (1.0 - s);
            n[b] = rho * s;
            out.push(QuadPoint {
                n,
                w: wr * ws * rho,
            });
        }
    }
    out
}

/// Relative accuracy asked of each element integral, per (distance / size)²: the kernels
/// fall off like 1/R², so this asks the same absolute error of near and far elements.
///
/// Why so tight: after an incision a row far from the cut keeps its diagonal block, because
/// the T* integral over the closed groove is zero for a source outside it. Numerically that
/// sum is the quadrature error of the groove's elements, so it is what separates a bordered
/// system from one assembled afresh on the cut surface. At 1e-10 the far-row drift stays
/// below 1e-9 of the block (`tests_cut`).
pub const ACCURACY: Real = 1e-10;

/// Most points per side of a regular rule; closer sources get the element subdivided.
pub const MAX_SIDE: usize = 12;

/// Points per side of the regular rule for a source at `ratio` = distance to the element /
/// its longest edge, or `None` when the element should be split first.
///
/// Gauss–Legendre with m points converges like ρ^(−2m) for an integrand analytic inside the
/// Bernstein ellipse of parameter ρ. The kernels are singular at the source; in the worst
/// place, above the middle of the element, that is at ±2 i ratio in the rule's [−1, 1]
/// coordinate, on the ellipse ρ = 2 ratio + √(4 ratio² + 1).
pub fn side_for(ratio: Real) -> Option<usize> {
    if ratio.is_nan() || ratio <= 0.0 {
        return None;
    }
    let b = 2.0 * ratio;
    let rho = b + (b * b + 1.0).sqrt();
    let target = ACCURACY * ratio.max(0.5).powi(2);
    let m = (-target.ln() / (2.0 * rho.ln())).ceil();
    if m.is_finite() && m <= MAX_SIDE as Real {
        Some((m as usize).max(2))
    } else {
        None
    }
}

/// The rules an assembly uses, built once.
#[derive(Clone, Debug)]
pub struct Rules {
    /// `regular[m]` has m × m points (index 0 and 1 unused).
    pub regular: Vec<Vec<QuadPoint>>,
    /// The singular rule per source corner.
    pub singular: [Vec<QuadPoint>; 3],
}

/// Points per side of the singular rule.
pub const SINGULAR_SIDE: usize = 8;

impl Rules {
    pub fn new() -> Self {
        Self {
            regular: (0..=MAX_SIDE).map(regular).collect(),
            singular: [0, 1, 2].map(|c| singular(SINGULAR_SIDE, c)),
        }
    }
}

impl Default for Rules {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legendre_integrates_polynomials_exactly() {
        for n in 1..10 {
            let g = gauss_legendre(n);
            for p in 0..(2 * n) {
                let s: Real = g.iter().map(|&(x, w)| w * x.powi(p as i32)).sum();
                assert!((s - 1.0 / (p as Real + 1.0)).abs() < 1e-14, "n {n} p {p}");
            }
        }
    }

    #[test]
    fn regular_rule_integrates_monomials() {
        // ∫ ξ^a η^b over the reference triangle = a! b! / (a + b + 2)!.
        let fact = |k: u32| (1..=k).map(Real::from).product::<Real>();
        for m in 2..=8 {
            let rule = regular(m);
            for a in 0..(m as u32) {
                for b in 0..(m as u32 - a) {
                    let s: Real = rule
                        .iter()
                        .map(|q| q.w * q.n[1].powi(a as i32) * q.n[2].powi(b as i32))
                        .sum();
                    let exact = fact(a) * fact(b) / fact(a + b + 2);
                    assert!((s - exact).abs() < 1e-14, "m {m} a {a} b {b}");
                }
            }
        }
    }

    #[test]
    fn singular_rule_integrates_one_over_r() {
        // Right isosceles triangle, legs 1, source at the right angle: ∫ 1/R dA = √2 ln(1+√2).
        let exact = 2f64.sqrt() * (1.0 + 2f64.sqrt()).ln();
        let corners = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        for corner in 0..3 {
            let rule = singular(SINGULAR_SIDE, corner);
            let src = corners[corner];
            let s: Real = rule
                .iter()
                .map(|q| {
                    let x: Real = (0..3).map(|k| q.n[k] * corners[k][0]).sum();
                    let y: Real = (0..3).map(|k| q.n[k] * corners[k][1]).sum();
                    let r = ((x - src[0]).powi(2) + (y - src[1]).powi(2)).sqrt();
                    q.w / r
                })
                .sum();
            // After the Duffy map the integrand is 1 / |a + s (b − a)|: smooth, so 8 points
            // reach about 1e-7.
            if corner == 0 {
                assert!((s - exact).abs() < 1e-6, "{s} vs {exact}");
            } else {
                // From a 45° corner the far side is at distance 1: ∫_0^{π/4} dθ / cos θ.
                let e45 = (1.0 + 2f64.sqrt()).ln();
                assert!((s - e45).abs() < 1e-6, "corner {corner}: {s} vs {e45}");
            }
        }
    }
}
