//! The supernodal triangular solves L Lᵀ x = b of `SparseCholesky`, with the elimination
//! tree's independent subtrees on two threads.
//!
//! L's supernodes form a tree: a supernode's off-diagonal rows all belong to its ancestors.
//! The forward solve L y = b visits children before parents, the backward Lᵀ x = y parents
//! before children, and supernodes in disjoint subtrees never touch each other's unknowns:
//! they meet only in their common ancestors. So the tree is cut under a "top" (the root
//! supernodes down to where the rest falls apart into subtrees of balanced work; with a
//! nested-dissection ordering, the top separators) and the subtrees are dealt into `GROUPS`
//! groups of about equal work. Forward: each group on its own thread, its updates to the top's
//! unknowns summed into a buffer of its own; the buffers are added to the top in group order
//! and the top is solved on the calling thread. Backward: the top first, then the groups in
//! parallel, each reading the top's (final) unknowns.
//!
//! The groups are fixed by the factor's structure, never by the thread count, and the serial
//! path runs the same arithmetic in the same order: one thread and two give the same bits.
//!
//! Each group (and the top) keeps its unknowns in a contiguous vector of its own, supernode
//! after supernode, with the supernodes' row patterns renumbered into it (or into the top's
//! vector); the fill-reducing permutation is folded into the gather from b and the scatter
//! back. The dense work of a supernode (a column-major block of `rows` × `cols`, the
//! triangle on top) is done column by column on contiguous memory: forward, one scaled
//! subtraction per column below its diagonal; backward, one dot product per column. Without
//! fused multiply-adds, so the AVX2 build of the loops gives the baseline's bits.
//!
//! faer's own solve (`LltRef::solve_in_place_with_conj`) goes through a general matrix
//! product and a triangular solve per supernode, each with its dispatch and work memory;
//! most supernodes of a 3-D mesh are a few columns wide, where that overhead dominates.

// Supernode tables are read at one index across several arrays: explicit indices read clearest.
#![allow(clippy::needless_range_loop)]

use faer::sparse::linalg::cholesky::supernodal::SymbolicSupernodalCholesky;

use crate::math::Real;

/// Groups of subtrees solved concurrently: the machines this runs on have two cores or
/// more, and a finer split leaves more work in the serial top.
pub const GROUPS: usize = 2;

/// Subtrees opened (root moved to the top, children to the candidates) at most while the
/// split is searched: the best split of the beams and grids is found within tens.
const MAX_OPENED: usize = 256;

/// Work estimate of a supernode beyond its values: the gather and scatter of its rows and
/// the per-supernode bookkeeping, in units of one value's multiply-add.
const ROW_WORK: u64 = 2;
const NODE_WORK: u64 = 32;

/// Not a segment index: the top.
const TOP: u32 = u32::MAX;

/// How L's values are stored for the solve: `f64`, or `f32` for a preconditioner's copy
/// (`SparseCholesky::single_precision_solves`). The arithmetic is f64 either way; an f32
/// copy halves the bytes a memory-bound solve streams, and forward and backward read the
/// same rounded L, so the preconditioner stays exactly L̃ L̃ᵀ: symmetric positive definite.
pub trait Stored: Copy + Send + Sync + 'static {
    fn widen(self) -> Real;
    /// Four consecutive values widened into one AVX register.
    ///
    /// # Safety
    /// `p` must point at four readable values, and the CPU must support AVX.
    #[cfg(target_arch = "x86_64")]
    unsafe fn load4(p: *const Self) -> std::arch::x86_64::__m256d;
}

