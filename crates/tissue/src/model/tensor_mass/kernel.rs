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
//! One generic kernel, over lanes of `W4` (four f64, one block at a time) or of `f64` (one
//! tetrahedron at a time, the tests' cross-check). The block path is compiled twice: inside
//! an `avx2,fma`-enabled function chosen at run time (one AVX instruction per `W4`
//! operation, its multiply-adds fused), and for the baseline target (SSE2 or NEON pairs) as
//! the fallback. The fallback and the scalar path do the same operations in the same order
//! without fusing, so they give the same bits; the fused path rounds once per multiply-add
//! instead of twice, so it agrees with them to rounding (1e-15 relative on the tests'
//! meshes). Fusing cut the AVX2 kernel's instructions by a quarter: fewer operations and
//! fewer temporaries spilled to the stack (a quarter of the unfused kernel's time went to
//! spills).

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
    /// Per block: its corner forces and energy, computed on rayon's threads and then summed
    /// in block order (large meshes, see `PARALLEL_MIN_BLOCKS`).
    scratch: Vec<BlockOut>,
}

/// Blocks (of four tetrahedra) from which the force pass computes the blocks on rayon's
/// threads; their sum into the node forces stays on the calling thread, in block order, so
/// the result has the same bits as one thread's.
pub const PARALLEL_MIN_BLOCKS: usize = 1024;

/// One block's corner forces (corner, component) and energy, per lane.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct BlockOut {
    f: [[[Real; LANES]; 3]; 4],
    e: [Real; LANES],
}

impl Default for BlockOut {
    fn default() -> Self {
        Self {
            f: [[[0.0; LANES]; 3]; 4],
            e: [0.0; LANES],
        }
    }
}

impl<const FMA: bool> From<([[W4<FMA>; 3]; 4], W4<FMA>)> for BlockOut {
    #[inline(always)]
    fn from((f, e): ([[W4<FMA>; 3]; 4], W4<FMA>)) -> Self {
        let mut out = BlockOut {
            f: [[[0.0; LANES]; 3]; 4],
            e: e.0,
        };
        for c in 0..4 {
            for i in 0..3 {
                out.f[c][i] = f[c][i].0;
            }
        }
        out
    }
}

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
        Self {
            blocks,
            len: list.len(),
            nodes_needed,
            stvk: el.is_some(),
            penalty: kappa > 0.0,
            scratch: Vec::new(),
        }
    }

    /// Tetrahedra packed.
    #[allow(clippy::len_without_is_empty)]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Bytes of packed data the force pass reads.
    pub fn bytes(&self) -> usize {
        self.blocks.len() * std::mem::size_of::<Block>()
    }

    /// f += the St Venant–Kirchhoff forces at displacements `u`; returns their energy.
    /// Four lanes in AVX2 registers when the CPU has AVX2 and FMA, else in pairs of the
    /// baseline's (SSE2 on x86-64, NEON on aarch64): ≈ 1.5× slower, still ≈ 1.4× faster
    /// than one tetrahedron at a time.
    /// On meshes of `PARALLEL_MIN_BLOCKS` blocks or more (and more than one rayon thread)
    /// the blocks are computed in parallel and summed in order: the same bits.
    pub fn add_forces(&mut self, u: &[Vec3], f: &mut [Vec3]) -> Real {
        if u.len() < self.nodes_needed || f.len() < self.nodes_needed {
            return 0.0;
        }
        #[cfg(feature = "parallel")]
        if self.blocks.len() >= PARALLEL_MIN_BLOCKS && rayon::current_num_threads() > 1 {
            return match (self.stvk, self.penalty) {
                (true, true) => self.run_parallel::<true, true>(u, f),
                (true, false) => self.run_parallel::<true, false>(u, f),
                (false, true) => self.run_parallel::<false, true>(u, f),
                (false, false) => 0.0,
            };
        }
        match (self.stvk, self.penalty) {
            (true, true) => self.run::<true, true>(u, f),
            (true, false) => self.run::<true, false>(u, f),
            (false, true) => self.run::<false, true>(u, f),
            (false, false) => 0.0,
        }
    }

    /// The blocks on rayon's threads, in chunks, each block's output into `scratch`; then
    /// the sum in block order, as `add_forces_wide` does it.
    #[cfg(feature = "parallel")]
    fn run_parallel<const STVK: bool, const PENALTY: bool>(
        &mut self,
        u: &[Vec3],
        f: &mut [Vec3],
    ) -> Real {
        use rayon::prelude::*;
        const CHUNK: usize = 64;
        self.scratch.resize(self.blocks.len(), BlockOut::default());
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma");
        self.blocks
            .par_chunks(CHUNK)
            .zip(self.scratch.par_chunks_mut(CHUNK))
            .for_each(|(blocks, out)| {
                #[cfg(target_arch = "x86_64")]
                if avx2 {
                    // SAFETY: the CPU supports the features this function is compiled for.
                    unsafe { blocks_out_avx2::<STVK, PENALTY>(blocks, u, out) };
                    return;
                }
                blocks_out::<STVK, PENALTY, false>(blocks, u, out);
            });
        let mut w = 0.0;
        for (b, (block, out)) in self.blocks.iter().zip(&self.scratch).enumerate() {
            scatter(block, lanes_used(b, self.len), out, f, &mut w);
        }
        w
    }

    fn run<const STVK: bool, const PENALTY: bool>(&self, u: &[Vec3], f: &mut [Vec3]) -> Real {
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports the features this function is compiled for.
            return unsafe { add_forces_avx2::<STVK, PENALTY>(&self.blocks, self.len, u, f) };
        }
        add_forces_wide::<STVK, PENALTY, false>(&self.blocks, self.len, u, f)
    }

    /// The block path compiled for the baseline target only (the fallback of `add_forces`).
    #[cfg(test)]
    pub fn add_forces_baseline(&self, u: &[Vec3], f: &mut [Vec3]) -> Real {
        match (self.stvk, self.penalty) {
            (true, true) => add_forces_wide::<true, true, false>(&self.blocks, self.len, u, f),
            (true, false) => add_forces_wide::<true, false, false>(&self.blocks, self.len, u, f),
            (false, true) => add_forces_wide::<false, true, false>(&self.blocks, self.len, u, f),
            (false, false) => 0.0,
        }
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

/// The AVX2 instance of `add_forces_wide`.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn add_forces_avx2<const STVK: bool, const PENALTY: bool>(
    blocks: &[Block],
    len: usize,
    u: &[Vec3],
    f: &mut [Vec3],
) -> Real {
    add_forces_wide::<STVK, PENALTY, true>(blocks, len, u, f)
}

