//! The contact problem of points that may be pushed but not pulled, on a dense symmetric
//! response: a mixed linear complementarity problem (LCP).
//!
//! Rows `0..bilateral` are held exactly (w = 0, λ of either sign: a vertex held at its
//! target, a contact held along its normal); the others are unilateral (a fine surface's
//! point against an instrument's plane: its gap w ≥ 0, its push λ ≥ 0, and λ w = 0):
//!
//! ```text
//!   w = M λ + b,   w_B = 0,   w_U ≥ 0,  λ_U ≥ 0,  λ_U · w_U = 0
//! ```
//!
//! M is the response of the rows to each other's multipliers (J K⁻¹ Jᵀ on a stiffness, the
//! compliance of a pre-computed model): symmetric positive semi-definite. It is singular
//! when a fine surface has more points on the instrument than the coarse vertices they
//! follow have directions (four points on one coarse triangle are tied by three of its
//! vertices' motions). The multipliers are then not unique but the displacement is; a
//! relative `REGULARISATION` on the unilateral diagonal (a contact compliance of 1e-9 of
//! the stiffest row's, far below any displacement the models report) makes M positive
//! definite, so the problem has one solution, and block principal pivoting (Júdice and
//! Pires, 1994) finds it: guess which unilateral rows push, solve the equalities on those,
//! swap every row whose sign is wrong, and fall back to swapping one row at a time
//! (Murty's rule, finite for positive definite M) when the block swaps stop reducing the
//! number of wrong rows.

use faer::linalg::solvers::Solve;
use faer::{Mat, MatRef, Side};

use crate::error::SimError;
use crate::math::Real;

/// The unilateral diagonal is raised by this much of the largest diagonal entry.
pub const REGULARISATION: Real = 1e-9;

/// Block swaps tried without fewer wrong rows before swapping one at a time.
const BLOCK_TRIES: usize = 3;

/// A solved LCP: the multipliers and how many pivoting rounds it took.
#[derive(Clone, Debug, PartialEq)]
pub struct LcpSolution {
    pub lambda: Vec<Real>,
    pub rounds: usize,
}

