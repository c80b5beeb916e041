//! Fine-surface points against instruments' planes, beside held contacts, on a dense vertex
//! response: what `fem-condensed`, `fem-precomputed-tensors` and `bem` share for
//! `Deformable::set_point_contacts`.
//!
//! Every row is a combination of vertex displacements along a unit direction e,
//! Σᵢ cᵢ e·uᵥᵢ, and its multiplier λ applies the forces λ cᵢ e on those vertices. A held
//! contact (`set_constraints_along`) gives one row per held direction (one term, c = 1:
//! bilateral, w = 0); a point tied to three surface vertices with weights wᵢ gives one
//! unilateral row along the plane's normal (its gap w ≥ 0, its push λ ≥ 0, λ w = 0). With
//! R(j, s) the displacement of vertex j per unit force from source s, the rows' response is
//!
//! ```text
//!   M_rs = Σ_{i∈r} Σ_{k∈s} c_i c_k e_rᵀ R(v_i, source_k) e_s,   b_r = Σ_{i∈r} c_i e_r·u₀(v_i) − t_r
//! ```
//!
//! and `solve::lcp::solve_mixed` gives λ. A held contact's multiplier and a load on the same
//! vertex may act differently (the BEM's contact traction is discontinuous at its rim, a
//! load acts over the vertex's whole hat), hence the source says which it is.
//!
//! The compliances of `fem-condensed` and `fem-precomputed-tensors` are symmetric (Betti),
//! so M is; the BEM's collocation response is only nearly so. For it, the symmetric part
//! of M solves the problem with the rest of M lagged a round (a splitting that contracts
//! when the unsymmetric part is the smaller), and each round's pushing rows are solved with
//! M itself until their answer is complementary (`split`): the answer is the LCP's for the
//! response the model actually has, not for its symmetric part.

use faer::Mat;
use faer::linalg::solvers::Solve;

use crate::error::SimError;
use crate::math::{Mat3, Real, Vec3};

#[cfg(test)]
use super::lcp::REGULARISATION;
use super::lcp::{GAP_TOLERANCE, first_guess, solve_mixed};
use super::lemke::lemke;

/// A force's origin: a vertex, and whether it is a held contact's multiplier (else a load).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Source {
    pub vertex: usize,
    pub held: bool,
}

/// The response a model answers the rows from (vertex indices are the model's own: free
/// surface slots for the condensed kinds, surface vertices for the BEM).
pub(crate) trait VertexResponse {
    /// Whether R is symmetric (then M is, and `solve_mixed` answers it alone).
    const SYMMETRIC: bool;
    /// R(j, s): the displacement of vertex j per unit force from `source`.
    fn response(&self, j: usize, source: Source) -> Mat3;
    /// The displacement of vertex j under the loads alone.
    fn free(&self, j: usize) -> Vec3;
}

/// One row: up to three (vertex, coefficient) terms along `dir`, reaching `target`.
#[derive(Clone, Copy, Debug)]
struct Row {
    terms: [(usize, Real); 3],
    len: usize,
    dir: Vec3,
    target: Real,
}

impl Row {
    fn terms(&self) -> &[(usize, Real)] {
        &self.terms[..self.len]
    }
}

/// The rows of one step's problem and its answer; kept across steps so that the pushing
/// points of the last solve start the next (a warm start: the same points, nearly the same
/// planes, usually no pivoting).
#[derive(Default)]
pub(crate) struct PointRows {
    rows: Vec<Row>,
    bilateral: usize,
    lambda: Vec<Real>,
    pushing: Vec<bool>,
    /// Pivoting rounds of the last solve (the LCP's and `refine`'s).
    pub rounds: usize,
    /// The last solve of an unsymmetric response kept its symmetric part's answer: `refine`
    /// found no complementary set within its rounds (the model reports the step capped).
    pub capped: bool,
}

/// Block swaps `refine` tries without fewer wrong rows before swapping one at a time.
#[cfg(test)]
const REFINE_BLOCK_TRIES: usize = 3;

/// Rounds of `split` before Lemke's method takes over (the liver's probes need up to ~10
/// when the splitting converges at all, random problems with ρ up to 1.4 up to 16).
const SPLIT_ROUNDS: usize = 25;

/// A pushing row's λ below −this times the largest |λ| is a wrong sign (roundoff above it).
const SIGN_TOLERANCE: Real = 1e-12;

/// The multipliers that make the gaps of `rows` zero (M restricted to them, one LU),
/// zero on every other row: a candidate answer whose pushing set is `rows`.
fn pushes_on(m: &Mat<Real>, b: &[Real], rows: &[usize]) -> Vec<Real> {
    let k = rows.len();
    let mut lambda = vec![0.0; b.len()];
    if k > 0 {
        let a = Mat::<Real>::from_fn(k, k, |p, q| m[(rows[p], rows[q])]);
        let x = a
            .partial_piv_lu()
            .solve(Mat::<Real>::from_fn(k, 1, |p, _| -b[rows[p]]));
        for (p, &i) in rows.iter().enumerate() {
            lambda[i] = x[(p, 0)];
        }
    }
    lambda
}

