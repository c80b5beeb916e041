//! Sparse symmetric matrices with a pattern built once, and a sparse Cholesky wrapper over faer.
//!
//! The pattern is that of a finite-element matrix with `block` unknowns per node: node `a`
//! couples with node `b` when some element contains both, and then all `block × block`
//! unknowns couple. Both triangles are stored (the full matrix is needed for products such as
//! reactions `f − K u`); the factorisation reads only the lower one.
//!
//! `SparseCholesky` keeps the symbolic factorisation (fill-reducing ordering and the pattern
//! of L), the numeric values and the work memory, so that refactorising a matrix with the same
//! pattern and solving allocate nothing. faer computes the factor; a supernodal factor is
//! solved by `tree_solve` (our loops, the elimination tree's subtrees on two threads when
//! measured faster), a simplicial one by faer.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    CholeskySymbolicParams, LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
    factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par, Side};

use crate::error::SimError;
use crate::math::{Real, Vec3};

use super::tree_solve::TreeSolve;

/// The compressed-column pattern of a symmetric matrix with `block` unknowns per node.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockPattern {
    /// Unknowns per node (3 for displacements).
    pub block: usize,
    /// `node_ptr[a]..node_ptr[a+1]` indexes `node_adj`: the nodes coupled with `a`, ascending
    /// (including `a` itself).
    pub node_ptr: Vec<usize>,
    pub node_adj: Vec<u32>,
    /// Column starts of the scalar matrix (length `block · nodes + 1`).
    pub col_ptr: Vec<usize>,
    /// Row of each stored value, ascending within a column.
    pub row_idx: Vec<usize>,
}

impl BlockPattern {
    /// The pattern of the elements `elements` (flat, `nodes_per_element` node ids each) over
    /// `nodes` nodes. Every node gets a diagonal block, even one that no element uses.
    /// Node ids must be `< nodes` (callers validate meshes first).
    pub fn from_elements(
        nodes: usize,
        block: usize,
        elements: &[u32],
        nodes_per_element: usize,
    ) -> Self {
        let per = nodes_per_element.max(1);
        // Count with repetitions, fill, then sort and deduplicate each node's list in place.
        let mut count = vec![1usize; nodes];
        for e in elements.chunks_exact(per) {
            for &a in e {
                count[a as usize] += per;
            }
        }
        let mut start = Vec::with_capacity(nodes + 1);
        start.push(0);
        for c in &count {
            start.push(start.last().copied().unwrap_or(0) + c);
        }
        let mut fill: Vec<usize> = start[..nodes].to_vec();
        let mut raw = vec![0u32; start[nodes]];
        for a in 0..nodes {
            raw[fill[a]] = a as u32;
            fill[a] += 1;
        }
        for e in elements.chunks_exact(per) {
            for &a in e {
                let slot = &mut fill[a as usize];
                raw[*slot..*slot + per].copy_from_slice(e);
                *slot += per;
            }
        }
        let mut node_ptr = Vec::with_capacity(nodes + 1);
        let mut node_adj = Vec::new();
        node_ptr.push(0);
        for a in 0..nodes {
            let list = &mut raw[start[a]..start[a + 1]];
            list.sort_unstable();
            let mut last = u32::MAX;
            for &b in list.iter() {
                if b != last {
                    node_adj.push(b);
                    last = b;
                }
            }
            node_ptr.push(node_adj.len());
        }
        let n = nodes * block;
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::with_capacity(node_adj.len() * block * block);
        col_ptr.push(0);
        for a in 0..nodes {
            for _ in 0..block {
                for &b in &node_adj[node_ptr[a]..node_ptr[a + 1]] {
                    row_idx.extend((0..block).map(|j| b as usize * block + j));
                }
                col_ptr.push(row_idx.len());
            }
        }
        Self {
            block,
            node_ptr,
            node_adj,
            col_ptr,
            row_idx,
        }
    }

    /// Number of scalar rows (= columns).
    pub fn dim(&self) -> usize {
        self.col_ptr.len() - 1
    }

    /// Number of stored values.
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Position of node `b` among the neighbours of node `a`, if they are coupled.
    pub fn neighbour_position(&self, a: usize, b: usize) -> Option<usize> {
        let list = self
            .node_adj
            .get(*self.node_ptr.get(a)?..*self.node_ptr.get(a + 1)?)?;
        list.binary_search(&(b as u32)).ok()
    }

    /// Index into the values of entry (row, col), if it is in the pattern.
    pub fn slot(&self, row: usize, col: usize) -> Option<usize> {
        let b = self.block;
        let pos = self.neighbour_position(col / b, row / b)?;
        Some(self.col_ptr[col] + pos * b + row % b)
    }

    /// The diagonal's value index of every column.
    pub fn diagonal_slots(&self) -> Vec<usize> {
        (0..self.dim())
            .map(|c| self.slot(c, c).unwrap_or(usize::MAX))
            .collect()
    }

    /// A faer matrix with this pattern and the given values (`values.len() == nnz()`).
    pub fn to_faer(&self, values: &[Real]) -> Result<SparseColMat<usize, Real>, SimError> {
        if values.len() != self.nnz() {
            return Err(internal("value count does not match the pattern"));
        }
        let n = self.dim();
        let symbolic = SymbolicSparseColMat::new_checked(
            n,
            n,
            self.col_ptr.clone(),
            None,
            self.row_idx.clone(),
        );
        Ok(SparseColMat::new(symbolic, values.to_vec()))
    }

    /// A borrowed faer view of this pattern with the given values.
    pub fn view<'a>(&'a self, values: &'a [Real]) -> SparseColMatRef<'a, usize, Real> {
        let n = self.dim();
        // SAFETY-free: the checked constructor validates the (sorted) pattern.
        let symbolic = faer::sparse::SymbolicSparseColMatRef::new_checked(
            n,
            n,
            &self.col_ptr,
            None,
            &self.row_idx,
        );
        SparseColMatRef::new(symbolic, values)
    }

