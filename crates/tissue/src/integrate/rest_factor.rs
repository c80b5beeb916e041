//! The implicit solve's factorised preconditioner: P = M + h·C₀ + h²·K₀ with the system's
//! Jacobians at rest, assembled and factorised once by sparse Cholesky and applied as P⁻¹
//! in CG (as `fem-corotational`'s warp preconditioner, without the rotations).
//!
//! Why it works: CG with Jacobi needs iterations growing with √cond(A), and a 10 ms step on
//! a voxel lattice makes A = M + hC + h²K far from diagonal (≈90 iterations on the pelvis).
//! A lattice's links stay nearly parallel to their rest directions under moderate
//! deformation, so A differs from P by little and P⁻¹A has its eigenvalues clustered near 1.
//!
//! The system gives K₀ and C₀ as sums of rank-one terms over a few particles
//! (`RankOneJacobians`): k u uᵀ for a spring (u = ±n on its two ends) or for a voxel's
//! volume term (u = ∂J/∂x), and a diagonal for mass damping. P is refactorised only when
//! the step, the particles or the terms (`ParticleSystem::rest_jacobians_version`: links cut,
//! voxels carved) change, or when the held particles changed since the factorisation and
//! the last solve needed markedly more iterations than the first after it. Particles held
//! at factorisation keep only their diagonal block (decoupled, so P stays SPD and block
//! diagonal in held/free); particles held later are masked out of P⁻¹'s result, which is
//! then the inverse of a Schur complement of P: still SPD, so CG converges to the same
//! answer, only the iteration count depends on how close P is.
//!
//! Measured on linked volumes' voxel organs (docs/performance.md) it cuts CG's iterations
//! 4-10× but costs more than it saves: the factor holds ~9 million values for 16k unknowns,
//! and each application reads it twice. Hence opt-in (`Preconditioner::RestFactor`).

use crate::error::SimError;
use crate::math::{Real, Vec3};
use crate::solve::{BlockPattern, SparseCholesky};

/// K₀ = Σ_t k_t u_t u_tᵀ and C₀ = Σ_t c_t u_t u_tᵀ + diag(d): each term's vector u_t is
/// non-zero on a few particles (its entries `start[t]..start[t + 1]`; a particle may
/// appear twice, its parts add).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RankOneJacobians {
    pub start: Vec<usize>,
    pub particles: Vec<u32>,
    pub directions: Vec<Vec3>,
    /// k_t, N/m (per unit u).
    pub stiffness: Vec<Real>,
    /// c_t, N·s/m.
    pub damping: Vec<Real>,
    /// C₀'s diagonal per particle (the same on its three unknowns), N·s/m.
    pub damping_diagonal: Vec<Real>,
}

impl RankOneJacobians {
    /// Empty, for `n` particles.
    pub fn clear(&mut self, n: usize) {
        self.start.clear();
        self.start.push(0);
        self.particles.clear();
        self.directions.clear();
        self.stiffness.clear();
        self.damping.clear();
        self.damping_diagonal.clear();
        self.damping_diagonal.resize(n, 0.0);
    }

    /// Appends the term k u uᵀ (stiffness), c u uᵀ (damping) with u given as (particle,
    /// part) pairs.
    pub fn push(&mut self, parts: impl IntoIterator<Item = (u32, Vec3)>, k: Real, c: Real) {
        for (p, d) in parts {
            self.particles.push(p);
            self.directions.push(d);
        }
        self.start.push(self.particles.len());
        self.stiffness.push(k);
        self.damping.push(c);
    }

    pub fn terms(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    fn term(&self, t: usize) -> (&[u32], &[Vec3]) {
        let r = self.start[t]..self.start[t + 1];
        (&self.particles[r.clone()], &self.directions[r])
    }
}

/// What the factor was computed for.
#[derive(Clone, Debug, PartialEq)]
struct Key {
    h: Real,
    version: u64,
    n: usize,
}

/// The factorised rest system matrix and its bookkeeping. A clone has no factor (the next
/// solve computes it).
#[derive(Default)]
pub(super) struct RestPreconditioner {
    terms: RankOneJacobians,
    pattern: Option<BlockPattern>,
    cholesky: Option<SparseCholesky>,
    /// The terms' version the pattern was analysed for.
    pattern_version: Option<(u64, usize)>,
    key: Option<Key>,
    /// Particles held when the factor was computed.
    held_at_factor: Vec<bool>,
    /// CG iterations of the first solve after the factorisation, and of the last one.
    baseline: Option<usize>,
    last_iterations: usize,
    /// A key whose matrix failed to factorise (Jacobi is used until the key changes).
    failed: Option<Key>,
    values: Vec<Real>,
    scratch: Vec<Real>,
    pub factorizations: usize,
}

impl Clone for RestPreconditioner {
    fn clone(&self) -> Self {
        Self::default()
    }
}

impl std::fmt::Debug for RestPreconditioner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RestPreconditioner")
            .field("key", &self.key)
            .field("cholesky", &self.cholesky)
            .field("factorizations", &self.factorizations)
            .finish()
    }
}

/// Refactorise after a change of the held particles once a solve needs this many times the
/// iterations of the first solve after the factorisation (plus `SLACK`): a few particles
/// held or let go cost an iteration or two, not a factorisation.
const DEGRADED: usize = 2;
const SLACK: usize = 4;

