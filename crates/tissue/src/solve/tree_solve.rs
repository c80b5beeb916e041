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

use std::sync::atomic::{AtomicUsize, Ordering as AtomicOrdering};

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
    /// The plan on two threads (the top's large supernodes split), and on one (whole: the
    /// same arithmetic on every element without the split's extra passes).
    plan: Plan,
    serial_plan: Plan,
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
        let plan = Plan::new(&nodes, &groups, &top, MIN_SPLIT);
        let serial_plan = Plan::new(&nodes, &groups, &top, usize::MAX);
        Some(Self {
            plan,
            serial_plan,
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

    /// The top's supernodes (columns, rows), children first: what the serial top is made of.
    pub fn top_shape(&self) -> Vec<(u32, u32)> {
        self.top
            .nodes
            .iter()
            .map(|&s| (self.nodes[s as usize].cols, self.nodes[s as usize].rows))
            .collect()
    }

    /// How many of the top's supernodes are split between the two threads.
    pub fn split_supernodes(&self) -> usize {
        self.plan
            .chunks
            .iter()
            .flatten()
            .filter(|t| matches!(t, Task::BackGather(_)))
            .count()
    }

    /// Work estimates: the whole solve, its serial top, its largest group.
    pub fn work(&self) -> (u64, u64, u64) {
        (self.work_total, self.work_top, self.work_group)
    }

    /// The critical path of a two-thread solve with the top counted serial (top plus the
    /// largest group), in factor values: `values` scaled by the work estimates' share
    /// (`Ordering::ForSolves` says why the top counts whole).
    pub fn span(&self, values: usize) -> f64 {
        values as f64 * (self.work_top + self.work_group) as f64 / self.work_total.max(1) as f64
    }

    /// True when the groups carry enough of the work for a second thread to pay: the top
    /// and the largest group together at most `ratio` of the whole.
    pub fn splits(&self, ratio: f64) -> bool {
        ((self.work_top + self.work_group) as f64) <= ratio * self.work_total as f64
    }

    /// Solves L Lᵀ x = b in place (`rhs` holds b, then x) with L's `values`: the split
    /// plan's chunks on two of rayon's threads when `parallel`, the serial plan otherwise
    /// (the same bits either way: a split supernode does each element's arithmetic in the
    /// same order as a whole one).
    pub fn solve<V: Stored>(&mut self, values: &[V], rhs: &mut [Real], parallel: bool) {
        let Self {
            nodes,
            pattern,
            groups,
            top,
            plan,
            serial_plan,
            avx2,
            ..
        } = self;
        let shared = Shared {
            nodes,
            pattern,
            l: values,
            groups: groups.as_mut_ptr(),
            top_x: top.x.as_mut_ptr(),
            top_w: top.work.as_mut_ptr(),
            top_orig: &top.orig,
            top_len: (top.x.len(), top.work.len()),
            rhs: rhs.as_mut_ptr(),
            n: rhs.len(),
            next: AtomicUsize::new(0),
            done: AtomicUsize::new(0),
        };
        let avx2 = *avx2;
        #[cfg(feature = "parallel")]
        if parallel {
            let plan = &*plan;
            rayon::join(|| drive(&shared, plan, avx2), || drive(&shared, plan, avx2));
            return;
        }
        let _ = (parallel, plan);
        drive(&shared, serial_plan, avx2);
    }
}

/// Below this many values (columns × rows) a top supernode is solved by one thread: the
/// split's two waits cost about a microsecond, the work of this many values a few.
const MIN_SPLIT: usize = 16_384;

/// Columns per panel of a split supernode's forward triangle: the panel's own triangle is
/// serial, the rows below it are split.
const PANEL: usize = 64;

/// One piece of a solve's work. Chunks of one phase are independent; a phase starts when
/// every chunk before it has finished.
#[derive(Clone, Copy, Debug)]
enum Task {
    /// A group's forward solve (gathered from b, its updates to the top in its buffer).
    GroupForward(u32),
    /// The top's unknowns gathered from b, the groups' updates added in group order.
    TopGather,
    /// A small top supernode's forward solve, whole.
    NodeForward(u32),
    /// A split top supernode's forward triangle on columns (and rows) `a..b` (at `a` = 0,
    /// its columns copied in first).
    PanelTriangle { s: u32, a: u32, b: u32 },
    /// Rows `lo..hi` (all below `b`) of a split top supernode updated by columns `a..b`;
    /// after its last panel, the rows below the triangle scattered into the top's unknowns.
    PanelRows {
        s: u32,
        a: u32,
        b: u32,
        lo: u32,
        hi: u32,
    },
    /// A small top supernode's backward solve, whole.
    NodeBackward(u32),
    /// A split top supernode's columns and rows gathered for its backward solve.
    BackGather(u32),
    /// Columns `c0..c1` of a split top supernode: the dots with the rows below the triangle.
    BackRect { s: u32, c0: u32, c1: u32 },
    /// A split top supernode's backward triangle, its columns written back.
    BackTriangle(u32),
    /// A group's backward solve, scattered into x.
    GroupBackward(u32),
    /// The top's unknowns scattered into x.
    TopScatter,
}

/// The solve as phases of chunks of tasks, fixed by the factor's structure.
#[derive(Clone, Debug, Default)]
struct Plan {
    chunks: Vec<Vec<Task>>,
    /// Per chunk: the index of its phase's first chunk (what must have finished before it).
    needs: Vec<usize>,
}

impl Plan {
    /// A phase of `chunks` independent chunks; a phase of one chunk joins a serial phase just
    /// before it.
    fn phase(&mut self, chunks: Vec<Vec<Task>>) {
        let alone = self.needs.last() == Some(&(self.chunks.len().wrapping_sub(1)));
        if let [one] = chunks.as_slice()
            && alone
            && let Some(last) = self.chunks.last_mut()
        {
            last.extend_from_slice(one);
            return;
        }
        let first = self.chunks.len();
        for c in chunks {
            self.chunks.push(c);
            self.needs.push(first);
        }
    }

    fn serial(&mut self, task: Task) {
        self.phase(vec![vec![task]]);
    }

    /// Groups forward, the top forward and backward (its supernodes of `min_split` values or
    /// more split in two by rows forward and by columns backward), groups backward.
    fn new(nodes: &[Node], groups: &[Segment], top: &Segment, min_split: usize) -> Self {
        let mut plan = Plan::default();
        plan.phase(
            (0..groups.len() as u32)
                .map(|g| vec![Task::GroupForward(g)])
                .collect(),
        );
        plan.serial(Task::TopGather);
        let split = |s: u32| {
            let nd = nodes[s as usize];
            (nd.cols as usize * nd.rows as usize >= min_split).then_some(nd)
        };
        for &s in &top.nodes {
            let Some(nd) = split(s) else {
                plan.serial(Task::NodeForward(s));
                continue;
            };
            let (nc, nr) = (nd.cols as usize, nd.rows as usize);
            for a in (0..nc).step_by(PANEL) {
                let b = (a + PANEL).min(nc);
                plan.serial(Task::PanelTriangle {
                    s,
                    a: a as u32,
                    b: b as u32,
                });
                if b < nr {
                    // Halves on a multiple of 8 rows from b: whole vector steps.
                    let mid = (b + (nr - b) / 2 / 8 * 8).max(b);
                    let rows = |lo: usize, hi: usize| {
                        vec![Task::PanelRows {
                            s,
                            a: a as u32,
                            b: b as u32,
                            lo: lo as u32,
                            hi: hi as u32,
                        }]
                    };
                    plan.phase(vec![rows(b, mid), rows(mid, nr)]);
                }
            }
        }
        for &s in top.nodes.iter().rev() {
            let Some(nd) = split(s) else {
                plan.serial(Task::NodeBackward(s));
                continue;
            };
            let nc = nd.cols;
            plan.serial(Task::BackGather(s));
            if nd.rows > nc {
                let mid = nc / 2;
                plan.phase(vec![
                    vec![Task::BackRect { s, c0: 0, c1: mid }],
                    vec![Task::BackRect { s, c0: mid, c1: nc }],
                ]);
            }
            plan.serial(Task::BackTriangle(s));
        }
        let mut last: Vec<Vec<Task>> = (0..groups.len() as u32)
            .map(|g| vec![Task::GroupBackward(g)])
            .collect();
        last.push(vec![Task::TopScatter]);
        plan.phase(last);
        plan
    }
}

/// What the chunks share while a solve runs: the factor, and raw pointers to the segments'
/// vectors and x, which the plan's phases hand out so that no two running chunks write the
/// same element (or read one the other writes).
struct Shared<'a, V> {
    nodes: &'a [Node],
    pattern: &'a [u32],
    l: &'a [V],
    groups: *mut Segment,
    /// The top's unknowns and work vector (lengths `top_len`), and its rows' originals.
    top_x: *mut Real,
    top_w: *mut Real,
    top_orig: &'a [u32],
    top_len: (usize, usize),
    rhs: *mut Real,
    n: usize,
    /// The next chunk to claim, and how many have finished.
    next: AtomicUsize,
    done: AtomicUsize,
}