/// Solves the mixed LCP above for `m` (only its lower triangle is read) and `b`, the first
/// `bilateral` rows held exactly. `pushing` guesses, per unilateral row, whether it pushes
/// (missing entries: it pushes where its free gap b is negative). Errors (never panics) on
/// mismatched sizes, non-finite data, or a bilateral block that is not positive definite.
pub fn solve_mixed(
    m: MatRef<'_, Real>,
    b: &[Real],
    bilateral: usize,
    pushing: &[bool],
) -> Result<LcpSolution, SimError> {
    let n = b.len();
    if m.nrows() != n || m.ncols() != n || bilateral > n {
        return Err(SimError::BadParameter {
            name: "contact problem",
            value: format!(
                "{}×{} matrix, {n} rows, {bilateral} held",
                m.nrows(),
                m.ncols()
            ),
            reason: "the response must be square with one row per gap (internal)".into(),
        });
    }
    if b.iter().any(|v| !v.is_finite()) || (0..n).any(|i| !m[(i, i)].is_finite()) {
        return Err(SimError::BadParameter {
            name: "contact problem",
            value: format!("{n} rows"),
            reason: "a gap or a response is not finite".into(),
        });
    }
    let max_diag = (0..n).map(|i| m[(i, i)].abs()).fold(0.0, Real::max);
    let eps = REGULARISATION * max_diag.max(Real::MIN_POSITIVE);
    let diag = |i: usize| m[(i, i)] + if i >= bilateral { eps } else { 0.0 };

    // Which rows are solved as equalities (the bilateral ones always).
    let mut active: Vec<bool> = (0..n)
        .map(|i| i < bilateral || pushing.get(i - bilateral).copied().unwrap_or(b[i] < 0.0))
        .collect();
    let mut lambda = vec![0.0; n];
    let mut w = vec![0.0; n];
    let mut best_wrong = usize::MAX;
    let mut tries = BLOCK_TRIES;
    // Murty's rule ends within 2ⁿ rounds in theory and within a few n in practice; the
    // block rounds before it are bounded by BLOCK_TRIES per improvement (at most n).
    let cap = 10 * n + 50;
    for round in 1..=cap {
        solve_active(m, b, &active, &diag, &mut lambda)?;
        // Gaps of every row: w = M λ + b (M symmetric, lower triangle read).
        for i in 0..n {
            let mut v = b[i];
            for j in 0..n {
                let mij = if i == j {
                    diag(i)
                } else if i > j {
                    m[(i, j)]
                } else {
                    m[(j, i)]
                };
                v += mij * lambda[j];
            }
            w[i] = v;
        }
        // Wrong rows: an equality that pulls, a free row that penetrates. A tolerance
        // relative to the row's scale keeps roundoff from swapping a row back and forth.
        let scale_w = b
            .iter()
            .fold(0.0, |a: Real, v| a.max(v.abs()))
            .max(Real::MIN_POSITIVE);
        let scale_l = lambda
            .iter()
            .fold(0.0, |a: Real, v| a.max(v.abs()))
            .max(Real::MIN_POSITIVE);
        let wrong: Vec<usize> = (bilateral..n)
            .filter(|&i| {
                if active[i] {
                    lambda[i] < -1e-12 * scale_l
                } else {
                    w[i] < -1e-12 * scale_w
                }
            })
            .collect();
        if wrong.is_empty() {
            for i in bilateral..n {
                if !active[i] {
                    lambda[i] = 0.0;
                }
            }
            return Ok(LcpSolution {
                lambda,
                rounds: round,
            });
        }
        if wrong.len() < best_wrong {
            best_wrong = wrong.len();
            tries = BLOCK_TRIES;
            wrong.iter().for_each(|&i| active[i] = !active[i]);
        } else if tries > 0 {
            tries -= 1;
            wrong.iter().for_each(|&i| active[i] = !active[i]);
        } else if let Some(&i) = wrong.last() {
            active[i] = !active[i];
        }
    }
    Err(SimError::BadParameter {
        name: "contact problem",
        value: format!("{n} rows"),
        reason: format!("no complementary solution after {cap} pivoting rounds"),
    })
}

