//! The corotated stiffness assembled once per step into 3×3 block-sparse rows (BSR).
//!
//! The matrix-free product recomputes F, R σ and the scatter of every element in every CG
//! iteration; with the rotations fixed over a step it is cheaper to assemble K = Σ R K_e Rᵀ
//! once (16 blocks per element) into a pattern fixed at construction (node-node adjacency of
//! the tets), so that each CG product is one mat-vec over the nodes. K is symmetric, so only
//! the blocks on and above the diagonal are stored (half the memory traffic per product).
//!
//! Block (a, b) of an element, with g the shape-function gradients and ĝ = R g:
//! V (λ ĝ_a ĝ_bᵀ + μ ĝ_b ĝ_aᵀ + μ (g_a·g_b) I), the product rule of `force::add_stiffness_product`.

use crate::math::{Mat3, Real};
use crate::solve::BlockPattern;

use super::force::{ElementRest, Lame, Lames};

/// The slot of a block below the diagonal (not stored).
const SKIP: u32 = u32::MAX;

/// A 3×3 block, row-major.
type Block = [Real; 9];

/// blk += one element's block (a, b): l ĝ_a ĝ_bᵀ + m ĝ_b ĝ_aᵀ + d I, with ĝ = R g, l = λV,
/// m = μV and d = μV g_a·g_b.
#[inline]
fn add_term(blk: &mut Block, ga: &[Real; 3], gb: &[Real; 3], l: Real, m: Real, d: Real) {
    for i in 0..3 {
        for j in 0..3 {
            blk[3 * i + j] += l * ga[i] * gb[j] + m * gb[i] * ga[j];
        }
        blk[4 * i] += d;
    }
}

/// The node-node stiffness in block-sparse rows, with each element's 16 block slots.
#[derive(Clone, Debug, Default)]
pub struct BlockStiffness {
    /// Row r's blocks (columns ≥ r) are `row_start[r]..row_start[r + 1]`, the first being
    /// the diagonal one.
    row_start: Vec<usize>,
    cols: Vec<u32>,
    blocks: Vec<Block>,
    /// Per element, the slot of block (a, b) at index 4a + b, `SKIP` below the diagonal.
    slots: Vec<[u32; 16]>,
    /// Per node, the slot of its diagonal block.
    diag: Vec<u32>,
    /// Block `s`'s terms are `terms[term_start[s]..term_start[s + 1]]`, each `16 e + k`
    /// (element e's block k = 4a + b), in element order: the parallel assembly gathers them
    /// and adds them in the order the serial one scatters them.
    term_start: Vec<u32>,
    terms: Vec<u32>,
    /// The product's two parts (`apply`): rows `..split` and `split..` (0: one part, on
    /// meshes too small for a second thread to pay). The first part's transposed blocks
    /// reach rows `split..spill_end` of the second.
    split: usize,
    spill_end: usize,
    /// The parallel assembly's scratch, one per element, filled before the blocks gather
    /// their terms (a block's terms recomputing them did five times the rotations' work:
    /// 2 per term, 10 terms per element, against 4).
    prepared: Vec<Prepared>,
}

/// What an element's terms share in one assembly: the rotated gradients ĝ = R g, λV, μV
/// and d = μV g_a·g_b per block k = 4a + b, each computed by the serial scatter's
/// expression so that the gathered sums have its bits.
#[derive(Clone, Copy, Debug, Default)]
struct Prepared {
    rg: [[Real; 3]; 4],
    l: Real,
    m: Real,
    d: [Real; 16],
}

impl Prepared {
    fn new(e: &ElementRest, r: &Mat3, pair: Lame) -> Self {
        let g = e.shape_gradients();
        let (l, m) = (pair.lambda * e.volume, pair.mu * e.volume);
        Self {
            rg: g.map(|ga| (*r * ga).to_array()),
            l,
            m,
            d: std::array::from_fn(|k| m * g[k / 4].dot(g[k % 4])),
        }
    }
}

