//! The rest of the organ: linear FEM on its tetrahedra, condensed onto the interface nodes
//! and its outer surface nodes, as the survey's hybrid wants it (prescribed displacements
//! in, forces out).
//!
//! With the interface nodes held, the rest is a linear elastic body whose state is fixed by
//! three inputs: the interface displacements u_I (from the tensor-mass side), the forces λ
//! at its contact nodes (the instruments' and the supports' on its outer surface) and the
//! loads. Each gives a pre-computed response, one sparse solve per unit input with the
//! Cholesky factor `FemStatic` keeps:
//!
//! - per interface dof: the reactions at the interface (−S, S the stiffness of the rest
//!   condensed onto the interface, symmetric) and the outer surface displacements (G);
//! - per contact node (cached the first time a node is touched): the outer surface
//!   displacements under a unit force (the compliance columns W);
//! - the loads: the interface reactions r₀ and outer displacements u₀.
//!
//! A contact set c with target displacements t fixes λ_c from W_cc λ_c = t − u₀_c − G_c u_I,
//! and the force the rest exerts on the interface nodes is F_I = r₀ − S u_I + G_cᵀ λ_c
//! (Maxwell–Betti: the interface reaction per unit contact force is G_cᵀ). F_I is minus the
//! gradient of E(u_I) = ½ u_Iᵀ S u_I − r₀ᵀ u_I + ½ λ_cᵀ W_cc λ_c, so the coupling is
//! conservative and the tensor-mass integrator's energy guard sees it.

use std::cell::RefCell;
use std::collections::HashMap;
use std::time::Instant;

use faer::linalg::solvers::DenseSolveCore;
use faer::{Accum, Mat, MatRef, Par, Side};

use crate::error::{Error, SimError};
use crate::integrate::coupling::NodeCoupling;
use crate::material::Material;
use crate::math::{Mat3, Real, Vec3};
use crate::model::Deformable;
use crate::model::fem::{DofProblem, FemStatic, Order};

use super::split::{NONE, Split};
use super::sym_panels::SymPanels;

/// y (+)= alpha · a · x for column vectors.
fn gemv(y: &mut Mat<Real>, accum: Accum, a: MatRef<'_, Real>, x: MatRef<'_, Real>, alpha: Real) {
    faer::linalg::matmul::matmul(y.as_mut(), accum, a, x, alpha, Par::Seq);
}

/// x · y with four partial sums (so that it vectorises).
fn dot(x: &[Real], y: &[Real]) -> Real {
    let mut acc = [0.0; 4];
    let (xc, yc) = (x.chunks_exact(4), y.chunks_exact(4));
    let tail: Real = xc
        .remainder()
        .iter()
        .zip(yc.remainder())
        .map(|(a, b)| a * b)
        .sum();
    for (a, b) in xc.zip(yc) {
        for k in 0..4 {
            acc[k] += a[k] * b[k];
        }
    }
    acc.iter().sum::<Real>() + tail
}

/// Where a contact acts: one outer node (a support, a grasp, an instrument's contact on a
/// vertex) or a point tied to several outer nodes by weights (a fine surface's point,
/// `interact::PointContact`). The contact is a virtual node whose displacement is
/// Σ wᵢ uᵢ and whose force f acts as wᵢ f on each node, so its rows of G are Σ wᵢ G_i, its
/// block of W is Σ wᵢ w'ⱼ W_ij, and every formula of the module holds with these rows.
/// (A point that also follows interface nodes is not one: `Hybrid::route_points`.)
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Site {
    /// (outer slot, weight).
    pub terms: Vec<(u32, Real)>,
    /// A fine surface's point: its row is regularised (`held_inverse`), as several points
    /// on one coarse triangle can be tied by the same three nodes.
    pub point: bool,
}

impl Site {
    /// One outer node, weight 1.
    pub fn outer(slot: u32) -> Self {
        Self {
            terms: vec![(slot, 1.0)],
            point: false,
        }
    }

    /// The outer slot of a contact on one outer node (weight 1), else `NONE`.
    fn single_slot(&self) -> u32 {
        match self.terms.as_slice() {
            [(s, w)] if *w == 1.0 => *s,
            _ => NONE,
        }
    }

    /// The outer slots the site names, with their weights.
    pub fn outer_terms(&self) -> impl Iterator<Item = (u32, Real)> + '_ {
        self.terms.iter().copied()
    }
}

/// The contacts on the outer surface, as the coupling forces use them.
#[derive(Clone, Debug)]
struct Contacts {
    /// Where each contact acts.
    sites: Vec<Site>,
    /// Their target displacements (3 per contact).
    targets: Vec<Real>,
    /// t − u₀_c (3 per contact).
    rhs: Mat<Real>,
    /// G_c: rows of G at the contacts (3m × 3n_I).
    g: Mat<Real>,
    /// G_c again, row after row (each row contiguous), for the products every force
    /// evaluation takes: a few short dot products and axpys, which faer's general
    /// product dispatch costs more than.
    g_rows: Vec<Real>,
    /// Per contact: the direction it is held along (a frictionless contact), or `None`
    /// (held in all three directions).
    normals: Vec<Option<Vec3>>,
    /// W_cc (3m × 3m) and the map from the contacts' free gaps to their forces,
    /// P = B(BᵀW_ccB)⁻¹Bᵀ with B the held directions (3 unit columns per contact held in
    /// full, its normal for one held along a direction): W_cc⁻¹ when every contact is held
    /// in full. P is symmetric, so every coupling formula written with W_cc⁻¹ holds with P
    /// (λᵀW_ccλ = yᵀPy for λ = Py).
    w: Mat<Real>,
    w_inv: Mat<Real>,
}

impl Contacts {
    fn empty(ni: usize) -> Self {
        Self {
            sites: Vec::new(),
            targets: Vec::new(),
            normals: Vec::new(),
            rhs: Mat::zeros(0, 1),
            g: Mat::zeros(0, ni),
            g_rows: Vec::new(),
            w: Mat::zeros(0, 0),
            w_inv: Mat::zeros(0, 0),
        }
    }
}