/// The largest relative violation of complementarity by `lambda` (a held row's gap, a
/// point's penetration, a pushing point's gap or pull), of the largest |b|.
fn violation(m: &Mat<Real>, b: &[Real], bilateral: usize, lambda: &[Real]) -> Real {
    let n = b.len();
    let scale = b.iter().fold(Real::MIN_POSITIVE, |a, v| a.max(v.abs()));
    let pushing: Vec<usize> = (0..n).filter(|&j| lambda[j] != 0.0).collect();
    let top = lambda
        .iter()
        .fold(Real::MIN_POSITIVE, |a, v| a.max(v.abs()));
    (0..n)
        .map(|i| {
            let w = b[i] + pushing.iter().map(|&j| m[(i, j)] * lambda[j]).sum::<Real>();
            if i < bilateral || lambda[i] > 0.0 {
                w.abs() / scale
            } else {
                (-w / scale).max(-lambda[i] / top)
            }
        })
        .fold(0.0, Real::max)
}

/// Points Lemke's working set starts with beyond the splitting's pushing ones, and takes in
/// per round (the deepest).
const LEMKE_GROWTH: usize = 16;

/// Lemke's answer is taken as it is when `exact` cannot confirm it and it is complementary
/// to this much of the largest |b|.
const LEMKE_TOLERANCE: Real = 1e-9;

/// q = b + K λ, K = (M − Mᵀ)/2: the unsymmetric part's gaps from the pushes `lambda`.
fn add_skew(m: &Mat<Real>, b: &[Real], lambda: &[Real], q: &mut [Real]) {
    q.copy_from_slice(b);
    for (j, &l) in lambda.iter().enumerate() {
        if l != 0.0 {
            let (col, row) = (m.col(j), m.row(j));
            for (i, qi) in q.iter_mut().enumerate() {
                *qi += 0.5 * (col[i] - row[i]) * l;
            }
        }
    }
}

impl PointRows {
    /// Starts a new problem (keeps the last pushing set as the next guess).
    pub fn clear(&mut self) {
        self.rows.clear();
        self.bilateral = 0;
    }

    /// A held row (add all of them before any point): vertex `vertex` along `dir`, reaching
    /// `target` (e·u = target).
    pub fn push_held(&mut self, vertex: usize, dir: Vec3, target: Real) {
        debug_assert_eq!(self.bilateral, self.rows.len());
        self.rows.push(Row {
            terms: [(vertex, 1.0), (0, 0.0), (0, 0.0)],
            len: 1,
            dir,
            target,
        });
        self.bilateral += 1;
    }

    /// A point's row: its free vertices and weights (`None`: fixed, contributes nothing),
    /// its normal and reach (Σ wᵢ n·uᵢ ≥ reach). Returns false, adding nothing, when none of
    /// its vertices is free: the support holds it and it takes no push.
    pub fn push_point(
        &mut self,
        vertices: [Option<usize>; 3],
        weights: [Real; 3],
        normal: Vec3,
        reach: Real,
    ) -> bool {
        let mut row = Row {
            terms: [(0, 0.0); 3],
            len: 0,
            dir: normal,
            target: reach,
        };
        for (v, w) in vertices.iter().zip(weights) {
            if let Some(v) = *v
                && w != 0.0
            {
                row.terms[row.len] = (v, w);
                row.len += 1;
            }
        }
        if row.len == 0 {
            return false;
        }
        self.rows.push(row);
        true
    }

    /// Rows added so far (held ones first).
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// Solves the rows on `response`: the multipliers in row order (held rows: the force
    /// along their direction, of either sign; points: their push ≥ 0), in N.
    pub fn solve<R: VertexResponse>(&mut self, response: &R) -> Result<&[Real], SimError> {
        let n = self.rows.len();
        let (m, b) = self.matrix(response);
        #[cfg(test)]
        capture::offer(&m, &b, self.bilateral);
        let points = n - self.bilateral;
        if self.pushing.len() != points {
            self.guess_pushing(&b);
        }
        self.capped = false;
        self.rounds = 0;
        if R::SYMMETRIC {
            let solved = solve_mixed(m.as_ref(), &b, self.bilateral, &self.pushing)?;
            self.rounds = solved.rounds;
            self.lambda = solved.lambda;
        } else {
            match self.split(&m, &b) {
                Ok(true) => {}
                split => {
                    // The splitting cannot answer (its symmetric part is indefinite, or it
                    // does not contract): Lemke's method on M itself.
                    if !self.by_lemke(&m, &b)? {
                        // Not silent: the step says it is capped (`StepInfo::capped`) and
                        // keeps the splitting's last answer, or the error says why none.
                        split?;
                        self.capped = true;
                    }
                }
            }
        }
        self.pushing.clear();
        self.pushing
            .extend(self.lambda[self.bilateral..].iter().map(|&l| l > 0.0));
        Ok(&self.lambda)
    }

    /// A first guess of the pushing points when no last solve fits (`lcp::first_guess`).
    fn guess_pushing(&mut self, b: &[Real]) {
        let rows = &self.rows;
        self.pushing = first_guess(b, self.bilateral, |i| {
            rows[i].terms().iter().map(|t| t.0).collect::<Vec<usize>>()
        });
    }

