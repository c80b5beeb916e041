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
//! of M guesses the pushing points, then the rows are solved with M itself, swapping the
//! rows whose sign is wrong until none is (`refine`): the answer is complementary for the
//! response the model actually has, not for its symmetric part.

use faer::Mat;
use faer::linalg::solvers::Solve;

use crate::error::SimError;
use crate::math::{Mat3, Real, Vec3};

use super::lcp::{REGULARISATION, solve_mixed};

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
const REFINE_BLOCK_TRIES: usize = 3;

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
        let points = n - self.bilateral;
        if self.pushing.len() != points {
            self.guess_pushing(&b);
        }
        let guess = if R::SYMMETRIC {
            solve_mixed(m.as_ref(), &b, self.bilateral, &self.pushing)?
        } else {
            let sym = Mat::<Real>::from_fn(n, n, |i, j| 0.5 * (m[(i, j)] + m[(j, i)]));
            solve_mixed(sym.as_ref(), &b, self.bilateral, &self.pushing)?
        };
        self.rounds = guess.rounds;
        self.lambda = guess.lambda;
        self.capped = false;
        if !R::SYMMETRIC {
            let symmetric = self.lambda.clone();
            if !self.refine(&m, &b)? {
                // Not silent: the step says it is capped (`StepInfo::capped`).
                self.lambda = symmetric;
                self.capped = true;
            }
        }
        self.pushing.clear();
        self.pushing
            .extend(self.lambda[self.bilateral..].iter().map(|&l| l > 0.0));
        Ok(&self.lambda)
    }

    /// A first guess of the pushing points when no last solve fits: the penetrating ones,
    /// deepest first, each only if it names a vertex no point taken before names. Several
    /// points on one coarse triangle are tied by its three vertices' motions, so at most
    /// about one per vertex can push independently; guessing every penetrating point (the
    /// LCP's default) starts from a block so nearly singular (400 points on the liver's
    /// 160 top triangles: 58 guessed, 4 push) that the pivoting does not recover from the
    /// roundoff of multipliers a million times the true ones.
    fn guess_pushing(&mut self, b: &[Real]) {
        let mut order: Vec<usize> = (self.bilateral..b.len()).filter(|&i| b[i] < 0.0).collect();
        order.sort_by(|&i, &j| b[i].total_cmp(&b[j]));
        let mut taken: Vec<usize> = Vec::new();
        self.pushing.clear();
        self.pushing.resize(b.len() - self.bilateral, false);
        for i in order {
            let terms = self.rows[i].terms();
            if terms.iter().any(|t| !taken.contains(&t.0)) {
                taken.extend(terms.iter().map(|t| t.0));
                self.pushing[i - self.bilateral] = true;
            }
        }
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

    /// From the symmetric part's answer, the rows solved with the (not symmetric) M itself:
    /// the pushing rows' equalities by LU (the unilateral diagonal raised as `solve_mixed`
    /// does, for more points than directions), every row whose sign is then wrong swapped
    /// (one at a time, the last, once block swaps stop reducing them: Murty's rule, as
    /// `solve_mixed` does), until none is. False when none is found within 10 n + 50
    /// rounds (an unsymmetric M need not be a P-matrix: the liver's BEM with a fine surface
    /// cycled on 9 points under a block-only rule).
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
}
