//! Lemke's complementary pivoting (1965) for w = M z + q, w ≥ 0, z ≥ 0, wᵀz = 0 with a dense
//! M of any symmetry: the fallback of `points::PointRows` when the splitting on M's
//! symmetric part cannot answer (the BEM's response is unsymmetric, and on a fine surface
//! its symmetric part is not even semi-definite: eigenvalues down to −1e-4 of the largest on
//! the liver, so the dual active set on it may find a row "no push reaches" where M itself
//! has an answer).
//!
//! An artificial z₀ (column −1) makes the start feasible; then each pivot brings in the
//! complement of the variable that just left, the leaving row chosen by the smallest ratio,
//! ties broken lexicographically on the rows of B⁻¹ (the tableau's w columns), so no basis
//! repeats on degenerate problems (a fine surface's dependent rows are many). It ends when
//! z₀ leaves (a complementary solution) or on a ray (no leaving row): for a copositive-plus
//! M (positive semi-definite included) a ray proves that no solution exists; for others it
//! only says this method found none. Each pivot updates the dense n × (2 n + 2) tableau:
//! O(n²), a few ms at 1,500 rows.

use faer::Mat;

use crate::math::Real;

/// The answer z and the pivots taken, or None on a ray or after `max_pivots`.
pub(crate) fn lemke(m: &Mat<Real>, q: &[Real], max_pivots: usize) -> Option<(Vec<Real>, usize)> {
    let n = q.len();
    let Some(start) = (0..n)
        .filter(|&i| q[i] < 0.0)
        .min_by(|&a, &b| q[a].total_cmp(&q[b]))
    else {
        return Some((vec![0.0; n], 0));
    };
    // Columns: w (n), z (n), z₀, the right-hand side.
    let width = 2 * n + 2;
    let (art, rhs) = (2 * n, 2 * n + 1);
    let mut t = vec![0.0; n * width];
    for (i, row) in t.chunks_exact_mut(width).enumerate() {
        row[i] = 1.0;
        for j in 0..n {
            row[n + j] = -m[(i, j)];
        }
        row[art] = -1.0;
        row[rhs] = q[i];
    }
    let scale = q.iter().fold(0.0, |a: Real, v| a.max(v.abs()));
    let mut basis: Vec<usize> = (0..n).collect();
    let (mut r, mut enter) = (start, art);
    for pivots in 1..=max_pivots {
        pivot(&mut t, width, r, enter);
        let leaving = std::mem::replace(&mut basis[r], enter);
        if leaving == art {
            let mut z = vec![0.0; n];
            for (i, &v) in basis.iter().enumerate() {
                if (n..2 * n).contains(&v) {
                    z[v - n] = t[i * width + rhs].max(0.0);
                }
            }
            return Some((z, pivots));
        }
        enter = if leaving < n {
            leaving + n
        } else {
            leaving - n
        };
        r = leaving_row(&t, width, n, enter, scale)?;
    }
    None
}

/// Gauss-Jordan pivot of the tableau on (r, c).
fn pivot(t: &mut [Real], width: usize, r: usize, c: usize) {
    let (before, rest) = t.split_at_mut(r * width);
    let (row, after) = rest.split_at_mut(width);
    let p = row[c];
    row.iter_mut().for_each(|v| *v /= p);
    for other in before
        .chunks_exact_mut(width)
        .chain(after.chunks_exact_mut(width))
    {
        let f = other[c];
        if f != 0.0 {
            other
                .iter_mut()
                .zip(row.iter())
                .for_each(|(o, v)| *o -= f * v);
            other[c] = 0.0;
        }
    }
}

/// The row that leaves when column `enter` rises: the smallest ratio rhs / a over a > 0,
/// ties (within roundoff of the right-hand sides' scale) broken lexicographically on the
/// w columns (B⁻¹'s rows, each divided by its a). None: no row limits it (a ray).
fn leaving_row(t: &[Real], width: usize, n: usize, enter: usize, scale: Real) -> Option<usize> {
    let rhs = width - 1;
    let col_max = (0..n).fold(0.0, |a: Real, i| a.max(t[i * width + enter].abs()));
    let pivot_tol = 1e-11 * col_max;
    let mut best: Option<usize> = None;
    for i in 0..n {
        let a = t[i * width + enter];
        if a <= pivot_tol {
            continue;
        }
        let Some(k) = best else {
            best = Some(i);
            continue;
        };
        let b = t[k * width + enter];
        // rhs_i / a < rhs_k / b, compared as rhs_i b against rhs_k a.
        let (x, y) = (t[i * width + rhs] * b, t[k * width + rhs] * a);
        let tie = 1e-12 * scale * a.max(b);
        if x < y - tie {
            best = Some(i);
        } else if x <= y + tie {
            for j in 0..n {
                let (u, v) = (t[i * width + j] / a, t[k * width + j] / b);
                if u != v {
                    if u < v {
                        best = Some(i);
                    }
                    break;
                }
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small problem whose symmetric part is indefinite, solved (w = M z + q complementary),
    /// and a ray where no solution exists (w₀ = −z₀ − 1 < 0 for every z ≥ 0).
    #[test]
    fn solves_an_indefinite_problem_and_reports_a_ray() {
        let m = Mat::<Real>::from_fn(3, 3, |i, j| {
            [[1.0, 3.0, 0.0], [-2.0, 1.0, 1.0], [0.5, 0.0, 2.0]][i][j]
        });
        let q = [-1.0, -2.0, 0.5];
        let (z, _) = lemke(&m, &q, 50).unwrap();
        for i in 0..3 {
            let w = q[i] + (0..3).map(|j| m[(i, j)] * z[j]).sum::<Real>();
            assert!(
                z[i] >= 0.0 && w > -1e-12 && (z[i] * w).abs() < 1e-12,
                "{z:?}"
            );
        }
        let m = Mat::<Real>::from_fn(1, 1, |_, _| -1.0);
        assert!(lemke(&m, &[-1.0], 50).is_none());
    }
}