impl Stored for f64 {
    #[inline(always)]
    fn widen(self) -> Real {
        self
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn load4(p: *const Self) -> std::arch::x86_64::__m256d {
        // SAFETY: the caller's contract.
        unsafe { std::arch::x86_64::_mm256_loadu_pd(p) }
    }
}

impl Stored for f32 {
    #[inline(always)]
    fn widen(self) -> Real {
        Real::from(self)
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn load4(p: *const Self) -> std::arch::x86_64::__m256d {
        use std::arch::x86_64::{_mm_loadu_ps, _mm256_cvtps_pd};
        // SAFETY: the caller's contract.
        unsafe { _mm256_cvtps_pd(_mm_loadu_ps(p)) }
    }
}

#[derive(Clone, Copy, Debug)]
struct Node {
    /// Offset of the piece's dense block (column-major, `rows` × `cols`, columns `ld`
    /// apart: a piece of a wider supernode keeps the supernode's columns) in L's values.
    val: usize,
    ld: u32,
    cols: u32,
    /// Columns plus off-diagonal rows.
    rows: u32,
    /// Local index of its first column in its segment's vector.
    local: u32,
    /// Offset of its renumbered off-diagonal rows in `TreeSolve::pattern`.
    pat: usize,
    /// How many of those rows are in its own segment; the rest are the top's.
    own: u32,
}

/// faer's supernodes cut where another subtree joins them.
///
/// A supernode is a run of columns with one dense pattern; when a child subtree's first
/// off-diagonal row falls inside it (not at its first column), the columns before that row
/// are, in the elimination tree, a chain below the one it joins. faer's supernodes merge a
/// parent with the last of its children whenever that adds no zeros, so under a separator
/// ordered last (nested dissection) the separator's supernode also holds the last columns
/// of one half, and the split put that half's heaviest columns in the serial top (7.6% of
/// the 20k beam's work, 1.5% once cut). Cut there, each piece is a supernode of its own (the
/// same values, read with the supernode's column stride) and the split can fall between them.
struct Pieces<'a> {
    symbolic: &'a SymbolicSupernodalCholesky<usize>,
    /// Per piece: its supernode and its first column; pieces ascend by column.
    supernode: Vec<usize>,
    first: Vec<usize>,
    /// The piece holding the piece's first off-diagonal row (`usize::MAX`: a root).
    parent: Vec<usize>,
}

impl<'a> Pieces<'a> {
    /// `None` if a row of a supernode is not after it (never from faer's factors).
    fn new(symbolic: &'a SymbolicSupernodalCholesky<usize>) -> Option<Self> {
        let ns = symbolic.n_supernodes();
        let n = symbolic.nrows();
        let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
        // Where a supernode's subtree joins its parent: the first off-diagonal row.
        let mut cut = vec![false; n];
        for s in 0..ns {
            match symbolic.supernode(s).pattern().first() {
                Some(&r) if r < end[s] => return None,
                Some(&r) => cut[r] = true,
                None => {}
            }
        }
        let (mut supernode, mut first) = (Vec::with_capacity(ns), Vec::with_capacity(ns));
        let mut piece_of_col = vec![0usize; n];
        for s in 0..ns {
            for c in begin[s]..end[s] {
                if c == begin[s] || cut[c] {
                    supernode.push(s);
                    first.push(c);
                }
                piece_of_col[c] = first.len() - 1;
            }
        }
        let mut pieces = Self {
            symbolic,
            supernode,
            first,
            parent: Vec::new(),
        };
        pieces.parent = (0..pieces.len())
            .map(|p| {
                pieces
                    .off_diagonal_rows(p)
                    .next()
                    .map_or(usize::MAX, |r| piece_of_col[r])
            })
            .collect();
        Some(pieces)
    }

    fn len(&self) -> usize {
        self.first.len()
    }

    /// One past the piece's last column.
    fn end(&self, p: usize) -> usize {
        match self.supernode.get(p + 1) {
            Some(&s) if s == self.supernode[p] => self.first[p + 1],
            _ => self.symbolic.supernode_end()[self.supernode[p]],
        }
    }

    fn columns(&self, p: usize) -> std::ops::Range<usize> {
        self.first[p]..self.end(p)
    }

    fn cols(&self, p: usize) -> usize {
        self.end(p) - self.first[p]
    }

    /// Its columns and off-diagonal rows: the supernode's from the piece's first column on.
    fn rows(&self, p: usize) -> usize {
        let s = self.supernode[p];
        self.symbolic.supernode_end()[s] - self.first[p]
            + self.symbolic.supernode(s).pattern().len()
    }

    /// The supernode's rows: its block's column stride.
    fn ld(&self, p: usize) -> usize {
        let s = self.supernode[p];
        self.symbolic.supernode_end()[s] - self.symbolic.supernode_begin()[s]
            + self.symbolic.supernode(s).pattern().len()
    }

    /// Offset of the piece's diagonal entry of its first column in L's values.
    fn val(&self, p: usize) -> usize {
        let s = self.supernode[p];
        let k = self.first[p] - self.symbolic.supernode_begin()[s];
        self.symbolic.col_ptr_for_val()[s] + k * (self.ld(p) + 1)
    }