impl BlockStiffness {
    /// The pattern of `elements` over `nodes` nodes (node ids are < `nodes`, checked at build).
    pub fn new(elements: &[ElementRest], nodes: usize) -> Self {
        let mut adj: Vec<Vec<u32>> = vec![Vec::new(); nodes];
        for e in elements {
            for &a in &e.nodes {
                adj[a as usize].extend(e.nodes.iter().filter(|&&b| b >= a));
            }
        }
        let mut row_start = Vec::with_capacity(nodes + 1);
        let mut cols = Vec::new();
        row_start.push(0);
        for row in &mut adj {
            row.sort_unstable();
            row.dedup();
            cols.extend_from_slice(row);
            row_start.push(cols.len());
        }
        let slot = |a: u32, b: u32| -> u32 {
            if b < a {
                return SKIP;
            }
            let (s, t) = (row_start[a as usize], row_start[a as usize + 1]);
            // The pattern contains every (a, b) of every element by construction.
            let k = cols[s..t].binary_search(&b).unwrap_or(0);
            (s + k) as u32
        };
        let slots: Vec<[u32; 16]> = elements
            .iter()
            .map(|e| {
                let mut s = [0u32; 16];
                for (k, sk) in s.iter_mut().enumerate() {
                    *sk = slot(e.nodes[k / 4], e.nodes[k % 4]);
                }
                s
            })
            .collect();
        let diag = (0..nodes as u32).map(|a| slot(a, a)).collect();
        let mut term_start = vec![0u32; cols.len() + 1];
        for e in &slots {
            for &sk in e.iter().filter(|&&sk| sk != SKIP) {
                term_start[sk as usize + 1] += 1;
            }
        }
        for s in 0..cols.len() {
            term_start[s + 1] += term_start[s];
        }
        let mut fill = term_start.clone();
        let mut terms = vec![0u32; term_start[cols.len()] as usize];
        for (e, el) in slots.iter().enumerate() {
            for (k, &sk) in el.iter().enumerate() {
                if sk != SKIP {
                    terms[fill[sk as usize] as usize] = (16 * e + k) as u32;
                    fill[sk as usize] += 1;
                }
            }
        }
        // Split where half the blocks are above: a fixed choice of the structure, so the
        // product's bits do not depend on the thread count.
        let split = if elements.len() >= super::force::PARALLEL_MIN_ELEMENTS {
            row_start
                .partition_point(|&s| 2 * s < cols.len())
                .min(nodes)
        } else {
            0
        };
        let spill_end = cols[..row_start[split]]
            .iter()
            .map(|&c| c as usize + 1)
            .max()
            .unwrap_or(split)
            .max(split);
        Self {
            split,
            spill_end,
            blocks: vec![[0.0; 9]; cols.len()],
            row_start,
            cols,
            slots,
            diag,
            term_start,
            terms,
            prepared: Vec::new(),
        }
    }

    pub fn memory_bytes(&self) -> usize {
        self.row_start.len() * 8
            + self.cols.len() * 4
            + self.blocks.len() * 72
            + self.slots.len() * 64
            + self.diag.len() * 4
            + (self.term_start.len() + self.terms.len()) * 4
            + self.prepared.len() * std::mem::size_of::<Prepared>()
    }

    /// K = Σ R K_e Rᵀ for the given element rotations. On large meshes (and the `parallel`
    /// feature) each block gathers its terms on rayon's threads, in element order, with the
    /// arithmetic of the serial scatter: the same bits on any number of threads.
    pub fn assemble(&mut self, elements: &[ElementRest], lame: &Lames, rotations: &[Mat3]) {
        #[cfg(feature = "parallel")]
        if elements.len() >= super::force::PARALLEL_MIN_ELEMENTS
            && rayon::current_num_threads() > 1
            && self.slots.len() == elements.len()
        {
            use rayon::prelude::*;
            self.prepared.resize(elements.len(), Prepared::default());
            self.prepared
                .par_iter_mut()
                .enumerate()
                .with_min_len(1024)
                .for_each(|(e, p)| *p = Prepared::new(&elements[e], &rotations[e], lame.at(e)));
            let (start, terms, prepared) = (&self.term_start, &self.terms, &self.prepared);
            self.blocks
                .par_iter_mut()
                .enumerate()
                .with_min_len(256)
                .for_each(|(s, blk)| {
                    *blk = [0.0; 9];
                    for &t in &terms[start[s] as usize..start[s + 1] as usize] {
                        let (e, k) = (t as usize / 16, t as usize % 16);
                        let p = &prepared[e];
                        add_term(blk, &p.rg[k / 4], &p.rg[k % 4], p.l, p.m, p.d[k]);
                    }
                });
            return;
        }
        self.blocks.iter_mut().for_each(|b| *b = [0.0; 9]);
        let blocks = &mut self.blocks;
        for (i, ((e, r), slots)) in elements.iter().zip(rotations).zip(&self.slots).enumerate() {
            let p = Prepared::new(e, r, lame.at(i));
            for (k, &s) in slots.iter().enumerate() {
                if s != SKIP {
                    add_term(
                        &mut blocks[s as usize],
                        &p.rg[k / 4],
                        &p.rg[k % 4],
                        p.l,
                        p.m,
                        p.d[k],
                    );
                }
            }
        }
    }

    /// The stored blocks as a full symmetric matrix on `pattern` (both triangles; the pattern
    /// must be the node adjacency of the same elements, 3 unknowns per node). Blocks of
    /// `held` nodes (rows and columns) are left out.
    pub fn to_pattern_values(&self, pattern: &BlockPattern, held: &[bool]) -> Vec<Real> {
        let mut values = vec![0.0; pattern.nnz()];
        for (a, w) in self.row_start.windows(2).enumerate() {
            for (blk, &b) in self.blocks[w[0]..w[1]].iter().zip(&self.cols[w[0]..w[1]]) {
                let b = b as usize;
                if held[a] || held[b] {
                    continue;
                }
                for i in 0..3 {
                    for j in 0..3 {
                        let v = blk[3 * i + j];
                        if let Some(s) = pattern.slot(3 * a + i, 3 * b + j) {
                            values[s] = v;
                        }
                        if a != b
                            && let Some(s) = pattern.slot(3 * b + j, 3 * a + i)
                        {
                            values[s] = v;
                        }
                    }
                }
            }
        }
        values
    }