/// The pre-computed rest (see the module doc).
pub(super) struct RestPart {
    /// In a cell so that `node_displacements` (a sparse solve with the factor's scratch)
    /// can answer a `&self` read of the volume. `None` when the region covers the organ
    /// (nothing left to pre-compute: no interface, no outer surface, no loads).
    fem: Option<RefCell<FemStatic>>,
    density: Real,
    /// Rest-local node of each interface node (in `Split::interface` order).
    iface: Vec<u32>,
    /// Rest-local nodes of the outer surface (boundary nodes that are not interface nodes).
    pub outer: Vec<u32>,
    /// Rest-local node → outer slot, or `NONE`.
    outer_slot: Vec<u32>,
    /// S, −(interface reactions) per unit interface displacement (3n_I × 3n_I, symmetric),
    /// kept as panels of its upper triangle: the product every force evaluation takes reads
    /// half the bytes (`sym_panels`), and nothing needs the dense matrix.
    panels: SymPanels,
    /// Outer displacements per unit interface displacement, G (3n_O × 3n_I), stored
    /// transposed: the three rows of one outer node are contiguous, for the few nodes a
    /// contact search needs (`outer_displacement`).
    gt: Mat<Real>,
    /// Per outer slot, the Frobenius norm of its three rows of G: |G_o u| ≤ this · |u|.
    g_norms: Vec<Real>,
    /// Interface reactions and outer displacements under the loads, interface at rest.
    r0: Mat<Real>,
    u0: Mat<Real>,
    /// Outer displacements per unit force at an outer node (3n_O × 3), by outer slot, with
    /// the Frobenius norm of each outer node's 3 × 3 block of it.
    columns: HashMap<u32, Mat<Real>>,
    column_norms: HashMap<u32, Vec<Real>>,
    contacts: Contacts,
    /// The forces on every dof of the rest from the loads.
    forces: Vec<Real>,
    pub build_seconds: Real,
    pub column_solves: usize,
    /// W_FF⁻¹ of the contacts held in full (`held_inverse`).
    full_inverse: FullInverse,
}

impl std::fmt::Debug for RestPart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RestPart")
            .field("interface", &self.iface.len())
            .field("outer", &self.outer.len())
            .finish()
    }
}

impl RestPart {
    /// Assembles the rest's FEM and pre-computes its responses to the interface: 3n_I
    /// sparse solves.
    pub fn new(split: &Split, material: Material) -> Result<Self, Error> {
        if split.whole() {
            return Ok(Self::empty(material.density));
        }
        let start = Instant::now();
        let mut fem = FemStatic::new(&split.rest.mesh, material, Order::Linear)?;
        let iface: Vec<u32> = split
            .interface
            .iter()
            .map(|&g| split.rest.local[g as usize])
            .collect();
        let nodes = split.rest.global.len();
        let mut is_iface = vec![false; nodes];
        for &n in &iface {
            is_iface[n as usize] = true;
        }
        let mut outer: Vec<u32> = fem
            .surface_nodes()
            .iter()
            .copied()
            .filter(|&n| !is_iface[n as usize])
            .collect();
        outer.sort_unstable();
        outer.dedup();
        let mut outer_slot = vec![NONE; nodes];
        for (k, &n) in outer.iter().enumerate() {
            outer_slot[n as usize] = k as u32;
        }
        let (ni, no) = (3 * iface.len(), 3 * outer.len());
        let mut dp = held(&iface, nodes)?;
        let mut s = Mat::zeros(ni, ni);
        let mut gt = Mat::zeros(ni, no);
        for (a, &n) in iface.iter().enumerate() {
            for k in 0..3 {
                let col = 3 * a + k;
                dp.targets[3 * n as usize + k] = 1.0;
                let sol = fem.solve_dofs(&dp)?;
                dp.targets[3 * n as usize + k] = 0.0;
                for (b, &m) in iface.iter().enumerate() {
                    let r = sol.reactions[m as usize];
                    for l in 0..3 {
                        s[(3 * b + l, col)] = -r[l];
                    }
                }
                for (b, &m) in outer.iter().enumerate() {
                    let u = sol.displacements[m as usize];
                    for l in 0..3 {
                        gt[(col, 3 * b + l)] = u[l];
                    }
                }
            }
        }
        // S is symmetric in exact arithmetic; the solves leave roundoff that would make the
        // coupling slightly non-conservative.
        for j in 0..ni {
            for i in 0..j {
                let m = 0.5 * (s[(i, j)] + s[(j, i)]);
                s[(i, j)] = m;
                s[(j, i)] = m;
            }
        }
        let g_norms = (0..outer.len())
            .map(|b| {
                (0..ni)
                    .flat_map(|j| (0..3).map(move |l| (j, 3 * b + l)))
                    .map(|(j, r)| gt[(j, r)] * gt[(j, r)])
                    .sum::<Real>()
                    .sqrt()
            })
            .collect();
        let rest = Self {
            density: material.density,
            iface,
            outer,
            outer_slot,
            panels: SymPanels::new(&s),
            gt,
            g_norms,
            r0: Mat::zeros(ni, 1),
            u0: Mat::zeros(no, 1),
            columns: HashMap::new(),
            column_norms: HashMap::new(),
            contacts: Contacts::empty(ni),
            forces: vec![0.0; 3 * nodes],
            build_seconds: 0.0,
            column_solves: 0,
            full_inverse: FullInverse::default(),
            fem: Some(RefCell::new(fem)),
        };
        Ok(Self {
            build_seconds: start.elapsed().as_secs_f64(),
            ..rest
        })
    }

