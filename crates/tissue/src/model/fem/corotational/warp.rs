//! The warp-canceling preconditioner (Courtecuisse, Allard, Kerfriden, Bordas, Cotin &
//! Duriez 2014; SOFA's `PrecomputedWarpPreconditioner`): the step's matrix
//! A = c_m M + c_k Σ R_e K_e R_eᵀ differs from the rest matrix A₀ = c_m M + c_k K₀ mostly by
//! the rotations, so P⁻¹ = R A₀⁻¹ Rᵀ, with R block-diagonal in the nodes' rotations and A₀
//! factorised once by sparse Cholesky, is close to A⁻¹: CG then needs a few iterations where
//! Jacobi needs hundreds on a stiff material (the condition number of A grows as
//! c_k λ_max(K) / m, which a 1 ms step on E = 1e8 Pa makes ~1e4).
//!
//! A node's rotation is the polar factor of the volume-weighted sum of its elements'
//! rotations (started from its last one, so 2-3 Newton steps). Held nodes (fixed or
//! prescribed) are eliminated in A₀ (identity rows and columns): A₀ is refactorised when the
//! set of held nodes or the step's coefficients change, with the symbolic analysis kept.

use std::time::Instant;

use crate::error::SimError;
use crate::math::{Mat3, Real, Vec3};
use crate::solve::{BlockPattern, SparseCholesky};

use super::bsr::BlockStiffness;
use super::force::{ElementRest, Lames};
use super::rotation::polar_rotation_near;

/// Nodes from which their rotations are computed on rayon's threads (a polar factor is
/// ~0.1 µs: below ~1,000 nodes the pass is not much longer than waking a worker).
#[cfg(feature = "parallel")]
const PARALLEL_MIN_NODES: usize = 1024;

/// What A₀ was last factorised for.
#[derive(Clone, Debug, PartialEq)]
struct FactorKey {
    cm: Real,
    ck: Real,
    held: Vec<bool>,
}

/// The factorised rest matrix and the nodes' rotations.
#[derive(Debug)]
pub(super) struct WarpPreconditioner {
    pattern: BlockPattern,
    cholesky: SparseCholesky,
    /// K₀ on `pattern`, all nodes.
    rest_stiffness: BlockStiffness,
    key: Option<FactorKey>,
    held: Vec<bool>,
    node_rotations: Vec<Mat3>,
    sums: Vec<Mat3>,
    scratch: Vec<Real>,
    pub factorizations: usize,
    pub factor_seconds: Real,
}

impl WarpPreconditioner {
    /// Symbolic analysis of the node adjacency of `elements` over the nodes at `rest` (no
    /// factorisation yet). The ordering is AMD or nested dissection by the rest positions,
    /// whichever solves faster on the threads at hand (`SparseCholesky::for_solves`: the
    /// smaller factor on one thread, the shorter critical path on two). Solved with at
    /// every CG iteration, the factor is read from an f32 copy.
    pub fn new(elements: &[ElementRest], lame: &Lames, rest: &[Vec3]) -> Result<Self, SimError> {
        let nodes = rest.len();
        let flat: Vec<u32> = elements.iter().flat_map(|e| e.nodes).collect();
        let pattern = BlockPattern::from_elements(nodes, 3, &flat, 4);
        let mut cholesky = SparseCholesky::for_solves(&pattern, rest)?;
        // A preconditioner needs no f64 factor: half the bytes per solve (`sparse`).
        cholesky.single_precision_solves(true);
        let mut rest_stiffness = BlockStiffness::new(elements, nodes);
        rest_stiffness.assemble(elements, lame, &vec![Mat3::IDENTITY; elements.len()]);
        Ok(Self {
            pattern,
            cholesky,
            rest_stiffness,
            key: None,
            held: vec![false; nodes],
            node_rotations: vec![Mat3::IDENTITY; nodes],
            sums: vec![Mat3::ZERO; nodes],
            scratch: vec![0.0; 3 * nodes],
            factorizations: 0,
            factor_seconds: 0.0,
        })
    }

