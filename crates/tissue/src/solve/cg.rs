//! Preconditioned conjugate gradients over a matrix-free operator, for the implicit dynamic
//! models (Jacobi by default, or any SPD preconditioner given as a closure): the operator is a closure `apply(x, y)` writing y = A x, so a model can
//! apply its stiffness element by element without assembling it. The scratch vectors live
//! in a `CgWorkspace` sized once, so a solve allocates nothing.

use crate::math::Real;

/// Scratch vectors of one CG solve (residual, preconditioned residual, direction, A·p).
#[derive(Clone, Debug, Default)]
pub struct CgWorkspace {
    r: Vec<Real>,
    z: Vec<Real>,
    p: Vec<Real>,
    q: Vec<Real>,
}

/// What a CG solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CgResult {
    pub iterations: usize,
    /// ‖b − A x‖ / ‖b‖ at exit (0 when b = 0).
    pub relative_residual: Real,
}

impl CgWorkspace {
    /// A workspace for systems of `n` unknowns.
    pub fn new(n: usize) -> Self {
        Self {
            r: vec![0.0; n],
            z: vec![0.0; n],
            p: vec![0.0; n],
            q: vec![0.0; n],
        }
    }

    pub fn len(&self) -> usize {
        self.r.len()
    }

    pub fn is_empty(&self) -> bool {
        self.r.is_empty()
    }

    /// Solves A x = b for a symmetric positive (semi-)definite A, starting from the given x
    /// (a warm start), with the preconditioner diag(A)⁻¹ given as `inv_diag`. Stops after
    /// `max_iterations` or when ‖r‖ ≤ `tolerance`·‖b‖. Unknowns whose `inv_diag` is zero are
    /// left untouched, which is how callers project out constrained dofs (their `apply` must
    /// then ignore those entries of x and may write anything there in y).
    ///
    /// All slices must have the workspace's length (shorter ones are a caller bug; they are
    /// truncated to the shortest rather than panicking).
    pub fn solve(
        &mut self,
        apply: impl FnMut(&[Real], &mut [Real]),
        inv_diag: &[Real],
        b: &[Real],
        x: &mut [Real],
        max_iterations: usize,
        tolerance: Real,
    ) -> CgResult {
        let jacobi = |r: &[Real], z: &mut [Real]| {
            for ((zi, ri), d) in z.iter_mut().zip(r).zip(inv_diag) {
                *zi = d * ri;
            }
        };
        self.solve_preconditioned(apply, jacobi, inv_diag, b, x, max_iterations, tolerance)
    }

    /// Like `solve`, with any symmetric positive definite preconditioner:
    /// `precondition(r, z)` writes z = P⁻¹ r. Unknowns where `free` is zero are held as in
    /// `solve` (their entries of z are zeroed after `precondition`, which must not couple
    /// them into the free ones: a P⁻¹ that is block-diagonal in (free, held) does that).
    #[allow(clippy::too_many_arguments)]
    pub fn solve_preconditioned(
        &mut self,
        apply: impl FnMut(&[Real], &mut [Real]),
        precondition: impl FnMut(&[Real], &mut [Real]),
        free: &[Real],
        b: &[Real],
        x: &mut [Real],
        max_iterations: usize,
        tolerance: Real,
    ) -> CgResult {
        let mask = |v: &mut [Real]| {
            for (vi, d) in v.iter_mut().zip(free) {
                if *d == 0.0 {
                    *vi = 0.0;
                }
            }
        };
        let n = free.len();
        self.solve_filtered(
            apply,
            precondition,
            mask,
            &b[..n.min(b.len())],
            x,
            max_iterations,
            tolerance,
        )
    }

