//! The constrained linear system K u = f with some displacement components given.
//!
//! Constrained dofs are eliminated without changing the sparsity pattern: their rows and
//! columns of K are zeroed except the diagonal, which keeps K_cc (a scaled identity keeps the
//! matrix as well conditioned as K), and the right-hand side becomes f − K_{:,c} g on free
//! rows and K_cc g_c on constrained ones. The symbolic factorisation is therefore computed
//! once; the numeric one only when the set of constrained dofs changes; new targets and loads
//! only need a new solve.
//!
//! Before factorising, each connected piece of the mesh is checked for rigid-body modes left
//! free by the constraints, so that a free body gives a clear error instead of a solution
//! made of roundoff.

use crate::error::SimError;
use crate::math::{Real, Vec3};
use crate::solve::SparseCholesky;

use super::assembly::Assembler;

const FREE_BODY_HINT: &str = "is the body fixed? a free body has rigid-motion modes; \
    constrain at least three non-collinear vertices of every separate piece";

/// One problem at the dof level: which components are held, where, and the nodal forces.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DofProblem {
    /// Per dof (3·node + axis): held or free.
    pub constrained: Vec<bool>,
    /// The held dofs, ascending.
    pub list: Vec<usize>,
    /// Displacement of each held dof (ignored on free dofs), in m.
    pub targets: Vec<Real>,
    /// Nodal forces, in N.
    pub forces: Vec<Real>,
}

impl DofProblem {
    pub fn new(dofs: usize) -> Self {
        Self {
            constrained: vec![false; dofs],
            list: Vec::new(),
            targets: vec![0.0; dofs],
            forces: vec![0.0; dofs],
        }
    }

    /// Holds dof `d` at displacement `value`; a dof out of range is an error.
    pub fn hold(&mut self, d: usize, value: Real) -> Result<(), SimError> {
        let n = self.constrained.len();
        let (Some(held), Some(target)) = (self.constrained.get_mut(d), self.targets.get_mut(d))
        else {
            return Err(SimError::BadParameter {
                name: "held",
                value: format!("dof {d}"),
                reason: format!("the model has {n} dofs"),
            });
        };
        if !*held {
            *held = true;
            self.list.push(d);
        }
        *target = value;
        Ok(())
    }

    /// Holds the three dofs of `node` at displacement `d`.
    pub(crate) fn hold_node(&mut self, node: usize, d: Vec3) -> Result<(), SimError> {
        for k in 0..3 {
            self.hold(3 * node + k, d[k])?;
        }
        Ok(())
    }

    /// Sorts the held list (after a series of `hold`).
    pub fn finish(&mut self) {
        self.list.sort_unstable();
    }
}

/// K, its constrained copy, the factorisation cache and the work buffers.
pub struct System {
    pub assembler: Assembler,
    /// The assembled stiffness, pattern `assembler.pattern`.
    pub k: Vec<Real>,
    a: Vec<Real>,
    diag: Vec<usize>,
    chol: SparseCholesky,
    factored_for: Option<Vec<bool>>,
    rhs: Vec<Real>,
    rest: Vec<Vec3>,
    component: Vec<u32>,
    components: usize,
    /// Numeric factorisations done so far.
    pub refactorizations: usize,
    /// Solves done so far.
    pub solves: usize,
    /// Skips the rigid-mode check: for K + cM (dynamics), definite even for a free body.
    pub allow_free_body: bool,
}

impl System {
    /// Takes the assembled stiffness `k` of `assembler`'s pattern over nodes at `rest`.
    pub fn new(assembler: Assembler, k: Vec<Real>, rest: Vec<Vec3>) -> Result<Self, SimError> {
        let chol = SparseCholesky::with_positions(&assembler.pattern, &rest)?;
        let diag = assembler.pattern.diagonal_slots();
        let (component, components) = connected_components(&assembler, rest.len());
        let n = assembler.pattern.dim();
        Ok(Self {
            a: k.clone(),
            k,
            diag,
            chol,
            factored_for: None,
            rhs: vec![0.0; n],
            rest,
            component,
            components,
            refactorizations: 0,
            solves: 0,
            allow_free_body: false,
            assembler,
        })
    }

