//! Cubic B-spline basis functions of one parameter t ∈ [0, 1] with their first and second
//! derivatives, on uniform knots, in two set-ups:
//!
//! - clamped (open): knots 0,0,0,0, 1/m, …, (m−1)/m, 1,1,1,1 for `count` control points and
//!   m = count − 3 spans; the curve starts at the first control point and ends at the last,
//!   with end tangents along the first and last legs of the control polygon. A membrane edge.
//! - periodic: `count` spans on uniform knots, control indices taken modulo `count`; the curve
//!   closes on itself with C² continuity. The circumference of a tube.
//!
//! Derivatives are with respect to t, the parameter of the whole domain (not of a span).

use crate::error::SimError;
use crate::math::Real;

/// Smallest number of control points per parameter (a single cubic span).
pub const MIN_CONTROL_POINTS: usize = 4;

/// How the knots of one parameter are set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KnotKind {
    Clamped,
    Periodic,
}

/// The four non-zero basis functions at a parameter value and their control indices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BasisValues {
    /// Control point index of each of the four functions.
    pub index: [u32; 4],
    /// Values, first and second derivatives with respect to t.
    pub n: [[Real; 4]; 3],
}

/// Cubic B-spline basis on uniform knots over [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct Basis {
    kind: KnotKind,
    count: usize,
    /// Full knot vector (clamped only; the periodic case uses closed forms).
    knots: Vec<Real>,
}

impl Basis {
    /// Clamped (open) basis over `count` ≥ 4 control points.
    pub fn clamped(count: usize) -> Result<Self, SimError> {
        check_count(count)?;
        let m = count - 3;
        let mut knots = vec![0.0; 4];
        knots.extend((1..m).map(|k| k as Real / m as Real));
        knots.extend([1.0; 4]);
        Ok(Self {
            kind: KnotKind::Clamped,
            count,
            knots,
        })
    }

    /// Periodic basis over `count` ≥ 4 control points (the curve closes).
    pub fn periodic(count: usize) -> Result<Self, SimError> {
        check_count(count)?;
        Ok(Self {
            kind: KnotKind::Periodic,
            count,
            knots: Vec::new(),
        })
    }

    pub fn new(kind: KnotKind, count: usize) -> Result<Self, SimError> {
        match kind {
            KnotKind::Clamped => Self::clamped(count),
            KnotKind::Periodic => Self::periodic(count),
        }
    }

    pub fn kind(&self) -> KnotKind {
        self.kind
    }

    /// Number of control points.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Number of knot spans (polynomial pieces) over [0, 1].
    pub fn spans(&self) -> usize {
        match self.kind {
            KnotKind::Clamped => self.count - 3,
            KnotKind::Periodic => self.count,
        }
    }

    /// The parameter interval of span `s` (uniform knots).
    pub fn span_range(&self, s: usize) -> (Real, Real) {
        let m = self.spans() as Real;
        (s as Real / m, (s + 1) as Real / m)
    }

    /// The span holding t (t is clamped into [0, 1]; periodic t is wrapped first), and the
    /// local coordinate τ ∈ [0, 1] within it.
    fn locate(&self, t: Real) -> (usize, Real) {
        let m = self.spans();
        let t = match self.kind {
            KnotKind::Clamped => t.clamp(0.0, 1.0),
            KnotKind::Periodic => t.rem_euclid(1.0),
        };
        let x = t * m as Real;
        let s = (x.floor() as usize).min(m - 1);
        (s, x - s as Real)
    }

    /// The non-zero functions at t and their first and second derivatives.
    pub fn eval(&self, t: Real) -> BasisValues {
        let (s, tau) = self.locate(t);
        match self.kind {
            KnotKind::Periodic => {
                let m = self.spans() as Real;
                let c = self.count as u32;
                let index = std::array::from_fn(|k| (s as u32 + k as u32) % c);
                let [n, d, dd] = uniform_cubic(tau);
                BasisValues {
                    index,
                    n: [n, d.map(|x| x * m), dd.map(|x| x * m * m)],
                }
            }
            KnotKind::Clamped => self.cox_de_boor(s + 3, t.clamp(0.0, 1.0)),
        }
    }