/// λ on the active rows from M_AA λ_A = −b_A, zero elsewhere.
fn solve_active(
    m: MatRef<'_, Real>,
    b: &[Real],
    active: &[bool],
    diag: &impl Fn(usize) -> Real,
    lambda: &mut [Real],
) -> Result<(), SimError> {
    let rows: Vec<usize> = (0..b.len()).filter(|&i| active[i]).collect();
    lambda.iter_mut().for_each(|l| *l = 0.0);
    if rows.is_empty() {
        return Ok(());
    }
    let k = rows.len();
    let a = Mat::<Real>::from_fn(k, k, |r, c| {
        let (i, j) = (rows[r], rows[c]);
        if i == j {
            diag(i)
        } else if i > j {
            m[(i, j)]
        } else {
            m[(j, i)]
        }
    });
    let llt = a
        .llt(Side::Lower)
        .map_err(|_| SimError::NotPositiveDefinite {
            row: rows[0],
            hint: "the contact rows held exactly depend on each other (two holds of one \
                   direction of one vertex?)"
                .into(),
        })?;
    let mut x = Mat::<Real>::from_fn(k, 1, |r, _| -b[rows[r]]);
    llt.solve_in_place(x.as_mut());
    for (r, &i) in rows.iter().enumerate() {
        lambda[i] = x[(r, 0)];
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic generator (xorshift) for the tests' random problems.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> Real {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as Real / (1u64 << 53) as Real * 2.0 - 1.0
        }
    }

    /// M = Gᵀ G for a `rank` × `n` random G: positive semi-definite, singular below full rank.
    fn random_psd(rng: &mut Rng, n: usize, rank: usize) -> Mat<Real> {
        let g = Mat::<Real>::from_fn(rank, n, |_, _| rng.next());
        g.transpose() * &g
    }

    fn check_complementary(m: &Mat<Real>, b: &[Real], bilateral: usize, l: &[Real]) {
        let n = b.len();
        let scale = b.iter().fold(1e-300, |a: Real, v| a.max(v.abs()));
        for i in 0..n {
            let w: Real = b[i] + (0..n).map(|j| m[(i, j)] * l[j]).sum::<Real>();
            if i < bilateral {
                assert!(w.abs() < 1e-7 * scale, "held row {i}: gap {w}");
            } else {
                assert!(l[i] >= 0.0, "row {i} pulls: {}", l[i]);
                assert!(w > -1e-7 * scale, "row {i} penetrates: {w}");
                assert!(
                    l[i] * w.abs() < 1e-7 * scale * (1.0 + l[i]),
                    "row {i}: λ {} w {w}",
                    l[i]
                );
            }
        }
    }

    #[test]
    fn random_definite_and_singular_problems_are_complementary() {
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        for trial in 0..300usize {
            let n: usize = 1 + trial % 23;
            // Every third problem singular: more rows than directions.
            let rank = if trial % 3 == 0 { n.div_ceil(2) } else { n + 2 };
            let m = random_psd(&mut rng, n, rank);
            let bilateral = if trial % 5 == 0 && rank >= n {
                n / 3
            } else {
                0
            };
            // A problem that has a solution, as contact problems do (a singular M with an
            // arbitrary b may have none): b = w* − M λ* for a complementary pair.
            let (mut l, mut w) = (vec![0.0; n], vec![0.0; n]);
            for i in 0..n {
                if i < bilateral || rng.next() > 0.0 {
                    l[i] = rng.next() + if i < bilateral { 0.0 } else { 1.0 };
                } else {
                    w[i] = rng.next() + 1.0;
                }
            }
            let b: Vec<Real> = (0..n)
                .map(|i| w[i] - (0..n).map(|j| m[(i, j)] * l[j]).sum::<Real>())
                .collect();
            let s = solve_mixed(m.as_ref(), &b, bilateral, &[]).unwrap();
            check_complementary(&m, &b, bilateral, &s.lambda);
        }
    }

    #[test]
    fn a_singular_problem_gives_the_displacement_of_the_exact_solution() {
        // Two points on one spring: both rows say "push the one unknown to 1". The pushes
        // split between them but their sum is what one row alone needs.
        let m = Mat::<Real>::from_fn(2, 2, |_, _| 0.5);
        let b = [-1.0, -1.0];
        let s = solve_mixed(m.as_ref(), &b, 0, &[]).unwrap();
        let sum = s.lambda[0] + s.lambda[1];
        assert!((sum - 2.0).abs() < 1e-6, "{:?}", s.lambda);
        // A point that is already clear of the plane is not pushed.
        let m = Mat::<Real>::from_fn(2, 2, |i, j| if i == j { 1.0 } else { 0.2 });
        let s = solve_mixed(m.as_ref(), &[-1.0, 3.0], 0, &[]).unwrap();
        assert_eq!(s.lambda[1], 0.0);
        assert!((s.lambda[0] - 1.0).abs() < 1e-8);
    }

    #[test]
    fn bad_sizes_and_values_are_errors() {
        let m = Mat::<Real>::identity(2, 2);
        assert!(solve_mixed(m.as_ref(), &[1.0], 0, &[]).is_err());
        assert!(solve_mixed(m.as_ref(), &[Real::NAN, 1.0], 0, &[]).is_err());
        let zero = Mat::<Real>::zeros(1, 1);
        assert!(solve_mixed(zero.as_ref(), &[1.0], 1, &[]).is_err());
    }
}