    /// The modified PCG of Baraff & Witkin (1998, as corrected by Ascher & Boxerman 2003):
    /// solves A x = b on the subspace a filter S keeps (an orthogonal projection,
    /// `filter(v)` writing S v in place), the rest of x, (I − S) x, being the caller's
    /// known values, left as given. A held unknown is S = 0 on its entry; a node held along a
    /// direction n only is S = I − n nᵀ on its three entries. The residual, the
    /// preconditioned residual and each A·p are filtered, so CG runs on SAS with the
    /// preconditioner S P⁻¹ S (symmetric, positive definite on the subspace). The residual
    /// reported is ‖S(b − A x)‖ / ‖S b‖ (/ ‖S(b − A x_c)‖ when S b = 0). The normal components of A x − b the filter drops
    /// are the constraint forces (the caller reads them after the solve).
    #[allow(clippy::too_many_arguments)]
    pub fn solve_filtered(
        &mut self,
        mut apply: impl FnMut(&[Real], &mut [Real]),
        mut precondition: impl FnMut(&[Real], &mut [Real]),
        mut filter: impl FnMut(&mut [Real]),
        b: &[Real],
        x: &mut [Real],
        max_iterations: usize,
        tolerance: Real,
    ) -> CgResult {
        let n = self.r.len().min(b.len()).min(x.len());
        let (r, z, p, q) = (
            &mut self.r[..n],
            &mut self.z[..n],
            &mut self.p[..n],
            &mut self.q[..n],
        );
        let (b, x) = (&b[..n], &mut x[..n]);
        let norm = |v: &[Real]| v.iter().map(|a| a * a).sum::<Real>().sqrt();
        r.copy_from_slice(b);
        filter(r);
        let mut b_norm = norm(r);
        if b_norm == 0.0 {
            // No load on the free part: what moves it is the known part x_c = (I − S) x
            // alone (a held node moved from rest), S(b − A x_c), the reference then. x starts
            // at x_c (the warm start is dropped).
            z.copy_from_slice(x);
            filter(z);
            for (xi, zi) in x.iter_mut().zip(z.iter()) {
                *xi -= zi;
            }
            apply(x, q);
            for i in 0..n {
                r[i] = b[i] - q[i];
            }
            filter(r);
            b_norm = norm(r);
            if b_norm == 0.0 {
                return CgResult::default();
            }
        }
        apply(x, q);
        // A warm start worse than none in the energy norm of the free part is dropped: with
        // an iteration cap, a bad guess lets the error of truncated solves build up from
        // step to step until the dynamics blow up. With x = x_f + x_c (x_f = S x, x_c the
        // known part), A x_c (one more product) gives
        // φ(x_f) = ½x_fᵀA x_f − (b − A x_c)ᵀx_f = x_fᵀ(½(A x + A x_c) − b), to compare with
        // φ(0) = 0.
        z.copy_from_slice(x);
        filter(z);
        if z.iter().any(|v| *v != 0.0) {
            // z = x_c.
            for (zi, xi) in z.iter_mut().zip(x.iter()) {
                *zi = xi - *zi;
            }
            apply(z, p);
            // Entries with no free part are left out (a held row of A·x may be anything).
            let phi: Real = (0..n)
                .map(|i| (x[i] - z[i], i))
                .filter(|(xf, _)| *xf != 0.0)
                .map(|(xf, i)| xf * (0.5 * (q[i] + p[i]) - b[i]))
                .sum();
            if phi > 0.0 || phi.is_nan() {
                x.copy_from_slice(z);
                q.copy_from_slice(p);
            }
        }
        for i in 0..n {
            r[i] = b[i] - q[i];
        }
        filter(r);
        precondition(r, z);
        filter(z);
        p.copy_from_slice(z);
        let mut rz: Real = r.iter().zip(z.iter()).map(|(a, b)| a * b).sum();
        let mut res = norm(r) / b_norm;
        let mut it = 0;
        while it < max_iterations && res > tolerance {
            apply(p, q);
            filter(q);
            let pq: Real = p.iter().zip(q.iter()).map(|(a, b)| a * b).sum();
            // A breakdown (pᵀAp ≤ 0 or not finite): A is not positive definite along p.
            if !(pq > 0.0 && pq.is_finite()) {
                break;
            }
            let alpha = rz / pq;
            let mut rr = 0.0;
            for i in 0..n {
                x[i] += alpha * p[i];
                r[i] -= alpha * q[i];
                rr += r[i] * r[i];
            }
            precondition(r, z);
            filter(z);
            it += 1;
            res = rr.sqrt() / b_norm;
            let rz_new: Real = r.iter().zip(z.iter()).map(|(a, b)| a * b).sum();
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
        }
        CgResult {
            iterations: it,
            relative_residual: res,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 1-D Laplacian (2, −1) plus a diagonal shift: SPD, with a known solution.
    fn laplacian(x: &[Real], y: &mut [Real]) {
        let n = x.len();
        for i in 0..n {
            let l = if i > 0 { x[i - 1] } else { 0.0 };
            let r = if i + 1 < n { x[i + 1] } else { 0.0 };
            y[i] = 2.5 * x[i] - l - r;
        }
    }

    #[test]
    fn solves_a_laplacian_to_tolerance() {
        let n = 50;
        let exact: Vec<Real> = (0..n).map(|i| ((i * 7 % 11) as Real) - 5.0).collect();
        let mut b = vec![0.0; n];
        laplacian(&exact, &mut b);
        let mut ws = CgWorkspace::new(n);
        let mut x = vec![0.0; n];
        let res = ws.solve(laplacian, &vec![1.0 / 2.5; n], &b, &mut x, 200, 1e-12);
        assert!(res.relative_residual <= 1e-12, "{res:?}");
        // CG on n unknowns terminates in at most n steps in exact arithmetic.
        assert!(res.iterations <= n, "{res:?}");
        let err = x
            .iter()
            .zip(&exact)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, Real::max);
        assert!(err < 1e-10, "max error {err}");
        // A warm start at the solution needs no iteration.
        let again = ws.solve(laplacian, &vec![1.0 / 2.5; n], &b, &mut x, 200, 1e-10);
        assert_eq!(again.iterations, 0);
    }

    #[test]
    fn masked_unknowns_are_left_alone() {
        // Hold x[0] = 3 by masking it; the rest solves A_ff x_f = b_f − A_fc x_c.
        let n = 10;
        let mut inv = vec![1.0 / 2.5; n];
        inv[0] = 0.0;
        let mut x = vec![0.0; n];
        x[0] = 3.0;
        let b = vec![1.0; n];
        let mut ws = CgWorkspace::new(n);
        let res = ws.solve(laplacian, &inv, &b, &mut x, 100, 1e-13);
        assert_eq!(x[0], 3.0);
        let mut y = vec![0.0; n];
        laplacian(&x, &mut y);
        for (i, yi) in y.iter().enumerate().skip(1) {
            assert!((yi - 1.0).abs() < 1e-11, "row {i}: {yi} ({res:?})");
        }
    }

    /// No load on the free unknowns and a held one moved (a node pushed from rest): the
    /// free ones answer it (A_ff x_f = −A_fc x_c), they are not left at 0.
    #[test]
    fn a_held_unknown_moved_with_no_load_moves_the_free_ones() {
        let n = 10;
        let mut inv = vec![1.0 / 2.5; n];
        inv[0] = 0.0;
        let mut x = vec![0.0; n];
        x[0] = 3.0;
        let b = vec![0.0; n];
        let mut ws = CgWorkspace::new(n);
        let res = ws.solve(laplacian, &inv, &b, &mut x, 100, 1e-13);
        assert!(res.iterations > 0, "{res:?}");
        assert_eq!(x[0], 3.0);
        assert!(x[1] > 1.0, "{x:?}");
        let mut y = vec![0.0; n];
        laplacian(&x, &mut y);
        for (i, yi) in y.iter().enumerate().skip(1) {
            assert!(yi.abs() < 1e-11, "row {i}: {yi} ({res:?})");
        }
    }

    #[test]
    fn a_warm_start_worse_than_none_is_dropped_and_a_good_one_kept() {
        // One iteration from a wild guess (φ > 0) must end where one iteration from zero
        // does; from a near solution it must end nearer than that.
        let n = 20;
        let inv = {
            let mut inv = vec![1.0 / 2.5; n];
            inv[0] = 0.0;
            inv
        };
        let b = vec![1.0; n];
        let mut ws = CgWorkspace::new(n);
        let error = |x: &[Real]| {
            let mut y = vec![0.0; n];
            laplacian(x, &mut y);
            (1..n).map(|i| (y[i] - b[i]).powi(2)).sum::<Real>().sqrt()
        };
        let mut from_zero = vec![0.0; n];
        from_zero[0] = 3.0;
        ws.solve(laplacian, &inv, &b, &mut from_zero, 1, 0.0);
        let mut wild: Vec<Real> = (0..n)
            .map(|i| 1e3 * (-1.0 as Real).powi(i as i32))
            .collect();
        wild[0] = 3.0;
        ws.solve(laplacian, &inv, &b, &mut wild, 1, 0.0);
        assert_eq!(wild, from_zero);
        let mut exact = from_zero.clone();
        ws.solve(laplacian, &inv, &b, &mut exact, 200, 1e-14);
        let mut near: Vec<Real> = exact.iter().map(|v| v * 1.001).collect();
        near[0] = 3.0;
        ws.solve(laplacian, &inv, &b, &mut near, 1, 0.0);
        assert!(error(&near) < 1e-2 * error(&from_zero));
    }

    /// A node held along a direction n only (S = I − n nᵀ on its three entries): the
    /// solution is the constrained minimiser, which the two KKT conditions determine: the
    /// node sits on its plane (n·x = g, as given) and the residual b − A x vanishes except
    /// along n at that node (the constraint force).
    #[test]
    fn a_node_held_along_a_direction_keeps_its_component_and_is_free_across() {
        let n = 30;
        let node = 4;
        let dir = [1.0 / 3.0, 2.0 / 3.0, -2.0 / 3.0];
        let g = 0.7;
        let b: Vec<Real> = (0..n).map(|i| ((i * 5 % 7) as Real) - 3.0).collect();
        let filter = |v: &mut [Real]| {
            let j = 3 * node;
            let s: Real = (0..3).map(|k| dir[k] * v[j + k]).sum();
            (0..3).for_each(|k| v[j + k] -= s * dir[k]);
        };
        let mut x: Vec<Real> = (0..n).map(|i| 0.1 * i as Real).collect();
        // The known part: n·x_node = g.
        let j = 3 * node;
        let s: Real = (0..3).map(|k| dir[k] * x[j + k]).sum();
        (0..3).for_each(|k| x[j + k] += (g - s) * dir[k]);
        let mut ws = CgWorkspace::new(n);
        let jacobi = |r: &[Real], z: &mut [Real]| {
            z.iter_mut().zip(r).for_each(|(zi, ri)| *zi = ri / 2.5);
        };
        let res = ws.solve_filtered(laplacian, jacobi, filter, &b, &mut x, 200, 1e-14);
        assert!(res.relative_residual <= 1e-14, "{res:?}");
        let along: Real = (0..3).map(|k| dir[k] * x[j + k]).sum();
        assert!((along - g).abs() < 1e-14, "{along}");
        let mut y = vec![0.0; n];
        laplacian(&x, &mut y);
        let r: Vec<Real> = (0..n).map(|i| b[i] - y[i]).collect();
        for (i, ri) in r.iter().enumerate() {
            if i / 3 != node {
                assert!(ri.abs() < 1e-12, "row {i}: {ri}");
            }
        }
        // At the node: parallel to n, and not zero (the hold carries a force).
        let rn: Real = (0..3).map(|k| dir[k] * r[j + k]).sum();
        for k in 0..3 {
            assert!((r[j + k] - rn * dir[k]).abs() < 1e-12, "{:?}", &r[j..j + 3]);
        }
        assert!(rn.abs() > 1e-3, "{rn}");
    }
}
