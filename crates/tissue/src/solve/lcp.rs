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
//! compliance of a pre-computed model): symmetric positive semi-definite, M = G Gᵀ for some
//! G. It is singular, and badly so, on a fine surface: its points are barycentric
//! combinations of few coarse vertices, so hundreds of rows share the directions of a few
//! dozen vertices (rank a small fraction of the rows). The multipliers are then not unique;
//! the displacement (G λ: the coarse forces Jᵀ λ) and the gaps w are.
//!
//! Why a dual active-set method. The LCP is the optimality condition of the least-distance
//! problem in the coarse directions, min ½|z|² subject to gᵢ·z + bᵢ ≥ 0 (= 0 on held
//! rows), with z = Gᵀ λ and λ its multipliers; every quantity the method needs is an inner
//! product gᵢ·gⱼ = Mᵢⱼ, so G is never formed. Goldfarb and Idnani's dual method (1983)
//! starts from the unconstrained minimum and adds one violated row at a time, keeping the
//! rows it holds linearly independent: a row that depends on the held ones (a fine point
//! whose three vertices' directions the held points already fix) cannot be added as such,
//! and the step instead raises its push while shifting the held pushes along the
//! dependency until one of them reaches zero and is dropped. Dependent rows are handled by
//! construction, the active block's Cholesky factor (updated one row at a time) stays as
//! well conditioned as the independent rows are, and each full step strictly increases the
//! dual objective, so no active set repeats (finite, no cycling). The earlier solver
//! (block principal pivoting on M plus a 1e-9 regularisation) solved equalities on sets of
//! dependent rows, conditioned ~1e9, whose multipliers were roundoff a million times the
//! true ones; its sign tests then crawled or cycled (347 points of a liver with its surface
//! cut in 16: no answer in 3,520 rounds). An interior point would cost 20–40 dense solves
//! of all the rows; a reduction to independent rows first is what this method does as it
//! goes, on the rows that matter only.
//!
//! A row counts as dependent when what it adds to the held rows' directions is at most
//! `DEPENDENT` of its own response (the squared sine of its angle to their span). Its
//! answer is a basic one: at most as many pushing rows as independent directions (a few
//! points per coarse triangle, not all the points under the instrument), the displacement
//! and the summed forces equal to any other solution's. A violated row that depends only
//! on held (bilateral) rows, or on nothing (zero response), cannot be reached: an error,
//! not a huge push.

use faer::{Mat, MatRef};

use crate::error::SimError;
use crate::math::Real;

/// A relative regularisation some callers add to their own singular blocks (of the largest
/// diagonal entry). `solve_mixed` adds none: it handles dependent rows itself.
pub const REGULARISATION: Real = 1e-9;

/// A row is dependent on the held rows when the part of its response they do not explain
/// is at most this much of its own diagonal (its direction within ~3e-5 rad of their span).
pub const DEPENDENT: Real = 1e-9;

/// A free row is violated when its gap is below −`GAP_TOLERANCE` times the largest |b|.
pub(crate) const GAP_TOLERANCE: Real = 1e-11;

/// A solved LCP: the multipliers and how many active-set changes it took (rows added
/// and dropped).
#[derive(Clone, Debug, PartialEq)]
pub struct LcpSolution {
    pub lambda: Vec<Real>,
    pub rounds: usize,
}

/// The held rows and the Cholesky factor L of their block of M (row i of L has i + 1
/// entries), grown and shrunk one row at a time.
struct Active {
    rows: Vec<usize>,
    l: Vec<Vec<Real>>,
}

impl Active {
    fn new() -> Self {
        Self {
            rows: Vec::new(),
            l: Vec::new(),
        }
    }

    /// y = L⁻¹ c (forward substitution).
    fn forward(&self, c: &mut [Real]) {
        for i in 0..c.len() {
            let li = &self.l[i];
            let s: Real = (0..i).map(|j| li[j] * c[j]).sum();
            c[i] = (c[i] - s) / li[i];
        }
    }

    /// x = L⁻ᵀ y (back substitution).
    fn backward(&self, y: &mut [Real]) {
        for i in (0..y.len()).rev() {
            y[i] /= self.l[i][i];
            let yi = y[i];
            for (yj, lij) in y[..i].iter_mut().zip(&self.l[i]) {
                *yj -= lij * yi;
            }
        }
    }

    /// The held rows' multipliers that zero their gaps: M_AA λ_A = −b_A.
    fn multipliers(&self, b: &[Real]) -> Vec<Real> {
        let mut x: Vec<Real> = self.rows.iter().map(|&i| -b[i]).collect();
        self.forward(&mut x);
        self.backward(&mut x);
        x
    }

