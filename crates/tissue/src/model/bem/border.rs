//! Incisions without re-factorising: the new H and G are assembled only where the surface
//! changed, and A₀⁻¹ and W = A₀⁻¹ G are extended by a bordering (block Woodbury) update.
//!
//! After an incision the old vertices keep their positions and numbers and the new ones are
//! appended. An old row's entries change only in the columns K of the vertices whose
//! triangles changed (the changed old vertices and all new ones), plus its diagonal block,
//! which comes from the rigid-body sum of the row. New vertices bring new rows. Embedding
//! the old matrix as Ã = diag(A₀, I), the new matrix is
//!   A₀' = Ã + U Vᵀ,   U = [ΔA_{:,K} | E_R],   Vᵀ = [E_Kᵀ ; ΔA_{R,∖K}],
//! with R the rows that change outside K, and
//!   A₀'⁻¹ = Ã⁻¹ − Y S⁻¹ Vᵀ Ã⁻¹,   Y = Ã⁻¹ U,   S = I + Vᵀ Y.
//! W' = A₀'⁻¹ G' needs Ã⁻¹ G' only in the columns K (the others are W's), so the whole
//! update costs O(n² (|K| + |R|)) instead of O(n³). The layer (Y, Vᵀ, S) is kept, so later
//! incisions (and `Ã⁻¹`) apply the accumulated inverse as the base LU plus layers.
//!
//! The diagonal block of a far row changes only by the quadrature error of the new
//! elements (the integral of T* over the closed groove vanishes exactly for a source
//! outside it). The error-controlled rules of `quadrature` keep that drift below 5e-9 of the
//! block (2194-vertex liver), so far rows keep their old diagonal and only the new rows
//! enter R; a row that drifts more than `DIAGONAL_TOLERANCE` (a sliver next to a source the
//! rules could not resolve) is bordered too. The re-assembly reference
//! (`CutUpdate::Reassembly`) applies the same rule, so both give the same H entry for
//! entry; a model built afresh on the cut surface differs from both by the drift, which
//! moves the solution by about 1e-9 (`tests_cut`).

use std::sync::Arc;

use faer::linalg::solvers::{PartialPivLu, Solve};
use faer::{Accum, Mat, MatMut, MatRef};

use crate::error::SimError;
use crate::math::{Real, Vec3};

use super::assembly::Geometry;
use super::assembly::{Element, Influence, assemble_rows};
use super::kelvin::Kelvin;
use super::quadrature::Rules;
use super::system::{
    BemSystem, RimColumns, base_entry, matmul_columns, not_factored, solve_columns,
};

/// Far rows whose diagonal block changes by less than this (max norm, relative to the
/// block's largest entry) keep their old diagonal, in H and in the bordered inverse; rows
/// that change more are bordered. The drift measured with the error-controlled rules is
/// 1e-12 … 2.5e-9 on a 642-vertex sphere and up to 4.4e-9 on the 2194-vertex liver, so
/// in practice no far row is bordered.
pub const DIAGONAL_TOLERANCE: Real = 1e-6;

/// Smallest |pivot| / largest |pivot| of the bordering's capacitance matrix.
const PIVOT_RATIO: Real = 1e-13;

/// A₀⁻¹ as the LU of the first factorisation and the bordering layers of later cuts.
/// Shared, not copied, by its clones: background rim solves (`rim_worker`) hold one while
/// the system goes on (and a cut adds a layer to its own copy only).
#[derive(Clone)]
pub struct BaseInverse {
    lu: Arc<Mat<Real>>,
    perm: Arc<[usize]>,
    perm_inv: Arc<[usize]>,
    layers: Vec<Arc<Layer>>,
}

/// One bordering: Ã⁻¹ (the previous inverse padded with identity) minus Y S⁻¹ Vᵀ Ã⁻¹.
///
/// Much of U and Vᵀ is unit vectors, and is kept as indices: Vᵀ's first |K| rows select
/// the unknowns K, and U's columns for new rows are unit vectors that Ã⁻¹ leaves alone (its
/// identity block), so Y has them too. Only the rest is multiplied, which saves 40% of an
/// incision on the liver, where the new rows are 384 of the rank's 909.
struct Layer {
    prev: usize,
    /// The unknowns K whose columns changed, and the rows R bordered outside them (old
    /// ones first, then the new ones).
    kc: Vec<usize>,
    rr: Vec<usize>,
    /// Y's columns that are not unit vectors: those of K and of R's old rows.
    y: Mat<Real>,
    /// Vᵀ's rows below the selection of K: ΔA over R, outside the columns K.
    vr: Mat<Real>,
    s: PartialPivLu<Real>,
}

