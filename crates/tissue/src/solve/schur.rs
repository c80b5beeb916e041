//! Extra held unknowns imposed on a factorised matrix through their Schur complement, so that
//! holding a few more unknowns does not cost a new sparse factorisation.
//!
//! With A0 factorised (its own held unknowns already eliminated) and the extra held unknowns
//! E (columns of the identity), Lagrange multipliers λ give
//!
//! ```text
//! A0 u = b + E λ,   Eᵀ u = g_E   ⇒   S λ = g_E − Eᵀ A0⁻¹ b,   S = Eᵀ A0⁻¹ E,
//! ```
//!
//! then one more solve with b + E λ. S is symmetric positive definite when A0 is. Its entries
//! are kept for every unknown seen so far (h × h values, not the n × h columns they come
//! from): a column A0⁻¹ e_j is computed once, when unknown j is first held, in blocks of
//! right-hand sides that share one pass over the factor. The dense factorisation of the
//! active part of S is kept while the active set does not change.
//!
//! A held row may also combine several unknowns, cᵀu = g (a node held along a direction n
//! only: c is n on its three unknowns): with C the rows' coefficients over the unknowns,
//! the multipliers solve (Cᵀ S C) λ = g − Cᵀ A0⁻¹ b and the load is E C λ. The columns
//! are still those of single unknowns, so they are shared by every direction a node is
//! held along.

use std::collections::HashMap;

use faer::linalg::solvers::{Llt, Solve};
use faer::{Mat, Side};

use crate::error::SimError;
use crate::math::Real;

use super::SparseCholesky;

/// One held row: its unknowns and their coefficients (a single unknown with 1: a held
/// unknown).
pub type HeldRow = Vec<(usize, Real)>;

/// Bytes of right-hand sides solved together when computing new columns.
const BLOCK_BYTES: usize = 64 << 20;

/// The Schur complement's entries over the unknowns seen so far, and the factorisation of its
/// active part.
#[derive(Default)]
pub struct HeldSchur {
    /// Unknown → its slot in `s`.
    slot: HashMap<usize, usize>,
    /// Slot → unknown.
    unknowns: Vec<usize>,
    /// S over the slots, column after column (`unknowns.len()²` values).
    s: Vec<Real>,
    /// The active rows of the last factorised part (unknown, coefficient), and its
    /// factorisation.
    active: Vec<HeldRow>,
    llt: Option<Llt<Real>>,
}

impl std::fmt::Debug for HeldSchur {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HeldSchur")
            .field("unknowns", &self.unknowns.len())
            .field("active", &self.active.len())
            .finish()
    }
}

impl HeldSchur {
    /// Forgets everything (the factorised matrix changed).
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// Unknowns whose column is known.
    pub fn len(&self) -> usize {
        self.unknowns.len()
    }

    pub fn is_empty(&self) -> bool {
        self.unknowns.is_empty()
    }

    /// How many of `extra` have no column yet.
    pub fn missing(&self, extra: &[usize]) -> usize {
        extra.iter().filter(|d| !self.slot.contains_key(d)).count()
    }