    /// The rest of a region that covers the whole organ: nothing, coupled to nothing.
    fn empty(density: Real) -> Self {
        Self {
            fem: None,
            density,
            iface: Vec::new(),
            outer: Vec::new(),
            outer_slot: Vec::new(),
            panels: SymPanels::default(),
            gt: Mat::zeros(0, 0),
            g_norms: Vec::new(),
            r0: Mat::zeros(0, 1),
            u0: Mat::zeros(0, 1),
            columns: HashMap::new(),
            column_norms: HashMap::new(),
            contacts: Contacts::empty(0),
            forces: Vec::new(),
            build_seconds: 0.0,
            column_solves: 0,
            full_inverse: FullInverse::default(),
        }
    }

    /// Is there a rest at all (false when the region covers the organ)?
    pub fn exists(&self) -> bool {
        self.fem.is_some()
    }

    /// The rest's FEM (only called with a rest: every caller is reached through an
    /// interface node or an outer slot, of which an empty rest has none).
    fn fem(&self) -> Result<&RefCell<FemStatic>, SimError> {
        self.fem.as_ref().ok_or_else(|| SimError::Unsupported {
            model: "hybrid",
            operation: "the pre-computed rest",
            reason: "the cut region covers the whole organ: there is no rest".into(),
        })
    }

    /// Outer slot of rest-local node `n`.
    pub fn outer_slot(&self, n: u32) -> Option<u32> {
        self.outer_slot
            .get(n as usize)
            .copied()
            .filter(|&s| s != NONE)
    }

    /// Sets the loads: gravity over the rest's tetrahedra and point forces on rest-local
    /// nodes; one sparse solve.
    pub fn set_loads(&mut self, gravity: Vec3, point: &[(u32, Vec3)]) -> Result<(), SimError> {
        if !self.exists() {
            return Ok(());
        }
        let mut f = self.fem()?.borrow().body_load(gravity * self.density);
        // The region carries the rest's mass share at the interface nodes, and its weight.
        for &n in &self.iface {
            for k in 0..3 {
                f[3 * n as usize + k] = 0.0;
            }
        }
        for &(n, p) in point {
            for k in 0..3 {
                f[3 * n as usize + k] += p[k];
            }
        }
        let mut dp = held(&self.iface, self.outer_slot.len())?;
        dp.forces.copy_from_slice(&f);
        let sol = self.fem()?.borrow_mut().solve_dofs(&dp)?;
        let targets = self.contacts.targets.clone();
        for (b, &m) in self.iface.iter().enumerate() {
            for l in 0..3 {
                self.r0[(3 * b + l, 0)] = sol.reactions[m as usize][l];
            }
        }
        for (b, &m) in self.outer.iter().enumerate() {
            for l in 0..3 {
                self.u0[(3 * b + l, 0)] = sol.displacements[m as usize][l];
            }
        }
        self.forces = f;
        let sites = self.contacts.sites.clone();
        let normals = self.contacts.normals.clone();
        // The contacts' right-hand sides hold u₀.
        self.set_contacts(&sites, &targets, &normals)
    }

    /// Σ wᵢ u₀ᵢ of a site along axis `l` (the interface is at rest under the loads alone).
    fn site_base(&self, site: &Site, l: usize) -> Real {
        site.outer_terms()
            .map(|(s, w)| w * self.u0[(3 * s as usize + l, 0)])
            .sum()
    }

    /// The compliance columns of outer slot `slot` (3 sparse solves the first time).
    fn ensure_column(&mut self, slot: u32) -> Result<(), SimError> {
        if self.columns.contains_key(&slot) {
            return Ok(());
        }
        let n = self.outer[slot as usize] as usize;
        let mut dp = held(&self.iface, self.outer_slot.len())?;
        let mut w = Mat::zeros(3 * self.outer.len(), 3);
        for k in 0..3 {
            dp.forces[3 * n + k] = 1.0;
            let sol = self.fem()?.borrow_mut().solve_dofs(&dp)?;
            dp.forces[3 * n + k] = 0.0;
            for (b, &m) in self.outer.iter().enumerate() {
                for l in 0..3 {
                    w[(3 * b + l, k)] = sol.displacements[m as usize][l];
                }
            }
        }
        self.column_solves += 3;
        let norms = (0..self.outer.len())
            .map(|b| {
                (0..3)
                    .flat_map(|k| (0..3).map(move |l| (3 * b + l, k)))
                    .map(|(r, k)| w[(r, k)] * w[(r, k)])
                    .sum::<Real>()
                    .sqrt()
            })
            .collect();
        self.column_norms.insert(slot, norms);
        self.columns.insert(slot, w);
        Ok(())
    }

    /// Where the contacts set act.
    pub fn contact_sites(&self) -> &[Site] {
        &self.contacts.sites
    }

    /// Are these the contacts, directions and targets already set?
    pub fn same_contacts(
        &self,
        sites: &[Site],
        targets: &[Real],
        normals: &[Option<Vec3>],
    ) -> bool {
        self.contacts.sites == sites
            && self.contacts.normals == normals
            && self.contacts.targets == targets
    }

    /// The directions the contacts set are held along (`None`: in full).
    pub fn contact_normals(&self) -> &[Option<Vec3>] {
        &self.contacts.normals
    }