// SAFETY: the raw pointers are only dereferenced by chunks, and the plan's phases keep
// concurrently running chunks on disjoint elements (see `run`).
unsafe impl<V: Sync> Sync for Shared<'_, V> {}

/// Claims chunks in order until none is left, each run once every chunk of the phases
/// before it has finished. With one thread this is the plan in order; with two, whichever
/// thread is free takes the next chunk, so a helper that starts late only takes less.
fn drive<V: Stored>(sh: &Shared<'_, V>, plan: &Plan, avx2: bool) {
    loop {
        let c = sh.next.fetch_add(1, AtomicOrdering::Relaxed);
        let Some(chunk) = plan.chunks.get(c) else {
            return;
        };
        let mut spins = 0u32;
        // Chunks are claimed in order, so the chunks this one waits for are being run.
        while sh.done.load(AtomicOrdering::Acquire) < plan.needs[c] {
            spins += 1;
            if spins < 1 << 14 {
                std::hint::spin_loop();
            } else {
                std::thread::yield_now();
            }
        }
        for &task in chunk {
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                // SAFETY: `avx2` was detected on this CPU; the phases (see `run`).
                unsafe { run_avx2(sh, task) };
                continue;
            }
            let _ = avx2;
            // SAFETY: the phases (see `run`).
            unsafe { run::<V, false>(sh, task) };
        }
        sh.done.fetch_add(1, AtomicOrdering::AcqRel);
    }
}

