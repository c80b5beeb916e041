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

use std::collections::HashMap;

use faer::linalg::solvers::{Llt, Solve};
use faer::{Mat, Side};

use crate::error::SimError;
use crate::math::Real;

use super::SparseCholesky;

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
    /// The active unknowns of the last factorised part, and its factorisation.
    active: Vec<usize>,
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
        let new: Vec<usize> = extra
            .iter()
            .copied()
            .filter(|d| !self.slot.contains_key(d))
            .collect();
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
        if self.active != extra || self.llt.is_none() {
            self.llt = None;
            let h = self.unknowns.len();
            let mut idx = Vec::with_capacity(extra.len());
            for e in extra {
                idx.push(*self.slot.get(e).ok_or_else(|| SimError::BadParameter {
                    name: "held",
                    value: format!("dof {e}"),
                    reason: "no Schur column for it (internal)".into(),
                })?);
            }
            let m =
                Mat::<Real>::from_fn(extra.len(), extra.len(), |i, j| self.s[idx[j] * h + idx[i]]);
            let llt = m
                .llt(Side::Lower)
                .map_err(|_| SimError::NotPositiveDefinite {
                    row: extra.first().copied().unwrap_or(0),
                    hint: "the Schur complement of the held unknowns is not positive definite"
                        .into(),
                })?;
            self.llt = Some(llt);
            self.active = extra.to_vec();
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
