//! Stiffness-proportional (Rayleigh β) damping for explicit schemes, taken out of the force
//! and applied once per step as an implicit velocity update.
//!
//! Why: the damping force −βK v has rates βω² that grow with the square of the mesh's
//! highest frequency. On stiff tissue (the issue-24 beam: E = 1e8 Pa, β = 0.02 s, ω_max ≈
//! 1e5 rad/s) the explicit limit 2/(βω²_max) is ~1e-8 s: 1e5 substeps per millisecond,
//! while the elastic force alone allows ~1e-5 s. The damping term is linear in v and
//! dissipative, so it does not need to be explicit. The step is split (Lie splitting):
//!
//! 1. the explicit scheme steps the elastic force, loads and mass damping α M v over dt in
//!    as many substeps as the *undamped* limit asks;
//! 2. the velocities then solve (M + dt β K₀) v = M v* − dt β K₀,fh v_h: backward Euler on
//!    M v̇ = −β K₀ v over dt, with held particles at their step velocity v_h.
//!
//! Step 2 is unconditionally stable (it contracts the kinetic energy: vᵀMv + dt β vᵀK₀v =
//! vᵀMv*) and first-order accurate in dt β ω²: on the beam's first mode (ω ≈ 32 rad/s) the
//! decay rate is the exact Rayleigh rate to 2e-5, while the modes above 1/√(dt β) (≈ 220
//! rad/s at 1 ms) get their velocity removed each step, as the continuous overdamped
//! Rayleigh modes would (they relax in 1/(βω²) ≪ dt). K₀ is the rest (linear) stiffness,
//! the same K the linear Rayleigh damping of these models uses. The matrix is factorised
//! once (sparse Cholesky over faer) and again only when dt, the held particles or K₀ (a cut)
//! change; each step costs one solve and two sparse products.

use crate::error::SimError;
use crate::math::{Mat3, Real, Vec3};
use crate::solve::sparse::{BlockPattern, SparseCholesky};

/// The rest stiffness K₀ of a tetrahedral system, its factorised M + dt β K₀ and buffers.
/// A clone has no factor yet (the next `prepare` computes it).
#[derive(Debug)]
pub struct SplitDamping {
    beta: Real,
    pattern: BlockPattern,
    /// K₀'s values on `pattern` (both triangles).
    k: Vec<Real>,
    /// The factorised matrix's values.
    a: Vec<Real>,
    /// The symbolic analysis is done at the first `prepare`.
    chol: Option<SparseCholesky>,
    /// Rest positions of the nodes, for a nested-dissection ordering of the factor (empty:
    /// AMD).
    positions: Vec<Vec3>,
    /// dt, masses and held flags the factor was computed for.
    factored_for: Option<(Real, Vec<Real>, Vec<bool>)>,
    rhs: Vec<Real>,
    tmp: Vec<Real>,
    held: Vec<bool>,
    /// The damping matrix at the current state, when it is not the rest one (`set_current_edges`),
    /// and the conjugate-gradient vectors that solve with it.
    current: Vec<Real>,
    cg: [Vec<Real>; 4],
    /// Preconditioned CG iterations of the last `apply` (0: the rest matrix solved directly)
    /// and whether they reached their tolerance.
    last_iterations: usize,
    last_converged: bool,
    /// Whether `chol` holds the rest matrix (else a current one, `refactor_current`).
    factor_of_rest: bool,
    /// Current matrices factorised because CG on them stalled (`refactor_current`).
    refactors: usize,
    /// CG stalled since the last rest factorisation: the current matrices are factorised
    /// and solved directly, without trying CG first.
    direct: bool,
}