    /// Holds row `p` given y = L⁻¹ M_Ap and its pivot δ = M_pp − |y|² > 0.
    fn push(&mut self, p: usize, mut y: Vec<Real>, delta: Real) {
        y.push(delta.sqrt());
        self.rows.push(p);
        self.l.push(y);
    }

    /// Lets go of the k-th held row: its row and column leave L, and the rows below take
    /// its column back by a rank-one update of their block (stable, O(held²)).
    fn remove(&mut self, k: usize) {
        self.rows.remove(k);
        self.l.remove(k);
        let mut x: Vec<Real> = self.l[k..].iter_mut().map(|row| row.remove(k)).collect();
        for (j, xj) in (k..self.l.len()).zip(0..) {
            let ljj = self.l[j][j];
            let r = ljj.hypot(x[xj]);
            let (c, s) = (r / ljj, x[xj] / ljj);
            self.l[j][j] = r;
            for (i, xi) in (j + 1..self.l.len()).zip(xj + 1..) {
                let lij = (self.l[i][j] + s * x[xi]) / c;
                x[xi] = c * x[xi] - s * lij;
                self.l[i][j] = lij;
            }
        }
    }
}

/// Solves the mixed LCP above for `m` (its lower triangle is what counts: an exactly
/// symmetric `m` stored by columns is read in place, any other is mirrored into a copy) and `b`, the first
/// `bilateral` rows held exactly. `pushing` guesses, per unilateral row, which rows push
/// (a warm start: the last solve's pushing rows; missing entries: not pushing). Errors
/// (never panics) on mismatched sizes, non-finite data, held rows that depend on each
/// other, a violated row no push can reach, or no solution within 10 n + 50 rows added.
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
    // The columns of the full symmetric matrix, contiguous: `m`'s own when it is stored by
    // columns and exactly symmetric (no copy: 114 MB at 3,774 rows), else the lower
    // triangle mirrored into a copy.
    let copy: Mat<Real>;
    let cols: Vec<&[Real]> = match symmetric_columns(m) {
        Some(cols) => cols,
        None => {
            copy = Mat::<Real>::from_fn(n, n, |i, j| if i >= j { m[(i, j)] } else { m[(j, i)] });
            (0..n).map(|j| copy.col_as_slice(j)).collect()
        }
    };
    if b.iter().any(|v| !v.is_finite()) || cols.iter().any(|c| c.iter().any(|v| !v.is_finite())) {
        return Err(SimError::BadParameter {
            name: "contact problem",
            value: format!("{n} rows"),
            reason: "a gap or a response is not finite".into(),
        });
    }
    let tol_w = GAP_TOLERANCE * b.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
    let mut rounds = 0;

    // The held rows first (always independent, or the problem is ill-posed), then the
    // guessed pushing rows that are independent of those before.
    let mut active = Active::new();
    let mut held = vec![false; n];
    let guessed = (bilateral..n).filter(|&i| pushing.get(i - bilateral).copied().unwrap_or(false));
    for i in (0..bilateral).chain(guessed) {
        let ci = cols[i];
        let mut y: Vec<Real> = active.rows.iter().map(|&j| ci[j]).collect();
        active.forward(&mut y);
        let delta = ci[i] - y.iter().map(|v| v * v).sum::<Real>();
        if delta > DEPENDENT * ci[i] && delta > 0.0 {
            active.push(i, y, delta);
            held[i] = true;
        } else if i < bilateral {
            return Err(SimError::NotPositiveDefinite {
                row: i,
                hint: "the contact rows held exactly depend on each other (two holds of one \
                       direction of one vertex?)"
                    .into(),
            });
        }
    }
    // A guess is a valid start where its pushes are ≥ 0: drop the most pulling guessed
    // row until none pulls (the held rows' optimum is then a dual-feasible point).
    let mut u = active.multipliers(b);
    while let Some(k) = (0..active.rows.len())
        .filter(|&k| active.rows[k] >= bilateral && u[k] < 0.0)
        .min_by(|&x, &y| u[x].total_cmp(&u[y]))
    {
        held[active.rows[k]] = false;
        active.remove(k);
        u = active.multipliers(b);
    }

    let cap = 10 * n + 50;
    let mut added = 0;
    let mut w = vec![0.0; n];
    loop {
        // Every gap from the held pushes (recomputed, so no drift accumulates).
        w.copy_from_slice(b);
        for (&j, &uj) in active.rows.iter().zip(&u) {
            if uj != 0.0 {
                let cj = cols[j];
                w.iter_mut().zip(cj).for_each(|(wi, mij)| *wi += mij * uj);
            }
        }
        // The most penetrating free row, if any.
        let Some(p) = (bilateral..n)
            .filter(|&i| !held[i] && w[i] < -tol_w)
            .min_by(|&x, &y| w[x].total_cmp(&w[y]))
        else {
            break;
        };
        if added == cap {
            return Err(SimError::BadParameter {
                name: "contact problem",
                value: format!("{n} rows ({bilateral} held)"),
                reason: format!("no complementary solution after {cap} rows added"),
            });
        }
        added += 1;
        let cp = cols[p];
        let mut up = 0.0;
        loop {
            rounds += 1;
            // r = M_AA⁻¹ M_Ap: how the held pushes shift per unit push of p; δ: how much
            // of p's response they leave (0 for a dependent row).
            let mut y: Vec<Real> = active.rows.iter().map(|&j| cp[j]).collect();
            active.forward(&mut y);
            let delta = cp[p] - y.iter().map(|v| v * v).sum::<Real>();
            let mut r = y.clone();
            active.backward(&mut r);
            let wp = b[p]
                + active
                    .rows
                    .iter()
                    .zip(&u)
                    .map(|(&j, &uj)| cp[j] * uj)
                    .sum::<Real>()
                + cp[p] * up;
            let full = if delta > DEPENDENT * cp[p] && delta > 0.0 {
                (-wp / delta).max(0.0)
            } else {
                Real::INFINITY
            };
            // The first pushing row that the shift brings to zero.
            // Shifts within roundoff of the largest (a row that duplicates a held one)
            // are none.
            let shift = DEPENDENT * r.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
            let partial = (0..active.rows.len())
                .filter(|&k| active.rows[k] >= bilateral && r[k] > shift)
                .map(|k| (u[k].max(0.0) / r[k], k))
                .min_by(|x, y| x.0.total_cmp(&y.0));
            match partial {
                Some((t, k)) if t < full => {
                    u.iter_mut().zip(&r).for_each(|(uk, rk)| *uk -= t * rk);
                    up += t;
                    held[active.rows[k]] = false;
                    active.remove(k);
                    u.remove(k);
                }
                _ if full.is_finite() => {
                    active.push(p, y, delta);
                    held[p] = true;
                    // The held rows' gaps are all zero now: their pushes from the factor.
                    u = active.multipliers(b);
                    break;
                }
                _ => {
                    return Err(SimError::BadParameter {
                        name: "contact problem",
                        value: format!("row {p} of {n} ({bilateral} held), gap {wp:e}"),
                        reason: "the row penetrates and no push reaches it: it moves only \
                                 as rows held exactly do (or not at all)"
                            .into(),
                    });
                }
            }
        }
    }
    let mut lambda = vec![0.0; n];
    for (&i, &ui) in active.rows.iter().zip(&u) {
        // A pushing row's λ may be a roundoff below zero.
        lambda[i] = if i < bilateral { ui } else { ui.max(0.0) };
    }
    Ok(LcpSolution { lambda, rounds })
}