    /// The forces of the last solve on each source, summed per (vertex, kind): what the
    /// model superposes on its loads' response.
    pub fn forces(&self, mut add: impl FnMut(Source, Vec3)) {
        for (r, (row, &l)) in self.rows.iter().zip(&self.lambda).enumerate() {
            if l == 0.0 {
                continue;
            }
            for &(v, c) in row.terms() {
                add(
                    Source {
                        vertex: v,
                        held: r < self.bilateral,
                    },
                    row.dir * (l * c),
                );
            }
        }
    }

    /// M and b of the module notes. The displacement of every vertex the rows name under
    /// one column's forces is formed once per column: O(rows · vertices · 3) response blocks
    /// and O(rows² · 3) products, not O(rows² · 9) blocks (a fine surface has several points
    /// per coarse triangle, so far fewer vertices than rows).
    fn matrix<R: VertexResponse>(&self, response: &R) -> (Mat<Real>, Vec<Real>) {
        let n = self.rows.len();
        let mut vertices: Vec<usize> = self
            .rows
            .iter()
            .flat_map(|r| r.terms().iter().map(|t| t.0))
            .collect();
        vertices.sort_unstable();
        vertices.dedup();
        let local = |v: usize| vertices.binary_search(&v).unwrap_or(0);
        let rows_local: Vec<[(usize, Real); 3]> = self
            .rows
            .iter()
            .map(|r| r.terms.map(|(v, c)| (local(v), c)))
            .collect();
        let mut m = Mat::<Real>::zeros(n, n);
        let mut u = vec![Vec3::ZERO; vertices.len()];
        for (s, col) in self.rows.iter().enumerate() {
            let held = s < self.bilateral;
            for (uj, &j) in u.iter_mut().zip(&vertices) {
                *uj = col
                    .terms()
                    .iter()
                    .map(|&(k, ck)| {
                        response.response(j, Source { vertex: k, held }) * (col.dir * ck)
                    })
                    .sum();
            }
            for (r, row) in self.rows.iter().enumerate() {
                m[(r, s)] = rows_local[r][..row.len]
                    .iter()
                    .map(|&(j, cj)| cj * row.dir.dot(u[j]))
                    .sum();
            }
        }
        let b = self
            .rows
            .iter()
            .map(|row| {
                let u: Real = row
                    .terms()
                    .iter()
                    .map(|&(j, c)| c * row.dir.dot(response.free(j)))
                    .sum();
                u - row.target
            })
            .collect();
        (m, b)
    }

    /// The rows solved with the (not symmetric) M = H + K itself, H = (M + Mᵀ)/2 its
    /// symmetric part and K = (M − Mᵀ)/2 the rest, by the splitting λₜ₊₁ = LCP(H, b + K λₜ):
    /// each round a warm-started dual active-set solve of the symmetric problem
    /// (`solve_mixed`, usually a few rows added or dropped), then its pushing rows solved
    /// with M itself by one LU (`exact`): done when their pushes are ≥ 0 and every other
    /// row's gap ≥ 0, the LCP's exact answer. Why it converges: with z = the forces
    /// the pushes apply, two rounds' changes obey |Δz|_H ≤ ρ |Δz_prev|_H with ρ the largest
    /// singular value of H^(−½) K H^(−½) on H's range, below 1 when the response's
    /// unsymmetric part is smaller than its symmetric part (Betti up to the collocation's
    /// error; the liver's: `bem::points::tests::exact_points_cost_study`); the λ's
    /// themselves need not converge (dependent rows), the forces and the gaps do, and the
    /// pushing set with them. False when `SPLIT_ROUNDS` pass without an exact answer (the
    /// last round's λ kept).
    fn split(&mut self, m: &Mat<Real>, b: &[Real]) -> Result<bool, SimError> {
        let n = b.len();
        // Exactly symmetric (a + b = b + a in floating point): `solve_mixed` reads it in place.
        let h = Mat::<Real>::from_fn(n, n, |i, j| 0.5 * (m[(i, j)] + m[(j, i)]));
        let mut q = b.to_vec();
        if self.lambda.len() == n {
            // The last step's answer starts the splitting (same rows: nearly the same λ).
            add_skew(m, b, &self.lambda, &mut q);
        }
        for _ in 0..SPLIT_ROUNDS {
            let solved = solve_mixed(h.as_ref(), &q, self.bilateral, &self.pushing)?;
            self.rounds += solved.rounds + 1;
            self.lambda = solved.lambda;
            if self.exact(m, b) {
                return Ok(true);
            }
            self.pushing.clear();
            self.pushing
                .extend(self.lambda[self.bilateral..].iter().map(|&l| l > 0.0));
            add_skew(m, b, &self.lambda, &mut q);
        }
        Ok(false)
    }