/// # Safety
/// The CPU must support AVX2; as `run`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_avx2<V: Stored>(sh: &Shared<'_, V>, task: Task) {
    // SAFETY: the caller's contract.
    unsafe { run::<V, true>(sh, task) }
}

/// One task. The plan runs a task touching a segment's vectors as a whole (`GroupForward`,
/// `TopGather`, `NodeForward`, `PanelTriangle`, `BackGather`, `BackTriangle`,
/// `GroupBackward`) alone or beside tasks of other segments; the two `PanelRows` of a phase
/// write the top's work rows `lo..hi` (disjoint, below the panel's columns, which they
/// read) and scatter to distinct unknowns of the top (a supernode's rows are distinct); the
/// two `BackRect` write columns `c0..c1` (disjoint) and read the rows below the triangle.
///
/// # Safety
/// Only as the plan's phases run it, with `AVX2` only when the CPU supports it.
#[inline(always)]
unsafe fn run<V: Stored, const AVX2: bool>(sh: &Shared<'_, V>, task: Task) {
    let (nodes, pattern, l) = (sh.nodes, sh.pattern, sh.l);
    // SAFETY (every block below): the phases, as above; the segments' vectors are not
    // resized while a solve runs, and `rhs` is `n` long.
    unsafe {
        let top_x = || std::slice::from_raw_parts_mut(sh.top_x, sh.top_len.0);
        let top_w = || std::slice::from_raw_parts_mut(sh.top_w, sh.top_len.1);
        let b = || std::slice::from_raw_parts(sh.rhs, sh.n);
        match task {
            Task::GroupForward(g) => {
                let g = &mut *sh.groups.add(g as usize);
                for (x, &o) in g.x.iter_mut().zip(&g.orig) {
                    *x = b()[o as usize];
                }
                g.up.fill(0.0);
                forward_body(g, nodes, pattern, l);
            }
            Task::TopGather => {
                let x = top_x();
                for (x, &o) in x.iter_mut().zip(sh.top_orig) {
                    *x = b()[o as usize];
                }
                for gi in 0..GROUPS {
                    let g = &*sh.groups.add(gi);
                    for (x, u) in x.iter_mut().zip(&g.up) {
                        *x += u;
                    }
                }
            }
            Task::NodeForward(s) => {
                forward_node(nodes[s as usize], top_x(), top_w(), &mut [], pattern, l);
            }
            Task::PanelTriangle { s, a, b } => {
                let (x, work) = (top_x(), top_w());
                let nd = nodes[s as usize];
                let (nr, at, ld) = (nd.rows as usize, nd.local as usize, nd.ld as usize);
                let (a, b) = (a as usize, b as usize);
                let nc = nd.cols as usize;
                let w = &mut work[..nr];
                if a == 0 {
                    w[..nc].copy_from_slice(&x[at..at + nc]);
                    w[nc..].fill(0.0);
                }
                for j in a..b {
                    let col = &l[nd.val + j * ld..nd.val + j * ld + b];
                    let wj = w[j] / col[j].widen();
                    w[j] = wj;
                    for (wi, ci) in w[j + 1..b].iter_mut().zip(&col[j + 1..]) {
                        *wi -= ci.widen() * wj;
                    }
                }
                x[at + a..at + b].copy_from_slice(&w[a..b]);
            }
            Task::PanelRows { s, a, b, lo, hi } => {
                let nd = nodes[s as usize];
                let (nc, ld) = (nd.cols as usize, nd.ld as usize);
                let (a, b, lo, hi) = (a as usize, b as usize, lo as usize, hi as usize);
                let panel = std::slice::from_raw_parts(sh.top_w.add(a), b - a);
                let rows = std::slice::from_raw_parts_mut(sh.top_w.add(lo), hi - lo);
                for (k, &wj) in panel.iter().enumerate() {
                    let j = a + k;
                    let col = &l[nd.val + j * ld + lo..nd.val + j * ld + hi];
                    for (wi, ci) in rows.iter_mut().zip(col) {
                        *wi -= ci.widen() * wj;
                    }
                }
                if b == nc {
                    let first = lo.max(nc);
                    let rows_at = &pattern[nd.pat + first - nc..nd.pat + hi - nc];
                    for (&r, &v) in rows_at.iter().zip(&rows[first - lo..]) {
                        *sh.top_x.add(r as usize) += v;
                    }
                }
            }
            Task::NodeBackward(s) => {
                backward_node::<V, AVX2>(nodes[s as usize], top_x(), &[], top_w(), pattern, l);
            }
            Task::BackGather(s) => {
                let (x, work) = (top_x(), top_w());
                let nd = nodes[s as usize];
                let (nc, nr, at) = (nd.cols as usize, nd.rows as usize, nd.local as usize);
                let w = &mut work[..nr];
                w[..nc].copy_from_slice(&x[at..at + nc]);
                for (wi, &r) in w[nc..].iter_mut().zip(&pattern[nd.pat..nd.pat + nr - nc]) {
                    *wi = x[r as usize];
                }
            }
            Task::BackRect { s, c0, c1 } => {
                let nd = nodes[s as usize];
                let (nc, nr, ld) = (nd.cols as usize, nd.rows as usize, nd.ld as usize);
                let w_rows = std::slice::from_raw_parts(sh.top_w.add(nc), nr - nc);
                let cols =
                    std::slice::from_raw_parts_mut(sh.top_w.add(c0 as usize), (c1 - c0) as usize);
                for (k, wj) in cols.iter_mut().enumerate() {
                    let at = nd.val + (c0 as usize + k) * ld;
                    *wj -= dot_for::<V, AVX2>(&l[at + nc..at + nr], w_rows);
                }
            }
            Task::BackTriangle(s) => {
                let (x, work) = (top_x(), top_w());
                let nd = nodes[s as usize];
                let (nc, at, ld) = (nd.cols as usize, nd.local as usize, nd.ld as usize);
                let w = &mut work[..nc];
                back_triangle::<V, AVX2>(&l[nd.val..], ld, w);
                x[at..at + nc].copy_from_slice(w);
            }
            Task::GroupBackward(g) => {
                let g = &mut *sh.groups.add(g as usize);
                let tx: &[Real] = top_x();
                for &s in g.nodes.iter().rev() {
                    backward_node::<V, AVX2>(
                        nodes[s as usize],
                        &mut g.x,
                        tx,
                        &mut g.work,
                        pattern,
                        l,
                    );
                }
                for (&x, &o) in g.x.iter().zip(&g.orig) {
                    *sh.rhs.add(o as usize) = x;
                }
            }
            Task::TopScatter => {
                for (&x, &o) in top_x().iter().zip(sh.top_orig) {
                    *sh.rhs.add(o as usize) = x;
                }
            }
        }
    }
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

/// The forward solve through a group's supernodes: their columns in `seg.x`, their
/// updates to rows of the same group into `seg.x` and to the top's rows into `seg.up`.
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
        forward_node(nodes[s as usize], x, work, up, pattern, l);
    }
}

