//! The element form's St Venant–Kirchhoff force kernel, packed for speed: the hot loop of
//! `tensor-mass-nonlinear`.
//!
//! The plain per-element code (`element::stvk_forces_energy`) reads a 4-gradient `TetRest`
//! and a 9-field `Elasticity` per tetrahedron and works through 3×3 matrix products in
//! glam's general form. Here the isotropic tetrahedra of the non-linear set are packed four
//! to a `Block`, one per lane (structure of arrays inside the block): corner ids, the
//! gradients g_1..g_3 (g_0 = −Σ g_a is never stored: H = Σ_{a≥1} (u_a − u_0) g_aᵀ), and
//! λV, 2μV, κV (the volume folded into the constants). The kernel computes only the six
//! distinct entries of the symmetric E and S, fuses the energy ½ V E:S into the same pass
//! (the blow-up guard asks for it every step), adds the volume penalty when it is on, and
//! writes P' = F S' straight into the corner forces −P' g_a.
//!
//! One generic kernel, over lanes of four f64 (one block at a time) or of `f64` (one
//! tetrahedron at a time, the tests' cross-check). The block path has two lane types: on
//! x86-64 with AVX2 and FMA (checked at run time) `avx::V4`, one `__m256d` per value, every
//! operation one intrinsic, multiply-adds fused, corners gathered and scattered as 256-bit
//! rows of a padded copy of the nodes (`Padded`) turned into lanes by 4×4 transposes in
//! registers; elsewhere `W4`, arrays that LLVM vectorises for the baseline target (SSE2 or
//! NEON pairs), unfused: the same operations in the same order as the scalar path, so the
//! same bits. The fused path agrees with them to rounding (1e-15 relative on the tests'
//! meshes).
//!
//! Large meshes are cut into a few runs of blocks (`PART_BLOCKS`), each summed into its own
//! force buffer and then added in run order: the runs go to rayon's threads when that
//! measures faster (`Chooser`), with the same bits either way.

// Matrix algebra on small fixed arrays reads clearest with explicit indices.
#![allow(clippy::needless_range_loop)]

use std::ops::{Add, Mul, Neg, Sub};

use crate::math::{Real, Vec3};

use super::elasticity::{Elasticity, TetRest};

/// Tetrahedra per block.
pub const LANES: usize = 4;

/// Four tetrahedra, one per lane; unused lanes of the last block have zero constants.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
struct Block {
    nodes: [[u32; LANES]; 4],
    /// g[3a + j][lane]: component j of g_{a+1}.
    g: [[Real; LANES]; 9],
    lambda_v: [Real; LANES],
    mu2_v: [Real; LANES],
    /// κV of the volume penalty.
    kappa_v: [Real; LANES],
}

/// A node's 3-vector padded to four f64 (the fourth zero), aligned: the gather and the
/// scatter move a corner with one 256-bit load (and store) instead of three scalars, and
/// turn four corners into lanes with a 4×4 transpose in registers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
struct Padded([Real; 4]);

/// A run of consecutive blocks whose forces go into their own buffer, over the nodes
/// `lo..lo + f.len()` its tetrahedra touch, and whose energy is summed on its own. The runs
/// are fixed by the mesh (see `PART_BLOCKS`), not by the thread count, and their buffers are
/// added into the node forces in run order: one thread and several give the same bits.
#[derive(Clone, Debug, Default)]
struct Part {
    blocks: std::ops::Range<usize>,
    lo: usize,
    f: Vec<Padded>,
    energy: Real,
}

/// The packed isotropic tetrahedra of the element form's non-linear set.
#[derive(Clone, Debug, Default)]
pub struct ElementKernel {
    blocks: Vec<Block>,
    len: usize,
    /// 1 + the largest corner id: the node arrays must be at least this long.
    nodes_needed: usize,
    /// The St Venant–Kirchhoff terms are on (off: a volume-penalty-only pass).
    stvk: bool,
    /// The volume penalty is on (κ > 0): its force and energy are fused into the pass.
    penalty: bool,
    parts: Vec<Part>,
    /// The displacements of the pass, padded.
    u: Vec<Padded>,
    /// Whether the parts run on rayon's threads: measured, not guessed (see `Chooser`).
    #[cfg(feature = "parallel")]
    chooser: crate::solve::chooser::Chooser,
}