impl Layer {
    fn vt_times(&self, x: MatRef<'_, Real>) -> Mat<Real> {
        vt_times(&self.kc, self.vr.as_ref(), x)
    }

    /// x −= Y z: the dense columns of Y by a product, its unit columns by row updates.
    fn sub_y_times(&self, mut x: MatMut<'_, Real>, z: MatRef<'_, Real>) {
        let dense = self.y.ncols();
        matmul_columns(
            x.as_mut(),
            Accum::Add,
            self.y.as_ref(),
            z.subrows(0, dense),
            -1.0,
        );
        let mk = self.kc.len();
        for j in dense..z.nrows() {
            let r = self.rr[j - mk];
            for c in 0..x.ncols() {
                x[(r, c)] -= z[(j, c)];
            }
        }
    }
}

/// Vᵀ x for Vᵀ = [E_Kᵀ ; vr]: the rows K of x, then vr x.
fn vt_times(kc: &[usize], vr: MatRef<'_, Real>, x: MatRef<'_, Real>) -> Mat<Real> {
    let mk = kc.len();
    let mut out = Mat::zeros(mk + vr.nrows(), x.ncols());
    for (i, &c) in kc.iter().enumerate() {
        out.row_mut(i).copy_from(x.row(c));
    }
    matmul_columns(
        out.as_mut().subrows_mut(mk, vr.nrows()),
        Accum::Replace,
        vr,
        x,
        1.0,
    );
    out
}

impl BaseInverse {
    pub(super) fn new(lu: Mat<Real>, perm: Vec<usize>, perm_inv: Vec<usize>) -> Self {
        Self {
            lu: Arc::new(lu),
            perm: perm.into(),
            perm_inv: perm_inv.into(),
            layers: Vec::new(),
        }
    }

    /// Incisions absorbed since the last factorisation.
    pub fn layers(&self) -> usize {
        self.layers.len()
    }

    /// The last bordering's size: (changed columns, changed rows outside them), in unknowns.
    pub fn last_rank(&self) -> Option<(usize, usize)> {
        self.layers.last().map(|l| (l.kc.len(), l.rr.len()))
    }

    /// rhs ← A₀⁻¹ rhs (rhs has as many rows as the current system).
    pub(super) fn solve_in_place(&self, rhs: MatMut<'_, Real>) {
        self.solve_level(self.layers.len(), rhs);
    }

    fn solve_level(&self, level: usize, mut rhs: MatMut<'_, Real>) {
        let Some(layer) = level.checked_sub(1).and_then(|l| self.layers.get(l)) else {
            let n = self.lu.nrows();
            let perm = faer::perm::PermRef::new_checked(&self.perm, &self.perm_inv, n);
            solve_columns((*self.lu).as_ref(), perm, rhs);
            return;
        };
        self.solve_level(level - 1, rhs.as_mut().subrows_mut(0, layer.prev));
        let mut z = layer.vt_times(rhs.as_ref());
        layer.s.solve_in_place(z.as_mut());
        layer.sub_y_times(rhs, z.as_ref());
    }
}

