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

#[derive(Clone, Copy, Debug)]
struct Node {
    /// Offset of the supernode's dense block (column-major, `rows` × `cols`) in L's values.
    val: usize,
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
        let ns = symbolic.n_supernodes();
        let n = symbolic.nrows();
        if perm_fwd.is_some_and(|p| p.len() != n) || n >= u32::MAX as usize {
            return None;
        }
        let (begin, end) = (symbolic.supernode_begin(), symbolic.supernode_end());
        let val_ptr = symbolic.col_ptr_for_val();
        let mut super_of_col = vec![0usize; n];
        for s in 0..ns {
            super_of_col[begin[s]..end[s]].fill(s);
        }
        // The parent is the supernode of the first off-diagonal row; always a later one.
        let mut parent = vec![usize::MAX; ns];
        let mut own = vec![0u64; ns];
        for s in 0..ns {
            let pattern = symbolic.supernode(s).pattern();
            if let Some(&r) = pattern.first() {
                parent[s] = super_of_col[r];
                if parent[s] <= s {
                    return None;
                }
            }
            let rows = (end[s] - begin[s] + pattern.len()) as u64;
            own[s] = (val_ptr[s + 1] - val_ptr[s]) as u64 + ROW_WORK * rows + NODE_WORK;
        }
        let mut sub = own.clone();
        for s in 0..ns {
            if parent[s] != usize::MAX {
                sub[parent[s]] += sub[s];
            }
        }
        let split = best_split(&parent, &sub, &own);
        // Segments: a frontier root's group, inherited down its subtree (parents come later).
        let mut seg = vec![TOP; ns];
        let mut root_group = vec![TOP; ns];
        for &(r, g) in &split.roots {
            root_group[r] = g as u32;
        }
        for s in (0..ns).rev() {
            seg[s] = if root_group[s] != TOP {
                root_group[s]
            } else if parent[s] != usize::MAX {
                seg[parent[s]]
            } else {
                TOP
            };
        }
        let mut groups = vec![Segment::default(); GROUPS];
        let mut top = Segment::default();
        let mut col_local = vec![0u32; n];
        let mut col_seg = vec![TOP; n];
        let mut nodes = Vec::with_capacity(ns);
        for s in 0..ns {
            let segment = match seg[s] {
                TOP => &mut top,
                g => &mut groups[g as usize],
            };
            let local = segment.orig.len() as u32;
            for (k, c) in (begin[s]..end[s]).enumerate() {
                col_local[c] = local + k as u32;
                col_seg[c] = seg[s];
                segment.orig.push(perm_fwd.map_or(c, |p| p[c]) as u32);
            }
            segment.nodes.push(s as u32);
            nodes.push(Node {
                val: val_ptr[s],
                cols: (end[s] - begin[s]) as u32,
                rows: (end[s] - begin[s] + symbolic.supernode(s).pattern().len()) as u32,
                local,
                pat: 0,
                own: 0,
            });
        }
        // Rows renumbered: first those in the supernode's own segment, then the top's.
        let mut pattern = Vec::with_capacity(symbolic.row_idx().len());
        for s in 0..ns {
            nodes[s].pat = pattern.len();
            let mut own_rows = 0;
            let mut in_top = false;
            for &r in symbolic.supernode(s).pattern() {
                if col_seg[r] == seg[s] && !in_top {
                    own_rows += 1;
                } else if col_seg[r] == TOP {
                    in_top = true;
                } else {
                    return None;
                }
                pattern.push(col_local[r]);
            }
            nodes[s].own = own_rows;
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
                .zip(&parent)
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
    pub fn solve(&mut self, values: &[Real], rhs: &mut [Real], parallel: bool) {
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
fn forward(seg: &mut Segment, nodes: &[Node], pattern: &[u32], l: &[Real], avx2: bool) {
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
fn backward(
    seg: &mut Segment,
    top_x: &[Real],
    nodes: &[Node],
    pattern: &[u32],
    l: &[Real],
    avx2: bool,
) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: `avx2` was detected on this CPU.
        return unsafe { backward_avx2(seg, top_x, nodes, pattern, l) };
    }
    let _ = avx2;
    backward_body::<false>(seg, top_x, nodes, pattern, l);
}

/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn forward_avx2(seg: &mut Segment, nodes: &[Node], pattern: &[u32], l: &[Real]) {
    forward_body(seg, nodes, pattern, l);
}

/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn backward_avx2(
    seg: &mut Segment,
    top_x: &[Real],
    nodes: &[Node],
    pattern: &[u32],
    l: &[Real],
) {
    backward_body::<true>(seg, top_x, nodes, pattern, l);
}

#[inline(always)]
fn forward_body(seg: &mut Segment, nodes: &[Node], pattern: &[u32], l: &[Real]) {
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
        let block = &l[nd.val..nd.val + nc * nr];
        let w = &mut work[..nr];
        w[..nc].copy_from_slice(&x[at..at + nc]);
        w[nc..].fill(0.0);
        for j in 0..nc {
            let col = &block[j * nr..(j + 1) * nr];
            let wj = w[j] / col[j];
            w[j] = wj;
            for (wi, ci) in w[j + 1..].iter_mut().zip(&col[j + 1..]) {
                *wi -= ci * wj;
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
fn backward_body<const AVX2: bool>(
    seg: &mut Segment,
    top_x: &[Real],
    nodes: &[Node],
    pattern: &[u32],
    l: &[Real],
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
        let block = &l[nd.val..nd.val + nc * nr];
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
            *wj -= dot_for::<AVX2>(&block[j * nr + nc..(j + 1) * nr], w_rows);
        }
        // Then the triangle, last column first.
        for j in (0..nc).rev() {
            let col = &block[j * nr..j * nr + nc];
            let d = dot_for::<AVX2>(&col[j + 1..], &w[j + 1..nc]);
            w[j] = (w[j] - d) / col[j];
        }
        x[at..at + nc].copy_from_slice(&w[..nc]);
    }
}

/// `dot`, with AVX2 intrinsics when compiled for it (`AVX2`).
#[inline(always)]
fn dot_for<const AVX2: bool>(a: &[Real], b: &[Real]) -> Real {
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
unsafe fn dot_avx2(a: &[Real], b: &[Real]) -> Real {
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
            let p0 = _mm256_mul_pd(_mm256_loadu_pd(pa.add(i)), _mm256_loadu_pd(pb.add(i)));
            let p1 = _mm256_mul_pd(
                _mm256_loadu_pd(pa.add(i + 4)),
                _mm256_loadu_pd(pb.add(i + 4)),
            );
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
        d += a[k] * b[k];
    }
    d
}

/// Σ a_i b_i in eight interleaved partial sums (vectorisable, and the same order on every
/// instruction set).
#[inline(always)]
fn dot(a: &[Real], b: &[Real]) -> Real {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 8];
    let (ac, bc) = (a.chunks_exact(8), b.chunks_exact(8));
    let (ar, br) = (ac.remainder(), bc.remainder());
    for (x, y) in ac.zip(bc) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut d = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
    for (x, y) in ar.iter().zip(br) {
        d += x * y;
    }
    d
}