/// Blocks (of four tetrahedra) per run: a mesh of `n` blocks is cut into
/// `n / PART_BLOCKS` runs (at least 1, at most `MAX_PARTS`), each computed as one task.
/// Below 2 × `PART_BLOCKS` blocks (8,192 tetrahedra) the pass is one run, whose sums are
/// those of a plain loop over the blocks.
pub const PART_BLOCKS: usize = 1024;

/// At most this many runs: each has its own force buffer to clear and add up, so more runs
/// than the cores that can share them cost a little and gain nothing on two cores.
pub const MAX_PARTS: usize = 4;

impl ElementKernel {
    /// Packs tetrahedra `list` (isotropic: `Elasticity::has_fibre` false) in the given order,
    /// with the volume penalty `kappa` (0: off).
    pub fn new(
        tets: &[[u32; 4]],
        rest: &[TetRest],
        el: &[Elasticity],
        list: &[u32],
        kappa: Real,
    ) -> Self {
        Self::packed(tets, rest, Some(el), list, kappa)
    }

    /// The volume penalty alone (any material) of tetrahedra `list`.
    pub fn penalty_only(tets: &[[u32; 4]], rest: &[TetRest], list: &[u32], kappa: Real) -> Self {
        Self::packed(tets, rest, None, list, kappa)
    }

    fn packed(
        tets: &[[u32; 4]],
        rest: &[TetRest],
        el: Option<&[Elasticity]>,
        list: &[u32],
        kappa: Real,
    ) -> Self {
        let mut blocks = Vec::with_capacity(list.len().div_ceil(LANES));
        let mut nodes_needed = 0;
        for chunk in list.chunks(LANES) {
            let mut b = Block::default();
            for (k, &t) in chunk.iter().enumerate() {
                let t = t as usize;
                let r = &rest[t];
                for c in 0..4 {
                    b.nodes[c][k] = tets[t][c];
                    nodes_needed = nodes_needed.max(tets[t][c] as usize + 1);
                }
                for a in 0..3 {
                    for j in 0..3 {
                        b.g[3 * a + j][k] = r.gradients[a + 1][j];
                    }
                }
                if let Some(e) = el.and_then(|el| el.get(t)) {
                    b.lambda_v[k] = e.lambda * r.volume;
                    b.mu2_v[k] = 2.0 * e.mu * r.volume;
                }
                b.kappa_v[k] = kappa * r.volume;
            }
            // Unused lanes read the first tetrahedron's corners (valid ids) and, with zero
            // constants, are never scattered.
            for k in chunk.len()..LANES {
                for c in 0..4 {
                    b.nodes[c][k] = b.nodes[c][0];
                }
            }
            blocks.push(b);
        }
        let runs = (blocks.len() / PART_BLOCKS).clamp(1, MAX_PARTS);
        let per = blocks.len().div_ceil(runs);
        let parts = (0..runs)
            .map(|p| {
                let range = (p * per).min(blocks.len())..((p + 1) * per).min(blocks.len());
                let (mut lo, mut hi) = (usize::MAX, 0);
                for b in range.clone() {
                    for c in 0..4 {
                        for &v in &blocks[b].nodes[c][..lanes_used(b, list.len())] {
                            lo = lo.min(v as usize);
                            hi = hi.max(v as usize + 1);
                        }
                    }
                }
                let lo = lo.min(hi);
                Part {
                    blocks: range,
                    lo,
                    f: vec![Padded::default(); hi - lo],
                    energy: 0.0,
                }
            })
            .collect();
        Self {
            blocks,
            len: list.len(),
            nodes_needed,
            stvk: el.is_some(),
            penalty: kappa > 0.0,
            parts,
            u: Vec::new(),
            #[cfg(feature = "parallel")]
            chooser: Default::default(),
        }
    }

    /// Tetrahedra packed.
    #[allow(clippy::len_without_is_empty)]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Runs the pass is cut into (see `PART_BLOCKS`).
    #[cfg(test)]
    pub fn parts(&self) -> usize {
        self.parts.len()
    }