impl Clone for SplitDamping {
    fn clone(&self) -> Self {
        Self {
            beta: self.beta,
            pattern: self.pattern.clone(),
            k: self.k.clone(),
            a: self.a.clone(),
            chol: None,
            positions: self.positions.clone(),
            factored_for: None,
            rhs: self.rhs.clone(),
            tmp: self.tmp.clone(),
            held: self.held.clone(),
            current: self.current.clone(),
            cg: self.cg.clone(),
            last_iterations: 0,
            last_converged: true,
            factor_of_rest: true,
            refactors: 0,
            direct: false,
        }
    }
}

impl SplitDamping {
    /// The pattern of `tets` over `nodes` nodes, with K₀ to be assembled by `assemble`.
    pub fn new(nodes: usize, tets: &[[u32; 4]], beta: Real) -> Self {
        let flat: Vec<u32> = tets.iter().flatten().copied().collect();
        Self::on_elements(nodes, &flat, 4, beta)
    }

    /// The pattern of springs (2-node elements) over `nodes` nodes. A spring network damps
    /// with its own constants c (not β k), so it assembles C itself with β = 1.
    pub fn for_edges(nodes: usize, edges: &[[u32; 2]]) -> Self {
        let flat: Vec<u32> = edges.iter().flatten().copied().collect();
        Self::on_elements(nodes, &flat, 2, 1.0)
    }

    fn on_elements(nodes: usize, flat: &[u32], per_element: usize, beta: Real) -> Self {
        let pattern = BlockPattern::from_elements(nodes, 3, flat, per_element);
        let nnz = pattern.nnz();
        let dim = pattern.dim();
        Self {
            beta,
            pattern,
            k: vec![0.0; nnz],
            a: vec![0.0; nnz],
            chol: None,
            positions: Vec::new(),
            factored_for: None,
            rhs: vec![0.0; dim],
            tmp: vec![0.0; dim],
            held: Vec::new(),
            current: Vec::new(),
            cg: Default::default(),
            last_iterations: 0,
            last_converged: true,
            factor_of_rest: true,
            refactors: 0,
            direct: false,
        }
    }

    /// Orders the factor by the nodes' `positions` (rest positions, one per node): geometric
    /// nested dissection when it gives a smaller factor than AMD (`SparseCholesky::
    /// with_positions`): the factor's two triangular solves, one pair per step, read all of
    /// it (3.6e6 values on the issue-24 beam at 19,200 tetrahedra, where AMD stays the
    /// smaller: ~19% of `tensor-mass-nonlinear`'s step there).
    pub fn with_positions(mut self, positions: &[Vec3]) -> Self {
        self.positions = positions.to_vec();
        self.chol = None;
        self.factored_for = None;
        self
    }

    /// The β it damps with, in s.
    pub fn beta(&self) -> Real {
        self.beta
    }

    /// Stored values of the factor (its size).
    pub fn factor_nnz(&self) -> usize {
        self.chol.as_ref().map_or(0, SparseCholesky::factor_nnz)
    }

    /// Rebuilds K₀ from the 4×4 blocks of the given tetrahedra (block (a, b) couples the
    /// force on corner a to the displacement of corner b); the next step refactorises.
    pub fn assemble(&mut self, blocks: impl Iterator<Item = ([u32; 4], [[Mat3; 4]; 4])>) {
        self.assemble_elements(blocks);
    }

    /// Rebuilds the damping matrix of springs (a, b) with 3×3 blocks c u uᵀ (the force
    /// on a is c u uᵀ (v_b − v_a)); the next step refactorises.
    pub fn assemble_edges(&mut self, springs: impl Iterator<Item = ([u32; 2], Mat3)>) {
        self.assemble_elements(springs.map(|(e, c)| (e, [[c, -c], [-c, c]])));
    }

    fn assemble_elements<const N: usize>(
        &mut self,
        blocks: impl Iterator<Item = ([u32; N], [[Mat3; N]; N])>,
    ) {
        let mut k = std::mem::take(&mut self.k);
        self.sum_blocks(blocks, &mut k);
        self.k = k;
        self.factored_for = None;
    }