    /// Sets the contacts: where each acts (`Site`), their target displacements (3 each; a
    /// support is a contact with target zero) and the direction each is held along
    /// (`None`: all three; a unit n: along n only, free across it, its force along n).
    /// Nothing changes on error.
    pub fn set_contacts(
        &mut self,
        sites: &[Site],
        targets: &[Real],
        normals: &[Option<Vec3>],
    ) -> Result<(), SimError> {
        if normals.len() != sites.len() || targets.len() != 3 * sites.len() {
            return Err(SimError::BadParameter {
                name: "contacts",
                value: format!(
                    "{} sites, {} targets, {} directions",
                    sites.len(),
                    targets.len(),
                    normals.len()
                ),
                reason: "needs 3 targets and one direction (or none) per contact".into(),
            });
        }
        let ni = self.panels.dim();
        let bad = sites
            .iter()
            .flat_map(|s| &s.terms)
            .find(|&&(s, w)| !w.is_finite() || s as usize >= self.outer.len());
        if let Some((s, w)) = bad {
            return Err(SimError::BadParameter {
                name: "contacts",
                value: format!("outer slot {s} with weight {w}"),
                reason: "a contact names a node the rest does not have (internal)".into(),
            });
        }
        if sites == self.contacts.sites.as_slice() && normals == self.contacts.normals.as_slice() {
            // The same contact set held the same ways (an instrument moving its targets):
            // only the right-hand side changes, W_cc and P stay.
            for (k, site) in sites.iter().enumerate() {
                for l in 0..3 {
                    self.contacts.rhs[(3 * k + l, 0)] =
                        targets[3 * k + l] - self.site_base(site, l);
                }
            }
            self.contacts.targets = targets.to_vec();
            return Ok(());
        }
        for site in sites {
            for (s, _) in site.outer_terms() {
                self.ensure_column(s)?;
            }
        }
        let m3 = 3 * sites.len();
        let mut c = Contacts {
            sites: sites.to_vec(),
            targets: targets.to_vec(),
            normals: normals.to_vec(),
            rhs: Mat::zeros(m3, 1),
            g: Mat::zeros(m3, ni),
            g_rows: Vec::new(),
            w: Mat::zeros(m3, m3),
            w_inv: Mat::zeros(m3, m3),
        };
        for (k, site) in sites.iter().enumerate() {
            for l in 0..3 {
                let r = 3 * k + l;
                c.rhs[(r, 0)] = targets[r] - self.site_base(site, l);
                for (s, w) in site.outer_terms() {
                    let row = 3 * s as usize + l;
                    for j in 0..ni {
                        c.g[(r, j)] += w * self.gt[(j, row)];
                    }
                }
            }
            for (s, w) in site.outer_terms() {
                let col = &self.columns[&s];
                for (q, other) in sites.iter().enumerate() {
                    for (s2, w2) in other.outer_terms() {
                        for l in 0..3 {
                            for l2 in 0..3 {
                                c.w[(3 * q + l2, 3 * k + l)] +=
                                    w * w2 * col[(3 * s2 as usize + l2, l)];
                            }
                        }
                    }
                }
            }
        }
        if m3 > 0 {
            for j in 0..m3 {
                for i in 0..j {
                    let m = 0.5 * (c.w[(i, j)] + c.w[(j, i)]);
                    c.w[(i, j)] = m;
                    c.w[(j, i)] = m;
                }
            }
            let keys: Vec<u32> = sites.iter().map(Site::single_slot).collect();
            let soft: Vec<bool> = sites.iter().map(|s| s.point).collect();
            c.w_inv = held_inverse(&c.w, &keys, normals, &soft, &mut self.full_inverse)?;
        }
        c.g_rows = (0..m3)
            .flat_map(|i| (0..ni).map(move |j| (i, j)))
            .map(|(i, j)| c.g[(i, j)])
            .collect();
        self.contacts = c;
        Ok(())
    }

    /// The contact forces λ_c (forces applied to the rest, 3 per contact) for interface
    /// displacements `u_i` (a 3n_I column).
    pub fn contact_forces(&self, u_i: &Mat<Real>) -> Mat<Real> {
        let mut y = Mat::zeros(0, 1);
        let mut z = Mat::zeros(0, 1);
        self.contact_forces_into(u_i, &mut y, &mut z);
        z
    }

    /// `contact_forces` into `z`, with `y` as scratch (both resized if needed): no
    /// allocation once they have the contact count's size.
    fn contact_forces_into(&self, u_i: &Mat<Real>, y: &mut Mat<Real>, z: &mut Mat<Real>) {
        let c = &self.contacts;
        let m3 = c.rhs.nrows();
        if y.nrows() != m3 {
            *y = Mat::zeros(m3, 1);
            *z = Mat::zeros(m3, 1);
        }
        if m3 == 0 {
            return;
        }
        let ni = u_i.nrows();
        let u = u_i.col_as_slice(0);
        for (i, row) in c.g_rows.chunks_exact(ni.max(1)).enumerate() {
            y[(i, 0)] = c.rhs[(i, 0)] - dot(row, u);
        }
        for i in 0..m3 {
            z[(i, 0)] = (0..m3).map(|j| c.w_inv[(i, j)] * y[(j, 0)]).sum();
        }
    }

    /// The forces the rest exerts on the interface nodes (3n_I) and the contact forces.
    pub fn interface_forces(&self, u_i: &Mat<Real>, out: &mut Mat<Real>) -> Mat<Real> {
        let mut y = Mat::zeros(0, 1);
        let mut z = Mat::zeros(0, 1);
        self.interface_forces_into(u_i, out, &mut y, &mut z);
        z
    }

    /// `interface_forces` with the contact forces into `z` (`y` scratch).
    fn interface_forces_into(
        &self,
        u_i: &Mat<Real>,
        out: &mut Mat<Real>,
        y: &mut Mat<Real>,
        z: &mut Mat<Real>,
    ) {
        self.contact_forces_into(u_i, y, z);
        out.as_mut().copy_from(self.r0.as_ref());
        self.panels
            .mul_add(u_i.col_as_slice(0), out.col_as_slice_mut(0), -1.0);
        // + G_cᵀ z, row after row of G_c.
        let ni = out.nrows();
        let o = out.col_as_slice_mut(0);
        for (i, row) in self.contacts.g_rows.chunks_exact(ni.max(1)).enumerate() {
            let zi = z[(i, 0)];
            for (oj, gj) in o.iter_mut().zip(row) {
                *oj += gj * zi;
            }
        }
    }