impl RestPreconditioner {
    /// Makes the factor current for step `h`, terms `version` (from `fill`, called only
    /// when they must be read), masses and held flags; `positions` order the factor. False
    /// when P cannot be factorised (not positive definite: a particle without mass or
    /// Jacobians that are not PSD at rest): the caller then falls back to Jacobi.
    pub fn ensure(
        &mut self,
        h: Real,
        version: u64,
        masses: &[Real],
        held: &[bool],
        positions: &[Vec3],
        fill: impl FnOnce(&mut RankOneJacobians),
    ) -> bool {
        let n = masses.len();
        let key = Key { h, version, n };
        if self.failed.as_ref() == Some(&key) {
            return false;
        }
        match self.refresh(key.clone(), masses, held, positions, fill) {
            Ok(()) => true,
            Err(_) => {
                self.failed = Some(key);
                self.key = None;
                false
            }
        }
    }

    fn refresh(
        &mut self,
        key: Key,
        masses: &[Real],
        held: &[bool],
        positions: &[Vec3],
        fill: impl FnOnce(&mut RankOneJacobians),
    ) -> Result<(), SimError> {
        let (h, version, n) = (key.h, key.version, key.n);
        let held_changed = self.held_at_factor.as_slice() != held;
        let degraded =
            |this: &Self, last: usize| this.baseline.is_some_and(|b| last > DEGRADED * b + SLACK);
        let current = self.key.as_ref() == Some(&key)
            && self.cholesky.as_ref().is_some_and(|c| c.is_factored());
        if current && !(held_changed && degraded(self, self.last_iterations)) {
            return Ok(());
        }
        if self.pattern_version != Some((version, n)) {
            self.terms.clear(n);
            fill(&mut self.terms);
            let pattern = self.pattern_of(n);
            self.cholesky = Some(SparseCholesky::with_positions(&pattern, positions)?);
            self.pattern = Some(pattern);
            self.pattern_version = Some((version, n));
        }
        self.key = None;
        self.assemble(h, masses, held);
        let (Some(pattern), Some(chol)) = (&self.pattern, &mut self.cholesky) else {
            return Err(SimError::Unsupported {
                model: "implicit Euler",
                operation: "the rest-factor preconditioner",
                reason: "no pattern was analysed".into(),
            });
        };
        chol.factorize(
            pattern,
            &self.values,
            "the rest system matrix M + h C + h^2 K of the implicit step is not positive definite",
        )?;
        self.key = Some(key);
        self.failed = None;
        self.held_at_factor.clear();
        self.held_at_factor.extend_from_slice(held);
        self.baseline = None;
        self.scratch.resize(3 * n, 0.0);
        self.factorizations += 1;
        Ok(())
    }

    /// Iterations of the solve just made with this factor.
    pub fn record(&mut self, iterations: usize) {
        self.last_iterations = iterations;
        if self.baseline.is_none() {
            self.baseline = Some(iterations);
        }
    }

    /// z = P⁻¹ r (flat). A failed solve (never after a successful factorisation) gives
    /// z = r.
    pub fn apply(&mut self, r: &[Real], z: &mut [Real]) {
        let Some(chol) = self.cholesky.as_mut() else {
            z.copy_from_slice(r);
            return;
        };
        self.scratch.copy_from_slice(r);
        if chol.solve_in_place(&mut self.scratch).is_ok() {
            z.copy_from_slice(&self.scratch);
        } else {
            z.copy_from_slice(r);
        }
    }

    /// The block pattern of the terms (each term couples all its particles).
    fn pattern_of(&self, n: usize) -> BlockPattern {
        let t = &self.terms;
        let width = (0..t.terms())
            .map(|i| t.start[i + 1] - t.start[i])
            .max()
            .unwrap_or(1)
            .max(1);
        let mut flat = Vec::with_capacity(t.terms() * width);
        for i in 0..t.terms() {
            let (ps, _) = t.term(i);
            let Some(&first) = ps.first() else { continue };
            flat.extend_from_slice(ps);
            // Padding repeats a particle: the pattern builder merges duplicates.
            flat.extend(std::iter::repeat_n(first, width - ps.len()));
        }
        BlockPattern::from_elements(n, 3, &flat, width)
    }

    /// P's values: M + h·C₀ + h²·K₀, every held particle keeping only its diagonal block.
    fn assemble(&mut self, h: Real, masses: &[Real], held: &[bool]) {
        let Some(pattern) = &self.pattern else { return };
        self.values.clear();
        self.values.resize(pattern.nnz(), 0.0);
        let t = &self.terms;
        let values = &mut self.values;
        let mut add = |a: usize, b: usize, ua: Vec3, ub: Vec3, w: Real| {
            // Block (row node a, column node b) += w ua ubᵀ.
            if a != b && (held.get(a) == Some(&true) || held.get(b) == Some(&true)) {
                return;
            }
            let Some(pos) = pattern.neighbour_position(b, a) else {
                return;
            };
            for j in 0..3 {
                let base = pattern.col_ptr[3 * b + j] + 3 * pos;
                for i in 0..3 {
                    values[base + i] += w * ua[i] * ub[j];
                }
            }
        };
        for term in 0..t.terms() {
            let w = h * t.damping[term] + h * h * t.stiffness[term];
            if w == 0.0 {
                continue;
            }
            let (ps, us) = t.term(term);
            for (&a, &ua) in ps.iter().zip(us) {
                for (&b, &ub) in ps.iter().zip(us) {
                    add(a as usize, b as usize, ua, ub, w);
                }
            }
        }
        for (a, (&m, &d)) in masses.iter().zip(&t.damping_diagonal).enumerate() {
            for i in 0..3 {
                let col = 3 * a + i;
                if let Some(s) = pattern.slot(col, col) {
                    values[s] += m + h * d;
                }
            }
        }
    }
}