    /// The rows below its columns, ascending: the supernode's later columns, then its pattern.
    fn off_diagonal_rows(&self, p: usize) -> impl Iterator<Item = usize> + '_ {
        let s = self.supernode[p];
        (self.end(p)..self.symbolic.supernode_end()[s])
            .chain(self.symbolic.supernode(s).pattern().iter().copied())
    }
}

/// A group of subtrees, or the top: its supernodes and its unknowns.
#[derive(Clone, Debug, Default)]
struct Segment {
    /// Supernodes, ascending (children before parents).
    nodes: Vec<u32>,
    /// The original (unpermuted) row of each local unknown.
    orig: Vec<u32>,
    x: Vec<Real>,
    /// A supernode's column and rows while it is solved.
    work: Vec<Real>,
    /// Groups: the forward solve's updates to the top's unknowns.
    up: Vec<Real>,
}

/// The tree-split solve of one supernodal symbolic factorisation.
#[derive(Clone, Debug)]
pub struct TreeSolve {
    nodes: Vec<Node>,
    pattern: Vec<u32>,
    groups: Vec<Segment>,
    top: Segment,
    /// Work estimates (see `ROW_WORK`): the whole solve, the top, the largest group.
    work_total: u64,
    work_top: u64,
    work_group: u64,
    avx2: bool,
}

impl TreeSolve {
    /// The split of `symbolic` (whose fill-reducing permutation, new → original, is
    /// `perm_fwd`; `None`: identity). `None` if the structure is not a tree as expected (a
    /// row of a supernode outside its ancestors), which faer's factors never give.
    pub fn new(
        symbolic: &SymbolicSupernodalCholesky<usize>,
        perm_fwd: Option<&[usize]>,
    ) -> Option<Self> {
        let n = symbolic.nrows();
        if perm_fwd.is_some_and(|p| p.len() != n) || n >= u32::MAX as usize {
            return None;
        }
        let pieces = Pieces::new(symbolic)?;
        let np = pieces.len();
        let parent = &pieces.parent;
        let mut own = vec![0u64; np];
        for p in 0..np {
            let (cols, rows) = (pieces.cols(p) as u64, pieces.rows(p) as u64);
            own[p] = cols * rows + ROW_WORK * rows + NODE_WORK;
        }
        let mut sub = own.clone();
        for p in 0..np {
            if parent[p] != usize::MAX {
                sub[parent[p]] += sub[p];
            }
        }
        let split = best_split(parent, &sub, &own);
        // Segments: a frontier root's group, inherited down its subtree (parents come later).
        let mut seg = vec![TOP; np];
        let mut root_group = vec![TOP; np];
        for &(r, g) in &split.roots {
            root_group[r] = g as u32;
        }
        for p in (0..np).rev() {
            seg[p] = if root_group[p] != TOP {
                root_group[p]
            } else if parent[p] != usize::MAX {
                seg[parent[p]]
            } else {
                TOP
            };
        }
        let mut groups = vec![Segment::default(); GROUPS];
        let mut top = Segment::default();
        let mut col_local = vec![0u32; n];
        let mut col_seg = vec![TOP; n];
        let mut nodes = Vec::with_capacity(np);
        for p in 0..np {
            let segment = match seg[p] {
                TOP => &mut top,
                g => &mut groups[g as usize],
            };
            let local = segment.orig.len() as u32;
            for (k, c) in pieces.columns(p).enumerate() {
                col_local[c] = local + k as u32;
                col_seg[c] = seg[p];
                segment.orig.push(perm_fwd.map_or(c, |p| p[c]) as u32);
            }
            segment.nodes.push(p as u32);
            nodes.push(Node {
                val: pieces.val(p),
                ld: pieces.ld(p) as u32,
                cols: pieces.cols(p) as u32,
                rows: pieces.rows(p) as u32,
                local,
                pat: 0,
                own: 0,
            });
        }
        // Rows renumbered: first those in the piece's own segment, then the top's.
        let mut pattern = Vec::with_capacity(symbolic.row_idx().len());
        for p in 0..np {
            nodes[p].pat = pattern.len();
            let mut own_rows = 0;
            let mut in_top = false;
            for r in pieces.off_diagonal_rows(p) {
                if col_seg[r] == seg[p] && !in_top {
                    own_rows += 1;
                } else if col_seg[r] == TOP {
                    in_top = true;
                } else {
                    return None;
                }
                pattern.push(col_local[r]);
            }
            nodes[p].own = own_rows;
        }
        let top_len = top.orig.len();
        for segment in groups.iter_mut().chain(std::iter::once(&mut top)) {
            let widest = segment
                .nodes
                .iter()
                .map(|&s| nodes[s as usize].rows as usize)
                .max()
                .unwrap_or(0);
            segment.x = vec![0.0; segment.orig.len()];
            segment.work = vec![0.0; widest];
        }
        for g in &mut groups {
            g.up = vec![0.0; top_len];
        }
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        Some(Self {
            nodes,
            pattern,
            groups,
            top,
            work_total: sub
                .iter()
                .zip(parent)
                .filter(|(_, p)| **p == usize::MAX)
                .map(|(w, _)| w)
                .sum(),
            work_top: split.top,
            work_group: split.longest,
            avx2,
        })
    }