    /// The stiffness a common translation meets at the interface nodes `iface_held` (in
    /// `Split::interface` order) and the contacts `contact_held` (in contact order), every
    /// other interface node and contact held: with d_I, d_c the unit translations,
    /// d_Iᵀ S d_I + yᵀ W_cc⁻¹ y, y = G_c d_I − d_c (the Hessian of the coupling energy in
    /// the interface displacements and the contact targets). 3×3, N/m.
    pub fn translation_stiffness(&self, iface_held: &[bool], contact_held: &[bool]) -> Mat3 {
        let ni = self.panels.dim();
        let m3 = self.contacts.rhs.nrows();
        let mut d = Mat::<Real>::zeros(ni, 3);
        for (a, _) in iface_held.iter().enumerate().filter(|(_, h)| **h) {
            for l in 0..3 {
                d[(3 * a + l, l)] = 1.0;
            }
        }
        let mut sd = Mat::<Real>::zeros(ni, 3);
        for l in 0..3 {
            self.panels
                .mul_add(d.col_as_slice(l), sd.col_as_slice_mut(l), 1.0);
        }
        let mut k = Mat::<Real>::zeros(3, 3);
        faer::linalg::matmul::matmul(
            k.as_mut(),
            Accum::Replace,
            d.as_ref().transpose(),
            sd.as_ref(),
            1.0,
            Par::Seq,
        );
        if m3 > 0 {
            let mut y = Mat::<Real>::zeros(m3, 3);
            faer::linalg::matmul::matmul(
                y.as_mut(),
                Accum::Replace,
                self.contacts.g.as_ref(),
                d.as_ref(),
                1.0,
                Par::Seq,
            );
            for (c, _) in contact_held.iter().enumerate().filter(|(_, h)| **h) {
                for l in 0..3 {
                    y[(3 * c + l, l)] -= 1.0;
                }
            }
            let mut wy = Mat::<Real>::zeros(m3, 3);
            faer::linalg::matmul::matmul(
                wy.as_mut(),
                Accum::Replace,
                self.contacts.w_inv.as_ref(),
                y.as_ref(),
                1.0,
                Par::Seq,
            );
            faer::linalg::matmul::matmul(
                k.as_mut(),
                Accum::Add,
                y.as_ref().transpose(),
                wy.as_ref(),
                1.0,
                Par::Seq,
            );
        }
        Mat3::from_cols_array_2d(&std::array::from_fn(|c| std::array::from_fn(|r| k[(r, c)])))
    }

    /// Displacements of the outer nodes (3n_O) for `u_i` and contact forces `z`.
    pub fn outer_displacements(&self, u_i: &Mat<Real>, z: &Mat<Real>) -> Mat<Real> {
        let mut u = self.u0.clone();
        gemv(
            &mut u,
            Accum::Add,
            self.gt.as_ref().transpose(),
            u_i.as_ref(),
            1.0,
        );
        for (k, site) in self.contacts.sites.iter().enumerate() {
            for (s, w) in site.outer_terms() {
                let col = &self.columns[&s];
                for l in 0..3 {
                    let f = w * z[(3 * k + l, 0)];
                    if f != 0.0 {
                        for i in 0..u.nrows() {
                            u[(i, 0)] += col[(i, l)] * f;
                        }
                    }
                }
            }
        }
        u
    }

    /// The displacement of outer slot `slot` under the loads alone, interface at rest (u₀).
    pub fn base_displacement(&self, slot: u32) -> Vec3 {
        let s = 3 * slot as usize;
        Vec3::new(self.u0[(s, 0)], self.u0[(s + 1, 0)], self.u0[(s + 2, 0)])
    }