    /// Replaces the matrix values (same pattern); the next solve refactorises.
    pub fn set_values(&mut self, k: &[Real]) {
        self.k.copy_from_slice(k);
        self.factored_for = None;
    }

    pub fn dofs(&self) -> usize {
        self.assembler.pattern.dim()
    }

    pub fn factor_nnz(&self) -> usize {
        self.chol.factor_nnz()
    }

    /// Solves `p` into `u` (length dofs) and the reactions f − K u on held dofs (zero on free
    /// ones) into `r`. On error `u` and `r` may hold partial results; callers solve into
    /// scratch buffers and keep their state.
    pub fn solve(
        &mut self,
        p: &DofProblem,
        u: &mut [Real],
        r: &mut [Real],
    ) -> Result<(), SimError> {
        let n = self.dofs();
        if p.constrained.len() != n || p.targets.len() != n || p.forces.len() != n {
            return Err(SimError::BadParameter {
                name: "problem",
                value: format!("{} dofs", p.constrained.len()),
                reason: format!("the model has {n} dofs"),
            });
        }
        // The fields are public: check that the list is exactly the held dofs, once each.
        let held = p.constrained.iter().filter(|&&h| h).count();
        if held != p.list.len()
            || p.list.windows(2).any(|w| w[0] >= w[1])
            || p.list
                .iter()
                .any(|&c| !p.constrained.get(c).copied().unwrap_or(false))
        {
            return Err(SimError::BadParameter {
                name: "problem",
                value: format!("{} held dofs listed, {held} marked", p.list.len()),
                reason: "the list must hold each marked dof once, ascending (call finish)".into(),
            });
        }
        if self.factored_for.as_deref() != Some(p.constrained.as_slice()) {
            self.factored_for = None;
            if !self.allow_free_body {
                self.check_rigid_modes(p)?;
            }
            self.eliminate(p);
            self.chol
                .factorize(&self.assembler.pattern, &self.a, FREE_BODY_HINT)?;
            self.refactorizations += 1;
            self.factored_for = Some(p.constrained.clone());
        }
        let (cp, ri) = (
            &self.assembler.pattern.col_ptr,
            &self.assembler.pattern.row_idx,
        );
        self.rhs.copy_from_slice(&p.forces);
        for &c in &p.list {
            let g = p.targets[c];
            if g != 0.0 {
                let range = cp[c]..cp[c + 1];
                for (&row, &kv) in ri[range.clone()].iter().zip(&self.k[range]) {
                    self.rhs[row] -= kv * g;
                }
            }
        }
        for &c in &p.list {
            self.rhs[c] = self.k[self.diag[c]] * p.targets[c];
        }
        self.chol.solve_in_place(&mut self.rhs)?;
        self.solves += 1;
        u.copy_from_slice(&self.rhs);
        for &c in &p.list {
            u[c] = p.targets[c];
        }
        if let Some(d) = u.iter().position(|v| !v.is_finite()) {
            return Err(SimError::Diverged {
                step: self.solves as u64,
                node: d / 3,
                reason: "the linear solve gave a non-finite displacement".into(),
            });
        }
        r.iter_mut().for_each(|v| *v = 0.0);
        // Row c of K is column c (K is symmetric).
        for &c in &p.list {
            let range = cp[c]..cp[c + 1];
            let ku: Real = ri[range.clone()]
                .iter()
                .zip(&self.k[range])
                .map(|(&row, &kv)| kv * u[row])
                .sum();
            r[c] = p.forces[c] - ku;
        }
        Ok(())
    }

    /// Builds the constrained matrix in `a` from `k`.
    fn eliminate(&mut self, p: &DofProblem) {
        let (cp, ri) = (
            &self.assembler.pattern.col_ptr,
            &self.assembler.pattern.row_idx,
        );
        for col in 0..self.dofs() {
            let held = p.constrained[col];
            let range = cp[col]..cp[col + 1];
            let rows = ri[range.clone()].iter().zip(&self.k[range.clone()]);
            for (a, (&row, &kv)) in self.a[range].iter_mut().zip(rows) {
                // Off-diagonal entries in a held row or column vanish.
                *a = if row != col && (held || p.constrained[row]) {
                    0.0
                } else {
                    kv
                };
            }
        }
    }