    /// Work estimates: the whole solve, its serial top, its largest group.
    pub fn work(&self) -> (u64, u64, u64) {
        (self.work_total, self.work_top, self.work_group)
    }

    /// True when the groups carry enough of the work for a second thread to pay: the top
    /// and the largest group together at most `ratio` of the whole.
    pub fn splits(&self, ratio: f64) -> bool {
        ((self.work_top + self.work_group) as f64) <= ratio * self.work_total as f64
    }

    /// Solves L Lᵀ x = b in place (`rhs` holds b, then x) with L's `values`, the groups on
    /// rayon's threads when `parallel` (the same bits either way).
    pub fn solve<V: Stored>(&mut self, values: &[V], rhs: &mut [Real], parallel: bool) {
        let Self {
            nodes,
            pattern,
            groups,
            top,
            avx2,
            ..
        } = self;
        let (nodes, pattern, avx2) = (&*nodes, &*pattern, *avx2);
        let b: &[Real] = rhs;
        for (x, &o) in top.x.iter_mut().zip(&top.orig) {
            *x = b[o as usize];
        }
        each(groups, parallel, |g| {
            for (x, &o) in g.x.iter_mut().zip(&g.orig) {
                *x = b[o as usize];
            }
            g.up.fill(0.0);
            forward(g, nodes, pattern, values, avx2);
        });
        for g in groups.iter() {
            for (x, u) in top.x.iter_mut().zip(&g.up) {
                *x += u;
            }
        }
        forward(top, nodes, pattern, values, avx2);
        backward(top, &[], nodes, pattern, values, avx2);
        let top_x = &top.x;
        each(groups, parallel, |g| {
            backward(g, top_x, nodes, pattern, values, avx2)
        });
        for segment in groups.iter().chain(std::iter::once(&*top)) {
            for (&x, &o) in segment.x.iter().zip(&segment.orig) {
                rhs[o as usize] = x;
            }
        }
    }
}

/// `f` on every group: on rayon's threads when `parallel` (and the feature is on).
fn each(groups: &mut [Segment], parallel: bool, f: impl Fn(&mut Segment) + Send + Sync) {
    #[cfg(feature = "parallel")]
    if parallel {
        use rayon::prelude::*;
        groups.par_iter_mut().for_each(f);
        return;
    }
    let _ = parallel;
    groups.iter_mut().for_each(f);
}

/// The chosen cut: the frontier's subtree roots with their group, and the work of the top
/// and of the largest group.
struct Split {
    roots: Vec<(usize, usize)>,
    top: u64,
    longest: u64,
}

impl Split {
    /// The work on the critical path with one thread per group.
    fn span(&self) -> u64 {
        self.top + self.longest
    }
}

/// Opens the heaviest subtree (its root to the top, its children to the frontier) again and
/// again from the roots, dealing the frontier's subtrees into the groups (heaviest first, to
/// the lightest group) after each opening, and keeps the cut with the least work on the
/// critical path.
fn best_split(parent: &[usize], sub: &[u64], own: &[u64]) -> Split {
    let ns = parent.len();
    let mut child_ptr = vec![0usize; ns + 1];
    for &p in parent.iter().filter(|&&p| p != usize::MAX) {
        child_ptr[p + 1] += 1;
    }
    for s in 0..ns {
        child_ptr[s + 1] += child_ptr[s];
    }
    let mut children = vec![0usize; child_ptr[ns]];
    let mut fill = child_ptr.clone();
    for (s, &p) in parent.iter().enumerate() {
        if p != usize::MAX {
            children[fill[p]] = s;
            fill[p] += 1;
        }
    }
    let mut frontier: Vec<usize> = (0..ns).filter(|&s| parent[s] == usize::MAX).collect();
    let total: u64 = frontier.iter().map(|&s| sub[s]).sum();
    let mut top = 0;
    let mut best = deal(&frontier, sub, top);
    for _ in 0..MAX_OPENED {
        let Some(i) = (0..frontier.len()).max_by_key(|&i| (sub[frontier[i]], frontier[i])) else {
            break;
        };
        let r = frontier.swap_remove(i);
        top += own[r];
        if 2 * top > total {
            break;
        }
        frontier.extend_from_slice(&children[child_ptr[r]..child_ptr[r + 1]]);
        let cut = deal(&frontier, sub, top);
        if cut.span() < best.span() {
            best = cut;
        }
    }
    best
}

