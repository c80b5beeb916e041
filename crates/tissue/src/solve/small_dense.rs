//! A small dense system (the contact block of `fem-condensed` and `fem-precomputed-tensors`,
//! the held-direction block of `along`) factorised and solved in place by faer, in memory
//! kept across steps: it grows only when a larger contact set appears, so a contact update
//! allocates nothing after warm-up.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::cholesky::llt::factor::{LltParams, LltRegularization, cholesky_in_place};
use faer::linalg::lu::partial_pivoting::factor::{PartialPivLuParams, lu_in_place};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::{Conj, Mat, MatMut, MatRef, Par};

use crate::error::SimError;
use crate::math::Real;

/// A small dense system solved in place, in memory kept across steps (grows only).
pub(crate) struct SmallDense {
    pub a: Mat<Real>,
    /// The right-hand side, solved in place by `solve_spd_rhs` / `solve_general_rhs`.
    rhs: Vec<Real>,
    perm: Vec<usize>,
    perm_inv: Vec<usize>,
    mem: MemBuffer,
}

impl SmallDense {
    pub fn new(cap: usize) -> Self {
        let mut s = Self {
            a: Mat::zeros(0, 0),
            rhs: Vec::new(),
            perm: Vec::new(),
            perm_inv: Vec::new(),
            mem: MemBuffer::new(StackReq::EMPTY),
        };
        s.reserve(cap);
        s
    }

    /// Makes room for an m × m system (allocates only when m exceeds the capacity).
    pub fn reserve(&mut self, m: usize) {
        if m <= self.a.nrows() && !self.perm.is_empty() {
            return;
        }
        let cap = m.max(2 * self.a.nrows()).max(3);
        self.a = Mat::zeros(cap, cap);
        self.rhs = vec![0.0; cap];
        self.perm = vec![0; cap];
        self.perm_inv = vec![0; cap];
        let req = StackReq::any_of(&[
            faer::linalg::cholesky::llt::factor::cholesky_in_place_scratch::<Real>(
                cap,
                Par::Seq,
                Default::default(),
            ),
            faer::linalg::lu::partial_pivoting::factor::lu_in_place_scratch::<usize, Real>(
                cap,
                cap,
                Par::Seq,
                Default::default(),
            ),
            faer::linalg::lu::partial_pivoting::solve::solve_in_place_scratch::<usize, Real>(
                cap,
                1,
                Par::Seq,
            ),
        ]);
        self.mem = MemBuffer::new(req);
    }

    /// The top-left m × m block and the first m entries of the right-hand side, to fill.
    pub fn block_and_rhs(&mut self, m: usize) -> (MatMut<'_, Real>, &mut [Real]) {
        self.reserve(m);
        (
            self.a.as_mut().submatrix_mut(0, 0, m, m),
            &mut self.rhs[..m],
        )
    }

    /// `solve_spd` on the first m entries of `rhs`.
    pub fn solve_spd_rhs(&mut self, m: usize) -> Result<&[Real], SimError> {
        let mut b = std::mem::take(&mut self.rhs);
        let solved = self.solve_spd(&mut b[..m]);
        self.rhs = b;
        solved.map(|()| &self.rhs[..m])
    }

    /// `solve_general` on the first m entries of `rhs`.
    pub fn solve_general_rhs(&mut self, m: usize) -> Result<&[Real], SimError> {
        let mut b = std::mem::take(&mut self.rhs);
        let solved = self.solve_general(&mut b[..m]);
        self.rhs = b;
        solved.map(|()| &self.rhs[..m])
    }

    /// Solves the SPD block (lower triangle read) for `b` in place.
    pub fn solve_spd(&mut self, b: &mut [Real]) -> Result<(), SimError> {
        let m = b.len();
        let mut a = self.a.as_mut().submatrix_mut(0, 0, m, m);
        let params: faer::Spec<LltParams, Real> = Default::default();
        cholesky_in_place(
            a.rb_mut(),
            LltRegularization::default(),
            Par::Seq,
            MemStack::new(&mut self.mem),
            params,
        )
        .map_err(|_| SimError::NotPositiveDefinite {
            row: 0,
            hint: "the compliance block of the contact vertices is singular".into(),
        })?;
        let rhs = MatMut::from_column_major_slice_mut(b, m, 1);
        faer::linalg::cholesky::llt::solve::solve_in_place_with_conj(
            a.rb(),
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut self.mem),
        );
        finite(b)
    }

    /// Solves the general block by LU with partial pivoting, for `b` in place.
    pub fn solve_general(&mut self, b: &mut [Real]) -> Result<(), SimError> {
        let m = b.len();
        let mut a = self.a.as_mut().submatrix_mut(0, 0, m, m);
        let params: faer::Spec<PartialPivLuParams, Real> = Default::default();
        let (_, perm) = lu_in_place(
            a.rb_mut(),
            &mut self.perm[..m],
            &mut self.perm_inv[..m],
            Par::Seq,
            MemStack::new(&mut self.mem),
            params,
        );
        let a: MatRef<'_, Real> = a.rb();
        let rhs = MatMut::from_column_major_slice_mut(b, m, 1);
        faer::linalg::lu::partial_pivoting::solve::solve_in_place_with_conj(
            a,
            a,
            perm,
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut self.mem),
        );
        finite(b)
    }
}

fn finite(b: &[Real]) -> Result<(), SimError> {
    match b.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(d) => Err(SimError::NotPositiveDefinite {
            row: d,
            hint: "the contact system is singular (two contacts on one vertex?)".into(),
        }),
    }
}