    /// Stored values of the Cholesky factor.
    pub fn factor_nnz(&self) -> usize {
        self.cholesky.factor_nnz()
    }

    /// Factorises A₀ = c_m M + c_k K₀ with the nodes `held` eliminated, unless it already is.
    pub fn ensure_factored(
        &mut self,
        cm: Real,
        ck: Real,
        masses: &[Real],
        held: impl Iterator<Item = bool>,
    ) -> Result<(), SimError> {
        for (h, new) in self.held.iter_mut().zip(held) {
            *h = new;
        }
        let same = self
            .key
            .as_ref()
            .is_some_and(|k| k.cm == cm && k.ck == ck && k.held == self.held);
        if same && self.cholesky.is_factored() {
            return Ok(());
        }
        let start = Instant::now();
        let mut values = self
            .rest_stiffness
            .to_pattern_values(&self.pattern, &self.held);
        values.iter_mut().for_each(|v| *v *= ck);
        for (a, (&m, &h)) in masses.iter().zip(&self.held).enumerate() {
            for i in 0..3 {
                let d = 3 * a + i;
                if let Some(s) = self.pattern.slot(d, d) {
                    values[s] = if h { 1.0 } else { values[s] + cm * m };
                }
            }
        }
        self.key = None;
        self.cholesky.factorize(
            &self.pattern,
            &values,
            "the rest system matrix of fem-corotational is not positive definite",
        )?;
        self.key = Some(FactorKey {
            cm,
            ck,
            held: self.held.clone(),
        });
        self.factorizations += 1;
        self.factor_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    /// Each node's rotation from its elements' (volume-weighted, polar).
    pub fn update_rotations(&mut self, elements: &[ElementRest], rotations: &[Mat3]) {
        self.sums.iter_mut().for_each(|s| *s = Mat3::ZERO);
        for (e, r) in elements.iter().zip(rotations) {
            let w = *r * e.volume;
            for &n in &e.nodes {
                self.sums[n as usize] += w;
            }
        }
        let polar = |(rot, sum): (&mut Mat3, &Mat3)| {
            if let Some(r) = polar_rotation_near(sum, rot) {
                *rot = r;
            }
        };
        // Each node on its own: the same bits on any number of threads.
        #[cfg(feature = "parallel")]
        if self.node_rotations.len() >= PARALLEL_MIN_NODES && rayon::current_num_threads() > 1 {
            use rayon::prelude::*;
            self.node_rotations
                .par_iter_mut()
                .zip(self.sums.par_iter())
                .with_min_len(256)
                .for_each(polar);
            return;
        }
        self.node_rotations
            .iter_mut()
            .zip(&self.sums)
            .for_each(polar);
    }

    /// z = R A₀⁻¹ Rᵀ r (flat). A failed solve (never after a successful factorisation)
    /// leaves z = r, an SPD fallback.
    pub fn apply(&mut self, r: &[Real], z: &mut [Real]) {
        let t = &mut self.scratch;
        for ((tc, rc), rot) in t
            .chunks_exact_mut(3)
            .zip(r.chunks_exact(3))
            .zip(&self.node_rotations)
        {
            let v = rot.transpose() * Vec3::new(rc[0], rc[1], rc[2]);
            tc.copy_from_slice(&v.to_array());
        }
        if self.cholesky.solve_in_place(t).is_err() {
            z.copy_from_slice(r);
            return;
        }
        for ((zc, tc), rot) in z
            .chunks_exact_mut(3)
            .zip(t.chunks_exact(3))
            .zip(&self.node_rotations)
        {
            let v = *rot * Vec3::new(tc[0], tc[1], tc[2]);
            zc.copy_from_slice(&v.to_array());
        }
    }

    /// Back to the rest rotations.
    pub fn reset(&mut self) {
        self.node_rotations
            .iter_mut()
            .for_each(|r| *r = Mat3::IDENTITY);
    }
}