    /// `split`'s fallback: Lemke's method (`lemke`) on M, the held rows eliminated first
    /// (M' = M_UU − M_UB M_BB⁻¹ M_BU, q' = b_U − M_UB M_BB⁻¹ b_B), on a working set of
    /// points grown until no other penetrates, its pushing rows then
    /// solved again by `exact` (Lemke's tableau gathers roundoff over its pivots). True with
    /// `self.lambda` set when the answer is complementary (to 1e-9 of the largest |b| if
    /// `exact` does not confirm it); false, `self.lambda` untouched, on a ray or its cap.
    fn by_lemke(&mut self, m: &Mat<Real>, b: &[Real]) -> Result<bool, SimError> {
        let (n, nb) = (b.len(), self.bilateral);
        let nu = n - nb;
        // X = M_BB⁻¹ [M_BU | b_B]: the held rows' multipliers per unit push, and for none.
        let x = Mat::<Real>::from_fn(nb, nb, |i, j| m[(i, j)])
            .partial_piv_lu()
            .solve(Mat::<Real>::from_fn(nb, nu + 1, |i, j| {
                if j < nu { m[(i, nb + j)] } else { b[i] }
            }));
        if (0..nu + 1).any(|j| (0..nb).any(|i| !x[(i, j)].is_finite())) {
            return Err(SimError::NotPositiveDefinite {
                row: 0,
                hint: "the contact rows held exactly depend on each other".into(),
            });
        }
        let through =
            |i: usize, j: usize| (0..nb).map(|k| m[(nb + i, k)] * x[(k, j)]).sum::<Real>();
        let q_all: Vec<Real> = (0..nu).map(|i| b[nb + i] - through(i, nu)).collect();
        let tol_w = GAP_TOLERANCE * b.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
        // Lemke's tableau is dense in all its rows (and its pivots wander among degenerate
        // ones), so it works on the points that matter: those the splitting pushed last and
        // the `LEMKE_GROWTH` deepest, joined each round by the `LEMKE_GROWTH` that the answer
        // leaves deepest (the set only grows: finitely many rounds).
        let mut set: Vec<usize> = (0..nu)
            .filter(|&i| self.lambda.get(nb + i).is_some_and(|&l| l > 0.0))
            .collect();
        let mut deepest: Vec<usize> = (0..nu).filter(|&i| q_all[i] < 0.0).collect();
        deepest.sort_by(|&i, &j| q_all[i].total_cmp(&q_all[j]));
        set.extend(deepest.iter().take(LEMKE_GROWTH));
        set.sort_unstable();
        set.dedup();
        for _ in 0..=nu {
            let k = set.len();
            let reduced = Mat::<Real>::from_fn(k, k, |p, r| {
                let (i, j) = (set[p], set[r]);
                m[(nb + i, nb + j)] - through(i, j)
            });
            let q: Vec<Real> = set.iter().map(|&i| q_all[i]).collect();
            let Some((z, pivots)) = lemke(&reduced, &q, 10 * k + 50) else {
                self.rounds += 10 * k + 50;
                return Ok(false);
            };
            self.rounds += pivots;
            let mut lambda = vec![0.0; n];
            for (&i, &zi) in set.iter().zip(&z) {
                lambda[nb + i] = zi;
            }
            for (h, l) in lambda[..nb].iter_mut().enumerate() {
                *l = -x[(h, nu)]
                    - set
                        .iter()
                        .zip(&z)
                        .map(|(&j, &zj)| x[(h, j)] * zj)
                        .sum::<Real>();
            }
            let pushing: Vec<usize> = (0..n).filter(|&j| lambda[j] != 0.0).collect();
            let mut in_set = vec![false; nu];
            set.iter().for_each(|&i| in_set[i] = true);
            let mut missed: Vec<(Real, usize)> = (0..nu)
                .filter(|&i| !in_set[i])
                .map(|i| {
                    let w = b[nb + i]
                        + pushing
                            .iter()
                            .map(|&j| m[(nb + i, j)] * lambda[j])
                            .sum::<Real>();
                    (w, i)
                })
                .filter(|&(w, _)| w < -tol_w)
                .collect();
            missed.sort_by(|a, b| a.0.total_cmp(&b.0));
            if missed.is_empty() {
                let last = std::mem::replace(&mut self.lambda, lambda);
                if self.exact(m, b) || violation(m, b, nb, &self.lambda) <= LEMKE_TOLERANCE {
                    return Ok(true);
                }
                self.lambda = last;
                return Ok(false);
            }
            set.extend(missed.iter().take(LEMKE_GROWTH).map(|&(_, i)| i));
            set.sort_unstable();
        }
        Ok(false)
    }

    /// The held rows and those `self.lambda` pushes, solved with M itself (one LU): true,
    /// with `self.lambda` replaced, when their pushes are ≥ 0 and every other point's gap
    /// ≥ 0 (within `SIGN_TOLERANCE` of the largest push, `GAP_TOLERANCE` of the largest |b|).
    fn exact(&mut self, m: &Mat<Real>, b: &[Real]) -> bool {
        let n = b.len();
        let rows: Vec<usize> = (0..n)
            .filter(|&i| i < self.bilateral || self.lambda[i] > 0.0)
            .collect();
        let mut lambda = pushes_on(m, b, &rows);
        if lambda.iter().any(|l| !l.is_finite()) {
            return false;
        }
        let scale_l = lambda.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
        if rows
            .iter()
            .any(|&i| i >= self.bilateral && lambda[i] < -SIGN_TOLERANCE * scale_l)
        {
            return false;
        }
        let tol_w = GAP_TOLERANCE * b.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
        let mut pushed = vec![false; n];
        rows.iter().for_each(|&i| pushed[i] = true);
        let penetrates = (self.bilateral..n).filter(|&i| !pushed[i]).any(|i| {
            let w: Real = b[i] + rows.iter().map(|&j| m[(i, j)] * lambda[j]).sum::<Real>();
            w < -tol_w
        });
        if penetrates {
            return false;
        }
        // Within the tolerance, a pushing row's λ may be a roundoff below 0.
        lambda[self.bilateral..]
            .iter_mut()
            .for_each(|l| *l = l.max(0.0));
        self.lambda = lambda;
        true
    }

