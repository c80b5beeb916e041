//! Contacts held along a direction only, solved exactly on a dense response between them:
//! what `fem-condensed`, `fem-precomputed-tensors` and `bem` share for
//! `Deformable::set_constraints_along` (the survey's reason for pre-computing a surface
//! response is to solve the contact problem with it exactly).
//!
//! A model answers its m contacts from unknowns a_k, three per contact (the force itself for
//! a compliance, a virtual displacement for Cotin's tensors, a traction for the BEM), through
//! a dense response: contact j moves by u₀_j + Σ_k A_jk a_k, and contact k applies the force
//! F_k a_k to the tissue. A contact held along a unit direction n pushes along n only,
//! F_k a_k = μ n, so a_k = F_k⁻¹ n μ; a contact held in full keeps one such row per axis.
//! With one row (k_r, e_r) per held direction and u_r = F_{k_r}⁻¹ e_r, the multipliers solve
//!
//! ```text
//!   Σ_c (e_rᵀ A_{k_r k_c} u_c) μ_c = e_rᵀ (t_{k_r} − u₀_{k_r})        (Eᵀ A F⁻¹ B μ = Eᵀ (t − u₀))
//! ```
//!
//! and a_k = Σ_{r of k} μ_r u_r. The block is symmetric positive definite when A F⁻¹ is a
//! compliance (`fem-condensed`: A = W_CC, F = I), read by its lower triangle and factorised
//! by Cholesky; otherwise it is a general system solved by LU with partial pivoting
//! (Cotin's tensors give A F⁻¹ = W_CC only up to roundoff, the BEM's collocation block is
//! not symmetric at all). A contact held along its normal costs one row, not three.

use faer::MatRef;

use crate::error::SimError;
use crate::math::{Mat3, Real, Vec3};

use super::SmallDense;

/// The dense response a model answers its contacts from (indices are contacts, 0..m).
pub(crate) trait ContactResponse {
    /// Whether A F⁻¹ is symmetric positive definite (Cholesky on its lower triangle; else
    /// LU).
    const SYMMETRIC: bool;
    /// A_jk: the displacement of contact j per unit of contact k's unknown.
    fn block(&self, j: usize, k: usize) -> Mat3;
    /// F_k⁻¹: contact k's unknown per unit of the force it applies to the tissue.
    fn unknown_per_force(&self, k: usize) -> Mat3;
    /// t_k − u₀_k: where contact k must go, less where the loads alone put it.
    fn gap(&self, k: usize) -> Vec3;
}

/// One held direction: its contact, the direction e, and u = F⁻¹ e.
#[derive(Clone, Copy, Debug)]
struct Row {
    contact: usize,
    dir: Vec3,
    unknown: Vec3,
}

/// The rows and the block of the last solve, kept so that a contact update allocates
/// nothing once the largest contact set was seen.
pub(crate) struct HeldRows {
    rows: Vec<Row>,
    small: SmallDense,
}

impl Default for HeldRows {
    fn default() -> Self {
        Self {
            rows: Vec::new(),
            small: SmallDense::new(0),
        }
    }
}

impl HeldRows {
    /// Solves for the unknowns of contacts held along `normals` (a unit vector: along it
    /// only; zero: in all three directions), writing a_k into `unknowns[3k..3k + 3]`.
    /// A singular block is an error, never a panic.
    pub fn solve<T: ContactResponse>(
        &mut self,
        response: &T,
        normals: &[Vec3],
        unknowns: &mut [Real],
    ) -> Result<(), SimError> {
        const AXES: [Vec3; 3] = [Vec3::X, Vec3::Y, Vec3::Z];
        if unknowns.len() < 3 * normals.len() {
            return Err(SimError::BadParameter {
                name: "unknowns",
                value: format!("{} for {} contacts", unknowns.len(), normals.len()),
                reason: "three unknowns per contact".into(),
            });
        }
        self.rows.clear();
        for (k, &n) in normals.iter().enumerate() {
            let per_force = response.unknown_per_force(k);
            let dirs = if n == Vec3::ZERO {
                &AXES[..]
            } else {
                std::slice::from_ref(&normals[k])
            };
            self.rows.extend(dirs.iter().map(|&dir| Row {
                contact: k,
                dir,
                unknown: per_force * dir,
            }));
        }
        let m = self.rows.len();
        let small = &mut self.small;
        let (mut block, rhs) = small.block_and_rhs(m);
        for (c, col) in self.rows.iter().enumerate() {
            let first = if T::SYMMETRIC { c } else { 0 };
            for (r, row) in self.rows.iter().enumerate().skip(first) {
                let a = response.block(row.contact, col.contact);
                block[(r, c)] = row.dir.dot(a * col.unknown);
            }
        }
        for (x, row) in rhs.iter_mut().zip(&self.rows) {
            *x = row.dir.dot(response.gap(row.contact));
        }
        let mu = if T::SYMMETRIC {
            small.solve_spd_rhs(m)?
        } else {
            small.solve_general_rhs(m)?
        };
        unknowns.iter_mut().for_each(|a| *a = 0.0);
        for (row, &mu) in self.rows.iter().zip(mu) {
            let k = row.contact;
            for i in 0..3 {
                unknowns[3 * k + i] += mu * row.unknown[i];
            }
        }
        Ok(())
    }
}