    /// The compliance columns' norms of the contacts in `dz` (outer slot, norm of its
    /// force change), for `displacement_bounds`: looked up once per search, not per vertex.
    /// A slot with no column (never touched) moves nothing and is left out.
    pub fn bound_terms<'a>(&'a self, dz: &[(u32, Real)]) -> Vec<(&'a [Real], Real)> {
        dz.iter()
            .filter_map(|(c, zn)| self.column_norms.get(c).map(|n| (n.as_slice(), *zn)))
            .collect()
    }

    /// How far each outer slot can move when the interface displacements change by a
    /// vector of norm `du` and the contact forces by vectors of norms `dz` (per contact:
    /// its column norms from `bound_terms`, the norm of its change): |G_o Δu| +
    /// Σ_c |W_oc Δz_c| ≤ ‖G_o‖_F |Δu| + Σ_c ‖W_oc‖_F |Δz_c|, into `out` (one entry per
    /// slot). In exact arithmetic; the caller adds the rounding. All slots at once: a
    /// scaled copy of G's norms and one axpy per contact, which vectorise.
    pub fn displacement_bounds(&self, du: Real, dz: &[(&[Real], Real)], out: &mut Vec<Real>) {
        out.clear();
        out.extend(self.g_norms.iter().map(|g| g * du));
        for &(norms, zn) in dz {
            for (o, n) in out.iter_mut().zip(norms) {
                *o += n * zn;
            }
        }
    }

    /// Outer slots count.
    pub fn outer_slots(&self) -> usize {
        self.outer.len()
    }

    /// The contact forces `z` (as `contact_forces` gives them) on the outer slots, each
    /// slot once (a point's force shared by its weights; the interface nodes' shares left
    /// out: they move nothing on the outer surface).
    pub fn forces_by_slot(&self, z: &Mat<Real>) -> Vec<(u32, Vec3)> {
        let mut out: Vec<(u32, Vec3)> = Vec::with_capacity(self.contacts.sites.len());
        for (k, site) in self.contacts.sites.iter().enumerate() {
            let f = Vec3::new(z[(3 * k, 0)], z[(3 * k + 1, 0)], z[(3 * k + 2, 0)]);
            for (s, w) in site.outer_terms() {
                match out.iter_mut().find(|(r, _)| *r == s) {
                    Some((_, g)) => *g += w * f,
                    None => out.push((s, w * f)),
                }
            }
        }
        out
    }

    /// The displacement of a contact's site (Σ wᵢ uᵢ over its outer nodes) for `u_i` and
    /// the contact forces `z`.
    pub fn site_displacement(&self, site: &Site, u_i: &Mat<Real>, z: &Mat<Real>) -> Vec3 {
        site.outer_terms()
            .map(|(s, w)| w * self.outer_displacement(s, u_i, z))
            .sum()
    }

    /// The displacement of outer slot `slot` for `u_i` and contact forces `z`: its three
    /// rows of `outer_displacements`, without the others.
    pub fn outer_displacement(&self, slot: u32, u_i: &Mat<Real>, z: &Mat<Real>) -> Vec3 {
        let o = 3 * slot as usize;
        let u = u_i.col_as_slice(0);
        let mut d = self.base_displacement(slot);
        for l in 0..3 {
            d[l] += dot(self.gt.col_as_slice(o + l), u);
        }
        for (k, site) in self.contacts.sites.iter().enumerate() {
            for (s, w) in site.outer_terms() {
                let col = &self.columns[&s];
                for m in 0..3 {
                    let f = w * z[(3 * k + m, 0)];
                    if f != 0.0 {
                        for l in 0..3 {
                            d[l] += col[(o + l, m)] * f;
                        }
                    }
                }
            }
        }
        d
    }

    /// Displacements of every node of the rest (a sparse solve): for a region growth, whose
    /// new region nodes start where the rest had them.
    pub fn node_displacements(&self, u_i: &Mat<Real>) -> Result<Vec<Vec3>, SimError> {
        if !self.exists() {
            return Ok(Vec::new());
        }
        let z = self.contact_forces(u_i);
        let mut dp = held(&self.iface, self.outer_slot.len())?;
        dp.forces.copy_from_slice(&self.forces);
        for (a, &n) in self.iface.iter().enumerate() {
            for k in 0..3 {
                dp.targets[3 * n as usize + k] = u_i[(3 * a + k, 0)];
            }
        }
        for (k, site) in self.contacts.sites.iter().enumerate() {
            for (s, w) in site.outer_terms() {
                let n = self.outer[s as usize] as usize;
                for l in 0..3 {
                    dp.forces[3 * n + l] += w * z[(3 * k + l, 0)];
                }
            }
        }
        Ok(self.fem()?.borrow_mut().solve_dofs(&dp)?.displacements)
    }

    /// The rest's total load (for balance checks): body and point forces, without the
    /// weight at the interface nodes (the region carries it).
    pub fn total_load(&self) -> Vec3 {
        let mut t = Vec3::ZERO;
        for c in self.forces.chunks_exact(3) {
            t += Vec3::new(c[0], c[1], c[2]);
        }
        t
    }

    /// The rest's lumped mass at each interface node, in kg.
    pub fn interface_masses(&self) -> Vec<Real> {
        let Some(fem) = &self.fem else {
            return Vec::new();
        };
        let m = crate::model::fem::mass::lumped_masses(fem.borrow().linear_mesh(), self.density);
        self.iface.iter().map(|&n| m[n as usize]).collect()
    }

    /// The moment about the origin of the loads and the contact forces `z`, at rest.
    #[cfg(test)]
    pub fn moment(&self, z: &Mat<Real>) -> Vec3 {
        let Some(fem) = &self.fem else {
            return Vec3::ZERO;
        };
        let fem = fem.borrow();
        let x = fem.rest_nodes();
        let mut m = Vec3::ZERO;
        for (n, f) in self.forces.chunks_exact(3).enumerate() {
            m += x[n].cross(Vec3::new(f[0], f[1], f[2]));
        }
        for (k, site) in self.contacts.sites.iter().enumerate() {
            for (s, w) in site.outer_terms() {
                let n = self.outer[s as usize] as usize;
                m += x[n].cross(w * Vec3::new(z[(3 * k, 0)], z[(3 * k + 1, 0)], z[(3 * k + 2, 0)]));
            }
        }
        m
    }

    pub fn memory_bytes(&self) -> usize {
        self.fem
            .as_ref()
            .map_or(0, |f| f.borrow().info().memory_bytes)
            + self.panels.bytes()
            + 8 * (self.gt.nrows() * self.gt.ncols() + self.columns.len() * 3 * self.gt.ncols())
    }

    /// The coupling seen from the region: interface node `i` is region node `region_node[i]`,
    /// at rest at `region_rest[region_node[i]]`.
    pub fn coupling<'a>(&'a self, region_node: &'a [u32], region_rest: &'a [Vec3]) -> Coupling<'a> {
        let n = 3 * self.iface.len();
        Coupling {
            rest: self,
            region_node,
            region_rest,
            scratch: RefCell::new(Scratch {
                u: Mat::zeros(n, 1),
                out: Mat::zeros(n, 1),
                y: Mat::zeros(0, 1),
                z: Mat::zeros(0, 1),
                probe: Mat::zeros(n, 1),
                fresh: false,
            }),
        }
    }
}

/// The inverse of the compliance block of the contacts held in full, kept while they stay
/// the same (the supports and sticking contacts; the frictionless ones change every step).
#[derive(Clone, Debug)]
struct FullInverse {
    slots: Vec<u32>,
    inv: Mat<Real>,
}

impl Default for FullInverse {
    fn default() -> Self {
        Self {
            slots: Vec::new(),
            inv: Mat::zeros(0, 0),
        }
    }
}

fn singular<E>(_: E) -> SimError {
    SimError::NotPositiveDefinite {
        row: 0,
        hint: "the compliance of the rest's contact nodes is singular: two contacts on the \
               same node?"
            .into(),
    }
}

fn symmetrise(m: &mut Mat<Real>) {
    for j in 0..m.ncols() {
        for i in 0..j {
            let s = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = s;
            m[(j, i)] = s;
        }
    }
}