    /// `out` = the sum of the element blocks on the pattern.
    fn sum_blocks<const N: usize>(
        &self,
        blocks: impl Iterator<Item = ([u32; N], [[Mat3; N]; N])>,
        out: &mut Vec<Real>,
    ) {
        out.clear();
        out.resize(self.pattern.nnz(), 0.0);
        let p = &self.pattern;
        for (el, k) in blocks {
            for (a, &na) in el.iter().enumerate() {
                for (b, &nb) in el.iter().enumerate() {
                    let (na, nb) = (na as usize, nb as usize);
                    let Some(pos) = p.neighbour_position(nb, na) else {
                        continue;
                    };
                    for j in 0..3 {
                        let col = 3 * nb + j;
                        let base = p.col_ptr[col] + pos * 3;
                        let c = k[a][b].col(j);
                        for (i, v) in c.to_array().iter().enumerate() {
                            out[base + i] += v;
                        }
                    }
                }
            }
        }
    }

    /// Sets the damping matrix of the current state (springs (a, b) with blocks c u uᵀ at
    /// their current directions) that the next `apply` solves with, the factorised rest
    /// matrix serving as its preconditioner. Without it `apply` uses the rest matrix.
    pub fn set_current_edges(&mut self, springs: impl Iterator<Item = ([u32; 2], Mat3)>) {
        let mut cur = std::mem::take(&mut self.current);
        self.sum_blocks(springs.map(|(e, c)| (e, [[c, -c], [-c, c]])), &mut cur);
        self.current = cur;
    }

    /// Factorises M + dt β K₀ for these masses and held particles unless it already is
    /// (held rows and columns become identity). Called before the step, so that a failure
    /// leaves the state untouched.
    pub fn prepare(&mut self, dt: Real, masses: &[Real], held: &[bool]) -> Result<(), SimError> {
        let n = self.pattern.dim() / 3;
        if masses.len() != n || held.len() != n {
            return Err(SimError::BadParameter {
                name: "split damping",
                value: format!("{} masses, {} held flags", masses.len(), held.len()),
                reason: format!("needs one per particle ({n})"),
            });
        }
        // A particle without mass (detached by a cut) is treated as held.
        self.held.clear();
        self.held.extend(
            held.iter()
                .zip(masses)
                .map(|(&h, &m)| h || m.is_nan() || m <= 0.0),
        );
        if let Some((d, m, h)) = &self.factored_for
            && *d == dt
            && m[..] == masses[..]
            && h[..] == self.held[..]
        {
            return Ok(());
        }
        self.factored_for = None;
        let k = std::mem::take(&mut self.k);
        let done = self.factorize(&k, dt * self.beta, masses);
        self.k = k;
        done?;
        self.factored_for = Some((dt, masses.to_vec(), self.held.clone()));
        self.factor_of_rest = true;
        self.direct = false;
        Ok(())
    }

    /// Factorises M + s K from `k` (K₀ or a current matrix; held rows and columns
    /// identity) into `chol`.
    fn factorize(&mut self, k: &[Real], s: Real, masses: &[Real]) -> Result<(), SimError> {
        let p = &self.pattern;
        for col in 0..p.dim() {
            let held_col = self.held[col / 3];
            let slots = p.col_ptr[col]..p.col_ptr[col + 1];
            let rows = &p.row_idx[slots.clone()];
            for ((a, &kv), &row) in self.a[slots.clone()].iter_mut().zip(&k[slots]).zip(rows) {
                *a = if held_col || self.held[row / 3] {
                    if row == col { 1.0 } else { 0.0 }
                } else {
                    s * kv + if row == col { masses[col / 3] } else { 0.0 }
                };
            }
        }
        let chol = match self.chol.as_mut() {
            Some(c) => c,
            None => self
                .chol
                .insert(SparseCholesky::with_positions(p, &self.positions)?),
        };
        chol.factorize(
            p,
            &self.a,
            "the split stiffness damping M + dt β K is singular (a node without mass?)",
        )
    }