    /// y = A x for a matrix with this pattern and `values`.
    pub fn mul_vec(&self, values: &[Real], x: &[Real], y: &mut [Real]) {
        y.iter_mut().for_each(|v| *v = 0.0);
        for (c, &xc) in x.iter().enumerate().take(self.dim()) {
            if xc == 0.0 {
                continue;
            }
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                y[self.row_idx[k]] += values[k] * xc;
            }
        }
    }
}

fn internal(what: &str) -> SimError {
    SimError::BadParameter {
        name: "matrix",
        value: String::new(),
        reason: what.to_string(),
    }
}

/// Smallest accepted ratio of a Cholesky pivot L_ii² to the matrix diagonal A_ii: below it the
/// matrix is singular to working precision (a rigid-body mode is left free). Genuine FEM
/// stiffness matrices stay far above it (a slender beam of aspect 100 has ratios ~1e-6).
const PIVOT_RATIO_MIN: Real = 1e-13;

/// The fill-reducing ordering of a factorisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ordering {
    /// Approximate minimum degree (faer's).
    Amd,
    /// Nested dissection of the node graph (`solve::ordering`).
    NestedDissection,
    /// Whichever of the two gives the smaller factor; AMD alone below
    /// `NESTED_DISSECTION_MIN_DIM` unknowns.
    Smaller,
    /// For a factor solved many times (a preconditioner): `Smaller` when the solves will
    /// run on one thread; with more (rayon's pool at build), whichever has the shorter
    /// critical path of a two-thread tree solve, its top counted serial (`TreeSolve::span`).
    ///
    /// Why the top counts serial though the tree solve splits it: the split waits about a
    /// hundred times per solve, and on a virtual machine a wait costs what the work
    /// saves. Measured on the 20k beam's warp factor (f32, `tree_solve_study`, both
    /// cores there): AMD 2,104 µs on one thread and 1,313 on two, nested dissection 2,215
    /// and 846; the spans so counted, 2.37M and 2.07M values, order them right, and those
    /// with the top split (1.92M and 2.07M) do not. A factor then depends on the thread
    /// count, so one and two threads agree to the iterative solve's tolerance, not to the
    /// bit.
    ForSolves,
}

/// Patterns with at least this many unknowns also get a nested-dissection analysis: below
/// it AMD's factor is small anyway and the second analysis would cost more than it saves.
const NESTED_DISSECTION_MIN_DIM: usize = 3000;

/// Supernodal factors with at least this many values are solved by `tree_solve` (our own
/// loops over the supernodes, the independent subtrees on two threads); smaller ones, and
/// simplicial factors, by faer's solve.
const TREE_MIN_VALUES: usize = 0;

/// The tree solve may run its groups on rayon's threads (when there are several, and when
/// `chooser` measures it faster) from this many factor values, and when its top and largest
/// group carry at most `PARALLEL_SPAN` of the work: below, waking a worker costs more than
/// half the solve saves.
const PARALLEL_MIN_VALUES: usize = 100_000;
const PARALLEL_SPAN: f64 = 0.75;

/// The threads a factor's solves may run on: rayon's pool at the call (one without the
/// `parallel` feature).
fn solve_threads() -> usize {
    #[cfg(feature = "parallel")]
    return rayon::current_num_threads();
    #[cfg(not(feature = "parallel"))]
    1
}

/// A node order of the pattern's nodes (`ordering`), expanded to their unknowns, as faer's
/// (forward: new → original, inverse) pair.
fn dof_permutation(pattern: &BlockPattern, nodes: &[u32]) -> (Vec<usize>, Vec<usize>) {
    let b = pattern.block;
    let fwd: Vec<usize> = nodes
        .iter()
        .flat_map(|&v| (0..b).map(move |k| b * v as usize + k))
        .collect();
    let mut inv = vec![0; fwd.len()];
    for (new, &old) in fwd.iter().enumerate() {
        inv[old] = new;
    }
    (fwd, inv)
}

/// A sparse Cholesky factorisation L Lᵀ = A of a symmetric positive definite matrix whose
/// pattern is fixed: `new` does the symbolic analysis; `factorize` can be called again for new
/// values; `solve_in_place` reuses its memory.
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<Real>,
    factor_mem: MemBuffer,
    solve_mem: MemBuffer,
    diag_slots: Vec<usize>,
    factored: bool,
    /// The supernodal solve split by the elimination tree (`tree_solve`), for factors of
    /// at least `TREE_MIN_VALUES` values.
    tree: Option<TreeSolve>,
    /// Whether `tree` may run its groups on rayon's threads (size and split permitting).
    parallel: bool,
    /// Whether it does, measured (`chooser`): the same bits either way.
    chooser: super::chooser::Chooser,
    /// A single-precision copy of L that the tree solve reads instead of `l_values`
    /// (`single_precision_solves`).
    single: Option<Vec<f32>>,
    /// Whether every solve reads `single` (`single_precision_solves`), or only
    /// `precondition_in_place`'s.
    single_always: bool,
    /// Tests: the tree's groups on rayon's threads always (`Some(true)`), never, or by size.
    #[cfg(test)]
    force_parallel: Option<bool>,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("dim", &self.symbolic.nrows())
            .field("factor_nnz", &self.l_values.len())
            .field("factored", &self.factored)
            .finish()
    }
}

impl SparseCholesky {
    /// Symbolic analysis (ordering, elimination tree, supernodes) of the pattern. The
    /// ordering is AMD (faer's).
    pub fn new(pattern: &BlockPattern) -> Result<Self, SimError> {
        Self::with_ordering(pattern, &[], Ordering::Amd)
    }