/// One supernode's forward solve: its columns in `x`, its updates to rows of its own
/// segment into `x` and to the top's rows into `up`.
#[inline(always)]
fn forward_node<V: Stored>(
    nd: Node,
    x: &mut [Real],
    work: &mut [Real],
    up: &mut [Real],
    pattern: &[u32],
    l: &[V],
) {
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

/// One supernode's backward solve, reading its own segment's unknowns from `x` and the
/// top's from `top_x`. `AVX2`: compiled for AVX2 (`run_avx2`), whose dot products use its
/// intrinsics.
#[inline(always)]
fn backward_node<V: Stored, const AVX2: bool>(
    nd: Node,
    x: &mut [Real],
    top_x: &[Real],
    work: &mut [Real],
    pattern: &[u32],
    l: &[V],
) {
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
    back_triangle::<V, AVX2>(block, ld, w_top);
    x[at..at + nc].copy_from_slice(w_top);
}

/// The backward triangle of a supernode whose block starts `block` (columns `ld` apart),
/// on its columns' unknowns `w` (the rows below already subtracted), last column first.
#[inline(always)]
fn back_triangle<V: Stored, const AVX2: bool>(block: &[V], ld: usize, w: &mut [Real]) {
    let nc = w.len();
    for j in (0..nc).rev() {
        let col = &block[j * ld..j * ld + nc];
        let d = dot_for::<V, AVX2>(&col[j + 1..], &w[j + 1..nc]);
        w[j] = (w[j] - d) / col[j].widen();
    }
}

/// `dot`, with AVX2 intrinsics when compiled for it (`AVX2`).
#[inline(always)]
fn dot_for<V: Stored, const AVX2: bool>(a: &[V], b: &[Real]) -> Real {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: only `run_avx2`, called when AVX2 was detected, passes `AVX2`.
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