    /// Bytes of packed data the force pass reads.
    pub fn bytes(&self) -> usize {
        self.blocks.len() * std::mem::size_of::<Block>()
    }

    /// Tests: run the parts on rayon's threads always (`Some(true)`), never, or as measured
    /// (`None`).
    #[cfg(all(test, feature = "parallel"))]
    pub fn force_parallel(&mut self, on: Option<bool>) {
        self.chooser.force(on);
    }

    /// f += the St Venant–Kirchhoff forces at displacements `u`; returns their energy.
    /// Four lanes in AVX2 registers when the CPU has AVX2 and FMA, else in pairs of the
    /// baseline's (SSE2 on x86-64, NEON on aarch64): ≈ 1.5× slower, still ≈ 1.4× faster
    /// than one tetrahedron at a time.
    /// Large meshes are cut into runs computed on rayon's threads when that measures faster
    /// (`Chooser`); the same bits either way.
    pub fn add_forces(&mut self, u: &[Vec3], f: &mut [Vec3]) -> Real {
        if u.len() < self.nodes_needed || f.len() < self.nodes_needed {
            return 0.0;
        }
        if !self.stvk && !self.penalty {
            return 0.0;
        }
        self.u.clear();
        self.u.extend(
            u[..self.nodes_needed]
                .iter()
                .map(|p| Padded([p.x, p.y, p.z, 0.0])),
        );
        let path = VectorPath::detect();
        let (blocks, len, u, stvk, penalty) =
            (&self.blocks, self.len, &self.u, self.stvk, self.penalty);
        let run = |part: &mut Part| match (stvk, penalty) {
            (true, true) => run_part::<true, true>(blocks, len, u, path, part),
            (true, false) => run_part::<true, false>(blocks, len, u, path, part),
            (false, true) => run_part::<false, true>(blocks, len, u, path, part),
            (false, false) => {}
        };
        #[cfg(feature = "parallel")]
        if self.parts.len() > 1 && rayon::current_num_threads() > 1 {
            use rayon::prelude::*;
            let parallel = self.chooser.pick();
            let start = std::time::Instant::now();
            if parallel {
                self.parts.par_iter_mut().for_each(run);
            } else {
                self.parts.iter_mut().for_each(run);
            }
            self.chooser.record(parallel, start.elapsed());
            return sum_parts(&self.parts, f);
        }
        self.parts.iter_mut().for_each(run);
        sum_parts(&self.parts, f)
    }

    /// The block path compiled for the baseline target only (the fallback of `add_forces`),
    /// as one run.
    #[cfg(test)]
    pub fn add_forces_baseline(&self, u: &[Vec3], f: &mut [Vec3]) -> Real {
        self.add_forces_on(VectorPath::Baseline, u, f)
    }

    /// The block path on `path` (which the CPU must support: `VectorPath::detect` says
    /// which it does), as one run.
    #[cfg(test)]
    pub fn add_forces_on(&self, path: VectorPath, u: &[Vec3], f: &mut [Vec3]) -> Real {
        let up: Vec<Padded> = u.iter().map(|p| Padded([p.x, p.y, p.z, 0.0])).collect();
        let mut part = Part {
            blocks: 0..self.blocks.len(),
            lo: 0,
            f: vec![Padded::default(); u.len()],
            energy: 0.0,
        };
        let (b, len) = (&self.blocks, self.len);
        match (self.stvk, self.penalty) {
            (true, true) => run_part::<true, true>(b, len, &up, path, &mut part),
            (true, false) => run_part::<true, false>(b, len, &up, path, &mut part),
            (false, true) => run_part::<false, true>(b, len, &up, path, &mut part),
            (false, false) => {}
        }
        sum_parts(std::slice::from_ref(&part), f)
    }