    /// `solve`'s path for an unsymmetric response on a given M and b (`bilateral` held rows
    /// first), cold (no last answer): the multipliers, or None when capped.
    #[cfg(test)]
    pub(crate) fn solve_matrix(
        m: &Mat<Real>,
        b: &[Real],
        bilateral: usize,
    ) -> Result<(Option<Vec<Real>>, usize), SimError> {
        let mut rows = Self {
            bilateral,
            pushing: vec![false; b.len() - bilateral],
            ..Self::default()
        };
        let exact = rows.split(m, b)?;
        Ok((exact.then_some(rows.lambda), rows.rounds))
    }

    /// The solver `split` replaced (session 17): the symmetric part's answer, then the rows
    /// solved with M by block principal pivoting with a regularised LU per round. Kept as
    /// the second implementation the tests and the cost study compare with.
    #[cfg(test)]
    pub(crate) fn solve_by_pivoting(
        m: &Mat<Real>,
        b: &[Real],
        bilateral: usize,
    ) -> Result<(Option<Vec<Real>>, usize), SimError> {
        let n = b.len();
        let mut rows = Self {
            bilateral,
            ..Self::default()
        };
        let sym = Mat::<Real>::from_fn(n, n, |i, j| 0.5 * (m[(i, j)] + m[(j, i)]));
        let solved = solve_mixed(sym.as_ref(), b, bilateral, &[])?;
        rows.rounds = solved.rounds;
        rows.lambda = solved.lambda;
        let exact = rows.refine(m, b)?;
        Ok((exact.then_some(rows.lambda), rows.rounds))
    }

    /// From the symmetric part's answer, the rows solved with the (not symmetric) M itself:
    /// the pushing rows' equalities by LU (the unilateral diagonal raised by
    /// `REGULARISATION`), every row whose sign is then wrong swapped (one at a time, the
    /// last, once block swaps stop reducing them: Murty's rule) until none is. False when
    /// none is found within 10 n + 50 rounds.
    #[cfg(test)]
    fn refine(&mut self, m: &Mat<Real>, b: &[Real]) -> Result<bool, SimError> {
        let n = b.len();
        let max_diag = (0..n).map(|i| m[(i, i)].abs()).fold(0.0, Real::max);
        let eps = REGULARISATION * max_diag.max(Real::MIN_POSITIVE);
        let mut active: Vec<bool> = (0..n)
            .map(|i| i < self.bilateral || self.lambda[i] > 0.0)
            .collect();
        let scale_w = b
            .iter()
            .fold(0.0, |a: Real, v| a.max(v.abs()))
            .max(Real::MIN_POSITIVE);
        let (mut best, mut tries) = (usize::MAX, REFINE_BLOCK_TRIES);
        for round in 1..=10 * n + 50 {
            let rows: Vec<usize> = (0..n).filter(|&i| active[i]).collect();
            let k = rows.len();
            let a = Mat::<Real>::from_fn(k, k, |p, q| {
                let (i, j) = (rows[p], rows[q]);
                m[(i, j)]
                    + if i == j && i >= self.bilateral {
                        eps
                    } else {
                        0.0
                    }
            });
            let x = a
                .partial_piv_lu()
                .solve(Mat::<Real>::from_fn(k, 1, |p, _| -b[rows[p]]));
            self.lambda.iter_mut().for_each(|l| *l = 0.0);
            for (p, &i) in rows.iter().enumerate() {
                self.lambda[i] = x[(p, 0)];
            }
            if self.lambda.iter().any(|l| !l.is_finite()) {
                return Err(SimError::NotPositiveDefinite {
                    row: rows.first().copied().unwrap_or(0),
                    hint: "the contact rows' response is singular".into(),
                });
            }
            let scale_l = self
                .lambda
                .iter()
                .fold(0.0, |a: Real, v| a.max(v.abs()))
                .max(Real::MIN_POSITIVE);
            let wrong: Vec<usize> = (self.bilateral..n)
                .filter(|&i| {
                    if active[i] {
                        self.lambda[i] < -1e-12 * scale_l
                    } else {
                        let w: Real =
                            b[i] + (0..n).map(|j| m[(i, j)] * self.lambda[j]).sum::<Real>();
                        w < -1e-12 * scale_w
                    }
                })
                .collect();
            if wrong.len() < best {
                (best, tries) = (wrong.len(), REFINE_BLOCK_TRIES);
                wrong.iter().for_each(|&i| active[i] = !active[i]);
            } else if tries > 0 {
                tries -= 1;
                wrong.iter().for_each(|&i| active[i] = !active[i]);
            } else if let Some(&i) = wrong.last() {
                active[i] = !active[i];
            }
            if wrong.is_empty() {
                // Within the tolerance above, a pushing row's λ may be a roundoff below 0.
                self.lambda[self.bilateral..]
                    .iter_mut()
                    .for_each(|l| *l = l.max(0.0));
                self.rounds += round;
                return Ok(true);
            }
        }
        self.rounds += 10 * n + 50;
        Ok(false)
    }
}