/// The frontier's subtrees dealt into `GROUPS` groups, heaviest first, each to the lightest
/// group so far (ties: the lower index).
fn deal(frontier: &[usize], sub: &[u64], top: u64) -> Split {
    let mut order = frontier.to_vec();
    order.sort_unstable_by_key(|&s| (std::cmp::Reverse(sub[s]), s));
    let mut load = [0u64; GROUPS];
    let mut roots = Vec::with_capacity(order.len());
    for s in order {
        let g = (0..GROUPS).min_by_key(|&g| (load[g], g)).unwrap_or(0);
        load[g] += sub[s];
        roots.push((s, g));
    }
    Split {
        roots,
        top,
        longest: load.into_iter().max().unwrap_or(0),
    }
}

/// The forward solve through a segment's supernodes: their columns in `seg.x`, their
/// updates to rows of the same segment into `seg.x` and to the top's rows into `seg.up`.
fn forward<V: Stored>(seg: &mut Segment, nodes: &[Node], pattern: &[u32], l: &[V], avx2: bool) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` was detected on this CPU.
        return unsafe { forward_avx2(seg, nodes, pattern, l) };
    }
    let _ = avx2;
    forward_body(seg, nodes, pattern, l);
}

/// The backward solve through a segment's supernodes (descending), reading the top's
/// unknowns from `top_x`.
fn backward<V: Stored>(
    seg: &mut Segment,
    top_x: &[Real],
    nodes: &[Node],
    pattern: &[u32],
    l: &[V],
    avx2: bool,
) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` was detected on this CPU.
        return unsafe { backward_avx2(seg, top_x, nodes, pattern, l) };
    }
    let _ = avx2;
    backward_body::<V, false>(seg, top_x, nodes, pattern, l);
}

/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn forward_avx2<V: Stored>(seg: &mut Segment, nodes: &[Node], pattern: &[u32], l: &[V]) {
    forward_body(seg, nodes, pattern, l);
}

/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn backward_avx2<V: Stored>(
    seg: &mut Segment,
    top_x: &[Real],
    nodes: &[Node],
    pattern: &[u32],
    l: &[V],
) {
    backward_body::<V, true>(seg, top_x, nodes, pattern, l);
}

#[inline(always)]
fn forward_body<V: Stored>(seg: &mut Segment, nodes: &[Node], pattern: &[u32], l: &[V]) {
    let Segment {
        nodes: list,
        x,
        work,
        up,
        ..
    } = seg;
    for &s in list.iter() {
        let nd = nodes[s as usize];
        let (nc, nr, at) = (nd.cols as usize, nd.rows as usize, nd.local as usize);
        let ld = nd.ld as usize;
        let block = &l[nd.val..nd.val + (nc - 1) * ld + nr];
        let w = &mut work[..nr];
        w[..nc].copy_from_slice(&x[at..at + nc]);
        w[nc..].fill(0.0);
        for j in 0..nc {
            let col = &block[j * ld..j * ld + nr];
            let wj = w[j] / col[j].widen();
            w[j] = wj;
            for (wi, ci) in w[j + 1..].iter_mut().zip(&col[j + 1..]) {
                *wi -= ci.widen() * wj;
            }
        }
        x[at..at + nc].copy_from_slice(&w[..nc]);
        let (own, rest) = pattern[nd.pat..nd.pat + nr - nc].split_at(nd.own as usize);
        let (w_own, w_rest) = w[nc..].split_at(nd.own as usize);
        for (&r, &v) in own.iter().zip(w_own) {
            x[r as usize] += v;
        }
        for (&r, &v) in rest.iter().zip(w_rest) {
            up[r as usize] += v;
        }
    }
}