    /// Computes the columns A0⁻¹ e_j of the unknowns of `extra` not seen before, keeping
    /// their entries at every seen unknown. Returns how many columns were computed.
    pub fn add_columns(
        &mut self,
        chol: &SparseCholesky,
        n: usize,
        extra: &[usize],
    ) -> Result<usize, SimError> {
        let mut new: Vec<usize> = extra
            .iter()
            .copied()
            .filter(|d| !self.slot.contains_key(d))
            .collect();
        // An unknown named twice (a vertex under two points of a fine surface) gets one slot.
        new.sort_unstable();
        new.dedup();
        if new.is_empty() {
            return Ok(0);
        }
        let old = self.unknowns.len();
        let h = old + new.len();
        // Grow S to h × h, old entries in place.
        let mut s = vec![0.0; h * h];
        for j in 0..old {
            s[j * h..j * h + old].copy_from_slice(&self.s[j * old..(j + 1) * old]);
        }
        for &d in &new {
            self.slot.insert(d, self.unknowns.len());
            self.unknowns.push(d);
        }
        let block = (BLOCK_BYTES / (8 * n.max(1))).clamp(1, 64);
        let mut rhs = Vec::new();
        for (b, chunk) in new.chunks(block).enumerate() {
            rhs.clear();
            rhs.resize(n * chunk.len(), 0.0);
            for (k, &d) in chunk.iter().enumerate() {
                rhs[k * n + d] = 1.0;
            }
            chol.solve_many_in_place(&mut rhs, chunk.len())?;
            for k in 0..chunk.len() {
                let j = old + b * block + k;
                let z = &rhs[k * n..(k + 1) * n];
                for (i, &d) in self.unknowns.iter().enumerate() {
                    // S is symmetric: the new column also gives the new row.
                    s[j * h + i] = z[d];
                    s[i * h + j] = z[d];
                }
            }
        }
        self.s = s;
        self.active.clear();
        self.llt = None;
        Ok(new.len())
    }

    /// λ with S_EE λ = `d` for the active unknowns `extra` (every one with a column).
    pub fn multipliers(&mut self, extra: &[usize], d: &[Real]) -> Result<Vec<Real>, SimError> {
        let rows: Vec<HeldRow> = extra.iter().map(|&e| vec![(e, 1.0)]).collect();
        self.multipliers_rows(&rows, d)
    }

    /// Cᵀ S C for the held rows `rows` (each a combination of unknowns that all have a
    /// column): the response of each row to the others' multipliers.
    pub fn rows_matrix(&self, rows: &[HeldRow]) -> Result<Mat<Real>, SimError> {
        let h = self.unknowns.len();
        let mut idx: Vec<Vec<(usize, Real)>> = Vec::with_capacity(rows.len());
        for row in rows {
            let mut r = Vec::with_capacity(row.len());
            for &(e, c) in row {
                let slot = *self.slot.get(&e).ok_or_else(|| SimError::BadParameter {
                    name: "held",
                    value: format!("dof {e}"),
                    reason: "no Schur column for it (internal)".into(),
                })?;
                r.push((slot, c));
            }
            idx.push(r);
        }
        let s = &self.s;
        Ok(Mat::<Real>::from_fn(rows.len(), rows.len(), |i, j| {
            let mut v = 0.0;
            for &(a, ca) in &idx[i] {
                for &(b, cb) in &idx[j] {
                    v += ca * cb * s[b * h + a];
                }
            }
            v
        }))
    }

    /// λ with (Cᵀ S C) λ = `d` for the held rows `rows` (each a combination of unknowns
    /// that all have a column).
    pub fn multipliers_rows(
        &mut self,
        rows: &[HeldRow],
        d: &[Real],
    ) -> Result<Vec<Real>, SimError> {
        if self.active != rows || self.llt.is_none() {
            self.llt = None;
            let m = self.rows_matrix(rows)?;
            let first = rows.first().and_then(|r| r.first()).map_or(0, |r| r.0);
            let llt = m
                .llt(Side::Lower)
                .map_err(|_| SimError::NotPositiveDefinite {
                    row: first,
                    hint: "the Schur complement of the held unknowns is not positive definite"
                        .into(),
                })?;
            self.llt = Some(llt);
            self.active = rows.to_vec();
        }
        let llt = self.llt.as_ref().ok_or_else(|| SimError::BadParameter {
            name: "held",
            value: String::new(),
            reason: "no Schur factorisation (internal)".into(),
        })?;
        let mut x = Mat::<Real>::from_fn(d.len(), 1, |i, _| d[i]);
        llt.solve_in_place(x.as_mut());
        Ok((0..d.len()).map(|i| x[(i, 0)]).collect())
    }
}