    /// Applies the damping to `v` (free particles; held ones keep their velocity) and writes
    /// the damping force −β K v of the new velocities into `force` (what the held particles
    /// feel from it). K is the current matrix when one was set (`set_current_edges`), solved
    /// by conjugate gradients preconditioned with the rest factor, else the rest K₀ solved
    /// directly. Does nothing unless `prepare` succeeded for these masses and holds.
    pub fn apply(&mut self, masses: &[Real], v: &mut [Vec3], force: &mut [Vec3]) -> bool {
        let Some((dt, _, _)) = self.factored_for else {
            return false;
        };
        let n = self.held.len();
        if v.len() != n || force.len() != n || masses.len() != n {
            return false;
        }
        let s = dt * self.beta;
        let use_current = self.current.len() == self.k.len();
        let k = if use_current {
            std::mem::take(&mut self.current)
        } else {
            std::mem::take(&mut self.k)
        };
        let solved = self.solve(&k, s, masses, v, use_current);
        if solved {
            for (i, vi) in v.iter_mut().enumerate() {
                if !self.held[i] {
                    *vi = Vec3::new(self.rhs[3 * i], self.rhs[3 * i + 1], self.rhs[3 * i + 2]);
                }
            }
            for (i, vi) in v.iter().enumerate() {
                for j in 0..3 {
                    self.tmp[3 * i + j] = vi[j];
                }
            }
            self.pattern.mul_vec(&k, &self.tmp, &mut self.rhs);
            for (i, f) in force.iter_mut().enumerate() {
                *f = -self.beta
                    * Vec3::new(self.rhs[3 * i], self.rhs[3 * i + 1], self.rhs[3 * i + 2]);
            }
        }
        if use_current {
            self.current = k;
        } else {
            self.k = k;
        }
        solved
    }

    /// Solves (M + s K) v = M v* − s K v_h (held rows: v = v_h) into `rhs`.
    fn solve(
        &mut self,
        k: &[Real],
        s: Real,
        masses: &[Real],
        v: &[Vec3],
        use_current: bool,
    ) -> bool {
        for (i, vi) in v.iter().enumerate() {
            let held = self.held[i];
            for j in 0..3 {
                self.tmp[3 * i + j] = if held { vi[j] } else { 0.0 };
            }
        }
        self.pattern.mul_vec(k, &self.tmp, &mut self.rhs);
        for (i, vi) in v.iter().enumerate() {
            for j in 0..3 {
                let r = &mut self.rhs[3 * i + j];
                *r = if self.held[i] {
                    vi[j]
                } else {
                    masses[i] * vi[j] - s * *r
                };
            }
        }
        self.last_iterations = 0;
        self.last_converged = true;
        if use_current {
            if !self.direct {
                if !self.pcg(k, s, masses) {
                    return false;
                }
                if self.last_converged {
                    return true;
                }
                self.direct = true;
            }
            return self.refactor_current(k, s, masses);
        }
        // The rest matrix: its factor solves it (the rest one again if a current one took
        // its place).
        if !self.factor_of_rest {
            let rest = std::mem::take(&mut self.k);
            let done = self.factorize(&rest, s, masses);
            self.k = rest;
            if done.is_err() {
                return false;
            }
            self.factor_of_rest = true;
        }
        let Some(chol) = self.chol.as_mut() else {
            return false;
        };
        chol.solve_in_place(&mut self.rhs).is_ok()
    }