/// P = B(BᵀWB)⁻¹Bᵀ for the held directions B of `normals` (3 unit columns for `None`, the
/// direction otherwise): W⁻¹ when every contact is held in full. With F the contacts held
/// in full (A = W_FF, its inverse kept in `cache` while F stays) and N those held along
/// n (C = W_FN n, D = nᵀW_NN n), BᵀWB = [[A, C], [Cᵀ, D]] is eliminated by its Schur
/// complement S = D − CᵀA⁻¹C (k × k, k the normal holds), E = A⁻¹C:
/// P_FF = A⁻¹ + E S⁻¹ Eᵀ, P_FN = −E S⁻¹ nᵀ, P_NN = n S⁻¹ nᵀ. A new direction then costs
/// O(f²k) for f full contacts, not a factorisation of the whole block (the supports on
/// the rest are contacts held in full: hundreds of rows).
///
/// `slots` names the contacts held in full (their one outer slot: the cache's key); `soft`
/// marks a fine surface's points, whose diagonal of S is raised by `solve::lcp`'s
/// `REGULARISATION` of its largest entry: more points pushing on one coarse triangle than
/// its nodes have directions make S singular, and the raise picks one of the forces that
/// hold them (the displacement is the same for all).
fn held_inverse(
    w: &Mat<Real>,
    slots: &[u32],
    normals: &[Option<Vec3>],
    soft: &[bool],
    cache: &mut FullInverse,
) -> Result<Mat<Real>, SimError> {
    let full: Vec<usize> = (0..slots.len()).filter(|&k| normals[k].is_none()).collect();
    let along: Vec<(usize, Vec3)> = (0..slots.len())
        .filter_map(|k| normals[k].map(|n| (k, n)))
        .collect();
    let (nf, nk) = (3 * full.len(), along.len());
    let full_slots: Vec<u32> = full.iter().map(|&k| slots[k]).collect();
    // A key of `NONE` (a contact held in full on a point: not made today) is never cached.
    if cache.slots != full_slots || cache.inv.nrows() != nf || full_slots.contains(&NONE) {
        let mut a = Mat::<Real>::zeros(nf, nf);
        for (i, &ki) in full.iter().enumerate() {
            for (j, &kj) in full.iter().enumerate() {
                for l in 0..3 {
                    for m in 0..3 {
                        a[(3 * i + l, 3 * j + m)] = w[(3 * ki + l, 3 * kj + m)];
                    }
                }
            }
        }
        let mut inv = if nf > 0 {
            a.llt(Side::Lower).map_err(singular)?.inverse()
        } else {
            Mat::zeros(0, 0)
        };
        symmetrise(&mut inv);
        *cache = FullInverse {
            slots: full_slots,
            inv,
        };
    }
    let a_inv = &cache.inv;
    let m3 = w.nrows();
    let mut p = Mat::<Real>::zeros(m3, m3);
    // Row of the full block for row r of a full contact, by contact.
    let scatter_full = |p: &mut Mat<Real>, i: usize, j: usize, v: Real| {
        let (ki, kj) = (full[i / 3], full[j / 3]);
        p[(3 * ki + i % 3, 3 * kj + j % 3)] += v;
    };
    for j in 0..nf {
        for i in 0..nf {
            scatter_full(&mut p, i, j, a_inv[(i, j)]);
        }
    }
    if nk == 0 {
        return Ok(p);
    }
    // C = W_FN n (nf × k), D = nᵀ W_NN n (k × k).
    let mut c = Mat::<Real>::zeros(nf, nk);
    for (j, &(kj, n)) in along.iter().enumerate() {
        for (i, &ki) in full.iter().enumerate() {
            for l in 0..3 {
                c[(3 * i + l, j)] = (0..3).map(|m| w[(3 * ki + l, 3 * kj + m)] * n[m]).sum();
            }
        }
    }
    let mut s_mat = Mat::<Real>::zeros(nk, nk);
    for (i, &(ki, ni)) in along.iter().enumerate() {
        for (j, &(kj, nj)) in along.iter().enumerate() {
            let mut v = 0.0;
            for l in 0..3 {
                for m in 0..3 {
                    v += ni[l] * w[(3 * ki + l, 3 * kj + m)] * nj[m];
                }
            }
            s_mat[(i, j)] = v;
        }
    }
    let mut e = Mat::<Real>::zeros(nf, nk);
    if nf > 0 {
        faer::linalg::matmul::matmul(
            e.as_mut(),
            Accum::Replace,
            a_inv.as_ref(),
            c.as_ref(),
            1.0,
            Par::Seq,
        );
        faer::linalg::matmul::matmul(
            s_mat.as_mut(),
            Accum::Add,
            c.as_ref().transpose(),
            e.as_ref(),
            -1.0,
            Par::Seq,
        );
    }
    symmetrise(&mut s_mat);
    if along.iter().any(|&(k, _)| soft[k]) {
        let largest = (0..nk).map(|i| s_mat[(i, i)].abs()).fold(0.0, Real::max);
        for (i, &(k, _)) in along.iter().enumerate() {
            if soft[k] {
                s_mat[(i, i)] += crate::solve::lcp::REGULARISATION * largest;
            }
        }
    }
    let mut s_inv = s_mat.llt(Side::Lower).map_err(singular)?.inverse();
    symmetrise(&mut s_inv);
    // E S⁻¹ (nf × k).
    let mut es = Mat::<Real>::zeros(nf, nk);
    if nf > 0 {
        faer::linalg::matmul::matmul(
            es.as_mut(),
            Accum::Replace,
            e.as_ref(),
            s_inv.as_ref(),
            1.0,
            Par::Seq,
        );
        let mut ese = Mat::<Real>::zeros(nf, nf);
        faer::linalg::matmul::matmul(
            ese.as_mut(),
            Accum::Replace,
            es.as_ref(),
            e.as_ref().transpose(),
            1.0,
            Par::Seq,
        );
        for j in 0..nf {
            for i in 0..nf {
                scatter_full(&mut p, i, j, ese[(i, j)]);
            }
        }
    }
    for (j, &(kj, nj)) in along.iter().enumerate() {
        for i in 0..nf {
            let v = -es[(i, j)];
            let (ki, l) = (full[i / 3], i % 3);
            for m in 0..3 {
                p[(3 * ki + l, 3 * kj + m)] = v * nj[m];
                p[(3 * kj + m, 3 * ki + l)] = v * nj[m];
            }
        }
        for (i, &(ki, ni)) in along.iter().enumerate() {
            for l in 0..3 {
                for m in 0..3 {
                    p[(3 * ki + l, 3 * kj + m)] = ni[l] * s_inv[(i, j)] * nj[m];
                }
            }
        }
    }
    Ok(p)
}