/// H and G of the cut surface, computed from the old ones: K columns of old rows over the
/// elements touching K, full rows for new vertices, fresh rigid-body diagonals everywhere.
/// `old` has the first `old.vertices` vertices of `vertices`; `k` lists the vertices whose
/// triangles changed (old changed ones and all new ones). Returns the rows whose diagonal
/// changed beyond `DIAGONAL_TOLERANCE` (old rows outside K).
pub(super) fn influence_after_cut(
    old: &Influence,
    vertices: &[Vec3],
    elements: &[Element],
    kelvin: &Kelvin,
    k: &[usize],
) -> (Influence, Vec<usize>) {
    let (n0, n) = (old.vertices, vertices.len());
    let (d0, d) = (3 * n0, 3 * n);
    let mut in_k = vec![false; n];
    for &v in k {
        if let Some(f) = in_k.get_mut(v) {
            *f = true;
        }
    }
    let touching: Vec<Element> = elements
        .iter()
        .filter(|e| {
            e.nodes
                .iter()
                .any(|&v| in_k.get(v).copied().unwrap_or(false))
        })
        .copied()
        .collect();
    let rules = Rules::new();
    let mut h = vec![0.0; d * d];
    let mut g = vec![0.0; d * d];
    let mut drift = vec![0.0; n];
    let row = |i: usize, hr: &mut [Real], gr: &mut [Real], drift: &mut Real| {
        if i >= n0 {
            assemble_rows(i, vertices[i], elements, kelvin, &rules, hr, gr);
            return;
        }
        let mut th = vec![0.0; 3 * d];
        let mut tg = vec![0.0; 3 * d];
        assemble_rows(i, vertices[i], &touching, kelvin, &rules, &mut th, &mut tg);
        let mut before = [[0.0; 3]; 3];
        for (l, b) in before.iter_mut().enumerate() {
            let (src_h, src_g) = (
                &old.h[(3 * i + l) * d0..(3 * i + l + 1) * d0],
                &old.g[(3 * i + l) * d0..(3 * i + l + 1) * d0],
            );
            let (hl, gl) = (&mut hr[l * d..(l + 1) * d], &mut gr[l * d..(l + 1) * d]);
            hl[..d0].copy_from_slice(src_h);
            gl[..d0].copy_from_slice(src_g);
            for c in (0..d).filter(|c| in_k[c / 3]) {
                hl[c] = th[l * d + c];
                gl[c] = tg[l * d + c];
            }
            // The rigid-body diagonal, summed in the order `assemble_rows` sums it.
            b.copy_from_slice(&hl[3 * i..3 * i + 3]);
            hl[3 * i..3 * i + 3].fill(0.0);
            let mut sum = [0.0; 3];
            for (c, v) in hl.iter().enumerate() {
                sum[c % 3] += v;
            }
            for kk in 0..3 {
                hl[3 * i + kk] = -sum[kk];
            }
        }
        *drift = if in_k[i] {
            0.0
        } else {
            keep_far_diagonal(before, hr, i)
        };
    };
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        h.par_chunks_mut(3 * d)
            .zip(g.par_chunks_mut(3 * d))
            .zip(drift.par_iter_mut())
            .enumerate()
            .for_each(|(i, ((hr, gr), dr))| row(i, hr, gr, dr));
    }
    #[cfg(not(feature = "parallel"))]
    h.chunks_mut(3 * d)
        .zip(g.chunks_mut(3 * d))
        .zip(drift.iter_mut())
        .enumerate()
        .for_each(|(i, ((hr, gr), dr))| row(i, hr, gr, dr));
    let rows = (0..n0).filter(|&i| drift[i] > DIAGONAL_TOLERANCE).collect();
    (Influence { vertices: n, h, g }, rows)
}

/// The far-row rule that bordering and re-assembly share: the three rows `rows` of vertex
/// `i` get back the old diagonal block `before` when their fresh one moved by at most
/// `DIAGONAL_TOLERANCE` relative to it. Keeping it makes the stored H the matrix the
/// inverse belongs to, and the drift of a later cut is measured from it (it never
/// accumulates unseen). Returns the relative drift.
fn keep_far_diagonal(before: [[Real; 3]; 3], rows: &mut [Real], i: usize) -> Real {
    let d = rows.len() / 3;
    let (mut scale, mut change): (Real, Real) = (0.0, 0.0);
    for (l, b) in before.iter().enumerate() {
        for (k, &old) in b.iter().enumerate() {
            scale = scale.max(old.abs());
            change = change.max((rows[l * d + 3 * i + k] - old).abs());
        }
    }
    let drift = change / scale.max(Real::MIN_POSITIVE);
    if drift <= DIAGONAL_TOLERANCE {
        for (l, b) in before.iter().enumerate() {
            rows[l * d + 3 * i..l * d + 3 * i + 3].copy_from_slice(b);
        }
    }
    drift
}

/// Applies the far-row rule to a freshly assembled `new` (the old vertices first): the
/// re-assembly reference of an incision. `in_k`: vertices whose columns changed.
pub(super) fn keep_far_diagonals(old: &Influence, new: &mut Influence, in_k: &[bool]) {
    let (d0, d) = (old.dofs(), new.dofs());
    for i in (0..old.vertices).filter(|&i| !in_k.get(i).copied().unwrap_or(true)) {
        let mut before = [[0.0; 3]; 3];
        for (l, b) in before.iter_mut().enumerate() {
            b.copy_from_slice(&old.h[(3 * i + l) * d0 + 3 * i..(3 * i + l) * d0 + 3 * i + 3]);
        }
        keep_far_diagonal(before, &mut new.h[3 * i * d..(3 * i + 3) * d], i);
    }
}