    /// One tetrahedron at a time in plain f64 (the same arithmetic as the block path).
    #[cfg(test)]
    pub fn add_forces_scalar(&self, u: &[Vec3], f: &mut [Vec3]) -> Real {
        let mut w = 0.0;
        for (b, block) in self.blocks.iter().enumerate() {
            for k in 0..lanes_used(b, self.len) {
                let u0 = u[block.nodes[0][k] as usize];
                let mut d = [[0.0; 3]; 3];
                let mut g = [[0.0; 3]; 3];
                for a in 0..3 {
                    let ua = u[block.nodes[a + 1][k] as usize];
                    d[a] = [ua.x - u0.x, ua.y - u0.y, ua.z - u0.z];
                    for j in 0..3 {
                        g[a][j] = block.g[3 * a + j][k];
                    }
                }
                let c = [block.lambda_v[k], block.mu2_v[k], block.kappa_v[k]];
                let (fc, e) = match (self.stvk, self.penalty) {
                    (true, true) => stvk::<Real, true, true>(&d, &g, c),
                    (true, false) => stvk::<Real, true, false>(&d, &g, c),
                    (false, true) => stvk::<Real, false, true>(&d, &g, c),
                    (false, false) => ([[0.0; 3]; 4], 0.0),
                };
                for c in 0..4 {
                    f[block.nodes[c][k] as usize] += Vec3::from_array(fc[c]);
                }
                w += e;
            }
        }
        w
    }
}

fn lanes_used(block: usize, len: usize) -> usize {
    (len - block * LANES).min(LANES)
}

/// Adds the runs' buffers into the node forces, run by run, and returns their energy.
fn sum_parts(parts: &[Part], f: &mut [Vec3]) -> Real {
    let mut w = 0.0;
    for part in parts {
        for (fi, p) in f[part.lo..].iter_mut().zip(&part.f) {
            *fi += Vec3::new(p.0[0], p.0[1], p.0[2]);
        }
        w += part.energy;
    }
    w
}

/// Which compiled instance of the block path runs: chosen once per pass from what the CPU
/// has (the check is a cached load).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VectorPath {
    /// The baseline target (SSE2 or NEON pairs), unfused.
    Baseline,
    /// `avx::V4` lanes compiled for AVX2 and FMA: 16 vector registers.
    Avx2,
    /// The same `avx::V4` code compiled with AVX-512F and VL as well: the EVEX encoding
    /// gives 32 vector registers, so the ~100 spills per block the 16 registers forced (H,
    /// S, P and the gradients live at once) go, and the 20k beam's step is ~15 % cheaper.
    /// The arithmetic is the same operations in the same order: the same bits as `Avx2`.
    Avx512,
}

impl VectorPath {
    pub fn detect() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            let avx2 =
                std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
            let avx512 = std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512vl");
            match (avx2, avx512) {
                (true, true) => Self::Avx512,
                (true, false) => Self::Avx2,
                _ => Self::Baseline,
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        Self::Baseline
    }
}

/// One run on the instance `path` names.
#[inline(always)]
fn run_part<const STVK: bool, const PENALTY: bool>(
    blocks: &[Block],
    len: usize,
    u: &[Padded],
    path: VectorPath,
    part: &mut Part,
) {
    #[cfg(target_arch = "x86_64")]
    match path {
        // SAFETY: `VectorPath::detect` found the features these functions are compiled for.
        VectorPath::Avx512 => return unsafe { part_avx512::<STVK, PENALTY>(blocks, len, u, part) },
        // SAFETY: as above.
        VectorPath::Avx2 => return unsafe { part_avx2::<STVK, PENALTY>(blocks, len, u, part) },
        VectorPath::Baseline => {}
    }
    let _ = path;
    part_wide::<W4, STVK, PENALTY>(blocks, len, u, part);
}

/// The AVX2 instance of `part_wide`, on `avx::V4` lanes.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn part_avx2<const STVK: bool, const PENALTY: bool>(
    blocks: &[Block],
    len: usize,
    u: &[Padded],
    part: &mut Part,
) {
    part_wide::<avx::V4, STVK, PENALTY>(blocks, len, u, part)
}

/// `part_avx2` compiled with AVX-512F and VL too (see `VectorPath::Avx512`).
///
/// # Safety
/// The CPU must support AVX2, FMA, AVX-512F and AVX-512VL.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,avx512f,avx512vl")]
unsafe fn part_avx512<const STVK: bool, const PENALTY: bool>(
    blocks: &[Block],
    len: usize,
    u: &[Padded],
    part: &mut Part,
) {
    part_wide::<avx::V4, STVK, PENALTY>(blocks, len, u, part)
}