    /// Cox–de Boor on knot span `k` (knots[k] ≤ t ≤ knots[k+1]): functions k−3..=k.
    fn cox_de_boor(&self, k: usize, t: Real) -> BasisValues {
        let u = |i: usize| self.knots.get(i).copied().unwrap_or(1.0);
        // n[p][j]: N_{k−3+j, p}(t), j = 0..=4 (slot 4, N_{k+1,p}, is always 0 here).
        let mut n = [[0.0; 5]; 4];
        n[0][3] = 1.0;
        let ratio = |a: Real, b: Real| if b > 0.0 { a / b } else { 0.0 };
        for p in 1..=3 {
            for j in 0..4 {
                let i = k + j - 3;
                n[p][j] = ratio(t - u(i), u(i + p) - u(i)) * n[p - 1][j]
                    + ratio(u(i + p + 1) - t, u(i + p + 1) - u(i + 1)) * n[p - 1][j + 1];
            }
        }
        // dN_{i,p} = p (N_{i,p−1}/(u_{i+p}−u_i) − N_{i+1,p−1}/(u_{i+p+1}−u_{i+1})).
        let deriv = |p: usize, lower: &[Real; 5], j: usize| {
            let i = k + j - 3;
            p as Real
                * (ratio(lower[j], u(i + p) - u(i)) - ratio(lower[j + 1], u(i + p + 1) - u(i + 1)))
        };
        let mut d2 = [0.0; 5];
        for (j, d) in d2.iter_mut().enumerate().take(4) {
            *d = deriv(2, &n[1], j);
        }
        let value = std::array::from_fn(|j| n[3][j]);
        let first = std::array::from_fn(|j| deriv(3, &n[2], j));
        let second = std::array::from_fn(|j| deriv(3, &d2, j));
        BasisValues {
            index: std::array::from_fn(|j| (k + j - 3) as u32),
            n: [value, first, second],
        }
    }
}

/// The uniform cubic B-spline pieces on τ ∈ [0, 1]: values, d/dτ and d²/dτ².
fn uniform_cubic(t: Real) -> [[Real; 4]; 3] {
    let s = 1.0 - t;
    let (t2, t3) = (t * t, t * t * t);
    [
        [
            s * s * s / 6.0,
            (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
            (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
            t3 / 6.0,
        ],
        [
            -s * s / 2.0,
            (3.0 * t2 - 4.0 * t) / 2.0,
            (-3.0 * t2 + 2.0 * t + 1.0) / 2.0,
            t2 / 2.0,
        ],
        [s, 3.0 * t - 2.0, -3.0 * t + 1.0, t],
    ]
}

fn check_count(count: usize) -> Result<(), SimError> {
    if count < MIN_CONTROL_POINTS || count > u32::MAX as usize / 4 {
        return Err(SimError::BadParameter {
            name: "control",
            value: count.to_string(),
            reason: format!(
                "a cubic spline needs at least {MIN_CONTROL_POINTS} control points per parameter"
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn both(count: usize) -> [Basis; 2] {
        [
            Basis::clamped(count).unwrap(),
            Basis::periodic(count).unwrap(),
        ]
    }

    #[test]
    fn partition_of_unity_and_derivatives_match_differences() {
        for b in both(7) {
            for k in 0..=100 {
                // Off the knots: across a knot the third derivative jumps, which spoils the
                // central difference of the second derivative by O(h · jump).
                let t = 0.00317 + 0.994 * k as Real / 100.0;
                let e = b.eval(t);
                assert!((e.n[0].iter().sum::<Real>() - 1.0).abs() < 1e-14);
                assert!(e.n[1].iter().sum::<Real>().abs() < 1e-11);
                assert!(e.n[2].iter().sum::<Real>().abs() < 1e-9);
                assert!(e.n[0].iter().all(|&x| x >= -1e-15));
                // Central differences of the full function vector (indices may shift between
                // spans, so compare per control index).
                let h = 1e-5;
                let full = |t: Real, d: usize| {
                    let e = b.eval(t);
                    let mut v = vec![0.0; b.count()];
                    for j in 0..4 {
                        v[e.index[j] as usize] += e.n[d][j];
                    }
                    v
                };
                let (p, m, c) = (full(t + h, 0), full(t - h, 0), full(t, 1));
                let (p1, m1, c2) = (full(t + h, 1), full(t - h, 1), full(t, 2));
                for i in 0..b.count() {
                    assert!(((p[i] - m[i]) / (2.0 * h) - c[i]).abs() < 1e-6, "{t}");
                    assert!(((p1[i] - m1[i]) / (2.0 * h) - c2[i]).abs() < 1e-4, "{t}");
                }
            }
        }
    }

    #[test]
    fn clamped_interpolates_ends_and_periodic_wraps() {
        let b = Basis::clamped(6).unwrap();
        let (e0, e1) = (b.eval(0.0), b.eval(1.0));
        assert_eq!((e0.index[0], e0.n[0][0]), (0, 1.0));
        assert_eq!((e1.index[3], e1.n[0][3]), (5, 1.0));
        // End tangent along the first leg: N0'(0) = −3m, N1'(0) = 3m with m = 3 spans.
        assert!((e0.n[1][0] + 9.0).abs() < 1e-12 && (e0.n[1][1] - 9.0).abs() < 1e-12);
        let p = Basis::periodic(5).unwrap();
        assert_eq!(p.spans(), 5);
        let (a, z) = (p.eval(0.0), p.eval(1.0 - 1e-15));
        assert_eq!(a.index, [0, 1, 2, 3]);
        assert_eq!(z.index, [4, 0, 1, 2]);
        // t = 1 is t = 0 again.
        assert_eq!(p.eval(1.0), a);
        assert!(Basis::clamped(3).is_err() && Basis::periodic(2).is_err());
    }
}