/// What a bordering reads from the system it extends, shared rather than copied, so that a
/// worker can compute the extension while the system goes on answering steps.
pub(super) struct BorderBase {
    inf: Arc<Influence>,
    w: Arc<Mat<Real>>,
    inverse: BaseInverse,
    fixed: Vec<bool>,
    rim: RimColumns,
    generation: u64,
}

/// A bordering computed from a `BorderBase`, to be applied to the system it was taken from
/// (`BemSystem::apply_border`).
pub(super) struct Bordered {
    layer: Layer,
    w: Mat<Real>,
    inf: Influence,
    fixed: Vec<bool>,
    rim: RimColumns,
    support_area: Vec<Real>,
    geometry: Option<Geometry>,
    generation: u64,
}

impl BemSystem {
    /// What `BorderBase::border` needs: a few reference counts and the fixed set.
    pub(super) fn border_base(&self) -> Result<BorderBase, SimError> {
        let inverse = self.inverse.clone().ok_or_else(not_factored)?;
        if !self.is_factored() {
            return Err(not_factored());
        }
        Ok(BorderBase {
            inf: Arc::clone(&self.inf),
            w: Arc::clone(&self.w),
            inverse,
            fixed: self.fixed.clone(),
            rim: self.rim.clone(),
            generation: self.generation,
        })
    }

    /// Swaps in a bordering; refused (nothing changes) when the system changed since its
    /// base was taken.
    pub(super) fn apply_border(&mut self, b: Bordered) -> Result<(), SimError> {
        if b.generation != self.generation {
            return Err(SimError::BadParameter {
                name: "cut",
                value: "an incision computed in the background".into(),
                reason: "the system was re-factorised while it was computed".into(),
            });
        }
        if let Some(inv) = self.inverse.as_mut() {
            inv.layers.push(Arc::new(b.layer));
        }
        self.w = Arc::new(b.w);
        self.inf = Arc::new(b.inf);
        self.fixed = b.fixed;
        self.rim = b.rim;
        self.support_area = b.support_area;
        self.geometry = b.geometry.map(Arc::new);
        self.generation += 1;
        // A₀⁻¹ of the contact-rim option is not bordered: the caller re-factorises.
        self.drop_explicit_base_inverse();
        self.contacts.clear();
        self.capacitance = None;
        Ok(())
    }
}