/// The vector path over one run: one block per iteration, four tetrahedra in the lanes,
/// the corner forces summed into the run's buffer in block, lane, corner order (the order
/// of the one-tetrahedron path). Inlined into its callers, so it is compiled for their
/// target features.
#[inline(always)]
fn part_wide<L: Wide, const STVK: bool, const PENALTY: bool>(
    blocks: &[Block],
    len: usize,
    u: &[Padded],
    part: &mut Part,
) {
    part.f.fill(Padded::default());
    let mut w = 0.0;
    // Full blocks first, with the lane count a constant (their lane loops unrolled), then
    // the last block of the mesh when it is partial and in this run.
    let full_end = (len / LANES).clamp(part.blocks.start, part.blocks.end);
    for b in part.blocks.start..full_end {
        block_pass::<L, STVK, PENALTY>(&blocks[b], LANES, u, &mut part.f, part.lo, &mut w);
    }
    for b in full_end..part.blocks.end {
        let lanes = lanes_used(b, len);
        block_pass::<L, STVK, PENALTY>(&blocks[b], lanes, u, &mut part.f, part.lo, &mut w);
    }
    part.energy = w;
}

/// One block: its corner forces into the run's buffer, the energy of its `lanes` used
/// lanes added to `w` lane by lane.
#[inline(always)]
fn block_pass<L: Wide, const STVK: bool, const PENALTY: bool>(
    block: &Block,
    lanes: usize,
    u: &[Padded],
    fp: &mut [Padded],
    lo: usize,
    w: &mut Real,
) {
    let uc = L::gather(block, u);
    let mut d = [[L::splat(0.0); 3]; 3];
    let mut g = [[L::splat(0.0); 3]; 3];
    for a in 0..3 {
        for i in 0..3 {
            d[a][i] = uc[a + 1][i] - uc[0][i];
            g[a][i] = L::load(&block.g[3 * a + i]);
        }
    }
    let c = [
        L::load(&block.lambda_v),
        L::load(&block.mu2_v),
        L::load(&block.kappa_v),
    ];
    let (f, e) = stvk::<L, STVK, PENALTY>(&d, &g, c);
    L::scatter(block, lanes, &f, fp, lo);
    let e = e.lanes();
    for k in 0..lanes {
        *w += e[k];
    }
}

/// What the kernel needs of a lane type: f64 or four of them.
trait Lane:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self>
{
    fn splat(x: Real) -> Self;
    /// self·b + c: fused (one rounding) on the AVX2 path, else a product and a sum.
    fn mul_add(self, b: Self, c: Self) -> Self;
}

/// Four lanes, one tetrahedron of a block each, with the block's gather and scatter.
trait Wide: Lane {
    fn load(x: &[Real; LANES]) -> Self;
    fn lanes(self) -> [Real; LANES];
    /// uc[c][i], lane k: component i of the displacement at corner c of tetrahedron k.
    fn gather(block: &Block, u: &[Padded]) -> [[Self; 3]; 4];
    /// Adds the `lanes` used lanes' corner forces into the run's buffer `fp` (node `lo`
    /// first), lane by lane, corner by corner.
    fn scatter(block: &Block, lanes: usize, f: &[[Self; 3]; 4], fp: &mut [Padded], lo: usize);
}

impl Lane for Real {
    #[inline(always)]
    fn splat(x: Real) -> Self {
        x
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        self * b + c
    }
}

/// Four f64 lanes in an array, element-wise operations that LLVM vectorises for the
/// baseline target (SSE2 or NEON pairs); never fused, so the same bits as `f64` one
/// tetrahedron at a time.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct W4([Real; LANES]);

macro_rules! lanewise {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for W4 {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                W4([
                    self.0[0] $op o.0[0],
                    self.0[1] $op o.0[1],
                    self.0[2] $op o.0[2],
                    self.0[3] $op o.0[3],
                ])
            }
        }
    };
}
lanewise!(Add, add, +);
lanewise!(Sub, sub, -);
lanewise!(Mul, mul, *);

impl Neg for W4 {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        W4([-self.0[0], -self.0[1], -self.0[2], -self.0[3]])
    }
}