/// The problem with the interface nodes held at zero (targets and forces to be filled).
fn held(iface: &[u32], nodes: usize) -> Result<DofProblem, SimError> {
    let mut dp = DofProblem::new(3 * nodes);
    for &n in iface {
        dp.hold_node(n as usize, Vec3::ZERO)?;
    }
    dp.finish();
    Ok(dp)
}

/// The rest's forces on the region's interface nodes (`NodeCoupling`).
pub(super) struct Coupling<'a> {
    rest: &'a RestPart,
    region_node: &'a [u32],
    region_rest: &'a [Vec3],
    scratch: RefCell<Scratch>,
}

/// Vectors a force evaluation reuses: interface displacements and forces, the contacts'
/// right-hand side and forces.
struct Scratch {
    u: Mat<Real>,
    out: Mat<Real>,
    y: Mat<Real>,
    z: Mat<Real>,
    /// The interface displacements an energy request is for.
    probe: Mat<Real>,
    /// `out`, `y`, `z` are the forces at `u`.
    fresh: bool,
}

impl Coupling<'_> {
    fn gather(&self, x: &[Vec3], u: &mut Mat<Real>) {
        for (a, &n) in self.region_node.iter().enumerate() {
            let d = x[n as usize] - self.region_rest[n as usize];
            for k in 0..3 {
                u[(3 * a + k, 0)] = d[k];
            }
        }
    }
}

impl NodeCoupling for Coupling<'_> {
    fn add_forces(&self, x: &[Vec3], f: &mut [Vec3]) {
        let mut guard = self.scratch.borrow_mut();
        let Scratch {
            u,
            out,
            y,
            z,
            fresh,
            ..
        } = &mut *guard;
        self.gather(x, u);
        self.rest.interface_forces_into(u, out, y, z);
        *fresh = true;
        for (a, &n) in self.region_node.iter().enumerate() {
            f[n as usize] += Vec3::new(out[(3 * a, 0)], out[(3 * a + 1, 0)], out[(3 * a + 2, 0)]);
        }
    }

    /// E = ½ uᵀS u − r₀ᵀu + ½ λᵀW_cc λ, rewritten with what the force evaluation at the same
    /// u left (F_I = r₀ − S u + G_cᵀλ, W_cc λ = y = t − u₀ − G_c u) as
    /// E = −½ uᵀ(r₀ + F_I) + ½ (t − u₀)_cᵀ λ: no second dense S·u per step for the
    /// integrator's energy guard (it asks for the energy where it just took the forces).
    fn energy(&self, x: &[Vec3]) -> Real {
        let mut guard = self.scratch.borrow_mut();
        let Scratch {
            u,
            out,
            y,
            z,
            probe,
            fresh,
        } = &mut *guard;
        self.gather(x, probe);
        let same = *fresh && (0..u.nrows()).all(|i| u[(i, 0)] == probe[(i, 0)]);
        if !same {
            u.as_mut().copy_from(probe.as_ref());
            self.rest.interface_forces_into(u, out, y, z);
            *fresh = true;
        }
        let r0 = &self.rest.r0;
        let mut e = 0.0;
        for i in 0..u.nrows() {
            e -= 0.5 * u[(i, 0)] * (r0[(i, 0)] + out[(i, 0)]);
        }
        let rhs = &self.rest.contacts.rhs;
        for i in 0..z.nrows() {
            e += 0.5 * rhs[(i, 0)] * z[(i, 0)];
        }
        e
    }

    /// K = S + G_cᵀ W_cc⁻¹ G_c on the interface nodes.
    fn add_stiffness_product(&self, dx: &[Vec3], out: &mut [Vec3]) {
        let mut u = Mat::zeros(3 * self.region_node.len(), 1);
        for (a, &n) in self.region_node.iter().enumerate() {
            for k in 0..3 {
                u[(3 * a + k, 0)] = dx[n as usize][k];
            }
        }
        let rest = self.rest;
        let mut k = Mat::zeros(u.nrows(), 1);
        rest.panels
            .mul_add(u.col_as_slice(0), k.col_as_slice_mut(0), 1.0);
        let c = &rest.contacts;
        if c.g.nrows() > 0 {
            let mut y = Mat::zeros(c.g.nrows(), 1);
            gemv(&mut y, Accum::Replace, c.g.as_ref(), u.as_ref(), 1.0);
            let mut z = Mat::zeros(y.nrows(), 1);
            gemv(&mut z, Accum::Replace, c.w_inv.as_ref(), y.as_ref(), 1.0);
            gemv(
                &mut k,
                Accum::Add,
                c.g.as_ref().transpose(),
                z.as_ref(),
                1.0,
            );
        }
        for (a, &n) in self.region_node.iter().enumerate() {
            out[n as usize] += Vec3::new(k[(3 * a, 0)], k[(3 * a + 1, 0)], k[(3 * a + 2, 0)]);
        }
    }

    fn add_stiffness_diagonal(&self, d: &mut [Vec3]) {
        for (a, &n) in self.region_node.iter().enumerate() {
            let diagonal = Vec3::new(
                self.rest.panels.diagonal(3 * a),
                self.rest.panels.diagonal(3 * a + 1),
                self.rest.panels.diagonal(3 * a + 2),
            );
            if let Some(di) = d.get_mut(n as usize) {
                *di += diagonal;
            }
        }
    }
}