/// The largest problem `solve` builds while a study listens (`start`, then `take`), on
/// this thread: the cost study solves it again by both solvers.
#[cfg(test)]
pub(crate) mod capture {
    use std::cell::RefCell;

    use faer::Mat;

    use crate::math::Real;

    /// One problem: M, b and the held rows' count.
    pub(crate) struct Problem {
        pub m: Mat<Real>,
        pub b: Vec<Real>,
        pub bilateral: usize,
        /// Problems built while listening, and their rows in all.
        pub solves: usize,
        pub rows: usize,
    }

    thread_local! {
        static LARGEST: RefCell<Option<Option<Problem>>> = const { RefCell::new(None) };
    }

    /// Listens from now on.
    pub(crate) fn start() {
        LARGEST.with(|l| *l.borrow_mut() = Some(None));
    }

    /// Stops listening: the largest problem heard.
    pub(crate) fn take() -> Option<Problem> {
        LARGEST.with(|l| l.borrow_mut().take().flatten())
    }

    pub(super) fn offer(m: &Mat<Real>, b: &[Real], bilateral: usize) {
        LARGEST.with(|l| {
            if let Some(slot) = l.borrow_mut().as_mut() {
                let (solves, rows) = slot.as_ref().map_or((0, 0), |p| (p.solves, p.rows));
                let (solves, rows) = (solves + 1, rows + b.len());
                if slot.as_ref().is_none_or(|p| p.b.len() <= b.len()) {
                    *slot = Some(Problem {
                        m: m.clone(),
                        b: b.to_vec(),
                        bilateral,
                        solves,
                        rows,
                    });
                } else if let Some(p) = slot.as_mut() {
                    (p.solves, p.rows) = (solves, rows);
                }
            }
        });
    }
}