impl BorderBase {
    /// Replaces H and G by those of the cut surface (`inf`: old vertices first, new ones
    /// appended, none fixed) and extends A₀⁻¹ and W by bordering, into a `Bordered` that
    /// `BemSystem::apply_border` swaps in (the system is not touched here). `k`: the
    /// vertices whose columns changed (old changed ones and all new ones); `far_rows`: old
    /// rows outside K whose diagonal changed (from `influence_after_cut`). O(n² (|K| + |R|));
    /// applying it drops the contact set.
    pub(super) fn border(
        &self,
        inf: Influence,
        geometry: Option<Geometry>,
        k: &[usize],
        far_rows: &[usize],
    ) -> Result<Bordered, SimError> {
        let inverse = &self.inverse;
        let (n0, n) = (self.inf.dofs(), inf.dofs());
        let mut fixed = self.fixed.clone();
        fixed.resize(inf.vertices, false);
        // A₀ on the cut surface keeps the fixed tractions discontinuous at their rim as
        // `factor` does (`base_matrix`): its rim columns on the new geometry.
        let (rim, support_area) = match &geometry {
            Some(geo) => RimColumns::compute(geo, &fixed, inf.vertices),
            None => (RimColumns::default(), Vec::new()),
        };
        let old_fixed = &self.fixed;
        let (old, old_rim) = (self.inf.as_ref(), &self.rim);
        let a_old = |r: usize, c: usize| -> Real {
            match (r < n0, c < n0) {
                (true, true) => base_entry(old, old_fixed, r, c) + old_rim.at(r, c),
                (false, false) => Real::from(u8::from(r == c)),
                _ => 0.0,
            }
        };
        let delta =
            |r: usize, c: usize| base_entry(&inf, &fixed, r, c) + rim.at(r, c) - a_old(r, c);
        let mut in_k = vec![false; inf.vertices];
        let mut kc = Vec::new();
        for &v in k {
            if !in_k.get(v).copied().unwrap_or(true) {
                in_k[v] = true;
                kc.extend(3 * v..3 * v + 3);
            }
        }
        if let Some(v) = (self.inf.vertices..inf.vertices).find(|&v| !in_k[v]) {
            return Err(bad_border(v));
        }
        // R: the new rows and the far rows whose diagonal moved.
        let mut rr: Vec<usize> = far_rows
            .iter()
            .filter(|&&v| v < self.inf.vertices && !in_k[v])
            .flat_map(|&v| 3 * v..3 * v + 3)
            .collect();
        rr.extend(n0..n);
        let (mk, mr) = (kc.len(), rr.len());
        let r = mk + mr;
        // Y = Ã⁻¹ U in its dense columns: K's, solved, and the old far rows' A₀⁻¹ e_r.
        let far = rr.iter().take_while(|&&row| row < n0).count();
        let dense = mk + far;
        let mut y = Mat::from_fn(n, dense, |row, col| {
            if col < mk {
                delta(row, kc[col])
            } else {
                Real::from(u8::from(row == rr[col - mk]))
            }
        });
        inverse.solve_in_place(y.as_mut().subrows_mut(0, n0));
        // Vᵀ below the selection of K: the rows R outside the columns K.
        let vr = Mat::from_fn(mr, n, |row, col| {
            if in_k[col / 3] {
                0.0
            } else {
                delta(rr[row], col)
            }
        });
        // S = I + Vᵀ Y; Y's unit column for new row rr[j] is Vᵀ's column rr[j].
        let mut s = Mat::zeros(r, r);
        s.as_mut()
            .subcols_mut(0, dense)
            .copy_from(vt_times(&kc, vr.as_ref(), y.as_ref()));
        for j in dense..r {
            let col = rr[j - mk];
            for i in 0..r {
                s[(i, j)] = if i < mk {
                    Real::from(u8::from(kc[i] == col))
                } else {
                    vr[(i - mk, col)]
                };
            }
        }
        for i in 0..r {
            s[(i, i)] += 1.0;
        }
        let s = s.partial_piv_lu();
        let u = s.U();
        let (lo, hi) = (0..r).fold((Real::INFINITY, 0.0), |(lo, hi): (Real, Real), i| {
            (lo.min(u[(i, i)].abs()), hi.max(u[(i, i)].abs()))
        });
        if r > 0 && (lo.is_nan() || lo <= PIVOT_RATIO * hi) {
            return Err(SimError::NotPositiveDefinite {
                row: kc.first().copied().unwrap_or(0) / 3,
                hint: "the incision makes the BEM system singular".into(),
            });
        }
        let layer = Layer {
            prev: n0,
            kc,
            rr,
            y,
            vr,
            s,
        };
        // Z = Ã⁻¹ G': W in the old columns outside K, solved in the columns K.
        let mut z = Mat::from_fn(n, n, |row, col| {
            if row < n0 && col < n0 && !in_k[col / 3] {
                self.w[(row, col)]
            } else {
                inf.g_at(row, col)
            }
        });
        let mut zk = Mat::from_fn(n0, mk, |row, col| inf.g_at(row, layer.kc[col]));
        inverse.solve_in_place(zk.as_mut());
        for (j, &c) in layer.kc.iter().enumerate() {
            z.as_mut()
                .col_mut(c)
                .subrows_mut(0, n0)
                .copy_from(zk.col(j));
        }
        drop(zk);
        // W' = Z − Y S⁻¹ (Vᵀ Z).
        let mut vz = layer.vt_times(z.as_ref());
        layer.s.solve_in_place(vz.as_mut());
        layer.sub_y_times(z.as_mut(), vz.as_ref());
        if z.col_iter().any(|c| c.iter().any(|v| !v.is_finite())) {
            return Err(bad_border(0));
        }
        Ok(Bordered {
            layer,
            w: z,
            inf,
            fixed,
            rim,
            support_area,
            geometry,
            generation: self.generation,
        })
    }
}

impl BemSystem {
    /// Incisions absorbed by bordering since the last factorisation.
    pub fn borderings(&self) -> usize {
        self.inverse.as_ref().map_or(0, BaseInverse::layers)
    }

    /// The last bordering's rank: (changed columns, changed rows outside them), in unknowns.
    pub fn last_border_rank(&self) -> Option<(usize, usize)> {
        self.inverse.as_ref().and_then(BaseInverse::last_rank)
    }
}

fn bad_border(v: usize) -> SimError {
    SimError::NotPositiveDefinite {
        row: v,
        hint: "the bordered BEM system after the incision is not usable".into(),
    }
}