/// The 3×3 block of `m` whose first entry is (r0, c0).
pub(crate) fn block3(m: MatRef<'_, Real>, r0: usize, c0: usize) -> Mat3 {
    Mat3::from_cols_array_2d(&[0, 1, 2].map(|c| [0, 1, 2].map(|r| m[(r0 + r, c0 + c)])))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A general (not symmetric) response: A_jk and F_k from a seeded sequence, A made
    /// diagonally dominant so that the problem is regular.
    struct Random {
        a: Vec<Mat3>,
        per_force: Vec<Mat3>,
        gap: Vec<Vec3>,
        m: usize,
    }

    impl ContactResponse for Random {
        const SYMMETRIC: bool = false;
        fn block(&self, j: usize, k: usize) -> Mat3 {
            self.a[j * self.m + k]
        }
        fn unknown_per_force(&self, k: usize) -> Mat3 {
            self.per_force[k]
        }
        fn gap(&self, k: usize) -> Vec3 {
            self.gap[k]
        }
    }

    /// The defining property: each contact held along n reaches its gap along n and
    /// applies a force F_k a_k along n; one held in full reaches its whole gap.
    #[test]
    fn held_rows_meet_their_gaps_and_push_along_their_directions() {
        let mut state = 3u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as Real / (1u64 << 53) as Real - 0.5
        };
        let mut mat = |diag: Real| {
            Mat3::from_cols_array(&std::array::from_fn(|_| next())) + Mat3::IDENTITY * diag
        };
        let m = 5;
        let a: Vec<Mat3> = (0..m * m)
            .map(|i| mat(if i % (m + 1) == 0 { 4.0 } else { 0.0 }))
            .collect();
        let per_force: Vec<Mat3> = (0..m).map(|_| mat(2.0)).collect();
        let mut vec = || Vec3::new(next(), next(), next());
        let gap: Vec<Vec3> = (0..m).map(|_| vec()).collect();
        let normals: Vec<Vec3> = (0..m)
            .map(|k| {
                if k % 2 == 0 {
                    vec().normalize()
                } else {
                    Vec3::ZERO
                }
            })
            .collect();
        let response = Random {
            a,
            per_force,
            gap,
            m,
        };
        let mut unknowns = vec![0.0; 3 * m];
        let mut held = HeldRows::default();
        held.solve(&response, &normals, &mut unknowns).unwrap();
        let at = |k: usize| Vec3::new(unknowns[3 * k], unknowns[3 * k + 1], unknowns[3 * k + 2]);
        for (j, n) in normals.iter().enumerate() {
            let reached: Vec3 = (0..m).map(|k| response.block(j, k) * at(k)).sum();
            if *n == Vec3::ZERO {
                assert!((reached - response.gap[j]).length() < 1e-12, "{j}");
            } else {
                assert!((reached - response.gap[j]).dot(*n).abs() < 1e-12, "{j}");
                let force = response.per_force[j].inverse() * at(j);
                assert!(force.cross(*n).length() < 1e-12 * force.length(), "{j}");
            }
        }
        // Too few unknowns for the contacts: an error, not a panic.
        assert!(held.solve(&response, &normals, &mut [0.0; 3]).is_err());
    }
}