/// The splitting's contraction on a problem (`split`'s notes): H's smallest and largest
/// eigenvalue, ρ = ‖H^(−½) K H^(−½)‖ on H's range (eigenvalues above 1e-12 of the largest),
/// and how much of K acts on H's null space (‖K N‖ / ‖K‖, N its null vectors).
#[cfg(test)]
pub(crate) fn contraction(m: &Mat<Real>) -> (Real, Real, Real, Real) {
    let n = m.nrows();
    let h = Mat::<Real>::from_fn(n, n, |i, j| 0.5 * (m[(i, j)] + m[(j, i)]));
    let k = Mat::<Real>::from_fn(n, n, |i, j| 0.5 * (m[(i, j)] - m[(j, i)]));
    let Ok(eig) = h.self_adjoint_eigen(faer::Side::Lower) else {
        return (Real::NAN, Real::NAN, Real::NAN, Real::NAN);
    };
    let s: Vec<Real> = (0..n).map(|i| eig.S()[i]).collect();
    let u = eig.U();
    let top = s.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
    let range: Vec<usize> = (0..n).filter(|&i| s[i] > 1e-12 * top).collect();
    let null: Vec<usize> = (0..n).filter(|&i| s[i] <= 1e-12 * top).collect();
    let q = Mat::<Real>::from_fn(n, range.len(), |i, c| u[(i, range[c])] / s[range[c]].sqrt());
    let c = q.transpose() * &k * &q;
    let rho = c
        .singular_values()
        .map_or(Real::NAN, |v| v.first().copied().unwrap_or(0.0));
    let knorm = k
        .singular_values()
        .map_or(Real::NAN, |v| v.first().copied().unwrap_or(0.0));
    let z = Mat::<Real>::from_fn(n, null.len(), |i, c| u[(i, null[c])]);
    let leak = if null.is_empty() || knorm == 0.0 {
        0.0
    } else {
        (&k * &z)
            .singular_values()
            .map_or(Real::NAN, |v| v.first().copied().unwrap_or(0.0))
            / knorm
    };
    (s[0], top, rho, leak)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three vertices with a symmetric (or slightly unsymmetric) positive definite
    /// response, nothing loaded.
    struct Three {
        skew: Real,
    }

    impl VertexResponse for Three {
        const SYMMETRIC: bool = false;
        fn response(&self, j: usize, s: Source) -> Mat3 {
            let k = s.vertex;
            let base = if j == k { 2.0 } else { 0.5 };
            let skew = if j < k { self.skew } else { 0.0 };
            Mat3::IDENTITY * (base + skew)
        }
        fn free(&self, _j: usize) -> Vec3 {
            Vec3::ZERO
        }
    }

    /// Two hundred points on one triangle (far more points than directions), a plane across
    /// them, a held vertex beside: complementary for the response itself, symmetric or not
    /// (the unsymmetric one through `refine`), and the held row exact.
    #[test]
    fn many_points_on_one_triangle_are_complementary() {
        let mut state = 5u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as Real / (1u64 << 53) as Real
        };
        let n = Vec3::new(0.1, 0.0, 1.0).normalize();
        let points: Vec<([Real; 3], Real)> = (0..200)
            .map(|_| {
                let (a, b) = (next(), next());
                let (a, b) = if a + b > 1.0 {
                    (1.0 - a, 1.0 - b)
                } else {
                    (a, b)
                };
                (
                    [1.0 - a - b, a, b],
                    0.3 * a - 0.1 * b + 0.05 * next() - 0.02,
                )
            })
            .collect();
        for skew in [0.0, 0.02] {
            let response = Three { skew };
            let mut rows = PointRows::default();
            rows.push_held(3, Vec3::X, 0.01);
            for (w, reach) in &points {
                assert!(rows.push_point([Some(0), Some(1), Some(2)], *w, n, *reach));
            }
            // A point on fixed vertices only takes no row.
            assert!(!rows.push_point([None; 3], [1.0, 0.0, 0.0], n, 1.0));
            // The held vertex 3 answers like the others.
            let lambda = rows.solve(&response).unwrap().to_vec();
            let mut u = [Vec3::ZERO; 4];
            rows.forces(|s, f| {
                for (j, uj) in u.iter_mut().enumerate() {
                    *uj += response.response(j, s) * f;
                }
            });
            assert!((u[3].x - 0.01).abs() < 1e-12, "held: {}", u[3].x);
            let (mut below, mut off): (Real, Real) = (0.0, 0.0);
            for ((w, reach), &l) in points.iter().zip(&lambda[1..]) {
                let g = (0..3).map(|i| w[i] * n.dot(u[i])).sum::<Real>() - reach;
                assert!(l >= 0.0);
                below = below.max(-g);
                if l > 0.0 {
                    off = off.max(g.abs());
                }
            }
            let pushed = lambda[1..].iter().filter(|&&l| l > 0.0).count();
            assert!(
                pushed > 0 && below < 1e-9 && off < 1e-9,
                "{pushed} {below:e} {off:e}"
            );
        }
    }

    /// A seeded generator in [0, 1).
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> Real {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as Real / (1u64 << 53) as Real
        }
    }

    /// The largest penetration, the largest |gap| of a pushing row, the smallest push and
    /// the largest |gap| of a held row, over the largest |b|.
    fn violations(m: &Mat<Real>, b: &[Real], bilateral: usize, l: &[Real]) -> [Real; 3] {
        let n = b.len();
        let scale = b.iter().fold(Real::MIN_POSITIVE, |a, v| a.max(v.abs()));
        let mut worst = [0.0 as Real; 3];
        for i in 0..n {
            let w = b[i] + (0..n).map(|j| m[(i, j)] * l[j]).sum::<Real>();
            if i < bilateral {
                worst[2] = worst[2].max(w.abs() / scale);
            } else {
                worst[0] = worst[0].max(-w / scale);
                if l[i] > 0.0 {
                    worst[1] = worst[1].max(w.abs() / scale);
                }
                assert!(l[i] >= 0.0, "row {i} pulls: {}", l[i]);
            }
        }
        worst
    }

    /// Small unsymmetric problems whose symmetric part is positive definite (P-matrices:
    /// one solution), a few held rows among them: `split` gives the one answer brute force
    /// finds among every pushing set, to 1e-9 of the largest push.
    #[test]
    fn small_unsymmetric_problems_agree_with_brute_force() {
        let mut rng = Rng(11);
        for trial in 0..200 {
            let n = 1 + trial % 8;
            let bilateral = if trial % 3 == 0 { n / 3 } else { 0 };
            let g = Mat::<Real>::from_fn(n, n, |_, _| rng.next() - 0.5);
            let e = Mat::<Real>::from_fn(n, n, |_, _| rng.next() - 0.5);
            let skew = 0.05 * (trial % 4) as Real;
            let m = Mat::<Real>::from_fn(n, n, |i, j| {
                (0..n).map(|k| g[(i, k)] * g[(j, k)]).sum::<Real>()
                    + if i == j { 0.05 } else { 0.0 }
                    + skew * (e[(i, j)] - e[(j, i)])
            });
            let b: Vec<Real> = (0..n).map(|_| rng.next() - 0.6).collect();
            // Brute force: the pushing sets whose equalities give pushes ≥ 0 and gaps ≥ 0.
            let mut found: Vec<Vec<Real>> = Vec::new();
            for set in 0..1usize << (n - bilateral) {
                let rows: Vec<usize> = (0..n)
                    .filter(|&i| i < bilateral || set >> (i - bilateral) & 1 == 1)
                    .collect();
                let l = pushes_on(&m, &b, &rows);
                let ok = (0..n).all(|i| {
                    let w = b[i] + (0..n).map(|j| m[(i, j)] * l[j]).sum::<Real>();
                    i < bilateral || (l[i] >= -1e-12 && w >= -1e-12)
                });
                if ok {
                    found.push(l);
                }
            }
            // A P-matrix may have the one answer twice (a row at λ = 0, w = 0).
            assert!(!found.is_empty(), "trial {trial}: brute force found none");
            let (l, _) = PointRows::solve_matrix(&m, &b, bilateral).unwrap();
            let l = l.unwrap_or_else(|| panic!("trial {trial}: capped"));
            let top = found[0].iter().fold(1.0, |a: Real, v| a.max(v.abs()));
            let off = (0..n).fold(0.0, |a: Real, i| a.max((l[i] - found[0][i]).abs()));
            assert!(
                off < 1e-9 * top,
                "trial {trial}: {l:?} against {:?}",
                found[0]
            );
            let v = violations(&m, &b, bilateral, &l);
            assert!(v.iter().all(|&x| x < 1e-12), "trial {trial}: {v:?}");
        }
    }

    /// A random vertex response: symmetric positive definite blocks plus an antisymmetric
    /// part scaled by `skew` (the BEM's collocation error is a few %).
    struct Random {
        blocks: Vec<Mat3>,
        vertices: usize,
    }

    impl Random {
        fn new(rng: &mut Rng, vertices: usize, skew: Real) -> Self {
            let d = 3 * vertices;
            let g = Mat::<Real>::from_fn(d, d, |_, _| rng.next() - 0.5);
            let e = Mat::<Real>::from_fn(d, d, |_, _| rng.next() - 0.5);
            let r = Mat::<Real>::from_fn(d, d, |i, j| {
                (0..d).map(|k| g[(i, k)] * g[(j, k)]).sum::<Real>() / d as Real
                    + if i == j { 0.1 } else { 0.0 }
                    + skew * 0.1 * (e[(i, j)] - e[(j, i)])
            });
            let blocks = (0..vertices * vertices)
                .map(|q| {
                    let (j, k) = (q / vertices, q % vertices);
                    Mat3::from_cols_array(&std::array::from_fn(|e| {
                        r[(3 * j + e % 3, 3 * k + e / 3)]
                    }))
                })
                .collect();
            Self { blocks, vertices }
        }
    }

    impl VertexResponse for Random {
        const SYMMETRIC: bool = false;
        fn response(&self, j: usize, s: Source) -> Mat3 {
            self.blocks[j * self.vertices + s.vertex]
        }
        fn free(&self, _j: usize) -> Vec3 {
            Vec3::ZERO
        }
    }

    /// Many points on a few triangles (far more rows than directions: singular M), an
    /// unsymmetric response, a held vertex: the splitting's answer is complementary for M
    /// to 1e-12 of the largest |b|, and its gaps are those of the pivoting solver it
    /// replaced (unique: the forces are), where that one finds an answer.
    #[test]
    fn singular_unsymmetric_problems_agree_with_the_pivoting_solver() {
        let mut rng = Rng(23);
        let mut compared = 0;
        for trial in 0..50 {
            // Up to ρ ≈ 3 (the last: the splitting gives up, Lemke answers).
            let response = Random::new(&mut rng, 6, [0.0, 0.1, 0.3, 0.6, 2.0][trial % 5]);
            let triangles = [[0, 1, 2], [1, 2, 3], [2, 3, 4]];
            let mut rows = PointRows::default();
            rows.push_held(5, Vec3::new(rng.next(), 1.0, rng.next()).normalize(), 0.01);
            for _ in 0..60 {
                let t = triangles[(3.0 * rng.next()) as usize % 3];
                let (a, c) = (rng.next(), rng.next());
                let (a, c) = if a + c > 1.0 {
                    (1.0 - a, 1.0 - c)
                } else {
                    (a, c)
                };
                let normal = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, 2.0).normalize();
                let reach = 0.3 * rng.next() - 0.05;
                rows.push_point(t.map(Some), [1.0 - a - c, a, c], normal, reach);
            }
            let (m, b) = rows.matrix(&response);
            let l = rows.solve(&response).unwrap().to_vec();
            let (_, _, rho, leak) = contraction(&m);
            eprintln!(
                "trial {trial}: rounds {}, rho {rho:.3}, leak {leak:.1e}",
                rows.rounds
            );
            assert!(!rows.capped, "trial {trial}");
            let v = violations(&m, &b, 1, &l);
            assert!(v.iter().all(|&x| x < 1e-11), "trial {trial}: {v:?}");
            // Lemke's method on the same M (`by_lemke`, the splitting's fallback): the same
            // gaps (unique), complementary to its tolerance.
            let mut lemke = PointRows {
                bilateral: 1,
                ..PointRows::default()
            };
            assert!(lemke.by_lemke(&m, &b).unwrap(), "trial {trial}: Lemke");
            let v = violations(&m, &b, 1, &lemke.lambda);
            assert!(
                v.iter().all(|&x| x < LEMKE_TOLERANCE),
                "trial {trial}: {v:?}"
            );
            let gap =
                |l: &[Real], i: usize| b[i] + (0..b.len()).map(|j| m[(i, j)] * l[j]).sum::<Real>();
            let scale = b.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
            let off = (0..b.len()).fold(0.0, |a: Real, i| {
                a.max((gap(&l, i) - gap(&lemke.lambda, i)).abs())
            });
            assert!(
                off < 1e-9 * scale,
                "trial {trial}: Lemke's gaps differ by {off:e}"
            );
            let (old, _) = PointRows::solve_by_pivoting(&m, &b, 1).unwrap();
            if let Some(old) = old {
                compared += 1;
                let gaps = |l: &[Real]| -> Vec<Real> {
                    (0..b.len())
                        .map(|i| b[i] + (0..b.len()).map(|j| m[(i, j)] * l[j]).sum::<Real>())
                        .collect()
                };
                let (w, w_old) = (gaps(&l), gaps(&old));
                let scale = b.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
                let off = w
                    .iter()
                    .zip(&w_old)
                    .fold(0.0, |a: Real, (x, y)| a.max((x - y).abs()));
                // The old solver's regularisation (1e-9 of the largest diagonal) moves it.
                assert!(off < 1e-7 * scale, "trial {trial}: gaps differ by {off:e}");
            }
        }
        assert!(
            compared >= 20,
            "the pivoting solver answered {compared} of 50"
        );
    }
}