impl Lane for W4 {
    #[inline(always)]
    fn splat(x: Real) -> Self {
        W4([x; LANES])
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        self * b + c
    }
}

impl Wide for W4 {
    #[inline(always)]
    fn load(x: &[Real; LANES]) -> Self {
        W4(*x)
    }
    #[inline(always)]
    fn lanes(self) -> [Real; LANES] {
        self.0
    }
    #[inline(always)]
    fn gather(block: &Block, u: &[Padded]) -> [[Self; 3]; 4] {
        let mut uc = [[W4([0.0; LANES]); 3]; 4];
        for c in 0..4 {
            for k in 0..LANES {
                let p = u[block.nodes[c][k] as usize].0;
                for i in 0..3 {
                    uc[c][i].0[k] = p[i];
                }
            }
        }
        uc
    }
    #[inline(always)]
    fn scatter(block: &Block, lanes: usize, f: &[[Self; 3]; 4], fp: &mut [Padded], lo: usize) {
        for k in 0..lanes {
            for c in 0..4 {
                let p = &mut fp[block.nodes[c][k] as usize - lo].0;
                for i in 0..3 {
                    p[i] += f[c][i].0[k];
                }
            }
        }
    }
}

/// The AVX2 lanes: one `__m256d` per value, every operation one intrinsic (multiply-adds
/// fused), the gather and scatter as 256-bit loads, stores and 4×4 transposes in registers.
/// Written with intrinsics rather than left to LLVM's vectoriser, which turned the
/// transposes' mix of arrays and vectors into scalar code and stack traffic.
///
/// `V4` values exist only inside `part_avx2` and `part_avx512` (compiled for AVX2 and FMA,
/// called after the CPU was checked): every function here is inlined into it, which is what makes the
/// intrinsics' `unsafe` sound.
#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;
    use std::ops::{Add, Mul, Neg, Sub};

    use super::{Block, LANES, Lane, Padded, Real, Wide};

    #[derive(Clone, Copy)]
    pub(super) struct V4(__m256d);

    macro_rules! op {
        ($tr:ident, $f:ident, $intr:ident) => {
            impl $tr for V4 {
                type Output = Self;
                #[inline(always)]
                fn $f(self, o: Self) -> Self {
                    // SAFETY: see the module's note.
                    V4(unsafe { $intr(self.0, o.0) })
                }
            }
        };
    }
    op!(Add, add, _mm256_add_pd);
    op!(Sub, sub, _mm256_sub_pd);
    op!(Mul, mul, _mm256_mul_pd);

    impl Neg for V4 {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            // Flips the sign bits, as f64's negation does.
            // SAFETY: see the module's note.
            V4(unsafe { _mm256_xor_pd(self.0, _mm256_set1_pd(-0.0)) })
        }
    }

    impl Lane for V4 {
        #[inline(always)]
        fn splat(x: Real) -> Self {
            // SAFETY: see the module's note.
            V4(unsafe { _mm256_set1_pd(x) })
        }
        #[inline(always)]
        fn mul_add(self, b: Self, c: Self) -> Self {
            // SAFETY: see the module's note.
            V4(unsafe { _mm256_fmadd_pd(self.0, b.0, c.0) })
        }
    }

    /// A padded node vector as a register.
    #[inline(always)]
    fn row(p: &Padded) -> __m256d {
        // SAFETY: `Padded` is four f64, aligned to 32 bytes; see the module's note.
        unsafe { _mm256_load_pd(p.0.as_ptr()) }
    }

    impl Wide for V4 {
        #[inline(always)]
        fn load(x: &[Real; LANES]) -> Self {
            // SAFETY: four f64 (the block's arrays are unaligned-safe with loadu).
            V4(unsafe { _mm256_loadu_pd(x.as_ptr()) })
        }
        #[inline(always)]
        fn lanes(self) -> [Real; LANES] {
            let mut out = [0.0; LANES];
            // SAFETY: four f64; see the module's note.
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), self.0) };
            out
        }
        #[inline(always)]
        fn gather(block: &Block, u: &[Padded]) -> [[Self; 3]; 4] {
            // Every corner id is below `nodes_needed`, and `add_forces` made `u` that long.
            let at = |v: u32| {
                debug_assert!((v as usize) < u.len());
                // SAFETY: in bounds (above).
                row(unsafe { u.get_unchecked(v as usize) })
            };
            // SAFETY: see the module's note.
            unsafe {
                let zero = V4(_mm256_setzero_pd());
                let mut uc = [[zero; 3]; 4];
                for c in 0..4 {
                    let n = block.nodes[c];
                    // Rows (x, y, z, 0) of the four lanes.
                    let (r0, r1, r2, r3) = (at(n[0]), at(n[1]), at(n[2]), at(n[3]));
                    let t0 = _mm256_unpacklo_pd(r0, r1); // x0 x1 z0 z1
                    let t1 = _mm256_unpackhi_pd(r0, r1); // y0 y1 0 0
                    let t2 = _mm256_unpacklo_pd(r2, r3); // x2 x3 z2 z3
                    let t3 = _mm256_unpackhi_pd(r2, r3); // y2 y3 0 0
                    uc[c][0] = V4(_mm256_permute2f128_pd(t0, t2, 0x20));
                    uc[c][1] = V4(_mm256_permute2f128_pd(t1, t3, 0x20));
                    uc[c][2] = V4(_mm256_permute2f128_pd(t0, t2, 0x31));
                }
                uc
            }
        }
        /// Corner by corner, then lane by lane (not the baseline's lane-major order: the
        /// sixteen transposed rows would not fit in registers); the sums differ from the
        /// baseline's by rounding only, as the fused multiply-adds already make them.
        #[inline(always)]
        fn scatter(block: &Block, lanes: usize, f: &[[Self; 3]; 4], fp: &mut [Padded], lo: usize) {
            // SAFETY: see the module's note.
            unsafe {
                let zero = _mm256_setzero_pd();
                for c in 0..4 {
                    let (x, y, z) = (f[c][0].0, f[c][1].0, f[c][2].0);
                    let t0 = _mm256_unpacklo_pd(x, y); // x0 y0 x2 y2
                    let t1 = _mm256_unpackhi_pd(x, y); // x1 y1 x3 y3
                    let t2 = _mm256_unpacklo_pd(z, zero); // z0 0 z2 0
                    let t3 = _mm256_unpackhi_pd(z, zero); // z1 0 z3 0
                    let rows = [
                        _mm256_permute2f128_pd(t0, t2, 0x20),
                        _mm256_permute2f128_pd(t1, t3, 0x20),
                        _mm256_permute2f128_pd(t0, t2, 0x31),
                        _mm256_permute2f128_pd(t1, t3, 0x31),
                    ];
                    for k in 0..lanes {
                        // The run's nodes are `lo..lo + fp.len()` (`ElementKernel::packed`).
                        let i = block.nodes[c][k] as usize - lo;
                        debug_assert!(i < fp.len());
                        let p = fp.get_unchecked_mut(i);
                        let sum = _mm256_add_pd(row(p), rows[k]);
                        _mm256_store_pd(p.0.as_mut_ptr(), sum);
                    }
                }
            }
        }
    }
}