/// The columns of `m` as slices when it is stored by columns and exactly symmetric.
fn symmetric_columns(m: MatRef<'_, Real>) -> Option<Vec<&[Real]>> {
    let n = m.ncols();
    let cols: Vec<&[Real]> = (0..n)
        .map(|j| m.col(j).try_as_col_major().map(|c| c.as_slice()))
        .collect::<Option<_>>()?;
    let symmetric = (0..n).all(|j| (j + 1..n).all(|i| cols[j][i] == cols[i][j]));
    symmetric.then_some(cols)
}

/// A first guess of the pushing unilateral rows (for `solve_mixed`'s `pushing`): the
/// penetrating ones (b < 0), deepest first, each only if it names a vertex (`names(i)`) no
/// row taken before names. Several points on one coarse triangle are tied by its three
/// vertices' motions, so about one per vertex can push independently. `solve_mixed` keeps
/// only the guessed rows that are independent and push, so any guess is safe; this one
/// saves it the rows it would add and drop one at a time.
pub fn first_guess<N: AsRef<[usize]>>(
    b: &[Real],
    bilateral: usize,
    names: impl Fn(usize) -> N,
) -> Vec<bool> {
    let mut order: Vec<usize> = (bilateral..b.len()).filter(|&i| b[i] < 0.0).collect();
    order.sort_by(|&i, &j| b[i].total_cmp(&b[j]));
    let mut taken: Vec<usize> = Vec::new();
    let mut pushing = vec![false; b.len().saturating_sub(bilateral)];
    for i in order {
        let named = names(i);
        let named = named.as_ref();
        if named.iter().any(|v| !taken.contains(v)) {
            taken.extend_from_slice(named);
            pushing[i - bilateral] = true;
        }
    }
    pushing
}

#[cfg(test)]
#[path = "lcp_tests.rs"]
mod tests;