/// `AVX2`: compiled for AVX2 (`backward_avx2`), whose dot products use its intrinsics.
#[inline(always)]
fn backward_body<V: Stored, const AVX2: bool>(
    seg: &mut Segment,
    top_x: &[Real],
    nodes: &[Node],
    pattern: &[u32],
    l: &[V],
) {
    let Segment {
        nodes: list,
        x,
        work,
        ..
    } = seg;
    for &s in list.iter().rev() {
        let nd = nodes[s as usize];
        let (nc, nr, at) = (nd.cols as usize, nd.rows as usize, nd.local as usize);
        let ld = nd.ld as usize;
        let block = &l[nd.val..nd.val + (nc - 1) * ld + nr];
        let w = &mut work[..nr];
        w[..nc].copy_from_slice(&x[at..at + nc]);
        let (own, rest) = pattern[nd.pat..nd.pat + nr - nc].split_at(nd.own as usize);
        let (w_own, w_rest) = w[nc..].split_at_mut(nd.own as usize);
        for (wi, &r) in w_own.iter_mut().zip(own) {
            *wi = x[r as usize];
        }
        for (wi, &r) in w_rest.iter_mut().zip(rest) {
            *wi = top_x[r as usize];
        }
        // The rows below the triangle first, columns in memory order: the bulk of most
        // supernodes, read forward as the hardware prefetcher expects (a column-by-column
        // sweep from the last column read the block backwards and took twice the forward
        // solve's time on the 20k beam).
        let (w_top, w_rows) = w.split_at_mut(nc);
        for (j, wj) in w_top.iter_mut().enumerate() {
            *wj -= dot_for::<V, AVX2>(&block[j * ld + nc..j * ld + nr], w_rows);
        }
        // Then the triangle, last column first.
        for j in (0..nc).rev() {
            let col = &block[j * ld..j * ld + nc];
            let d = dot_for::<V, AVX2>(&col[j + 1..], &w[j + 1..nc]);
            w[j] = (w[j] - d) / col[j].widen();
        }
        x[at..at + nc].copy_from_slice(&w[..nc]);
    }
}

/// `dot`, with AVX2 intrinsics when compiled for it (`AVX2`).
#[inline(always)]
fn dot_for<V: Stored, const AVX2: bool>(a: &[V], b: &[Real]) -> Real {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: only `backward_avx2`, called when AVX2 was detected, passes `AVX2`.
        return unsafe { dot_avx2(a, b) };
    }
    dot(a, b)
}

/// `dot` in AVX2 registers: the same eight partial sums (two vectors of four lanes) summed
/// in the same order, so the same bits. (LLVM vectorised the portable loop into 128-bit
/// halves and shuffles.)
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn dot_avx2<V: Stored>(a: &[V], b: &[Real]) -> Real {
    use std::arch::x86_64::{
        _mm256_add_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_setzero_pd, _mm256_storeu_pd,
    };
    let n = a.len().min(b.len());
    let full = n - n % 8;
    let (pa, pb) = (a.as_ptr(), b.as_ptr());
    let (mut s0, mut s1) = (_mm256_setzero_pd(), _mm256_setzero_pd());
    let mut i = 0;
    while i < full {
        // SAFETY: i + 8 ≤ n, and both slices are at least n long.
        unsafe {
            let p0 = _mm256_mul_pd(V::load4(pa.add(i)), _mm256_loadu_pd(pb.add(i)));
            let p1 = _mm256_mul_pd(V::load4(pa.add(i + 4)), _mm256_loadu_pd(pb.add(i + 4)));
            s0 = _mm256_add_pd(s0, p0);
            s1 = _mm256_add_pd(s1, p1);
        }
        i += 8;
    }
    let mut lanes = [0.0; 4];
    // SAFETY: four f64 stored into an array of four.
    unsafe { _mm256_storeu_pd(lanes.as_mut_ptr(), _mm256_add_pd(s0, s1)) };
    let mut d = (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]);
    for k in full..n {
        d += a[k].widen() * b[k];
    }
    d
}

/// Σ a_i b_i in eight interleaved partial sums (vectorisable, and the same order on every
/// instruction set).
#[inline(always)]
fn dot<V: Stored>(a: &[V], b: &[Real]) -> Real {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 8];
    let (ac, bc) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ar, br) = (ac.remainder(), bc.remainder());
    for (x, y) in ac.zip(bc) {
        for k in 0..8 {
            acc[k] += x[k].widen() * y[k];
        }
    }
    let mut d = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ar.iter().zip(br) {
        d += x.widen() * y;
    }
    d
}