/// St Venant–Kirchhoff forces on the four corners and energy of one tetrahedron (per lane).
/// `d[a]` = u_{a+1} − u_0, `g[a]` = g_{a+1}; `c` = [λV, 2μV, κV].
///
/// H = Σ_a d_a g_aᵀ, E = ½(H + Hᵀ + HᵀH), S' = V ℂ:E = 2μV E + λV tr(E) I,
/// P' = (I + H) S', f_{a+1} = −P' g_a, f_0 = −Σ f_{a+1}, energy ½ E:S'.
///
/// With `PENALTY`, the volume penalty (κ/2)(v − V)²/V of `element`: F = I + H maps the
/// rest tetrahedron onto the current one, so v = J V with J = det F and ∂v/∂x_a =
/// V cof(F) g_a. Its force is −κV (J − 1) cof(F) g_a, added to P' as κV (J − 1) cof(F); its
/// energy ½ κV (J − 1)². J − 1 = tr H + i₂(H) + det H, without the cancellation of det F − 1.
///
/// Plain loops over fixed arrays, no closures or `array::map`: those are separate functions
/// that LLVM may leave out of line, compiled without the caller's AVX2.
#[inline(always)]
fn stvk<L: Lane, const STVK: bool, const PENALTY: bool>(
    d: &[[L; 3]; 3],
    g: &[[L; 3]; 3],
    c: [L; 3],
) -> ([[L; 3]; 4], L) {
    let [lv, mv, kv] = c;
    let zero = L::splat(0.0);
    let half = L::splat(0.5);
    let mut h = [[zero; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            h[i][j] = d[2][i].mul_add(g[2][j], d[1][i].mul_add(g[1][j], d[0][i] * g[0][j]));
        }
    }
    let mut energy = zero;
    let mut p = [[zero; 3]; 3];
    if STVK {
        // The six distinct entries of E, in the order 00, 11, 22, 01, 02, 12.
        const IJ: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];
        let mut e = [zero; 6];
        for (k, &(i, j)) in IJ.iter().enumerate() {
            let q = h[2][i].mul_add(h[2][j], h[1][i].mul_add(h[1][j], h[0][i] * h[0][j]));
            e[k] = half * (h[i][j] + h[j][i] + q);
        }
        let lt = lv * (e[0] + e[1] + e[2]);
        let mut sv = [zero; 6];
        for k in 0..6 {
            sv[k] = mv * e[k];
        }
        for k in 0..3 {
            sv[k] = sv[k] + lt;
        }
        let shear = e[5].mul_add(sv[5], e[4].mul_add(sv[4], e[3] * sv[3]));
        let normal = e[2].mul_add(sv[2], e[1].mul_add(sv[1], e[0] * sv[0]));
        energy = half * L::splat(2.0).mul_add(shear, normal);
        let s = [
            [sv[0], sv[3], sv[4]],
            [sv[3], sv[1], sv[5]],
            [sv[4], sv[5], sv[2]],
        ];
        for i in 0..3 {
            for j in 0..3 {
                p[i][j] = h[i][2].mul_add(
                    s[2][j],
                    h[i][1].mul_add(s[1][j], h[i][0].mul_add(s[0][j], s[i][j])),
                );
            }
        }
    }
    if PENALTY {
        // Columns of F and their cross products: cof(F) = [f1 × f2, f2 × f0, f0 × f1].
        let one = L::splat(1.0);
        let mut fcol = [[zero; 3]; 3];
        for j in 0..3 {
            for i in 0..3 {
                fcol[j][i] = if i == j { h[i][j] + one } else { h[i][j] };
            }
        }
        let cof = [
            cross(&fcol[1], &fcol[2]),
            cross(&fcol[2], &fcol[0]),
            cross(&fcol[0], &fcol[1]),
        ];
        let tr = h[0][0] + h[1][1] + h[2][2];
        let i2 = (h[0][0] * h[1][1] - h[0][1] * h[1][0])
            + (h[0][0] * h[2][2] - h[0][2] * h[2][0])
            + (h[1][1] * h[2][2] - h[1][2] * h[2][1]);
        let hc = [[h[0][1], h[1][1], h[2][1]], [h[0][2], h[1][2], h[2][2]]];
        let hxh = cross(&hc[0], &hc[1]);
        let det = h[0][0] * hxh[0] + h[1][0] * hxh[1] + h[2][0] * hxh[2];
        let jm1 = tr + i2 + det;
        let k = kv * jm1;
        energy = energy + half * k * jm1;
        for i in 0..3 {
            for j in 0..3 {
                p[i][j] = k.mul_add(cof[j][i], p[i][j]);
            }
        }
    }
    // n_a = P' g_a: the force on corner a+1 is −n_a, on corner 0 Σ n_a.
    let mut f = [[zero; 3]; 4];
    for a in 0..3 {
        for i in 0..3 {
            let n = p[i][2].mul_add(g[a][2], p[i][1].mul_add(g[a][1], p[i][0] * g[a][0]));
            f[a + 1][i] = -n;
            f[0][i] = f[0][i] + n;
        }
    }
    (f, energy)
}

#[inline(always)]
fn cross<L: Lane>(a: &[L; 3], b: &[L; 3]) -> [L; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