    /// diag += the diagonal of K (flat).
    pub fn add_diagonal(&self, diag: &mut [Real]) {
        for (d, &s) in diag.chunks_exact_mut(3).zip(&self.diag) {
            let b = &self.blocks[s as usize];
            d[0] += b[0];
            d[1] += b[4];
            d[2] += b[8];
        }
    }

    /// y = c_m m z + c_k K z per node (flat z, y; `masses` per node).
    ///
    /// Each stored block adds to its own row and (off the diagonal) its transpose to its
    /// column's row, so a row's sum runs over the rows before it. On large meshes the rows
    /// are cut in two parts at `split`: the first part's transposed blocks that reach the
    /// second go into a buffer of their own, added to those rows after the second part has
    /// summed its own; the parts run on two of rayon's threads when there are several, in
    /// turn otherwise, with the same arithmetic: the same bits on any number of threads.
    pub fn apply(&self, cm: Real, ck: Real, masses: &[Real], z: &[Real], y: &mut [Real]) {
        let (n, split) = (self.row_start.len() - 1, self.split);
        if split == 0 {
            self.rows(0..n, z, y, 0, &mut []);
            mass_term(cm, ck, masses, z, y);
            return;
        }
        let (y0, y1) = y.split_at_mut(3 * split);
        let mut spill = vec![0.0; 3 * (self.spill_end - split)];
        let (z0, z1) = z.split_at(3 * split);
        let (m0, m1) = masses.split_at(split);
        let settled = 3 * (self.spill_end - split);
        let mut first = || {
            self.rows(0..split, z, y0, 0, &mut spill);
            mass_term(cm, ck, m0, z0, y0);
        };
        let mut second = || {
            self.rows(split..n, z, y1, split, &mut []);
            let at = settled.min(y1.len());
            mass_term(cm, ck, &m1[at / 3..], &z1[at..], &mut y1[at..]);
        };
        #[cfg(feature = "parallel")]
        if rayon::current_num_threads() > 1 {
            rayon::join(first, second);
        } else {
            first();
            second();
        }
        #[cfg(not(feature = "parallel"))]
        {
            first();
            second();
        }
        let y1 = &mut y[3 * split..];
        for (v, s) in y1.iter_mut().zip(&spill) {
            *v += s;
        }
        let at = settled.min(y1.len());
        mass_term(cm, ck, &m1[..at / 3], &z1[..at], &mut y1[..at]);
    }

    /// The blocks of `rows` into `y`, which holds rows `base..` (zeroed first); transposed
    /// blocks of columns past `y`'s rows into `spill`, which holds the rows after them.
    fn rows(
        &self,
        rows: std::ops::Range<usize>,
        z: &[Real],
        y: &mut [Real],
        base: usize,
        spill: &mut [Real],
    ) {
        y.iter_mut().for_each(|v| *v = 0.0);
        let end = 3 * base + y.len();
        for r in rows {
            let w = &self.row_start[r..r + 2];
            let i = 3 * r;
            let (zr0, zr1, zr2) = (z[i], z[i + 1], z[i + 2]);
            let (mut s0, mut s1, mut s2) = (0.0, 0.0, 0.0);
            for (b, &c) in self.blocks[w[0]..w[1]].iter().zip(&self.cols[w[0]..w[1]]) {
                let c = 3 * c as usize;
                let (z0, z1, z2) = (z[c], z[c + 1], z[c + 2]);
                s0 += b[0] * z0 + b[1] * z1 + b[2] * z2;
                s1 += b[3] * z0 + b[4] * z1 + b[5] * z2;
                s2 += b[6] * z0 + b[7] * z1 + b[8] * z2;
                if c != i {
                    // The block below the diagonal is this one's transpose.
                    let t = if c < end {
                        &mut y[c - 3 * base..c - 3 * base + 3]
                    } else {
                        &mut spill[c - end..c - end + 3]
                    };
                    t[0] += b[0] * zr0 + b[3] * zr1 + b[6] * zr2;
                    t[1] += b[1] * zr0 + b[4] * zr1 + b[7] * zr2;
                    t[2] += b[2] * zr0 + b[5] * zr1 + b[8] * zr2;
                }
            }
            let o = i - 3 * base;
            y[o] += s0;
            y[o + 1] += s1;
            y[o + 2] += s2;
        }
    }

    /// The product on one part and in one row order, as before the split (tests).
    #[cfg(test)]
    pub fn without_split(mut self) -> Self {
        self.split = 0;
        self
    }
}

/// y = c_m m z + c_k y per node.
fn mass_term(cm: Real, ck: Real, masses: &[Real], z: &[Real], y: &mut [Real]) {
    for ((yr, zr), m) in y.chunks_exact_mut(3).zip(z.chunks_exact(3)).zip(masses) {
        let cmm = cm * m;
        yr[0] = cmm * zr[0] + ck * yr[0];
        yr[1] = cmm * zr[1] + ck * yr[1];
        yr[2] = cmm * zr[2] + ck * yr[2];
    }
}