    /// CG stalled: the rest factor does not precondition the current matrix. Measured on
    /// the spring kinds, surface models (docs/performance.md, "Session 21"): their rest
    /// damping matrix is near zero across a membrane's flat faces, the damping is ~1e4
    /// times the mass over a 1 ms step on stiff tissue, so a turn of a few milliradians
    /// moves the preconditioned spectrum by tens; every step from the third stopped at the
    /// cap with a residual above ‖b‖, unreported. Even the previous step's own factor
    /// stalled on the next step. So from the first stall until the next rest factorisation
    /// (`prepare`: dt, masses or holds changed) each step factorises its current matrix and
    /// solves it directly: exact, one numeric factorisation a step (the symbolic one is
    /// kept). `rhs` holds b.
    fn refactor_current(&mut self, k: &[Real], s: Real, masses: &[Real]) -> bool {
        if self.factorize(k, s, masses).is_err() {
            return false;
        }
        self.factor_of_rest = false;
        self.refactors += 1;
        let Some(chol) = self.chol.as_mut() else {
            return false;
        };
        let solved = chol.solve_in_place(&mut self.rhs).is_ok();
        self.last_converged = solved;
        solved
    }

    /// Conjugate gradients on (M + s K) x = rhs (held rows identity), preconditioned by the
    /// factorised rest matrix read in f32 (`SparseCholesky::precondition_in_place`: half the
    /// bytes per solve; the rest matrix's own solve, `solve`, stays f64); the answer
    /// replaces `rhs`.
    fn pcg(&mut self, k: &[Real], s: Real, masses: &[Real]) -> bool {
        const TOLERANCE: Real = 1e-10;
        const MAX_ITERATIONS: usize = 50;
        let dim = self.rhs.len();
        let Some(chol) = self.chol.as_mut() else {
            return false;
        };
        for c in &mut self.cg {
            c.clear();
            c.resize(dim, 0.0);
        }
        let [x, r, z, p] = &mut self.cg;
        let held = &self.held;
        let pattern = &self.pattern;
        let tmp = &mut self.tmp;
        // y = (M + s K) q on free rows (held columns dropped), q on held rows.
        let mut apply = |q: &[Real], y: &mut [Real]| {
            for (i, t) in tmp.iter_mut().enumerate() {
                *t = if held[i / 3] { 0.0 } else { q[i] };
            }
            pattern.mul_vec(k, tmp, y);
            for i in 0..y.len() {
                y[i] = if held[i / 3] {
                    q[i]
                } else {
                    masses[i / 3] * q[i] + s * y[i]
                };
            }
        };
        let norm = |a: &[Real]| a.iter().map(|v| v * v).sum::<Real>().sqrt();
        let dot = |a: &[Real], b: &[Real]| a.iter().zip(b).map(|(a, b)| a * b).sum::<Real>();
        let b_norm = norm(&self.rhs);
        if b_norm == 0.0 {
            return true;
        }
        r.copy_from_slice(&self.rhs);
        z.copy_from_slice(r);
        if chol.precondition_in_place(z).is_err() {
            return false;
        }
        p.copy_from_slice(z);
        let mut rz = dot(r, z);
        let mut converged = false;
        for it in 1..=MAX_ITERATIONS {
            apply(p, z);
            let pap = dot(p, z);
            // Not positive (or NaN): the matrix lost definiteness; stop with what we have.
            if pap.is_nan() || pap <= 0.0 {
                break;
            }
            let alpha = rz / pap;
            for i in 0..dim {
                x[i] += alpha * p[i];
                r[i] -= alpha * z[i];
            }
            self.last_iterations = it;
            if norm(r) <= TOLERANCE * b_norm {
                converged = true;
                break;
            }
            z.copy_from_slice(r);
            if chol.precondition_in_place(z).is_err() {
                return false;
            }
            let rz_new = dot(r, z);
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..dim {
                p[i] = z[i] + beta * p[i];
            }
        }
        // Not converged to 1e-10 within the cap: `rhs` keeps b for `refactor_current`.
        self.last_converged = converged;
        if converged {
            self.rhs.copy_from_slice(x);
        }
        x.iter().all(|v| v.is_finite())
    }

    /// Preconditioned CG iterations of the last `apply` (0: the rest matrix, solved directly).
    pub fn last_iterations(&self) -> usize {
        self.last_iterations
    }