/// The AVX2 instance of `blocks_out`.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(all(target_arch = "x86_64", feature = "parallel"))]
#[target_feature(enable = "avx2,fma")]
unsafe fn blocks_out_avx2<const STVK: bool, const PENALTY: bool>(
    blocks: &[Block],
    u: &[Vec3],
    out: &mut [BlockOut],
) {
    blocks_out::<STVK, PENALTY, true>(blocks, u, out)
}

/// Each block's corner forces and energy into `out` (the parallel pass's work).
#[cfg(feature = "parallel")]
#[inline(always)]
fn blocks_out<const STVK: bool, const PENALTY: bool, const FMA: bool>(
    blocks: &[Block],
    u: &[Vec3],
    out: &mut [BlockOut],
) {
    for (block, o) in blocks.iter().zip(out) {
        *o = block_forces::<STVK, PENALTY, FMA>(block, u).into();
    }
}

/// The vector path: one block per iteration, four tetrahedra in the lanes of each `W4`.
/// Inlined into its callers, so it is compiled for their target features.
#[inline(always)]
fn add_forces_wide<const STVK: bool, const PENALTY: bool, const FMA: bool>(
    blocks: &[Block],
    len: usize,
    u: &[Vec3],
    f: &mut [Vec3],
) -> Real {
    let mut w = 0.0;
    for (b, block) in blocks.iter().enumerate() {
        let out = block_forces::<STVK, PENALTY, FMA>(block, u).into();
        scatter(block, lanes_used(b, len), &out, f, &mut w);
    }
    w
}

/// Gathers a block's corner displacements and computes its corner forces and energy.
#[inline(always)]
fn block_forces<const STVK: bool, const PENALTY: bool, const FMA: bool>(
    block: &Block,
    u: &[Vec3],
) -> ([[W4<FMA>; 3]; 4], W4<FMA>) {
    let mut uc = [[W4::ZERO; 3]; 4];
    for c in 0..4 {
        for k in 0..LANES {
            let p = u[block.nodes[c][k] as usize];
            uc[c][0].0[k] = p.x;
            uc[c][1].0[k] = p.y;
            uc[c][2].0[k] = p.z;
        }
    }
    let mut d = [[W4::ZERO; 3]; 3];
    let mut g = [[W4::ZERO; 3]; 3];
    for a in 0..3 {
        for i in 0..3 {
            d[a][i] = uc[a + 1][i] - uc[0][i];
            g[a][i] = W4(block.g[3 * a + i]);
        }
    }
    let c = [W4(block.lambda_v), W4(block.mu2_v), W4(block.kappa_v)];
    stvk::<W4<FMA>, STVK, PENALTY>(&d, &g, c)
}

/// Adds a block's used lanes into the node forces and its energy into `w`, lane by lane.
#[inline(always)]
fn scatter(block: &Block, lanes: usize, out: &BlockOut, f: &mut [Vec3], w: &mut Real) {
    for k in 0..lanes {
        for c in 0..4 {
            f[block.nodes[c][k] as usize] +=
                Vec3::new(out.f[c][0][k], out.f[c][1][k], out.f[c][2][k]);
        }
        *w += out.e[k];
    }
}

/// What the kernel needs of a lane type: f64 or four of them.
trait Lane:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self>
{
    fn splat(x: Real) -> Self;
    /// self·b + c: fused (one rounding) on the `fma` path, else a product and a sum.
    fn mul_add(self, b: Self, c: Self) -> Self;
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

/// Four f64 lanes; element-wise operations that LLVM turns into one AVX instruction each.
/// `FMA`: `mul_add` is fused (only inside functions compiled with the `fma` feature, where
/// `f64::mul_add` is one instruction; elsewhere it would call the C library).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct W4<const FMA: bool>([Real; LANES]);

impl<const FMA: bool> W4<FMA> {
    const ZERO: Self = W4([0.0; LANES]);
}

macro_rules! lanewise {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<const FMA: bool> $tr for W4<FMA> {
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

impl<const FMA: bool> Neg for W4<FMA> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        W4([-self.0[0], -self.0[1], -self.0[2], -self.0[3]])
    }
}

impl<const FMA: bool> Lane for W4<FMA> {
    #[inline(always)]
    fn splat(x: Real) -> Self {
        W4([x; LANES])
    }
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        if FMA {
            W4([
                self.0[0].mul_add(b.0[0], c.0[0]),
                self.0[1].mul_add(b.0[1], c.0[1]),
                self.0[2].mul_add(b.0[2], c.0[2]),
                self.0[3].mul_add(b.0[3], c.0[3]),
            ])
        } else {
            self * b + c
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