    /// `new` for a pattern whose node `a` sits at `positions[a]`: AMD, or geometric nested
    /// dissection when the pattern is large enough for it to matter and it gives the smaller
    /// factor (`solve::ordering`). Large 3-D meshes factorise several times faster with it.
    pub fn with_positions(pattern: &BlockPattern, positions: &[Vec3]) -> Result<Self, SimError> {
        Self::with_ordering(pattern, positions, Ordering::Smaller)
    }

    /// `with_positions` for a factor solved many times: `Ordering::ForSolves`.
    pub fn for_solves(pattern: &BlockPattern, positions: &[Vec3]) -> Result<Self, SimError> {
        Self::with_ordering(pattern, positions, Ordering::ForSolves)
    }

    /// With the ordering chosen by the caller (tests and studies compare them). Nested
    /// dissection needs every node's position; without them it is AMD.
    pub fn with_ordering(
        pattern: &BlockPattern,
        positions: &[Vec3],
        ordering: Ordering,
    ) -> Result<Self, SimError> {
        Self::build(
            pattern,
            positions,
            ordering,
            Default::default(),
            TREE_MIN_VALUES,
        )
    }

    /// `with_ordering` with faer's symbolic parameters (tests force a supernodal factor) and
    /// the smallest factor solved by the tree solve.
    fn build(
        pattern: &BlockPattern,
        positions: &[Vec3],
        ordering: Ordering,
        params: CholeskySymbolicParams<'_>,
        tree_min_values: usize,
    ) -> Result<Self, SimError> {
        let ordering = if positions.len() * pattern.block < pattern.dim() {
            Ordering::Amd
        } else {
            ordering
        };
        let n = pattern.dim();
        let sym = faer::sparse::SymbolicSparseColMatRef::new_checked(
            n,
            n,
            &pattern.col_ptr,
            None,
            &pattern.row_idx,
        );
        fn analyse_with(
            sym: faer::sparse::SymbolicSparseColMatRef<'_, usize>,
            ord: SymmetricOrdering<'_, usize>,
            params: CholeskySymbolicParams<'_>,
        ) -> Result<SymbolicCholesky<usize>, SimError> {
            factorize_symbolic_cholesky(sym, Side::Lower, ord, params)
                .map_err(|e| internal(&format!("symbolic Cholesky failed: {e:?}")))
        }
        let nested = || {
            let nodes =
                super::ordering::nested_dissection(&pattern.node_ptr, &pattern.node_adj, positions);
            let (fwd, inv) = dof_permutation(pattern, &nodes);
            analyse_with(
                sym,
                SymmetricOrdering::Custom(faer::perm::PermRef::new_checked(&fwd, &inv, n)),
                params,
            )
        };
        let symbolic = match ordering {
            Ordering::Amd => analyse_with(sym, SymmetricOrdering::Amd, params)?,
            Ordering::NestedDissection => nested()?,
            Ordering::Smaller | Ordering::ForSolves => {
                let amd = analyse_with(sym, SymmetricOrdering::Amd, params)?;
                if n >= NESTED_DISSECTION_MIN_DIM {
                    let nd = nested()?;
                    let by_span = ordering == Ordering::ForSolves && solve_threads() > 1;
                    let span = |s: &SymbolicCholesky<usize>| match s.raw() {
                        SymbolicCholeskyRaw::Supernodal(raw) => {
                            TreeSolve::new(raw, s.perm().map(|p| p.arrays().0))
                                .map(|t| t.span(s.len_val()))
                        }
                        SymbolicCholeskyRaw::Simplicial(_) => None,
                    };
                    let nd_first = match (by_span, span(&nd), span(&amd)) {
                        (true, Some(a), Some(b)) => a < b,
                        _ => nd.len_val() < amd.len_val(),
                    };
                    if nd_first { nd } else { amd }
                } else {
                    amd
                }
            }
        };
        let par = Par::Seq;
        let factor_mem = MemBuffer::try_new(
            symbolic.factorize_numeric_llt_scratch::<Real>(par, Default::default()),
        )
        .map_err(|_| internal("out of memory for the Cholesky work space"))?;
        let solve_mem = MemBuffer::try_new(symbolic.solve_in_place_scratch::<Real>(1, par))
            .map_err(|_| internal("out of memory for the Cholesky work space"))?;
        let l_values = vec![0.0; symbolic.len_val()];
        let tree = match symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) if s.len_val() >= tree_min_values && n > 0 => {
                TreeSolve::new(s, symbolic.perm().map(|p| p.arrays().0))
            }
            _ => None,
        };
        let parallel = tree
            .as_ref()
            .is_some_and(|t| symbolic.len_val() >= PARALLEL_MIN_VALUES && t.splits(PARALLEL_SPAN));
        Ok(Self {
            symbolic,
            l_values,
            factor_mem,
            solve_mem,
            diag_slots: pattern.diagonal_slots(),
            factored: false,
            tree,
            parallel,
            chooser: Default::default(),
            single: None,
            single_always: false,
            #[cfg(test)]
            force_parallel: None,
        })
    }

    /// Stored values of L (the factor's size).
    pub fn factor_nnz(&self) -> usize {
        self.l_values.len()
    }

    /// True when faer chose the supernodal (dense-block) factorisation over the simplicial one.
    pub fn is_supernodal(&self) -> bool {
        matches!(self.symbolic.raw(), SymbolicCholeskyRaw::Supernodal(_))
    }

    /// Whether solves go through `tree_solve`, and whether its groups run on rayon's
    /// threads when there are several (the same bits either way).
    pub fn tree_solve(&self) -> (bool, bool) {
        (self.tree.is_some(), self.parallel)
    }

    /// The tree solve's top supernodes (columns, rows), if it is used.
    pub fn tree_top_shape(&self) -> Option<Vec<(u32, u32)>> {
        self.tree.as_ref().map(TreeSolve::top_shape)
    }

    /// How many of the tree solve's top supernodes are split between two threads.
    pub fn tree_split_supernodes(&self) -> usize {
        self.tree.as_ref().map_or(0, TreeSolve::split_supernodes)
    }

    /// The tree solve's work estimates (whole, serial top, largest group), if it is used.
    pub fn tree_work(&self) -> Option<(u64, u64, u64)> {
        self.tree.as_ref().map(TreeSolve::work)
    }

    /// True after a successful `factorize`.
    pub fn is_factored(&self) -> bool {
        self.factored
    }

    /// Numeric factorisation of `values` (same pattern as given to `new`). A matrix that is
    /// not positive definite, or singular to working precision, gives
    /// `SimError::NotPositiveDefinite` naming an original row and carrying `hint`.
    pub fn factorize(
        &mut self,
        pattern: &BlockPattern,
        values: &[Real],
        hint: &str,
    ) -> Result<(), SimError> {
        self.factored = false;
        if values.len() != pattern.nnz() || pattern.dim() != self.symbolic.nrows() {
            return Err(internal("matrix does not match the analysed pattern"));
        }
        let a = pattern.view(values);
        let result = self.symbolic.factorize_numeric_llt::<Real>(
            &mut self.l_values,
            a,
            Side::Lower,
            Default::default(),
            Par::Seq,
            MemStack::new(&mut self.factor_mem),
            Default::default(),
        );
        let perm_fwd = self.symbolic.perm().map(|p| p.arrays().0);
        let original = |i: usize| perm_fwd.and_then(|f| f.get(i).copied()).unwrap_or(i);
        if let Err(e) = result {
            let faer::linalg::solvers::LltError::NonPositivePivot { index } = e;
            return Err(SimError::NotPositiveDefinite {
                row: original(index),
                hint: hint.to_string(),
            });
        }
        // Roundoff can leave a tiny positive pivot where the matrix is singular: compare each
        // pivot with the diagonal it came from.
        if let Some(row) = self.small_pivot(values, &original) {
            return Err(SimError::NotPositiveDefinite {
                row,
                hint: hint.to_string(),
            });
        }
        if let Some(single) = &mut self.single {
            single.clear();
            single.extend(self.l_values.iter().map(|&v| v as f32));
        }
        self.factored = true;
        Ok(())
    }

    /// Solves (`solve_in_place`) with a single-precision copy of L, for a preconditioner:
    /// the solve streams half the bytes (it is memory-bound: on the 20k beam's warp factor,
    /// 32 MB of f64 against a 32 MB L3), the arithmetic stays f64, and forward and backward
    /// read the same rounded L̃, so what is solved is exactly L̃ L̃ᵀ, symmetric positive
    /// definite (relative error of L̃ 6e-8, far below a CG tolerance). Only the tree solve
    /// reads it (supernodal factors); `solve_many_in_place` stays in f64. Takes effect from
    /// the present factor on.
    pub fn single_precision_solves(&mut self, on: bool) {
        let l = &self.l_values;
        self.single = (on && self.tree.is_some()).then(|| l.iter().map(|&v| v as f32).collect());
        self.single_always = on;
    }

    /// Solves with the single-precision copy of L (`single_precision_solves`, made at the
    /// first call and kept with every factorisation) while `solve_in_place` stays exact: for
    /// a factor that serves both as a direct solver and as a preconditioner (the split
    /// damping's rest factor, `integrate::split_damping`).
    pub fn precondition_in_place(&mut self, rhs: &mut [Real]) -> Result<(), SimError> {
        if self.single.is_none() && self.tree.is_some() {
            let l = &self.l_values;
            self.single = Some(l.iter().map(|&v| v as f32).collect());
        }
        self.solve_with(rhs, true)
    }

    fn small_pivot(&self, values: &[Real], original: &dyn Fn(usize) -> usize) -> Option<usize> {
        let ratio = |i: usize, lii: Real| {
            let row = original(i);
            let aii = self
                .diag_slots
                .get(row)
                .and_then(|&s| values.get(s))
                .copied()?;
            let ok = aii > 0.0 && lii * lii >= PIVOT_RATIO_MIN * aii;
            (!ok).then_some(row)
        };
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                // Each column of L starts with its diagonal.
                let cp = s.col_ptr();
                (0..s.nrows()).find_map(|j| ratio(j, *self.l_values.get(cp[j])?))
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                let l = faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef::<
                    '_,
                    usize,
                    Real,
                >::new(s, &self.l_values);
                (0..s.n_supernodes()).find_map(|k| {
                    let sn = l.supernode(k);
                    let v = sn.val();
                    (0..v.ncols()).find_map(|c| ratio(sn.start() + c, v[(c, c)]))
                })
            }
        }
    }

    /// Solves A x = b in place (`rhs` holds b, then x). Allocates nothing.
    pub fn solve_in_place(&mut self, rhs: &mut [Real]) -> Result<(), SimError> {
        self.solve_with(rhs, self.single_always)
    }

    /// `solve_in_place`, reading the f32 copy of L when `single` and there is one.
    fn solve_with(&mut self, rhs: &mut [Real], single: bool) -> Result<(), SimError> {
        if !self.factored {
            return Err(internal("solve before a successful factorisation"));
        }
        let n = self.symbolic.nrows();
        if rhs.len() != n {
            return Err(internal("right-hand side length does not match the matrix"));
        }
        if let Some(tree) = self.tree.as_mut() {
            #[cfg(feature = "parallel")]
            let may = self.parallel && rayon::current_num_threads() > 1;
            #[cfg(not(feature = "parallel"))]
            let may = false;
            #[cfg(test)]
            let may = may || self.force_parallel == Some(true);
            let single = self.single.as_deref().filter(|_| single);
            let mut solve = |parallel| match single {
                Some(l) => tree.solve(l, rhs, parallel),
                None => tree.solve(&self.l_values, rhs, parallel),
            };
            if !may {
                solve(false);
                return Ok(());
            }
            let parallel = self.chooser.pick();
            #[cfg(test)]
            let parallel = self.force_parallel.unwrap_or(parallel);
            let start = std::time::Instant::now();
            solve(parallel);
            self.chooser.record(parallel, start.elapsed());
            return Ok(());
        }
        self.faer_solve(rhs);
        Ok(())
    }

    /// faer's supernodal or simplicial solve, with its permutation.
    fn faer_solve(&mut self, rhs: &mut [Real]) {
        let n = self.symbolic.nrows();
        let llt = LltRef::<'_, usize, Real>::new(&self.symbolic, &self.l_values);
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, 1),
            Par::Seq,
            MemStack::new(&mut self.solve_mem),
        );
    }

    /// Solves A X = B in place for `ncols` right-hand sides stored column after column in
    /// `rhs` (length `ncols · dim`). One blocked pass over the factor serves every column,
    /// which is several times cheaper per column than `solve_in_place` on each. Allocates
    /// its work memory.
    pub fn solve_many_in_place(&self, rhs: &mut [Real], ncols: usize) -> Result<(), SimError> {
        if !self.factored {
            return Err(internal("solve before a successful factorisation"));
        }
        let n = self.symbolic.nrows();
        if rhs.len() != n * ncols {
            return Err(internal("right-hand side length does not match the matrix"));
        }
        let par = Par::Seq;
        let mut mem = MemBuffer::try_new(self.symbolic.solve_in_place_scratch::<Real>(ncols, par))
            .map_err(|_| internal("out of memory for the Cholesky work space"))?;
        let llt = LltRef::<'_, usize, Real>::new(&self.symbolic, &self.l_values);
        llt.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, ncols),
            par,
            MemStack::new(&mut mem),
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of 2-node "springs" over `n` nodes with one scalar unknown each.
    fn chain(n: usize) -> BlockPattern {
        let elements: Vec<u32> = (0..n as u32 - 1).flat_map(|i| [i, i + 1]).collect();
        BlockPattern::from_elements(n, 1, &elements, 2)
    }

    /// The values of the 1-D Laplacian tridiag(−1, 2, −1) on the chain's pattern.
    fn laplacian(p: &BlockPattern) -> Vec<Real> {
        let mut v = vec![0.0; p.nnz()];
        for c in 0..p.dim() {
            let range = p.col_ptr[c]..p.col_ptr[c + 1];
            for (x, &r) in v[range.clone()].iter_mut().zip(&p.row_idx[range]) {
                *x = if r == c { 2.0 } else { -1.0 };
            }
        }
        v
    }

    #[test]
    fn pattern_of_two_triangles() {
        let p = BlockPattern::from_elements(4, 2, &[0, 1, 2, 2, 1, 3], 3);
        assert_eq!(p.node_adj, vec![0, 1, 2, 0, 1, 2, 3, 0, 1, 2, 3, 1, 2, 3]);
        assert_eq!(p.dim(), 8);
        assert_eq!(p.nnz(), 2 * 2 * 14);
        assert_eq!(&p.col_ptr[..4], &[0, 6, 12, 20]);
        assert_eq!(&p.row_idx[12..20], &[0, 1, 2, 3, 4, 5, 6, 7]);
        assert_eq!(p.slot(7, 2), Some(19));
        assert_eq!(p.slot(6, 0), None);
    }

    #[test]
    fn cholesky_solves_the_laplacian_and_refactorises() {
        let n = 50;
        let p = chain(n);
        let mut chol = SparseCholesky::new(&p).unwrap();
        let v = laplacian(&p);
        chol.factorize(&p, &v, "").unwrap();
        // A x = e_0 has the solution x_i = (n − i) / (n + 1).
        let mut x = vec![0.0; n];
        x[0] = 1.0;
        chol.solve_in_place(&mut x).unwrap();
        for (i, xi) in x.iter().enumerate() {
            let want = (n - i) as Real / (n + 1) as Real;
            assert!((xi - want).abs() < 1e-13, "{i}: {xi} vs {want}");
        }
        // Same pattern, doubled values: half the solution.
        let v2: Vec<Real> = v.iter().map(|a| 2.0 * a).collect();
        chol.factorize(&p, &v2, "").unwrap();
        let mut y = vec![0.0; n];
        y[0] = 1.0;
        chol.solve_in_place(&mut y).unwrap();
        assert!((y[0] - x[0] / 2.0).abs() < 1e-14);
        let mut ax = vec![0.0; n];
        p.mul_vec(&v2, &y, &mut ax);
        assert!((ax[0] - 1.0).abs() < 1e-12 && ax[1..].iter().all(|a| a.abs() < 1e-12));
    }

    #[test]
    fn indefinite_and_singular_matrices_are_named() {
        let n = 30;
        let p = chain(n);
        let mut chol = SparseCholesky::new(&p).unwrap();
        // Row 17 with a negative diagonal: not positive definite.
        let mut v = laplacian(&p);
        let s = p.slot(17, 17).unwrap();
        v[s] = -3.0;
        match chol.factorize(&p, &v, "hint here") {
            Err(SimError::NotPositiveDefinite { hint, .. }) => assert_eq!(hint, "hint here"),
            other => panic!("{other:?}"),
        }
        assert!(chol.solve_in_place(&mut vec![0.0; n]).is_err());
        // The free chain (Neumann Laplacian, diag 1 at the ends) is singular: constants.
        let mut v = laplacian(&p);
        for end in [0, n - 1] {
            let s = p.slot(end, end).unwrap();
            v[s] = 1.0;
        }
        assert!(matches!(
            chol.factorize(&p, &v, ""),
            Err(SimError::NotPositiveDefinite { .. })
        ));
    }

    /// An n×n×n grid of tetrahedra-like 27-point node couplings (every node with the nodes of
    /// its surrounding cells), 3 unknowns per node: the pattern of a 3-D mesh.
    fn cube(n: usize) -> (BlockPattern, Vec<Vec3>) {
        let id = |i: usize, j: usize, k: usize| (i + n * (j + n * k)) as u32;
        let mut elements = Vec::new();
        for k in 0..n - 1 {
            for j in 0..n - 1 {
                for i in 0..n - 1 {
                    for c in 0..8 {
                        elements.push(id(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2)));
                    }
                }
            }
        }
        let positions = (0..n * n * n)
            .map(|v| {
                Vec3::new(
                    (v % n) as Real,
                    ((v / n) % n) as Real,
                    (v / (n * n)) as Real,
                )
            })
            .collect();
        (
            BlockPattern::from_elements(n * n * n, 3, &elements, 8),
            positions,
        )
    }

    /// SPD values on a pattern: a graph Laplacian (−1 off the diagonal between coupled
    /// unknowns of the same axis, −0.1 between axes) plus a diagonal large enough to dominate.
    fn spd(p: &BlockPattern) -> Vec<Real> {
        let mut v = vec![0.0; p.nnz()];
        for c in 0..p.dim() {
            let range = p.col_ptr[c]..p.col_ptr[c + 1];
            let count = range.len() as Real;
            for (x, &r) in v[range.clone()].iter_mut().zip(&p.row_idx[range]) {
                *x = if r == c {
                    count + 1.0
                } else if r % 3 == c % 3 {
                    -1.0
                } else {
                    -0.1 * ((r + c) % 7) as Real / 7.0
                };
            }
        }
        v
    }

    /// Both orderings solve the same system to the same answer, and on a 3-D mesh pattern
    /// nested dissection leaves the smaller factor (why the default considers it).
    #[test]
    fn nested_dissection_and_amd_solve_the_same_system() {
        let (p, positions) = cube(14);
        let v = spd(&p);
        let b: Vec<Real> = (0..p.dim())
            .map(|i| ((i * 37) % 11) as Real - 5.0)
            .collect();
        let mut solutions = Vec::new();
        let mut sizes = Vec::new();
        for ordering in [Ordering::Amd, Ordering::NestedDissection, Ordering::Smaller] {
            let mut chol = SparseCholesky::with_ordering(&p, &positions, ordering).unwrap();
            chol.factorize(&p, &v, "").unwrap();
            let mut x = b.clone();
            chol.solve_in_place(&mut x).unwrap();
            let mut ax = vec![0.0; p.dim()];
            p.mul_vec(&v, &x, &mut ax);
            let res = ax
                .iter()
                .zip(&b)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, Real::max);
            assert!(res < 1e-10, "{ordering:?}: residual {res}");
            sizes.push(chol.factor_nnz());
            solutions.push(x);
        }
        for (x, y) in solutions[0].iter().zip(&solutions[1]) {
            assert!((x - y).abs() < 1e-11, "{x} vs {y}");
        }
        assert!(
            sizes[1] < sizes[0],
            "nested dissection {} ≥ AMD {}",
            sizes[1],
            sizes[0]
        );
        assert_eq!(sizes[2], sizes[0].min(sizes[1]));
    }

    /// Study (prints): factor size and time of both orderings on growing 3-D grids.
    /// `cargo test --release --workspace --lib ordering_study -- --ignored --nocapture`
    #[test]
    #[ignore = "a printing study of the orderings, tens of seconds"]
    fn ordering_study() {
        for n in [16, 24, 32] {
            let (p, positions) = cube(n);
            let v = spd(&p);
            for ordering in [Ordering::Amd, Ordering::NestedDissection] {
                let t = std::time::Instant::now();
                let mut chol = SparseCholesky::with_ordering(&p, &positions, ordering).unwrap();
                let analysis = t.elapsed().as_secs_f64();
                let t = std::time::Instant::now();
                chol.factorize(&p, &v, "").unwrap();
                println!(
                    "{n}^3 nodes, {} unknowns, {ordering:?}: factor {} values, analysis {analysis:.2} s, \
                     numeric {:.2} s",
                    p.dim(),
                    chol.factor_nnz(),
                    t.elapsed().as_secs_f64()
                );
            }
        }
    }

    /// A factor forced supernodal (faer keeps small or thin ones simplicial), solved by the
    /// tree from any size.
    fn supernodal(p: &BlockPattern, positions: &[Vec3], ordering: Ordering) -> SparseCholesky {
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold:
                faer::sparse::linalg::SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        };
        SparseCholesky::build(p, positions, ordering, params, 0).unwrap()
    }

    fn max_abs(x: &[Real]) -> Real {
        x.iter().fold(0.0, |m: Real, v| m.max(v.abs()))
    }

    /// The tree solve against faer's on `p` with SPD values: within 1e-12 of the largest
    /// unknown, the same bits on two threads as on one, and again after a refactorisation
    /// with other values (the work memory reused). Returns the tree's work split.
    fn check_tree(
        p: &BlockPattern,
        positions: &[Vec3],
        ordering: Ordering,
        what: &str,
    ) -> (u64, u64, u64) {
        let mut chol = supernodal(p, positions, ordering);
        let work = chol
            .tree_work()
            .unwrap_or_else(|| panic!("{what}: no tree solve"));
        for (round, scale) in [1.0, 3.0].into_iter().enumerate() {
            let v: Vec<Real> = spd(p).iter().map(|a| a * scale).collect();
            chol.factorize(p, &v, "").unwrap();
            let b: Vec<Real> = (0..p.dim())
                .map(|i| ((i * 37 + round * 5) % 11) as Real - 5.0)
                .collect();
            let mut want = b.clone();
            chol.faer_solve(&mut want);
            let mut serial = b.clone();
            chol.force_parallel = Some(false);
            chol.solve_in_place(&mut serial).unwrap();
            let err = max_abs(
                &serial
                    .iter()
                    .zip(&want)
                    .map(|(x, y)| x - y)
                    .collect::<Vec<_>>(),
            );
            assert!(
                err <= 1e-12 * max_abs(&want),
                "{what}: {err:e} from faer's solve (largest unknown {:e})",
                max_abs(&want)
            );
            #[cfg(feature = "parallel")]
            {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(2)
                    .build()
                    .unwrap();
                chol.force_parallel = Some(true);
                let mut parallel = b.clone();
                pool.install(|| chol.solve_in_place(&mut parallel).unwrap());
                assert!(
                    serial
                        .iter()
                        .zip(&parallel)
                        .all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{what}: two threads changed the bits"
                );
            }
            check_single_precision(&mut chol, &b, &want, what);
        }
        work
    }

    /// The single-precision copy of L solves within f32's rounding of the f64 answer, gives
    /// the same bits on one thread and two, and is a symmetric operator (forward and
    /// backward read the same rounded L̃): b₂ · M⁻¹b₁ = b₁ · M⁻¹b₂, what CG relies on.
    fn check_single_precision(chol: &mut SparseCholesky, b: &[Real], want: &[Real], what: &str) {
        chol.single_precision_solves(true);
        chol.force_parallel = Some(false);
        let solve = |chol: &mut SparseCholesky, rhs: &[Real]| {
            let mut x = rhs.to_vec();
            chol.solve_in_place(&mut x).unwrap();
            x
        };
        let x = solve(chol, b);
        let err = max_abs(&x.iter().zip(want).map(|(x, y)| x - y).collect::<Vec<_>>());
        assert!(
            err <= 1e-5 * max_abs(want),
            "{what}, f32: {err:e} from the f64 solve (largest unknown {:e})",
            max_abs(want)
        );
        let b2: Vec<Real> = (0..b.len()).map(|i| ((i * 13) % 7) as Real - 3.0).collect();
        let x2 = solve(chol, &b2);
        let (d12, d21) = (dot(&b2, &x), dot(b, &x2));
        assert!(
            (d12 - d21).abs() <= 1e-12 * d12.abs().max(d21.abs()),
            "{what}, f32: not symmetric, {d12:e} against {d21:e}"
        );
        #[cfg(feature = "parallel")]
        {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(2)
                .build()
                .unwrap();
            chol.force_parallel = Some(true);
            let two = pool.install(|| solve(chol, b));
            assert!(
                x.iter().zip(&two).all(|(x, y)| x.to_bits() == y.to_bits()),
                "{what}, f32: two threads changed the bits"
            );
        }
        chol.single_precision_solves(false);
    }

    fn dot(a: &[Real], b: &[Real]) -> Real {
        a.iter().zip(b).map(|(x, y)| x * y).sum()
    }

    /// Two separate cubes of `n`³ nodes side by side: a forest of two trees.
    fn two_cubes(n: usize) -> (BlockPattern, Vec<Vec3>) {
        let (one, pos) = cube(n);
        let nodes = pos.len();
        let mut elements = Vec::new();
        for a in 0..nodes {
            for &b in &one.node_adj[one.node_ptr[a]..one.node_ptr[a + 1]] {
                for shift in [0, nodes as u32] {
                    elements.extend([a as u32 + shift, b + shift]);
                }
            }
        }
        let positions = pos
            .iter()
            .copied()
            .chain(
                pos.iter()
                    .map(|q| *q + Vec3::new(2.0 * n as Real, 0.0, 0.0)),
            )
            .collect();
        (
            BlockPattern::from_elements(2 * nodes, 3, &elements, 2),
            positions,
        )
    }

    /// `ForSolves` is the smaller factor on one thread and the shorter critical path (top
    /// counted whole) on two: on the issue-24 20k beam, AMD (3.56M values, span 2.37M) on
    /// one, nested dissection (4.03M, span 2.07M) on two.
    #[test]
    fn for_solves_takes_the_smaller_factor_on_one_thread_and_the_shorter_span_on_two() {
        use crate::benchmark::beam::{BeamSpec, size_cells};
        let mesh = BeamSpec::new(size_cells("20k").unwrap()).mesh();
        let flat: Vec<u32> = mesh.tets.iter().flatten().copied().collect();
        let p = BlockPattern::from_elements(mesh.vertices.len(), 3, &flat, 4);
        let built = |ordering| SparseCholesky::with_ordering(&p, &mesh.vertices, ordering).unwrap();
        let (amd, nd) = (built(Ordering::Amd), built(Ordering::NestedDissection));
        let span = |c: &SparseCholesky| c.tree.as_ref().unwrap().span(c.factor_nnz());
        assert!(amd.factor_nnz() < nd.factor_nnz());
        assert!(span(&nd) < span(&amd), "{} {}", span(&nd), span(&amd));
        for (threads, want) in [(1, &amd), (2, &nd)] {
            let chosen = crate::benchmark::with_threads(Some(threads), || {
                SparseCholesky::for_solves(&p, &mesh.vertices).unwrap()
            })
            .unwrap();
            // Without rayon every solve is serial.
            let want = if cfg!(feature = "parallel") {
                want
            } else {
                &amd
            };
            assert_eq!(chosen.factor_nnz(), want.factor_nnz(), "{threads} threads");
        }
    }

    #[test]
    fn tree_solve_equals_faers_on_many_patterns() {
        // A chain, ordered by AMD and by nested dissection (a balanced tree).
        let n = 3000;
        let line: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as Real, 0.0, 0.0)).collect();
        check_tree(&chain(n), &line, Ordering::Amd, "chain, AMD");
        let (total, top, group) =
            check_tree(&chain(n), &line, Ordering::NestedDissection, "chain, ND");
        assert!(
            top + group < total * 3 / 4,
            "chain, ND: {top} + {group} of {total}"
        );
        // A 3-D grid both ways: nested dissection splits under its top separator. Their top
        // supernodes are large enough to be split between the threads themselves (forward
        // by rows in panels, backward by columns), so those paths are checked too.
        let (p, positions) = cube(10);
        let (total, top, group) =
            check_tree(&p, &positions, Ordering::NestedDissection, "grid, ND");
        assert!(
            top + group < total * 3 / 4,
            "grid, ND: {top} + {group} of {total}"
        );
        check_tree(&p, &positions, Ordering::Amd, "grid, AMD");
        for ordering in [Ordering::NestedDissection, Ordering::Amd] {
            let chol = supernodal(&p, &positions, ordering);
            assert!(
                chol.tree_split_supernodes() > 0,
                "grid, {ordering:?}: no top supernode split: {:?}",
                chol.tree_top_shape()
            );
        }
        // Two nodes (one supernode), and a dense matrix: a tree that does not split.
        let tiny = BlockPattern::from_elements(2, 3, &[0, 1], 2);
        check_tree(&tiny, &[], Ordering::Amd, "tiny");
        let all: Vec<u32> = (0..24).collect();
        let dense = BlockPattern::from_elements(24, 3, &all, 24);
        let (total, top, group) = check_tree(&dense, &[], Ordering::Amd, "dense");
        assert_eq!(top + group, total, "dense: nothing to split");
        // A forest: two components, two roots.
        let (p, positions) = two_cubes(6);
        check_tree(&p, &positions, Ordering::NestedDissection, "forest, ND");
        check_tree(&p, &positions, Ordering::Amd, "forest, AMD");
    }

    /// Study (prints): the factor of the issue-24 beams' pattern under both orderings, and
    /// the time of one solve by faer, by the tree on one thread and on two (wall, best of
    /// interleaved batches): the ceiling of what the split gains on this machine.
    /// `cargo test --release -p tissue --lib tree_solve_study -- --ignored --nocapture`
    #[test]
    #[ignore = "a printing study of the solves, tens of seconds"]
    fn tree_solve_study() {
        use crate::benchmark::beam::{BeamSpec, size_cells};
        #[cfg(feature = "parallel")]
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let sizes = std::env::var("TREE_SIZES").unwrap_or_else(|_| "1k,5k,20k,80k".into());
        for size in sizes.split(',') {
            let mesh = BeamSpec::new(size_cells(size).unwrap()).mesh();
            let flat: Vec<u32> = mesh.tets.iter().flatten().copied().collect();
            let p = BlockPattern::from_elements(mesh.vertices.len(), 3, &flat, 4);
            let v = spd(&p);
            let b: Vec<Real> = (0..p.dim())
                .map(|i| ((i * 37) % 11) as Real - 5.0)
                .collect();
            for (ordering, single) in [
                (Ordering::Amd, false),
                (Ordering::Amd, true),
                (Ordering::NestedDissection, false),
                (Ordering::NestedDissection, true),
            ] {
                let mut chol = SparseCholesky::with_ordering(&p, &mesh.vertices, ordering).unwrap();
                chol.factorize(&p, &v, "").unwrap();
                chol.single_precision_solves(single);
                let reps = (20_000_000 / chol.factor_nnz().max(1)).clamp(1, 2000);
                let mut best = [f64::INFINITY; 3];
                for _ in 0..7 {
                    for (how, t) in best.iter_mut().enumerate() {
                        chol.force_parallel = Some(how == 2);
                        let mut x = b.clone();
                        let chol = &mut chol;
                        let mut batch = || {
                            let start = std::time::Instant::now();
                            for _ in 0..reps {
                                x.copy_from_slice(&b);
                                match how {
                                    0 => chol.faer_solve(&mut x),
                                    _ => chol.solve_in_place(&mut x).unwrap(),
                                }
                            }
                            start.elapsed().as_secs_f64() / reps as f64
                        };
                        #[cfg(feature = "parallel")]
                        let took = if how == 2 {
                            pool.install(batch)
                        } else {
                            batch()
                        };
                        #[cfg(not(feature = "parallel"))]
                        let took = batch();
                        *t = t.min(took);
                    }
                }
                let (total, top, group) = chol.tree_work().unwrap_or_default();
                println!("top: {:?}", chol.tree_top_shape());
                println!(
                    "{size} beam, {} unknowns, {ordering:?}{}: factor {} values, supernodal {}, \
                     work top {:.3} largest group {:.3}; solve faer {:.1} us, tree 1 thread \
                     {:.1} us, 2 threads {:.1} us (x{:.2} over faer, x{:.2} over 1 thread)",
                    p.dim(),
                    if single { " f32" } else { "" },
                    chol.factor_nnz(),
                    chol.is_supernodal(),
                    top as f64 / total.max(1) as f64,
                    group as f64 / total.max(1) as f64,
                    best[0] * 1e6,
                    best[1] * 1e6,
                    best[2] * 1e6,
                    best[0] / best[2],
                    best[1] / best[2],
                );
            }
        }
    }
}