    /// Whether the last `apply`'s iterations reached their tolerance (1e-10), or, stalled,
    /// the current matrix was factorised and solved directly.
    pub fn last_converged(&self) -> bool {
        self.last_converged
    }

    /// Current matrices factorised because CG on them stalled (`refactor_current`).
    pub fn refactors(&self) -> usize {
        self.refactors
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat square membrane of springs (grid edges and one diagonal per cell), its first
    /// row held, damping 1e4 times the mass over the step, as the spring kinds have on
    /// stiff tissue: the rest (flat) factor does not precondition the bent membrane's
    /// damping, and CG stalls (the spring kinds' steps did, unreported). Whatever the path,
    /// the velocities solve the backward-Euler damping update exactly.
    #[test]
    fn a_bent_membrane_s_damping_is_solved_exactly() {
        let n = 12;
        let node = |i: usize, j: usize| (i * n + j) as u32;
        let mut edges = Vec::new();
        for i in 0..n {
            for j in 0..n {
                if i + 1 < n {
                    edges.push([node(i, j), node(i + 1, j)]);
                }
                if j + 1 < n {
                    edges.push([node(i, j), node(i, j + 1)]);
                }
                if i + 1 < n && j + 1 < n {
                    edges.push([node(i, j), node(i + 1, j + 1)]);
                }
            }
        }
        let h = 0.01;
        let flat: Vec<Vec3> = (0..n * n)
            .map(|k| Vec3::new((k / n) as Real * h, (k % n) as Real * h, 0.0))
            .collect();
        let (m, dt, c) = (1e-3, 1e-3, 1e4);
        let blocks = |x: &[Vec3], e: [u32; 2]| {
            let u = (x[e[1] as usize] - x[e[0] as usize]).normalize();
            Mat3::from_cols(u * u.x, u * u.y, u * u.z) * c
        };
        let mut damping = SplitDamping::for_edges(n * n, &edges).with_positions(&flat);
        damping.assemble_edges(edges.iter().map(|&e| (e, blocks(&flat, e))));
        let masses = vec![m; n * n];
        let held: Vec<bool> = (0..n * n).map(|k| k < n).collect();
        damping.prepare(dt, &masses, &held).unwrap();
        for (step, bend) in [0.0, 0.2, 0.4, 0.6].into_iter().enumerate() {
            let bent: Vec<Vec3> = flat
                .iter()
                .map(|p| Vec3::new(p.x, p.y, bend * p.x * p.x + 0.5 * bend * p.x * p.y))
                .collect();
            damping.set_current_edges(edges.iter().map(|&e| (e, blocks(&bent, e))));
            let before: Vec<Vec3> = (0..n * n)
                .map(|k| {
                    let t = (k * 7 + step) as Real;
                    Vec3::new(t.sin(), (1.3 * t).cos(), (0.7 * t).sin()) * 0.01
                })
                .collect();
            let mut v = before.clone();
            let mut force = vec![Vec3::ZERO; n * n];
            assert!(damping.apply(&masses, &mut v, &mut force));
            assert!(damping.last_converged());
            // (M + dt C) v = M v* on the free particles, C at the bent directions.
            let mut cv = vec![Vec3::ZERO; n * n];
            for &e in &edges {
                let (a, b) = (e[0] as usize, e[1] as usize);
                let d = blocks(&bent, e) * (v[a] - v[b]);
                cv[a] += d;
                cv[b] -= d;
            }
            let scale: Real = before
                .iter()
                .map(|w| (m * *w).length())
                .fold(0.0, Real::max);
            for k in 0..n * n {
                if held[k] {
                    assert_eq!(v[k], before[k]);
                } else {
                    let r = (m * v[k] + dt * cv[k] - m * before[k]).length();
                    assert!(r <= 1e-9 * scale, "step {step}, particle {k}: {r:e}");
                }
            }
        }
        assert!(
            damping.refactors() > 0,
            "CG never stalled: the test lost its point"
        );
    }
}