    /// Fails when the held dofs of some connected piece leave one of its six rigid motions
    /// (three translations, three rotations about its centroid) free.
    fn check_rigid_modes(&self, p: &DofProblem) -> Result<(), SimError> {
        let nc = self.components;
        let mut centroid = vec![Vec3::ZERO; nc];
        let mut count = vec![0usize; nc];
        for (x, &c) in self.rest.iter().zip(&self.component) {
            centroid[c as usize] += *x;
            count[c as usize] += 1;
        }
        for (c, n) in centroid.iter_mut().zip(&count) {
            *c /= (*n).max(1) as Real;
        }
        let mut radius2 = vec![0.0; nc];
        for (x, &c) in self.rest.iter().zip(&self.component) {
            radius2[c as usize] += (*x - centroid[c as usize]).length_squared();
        }
        let mut gram = vec![[[0.0; 6]; 6]; nc];
        for &d in &p.list {
            let (node, axis) = (d / 3, d % 3);
            let c = self.component[node] as usize;
            let scale = (radius2[c] / count[c].max(1) as Real)
                .sqrt()
                .max(Real::MIN_POSITIVE);
            let x = (self.rest[node] - centroid[c]) / scale;
            // Row of dof d in the rigid-mode basis: translation e_axis, rotation e_k × x.
            let mut row = [0.0; 6];
            row[axis] = 1.0;
            for k in 0..3 {
                let mut w = Vec3::ZERO;
                w[k] = 1.0;
                row[3 + k] = w.cross(x)[axis];
            }
            for i in 0..6 {
                for j in 0..6 {
                    gram[c][i][j] += row[i] * row[j];
                }
            }
        }
        for (c, g) in gram.iter().enumerate() {
            let m = faer::Mat::<Real>::from_fn(6, 6, |i, j| g[i][j]);
            let eig = m
                .self_adjoint_eigenvalues(faer::Side::Lower)
                .unwrap_or_else(|_| vec![0.0; 6]);
            let max = eig.iter().copied().fold(0.0, Real::max);
            let min = eig.iter().copied().fold(Real::INFINITY, Real::min);
            if !(max > 0.0 && min > 1e-10 * max) {
                let node = self
                    .component
                    .iter()
                    .position(|&k| k as usize == c)
                    .unwrap_or(0);
                return Err(SimError::NotPositiveDefinite {
                    row: 3 * node,
                    hint: format!(
                        "{FREE_BODY_HINT} (piece {c} of {nc}, containing node {node}, can still \
                         move rigidly)"
                    ),
                });
            }
        }
        Ok(())
    }
}

/// Connected pieces of the mesh (nodes sharing an element), by union-find.
fn connected_components(assembler: &Assembler, nodes: usize) -> (Vec<u32>, usize) {
    let mut parent: Vec<u32> = (0..nodes as u32).collect();
    fn find(parent: &mut [u32], mut a: u32) -> u32 {
        while parent[a as usize] != a {
            let up = parent[parent[a as usize] as usize];
            parent[a as usize] = up;
            a = up;
        }
        a
    }
    for e in 0..assembler.element_count() {
        let el = assembler.element(e);
        let r0 = find(&mut parent, el[0]);
        for &n in &el[1..] {
            let r = find(&mut parent, n);
            if r != r0 {
                parent[r as usize] = r0;
            }
        }
    }
    let mut label = vec![u32::MAX; nodes];
    let mut component = vec![0u32; nodes];
    let mut count = 0u32;
    for (n, comp) in component.iter_mut().enumerate() {
        let r = find(&mut parent, n as u32) as usize;
        if label[r] == u32::MAX {
            label[r] = count;
            count += 1;
        }
        *comp = label[r];
    }
    (component, count as usize)
}
