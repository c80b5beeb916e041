//! The reordered BEM system and its pre-inverted form (eq. 11-12), with contact changes
//! absorbed by the Woodbury formula.
//!
//! Per vertex, either the displacement is known (fixed: U = 0; contact: U = U*) and the
//! traction unknown, or the traction is known (free: P = 0, or a point load) and the
//! displacement unknown. Exchanging the columns of H and −G of the vertices whose traction
//! is unknown gives the reordered matrix A with A x = b.
//!
//! The base matrix A₀ exchanges only the fixed vertices' columns (at least three
//! non-collinear fixed vertices make it regular). It is factorised once per fixed set and
//! W = A₀⁻¹ G is stored: column block j of W is the response of the whole surface (free
//! displacements, fixed tractions) to a unit traction at vertex j. Making a set C of free
//! vertices contacts changes A₀'s columns C from H to −G. Since A₀⁻¹ H_{:,C} = E_C, the
//! Woodbury capacitance matrix of that change is exactly −W_CC, and the update reduces to
//!   P_C = W_CC⁻¹ (U*_C − u_L,C),   x = u_L + W_{:,C} P_C,
//! where u_L = W P_load. A contact change costs one small LU (3|C|)², a static update
//! O(n·|C|); the n × n inverse of A is never formed (`explicit_inverse` builds it for
//! checks).
//!
//! Tractions are discontinuous at the rim of the fixed set (`base_matrix`), and optionally
//! at the rim of the contact set (`set_contact_rims`): then W_{:,C} is replaced by the
//! contacts' effective responses W̃_{:,C} (`contact_rims`), formed once per contact change
//! from cached per-triangle solves, and a static update stays O(n·|C|).

use std::sync::Arc;
use std::time::Instant;

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::lu::partial_pivoting::{factor, solve};
use faer::linalg::solvers::{DenseSolveCore, PartialPivLu, Solve};
use faer::{Accum, Conj, Mat, MatMut, MatRef, Par};

use crate::error::SimError;
use crate::math::{Mat3, Real, Vec3};
use crate::solve::{ContactResponse, HeldRows, block3};

use super::assembly::{Geometry, Influence};
use super::border::BaseInverse;
use super::contact_rims::{ContactRims, RimCache};
use super::quadrature::Rules;
use super::rim_worker::RimWorker;

/// Smallest |pivot| / largest |pivot| of A₀'s LU accepted as regular.
const PIVOT_RATIO: Real = 1e-12;

/// The capacitance matrix as its LU (for `explicit_inverse`) and its inverse: a static
/// update multiplies by the inverse, which needs no scratch memory (`solve` allocates
/// nothing). Its size is that of the contact set, so both cost O(|C|³) once per change.
pub(super) struct Capacitance {
    lu: PartialPivLu<Real>,
    inverse: Mat<Real>,
}

/// H, G, the pre-inverted base system and the current contact set.
pub struct BemSystem {
    /// H and G; shared so that an incision computed off the stepping thread reads them
    /// while the system goes on answering steps (`Bem`'s background incisions).
    pub(crate) inf: Arc<Influence>,
    /// The fixed set A₀ was factorised for.
    pub(super) fixed: Vec<bool>,
    /// W = A₀⁻¹ G (column-major, 3n × 3n); empty before the first factorisation. Shared
    /// like `inf`.
    pub(super) w: Arc<Mat<Real>>,
    pub(super) contacts: Vec<usize>,
    /// The capacitance matrix W_CC (W̃_CC with contact rims).
    pub(super) capacitance: Option<Capacitance>,
    /// A₀⁻¹ as its LU and the bordering updates of later incisions (`border`).
    pub(super) inverse: Option<BaseInverse>,
    pub factorizations: usize,
    pub woodbury_updates: usize,
    pub last_factor_seconds: Real,
    /// The surface, to re-integrate the rim triangles of the fixed set (`base_matrix`);
    /// without it the fixed vertices' tractions stay continuous across the rim.
    pub(super) geometry: Option<Arc<Geometry>>,
    /// Per vertex, the area its unknown traction acts on for the factorised fixed set (0 for
    /// the others); empty without geometry.
    pub(super) support_area: Vec<Real>,
    /// The rim columns of the factorised A₀ (see `base_matrix`).
    pub(super) rim: RimColumns,
    /// Contacts' tractions discontinuous at their rim too (`set_contact_rims`).
    pub(super) contact_rims: bool,
    /// With `contact_rims`: the current contacts' W̃_{:,C} and support areas.
    pub(super) rims: Option<ContactRims>,
    /// The memory of a replaced W̃, reused by the next contact change.
    pub(super) spare_response: Mat<Real>,
    /// q = A₀⁻¹ g per (triangle, corner), for `contact_rims`.
    pub(super) rim_cache: RimCache,
    /// Missing q solved by `rim_worker` while the contacts wait on the continuous rule.
    pub(super) rim_background: bool,
    pub(super) rim_worker: RimWorker,
    /// Wall time of the last incision's update (bordering or re-assembly), in s.
    pub last_cut_seconds: Real,
    /// Bumped whenever H, G, W or A₀⁻¹ change (a factorisation, an assembly, a bordering):
    /// a bordering computed from an older generation no longer applies.
    pub(super) generation: u64,
}

impl BemSystem {
    pub fn new(inf: Influence) -> Self {
        Self {
            fixed: vec![false; inf.vertices],
            inf: Arc::new(inf),
            w: Arc::new(Mat::zeros(0, 0)),
            contacts: Vec::new(),
            capacitance: None,
            inverse: None,
            factorizations: 0,
            woodbury_updates: 0,
            last_factor_seconds: 0.0,
            geometry: None,
            rim: RimColumns::default(),
            support_area: Vec::new(),
            contact_rims: false,
            rims: None,
            spare_response: Mat::zeros(0, 0),
            rim_cache: RimCache::default(),
            rim_background: false,
            rim_worker: RimWorker::default(),
            last_cut_seconds: 0.0,
            generation: 0,
        }
    }

    /// Makes the contacts' tractions discontinuous at the contact rim as the fixed ones are
    /// (needs the geometry; see `contact_rims`). A static update stays O(n·|C|); a contact
    /// change solves for the rim triangles not cached yet. A change of the setting drops
    /// the contact set: set the contacts again.
    pub fn set_contact_rims(&mut self, on: bool) {
        if on != self.contact_rims {
            self.contact_rims = on;
            self.contacts.clear();
            self.capacitance = None;
            self.rims = None;
        }
    }

    pub fn contact_rims(&self) -> bool {
        self.contact_rims
    }

    /// With contact rims on: solve the rim pairs a contact change misses on a worker thread
    /// (`rim_worker`) instead of before the change returns. Until they land, the contact set
    /// keeps continuous tractions; `collect_rim_solves` switches it over. Off: the change
    /// waits for its solves (the result does not depend on timing).
    pub fn set_rim_background(&mut self, on: bool) {
        self.rim_background = on;
    }

    pub fn rim_background(&self) -> bool {
        self.rim_background
    }

    /// Batches of background rim solves run at once, one thread each (default and most: one
    /// per core; at least 1).
    pub fn set_rim_threads(&mut self, threads: usize) {
        self.rim_worker.set_threads(threads);
    }

    pub fn rim_threads(&self) -> usize {
        self.rim_worker.threads()
    }

    /// Whether the contacts are on the continuous rule while the rim pairs they need are
    /// solved in the background.
    pub fn contacts_waiting_for_rims(&self) -> bool {
        self.rims.as_ref().is_some_and(|r| r.waiting)
    }

    /// Rim pairs asked of the worker and not delivered yet.
    pub fn pending_rim_solves(&self) -> usize {
        self.rim_worker.pending()
    }

    /// Stores finished background solves and, once every pair the waiting contacts need is
    /// there, re-forms the same contact set with its rims (a Woodbury update,
    /// O(n·pairs + |C|³)). Returns whether the contact model changed. Cheap when nothing
    /// landed. On error nothing changes.
    pub fn collect_rim_solves(&mut self) -> Result<bool, SimError> {
        if !self.absorb_rim_solves(false) || !self.rims_due() {
            return Ok(false);
        }
        let contacts = self.contacts.clone();
        self.apply_contacts(&contacts)?;
        Ok(true)
    }

    /// Waits for the rim pairs the current contacts need and re-forms the contact set with
    /// them: afterwards the contacts are as the blocking rule gives them, bit for bit.
    pub fn finish_rim_solves(&mut self) -> Result<(), SimError> {
        if !self.contacts_waiting_for_rims() {
            return Ok(());
        }
        // What is running lands; what waits is solved here rather than twice.
        self.rim_worker.drop_queue();
        self.absorb_rim_solves(true);
        let background = std::mem::replace(&mut self.rim_background, false);
        let contacts = self.contacts.clone();
        let applied = self.apply_contacts(&contacts);
        self.rim_background = background;
        applied
    }

    /// Gives the system its surface so that fixed tractions become discontinuous at the rim
    /// of the fixed set (see `base_matrix`). Takes effect at the next `factor`.
    pub(crate) fn set_geometry(&mut self, geometry: Option<Geometry>) {
        self.geometry = geometry.map(Arc::new);
    }

    pub(crate) fn geometry(&self) -> Option<&Geometry> {
        self.geometry.as_deref()
    }

    /// Replaces H and G (a deferred assembly); the factorisation is dropped.
    pub(crate) fn set_influence(&mut self, inf: Influence) {
        self.inf = Arc::new(inf);
        self.w = Arc::new(Mat::zeros(0, 0));
        self.generation += 1;
        self.contacts.clear();
        self.capacitance = None;
        self.inverse = None;
        self.drop_explicit_base_inverse();
    }

    /// The area over which fixed vertex `v`'s traction acts (what turns it into a reaction),
    /// if the system has its geometry; `None` otherwise (then: the tributary area).
    pub fn support_area(&self, v: usize) -> Option<Real> {
        if let Some(rims) = &self.rims
            && let Some(k) = self.contacts.iter().position(|&c| c == v)
        {
            return rims.area.get(k).copied();
        }
        match self.fixed.get(v) {
            Some(true) => self.support_area.get(v).copied(),
            _ => None,
        }
    }

    /// The reordered matrix with the tractions of the `constrained` vertices unknown and
    /// discontinuous at the rim of that set: a constrained vertex's column is −G restricted
    /// to its triangles whose three vertices are all constrained (`Geometry::
    /// traction_supports`), i.e. −G plus the G share of its rim triangles (`RimColumns`).
    /// Without geometry it is `reordered`. A₀ is this for the fixed set. Also returns the
    /// rim columns and the support areas.
    pub(super) fn base_matrix_parts(
        &self,
        constrained: &[bool],
    ) -> (Mat<Real>, RimColumns, Vec<Real>) {
        let mut a = self.reordered(constrained);
        let (rim, area) = match &self.geometry {
            Some(geo) => RimColumns::compute(geo, constrained, self.inf.vertices),
            None => (RimColumns::default(), Vec::new()),
        };
        rim.add_to(&mut a);
        (a, rim, area)
    }

    /// `base_matrix_parts` without the rim columns.
    pub fn base_matrix(&self, constrained: &[bool]) -> (Mat<Real>, Vec<Real>) {
        let (a, _, area) = self.base_matrix_parts(constrained);
        (a, area)
    }

    /// Drops what the contact-rim option derived from A₀⁻¹ (the cached q and the current
    /// W̃): stale after a bordering or a new factorisation.
    pub(super) fn drop_explicit_base_inverse(&mut self) {
        self.rim_cache.clear();
        self.rim_worker.cancel();
        self.rims = None;
    }

    pub fn dofs(&self) -> usize {
        self.inf.dofs()
    }
    pub fn influence(&self) -> &Influence {
        &self.inf
    }
    /// W = A₀⁻¹ G (empty before the first `factor`).
    pub fn response(&self) -> &Mat<Real> {
        &self.w
    }
    pub fn is_factored(&self) -> bool {
        self.w.nrows() == self.dofs() && self.dofs() > 0
    }
    pub fn fixed(&self) -> &[bool] {
        &self.fixed
    }
    pub fn contacts(&self) -> &[usize] {
        &self.contacts
    }

    /// The reordered matrix: columns of −G for vertices whose traction is unknown
    /// (`unknown_traction[v]`), of H otherwise (tractions continuous everywhere; A₀ is
    /// `base_matrix`).
    pub fn reordered(&self, unknown_traction: &[bool]) -> Mat<Real> {
        let n = self.dofs();
        Mat::from_fn(n, n, |r, c| base_entry(&self.inf, unknown_traction, r, c))
    }

    /// Factorises A₀ for `fixed` and computes W = A₀⁻¹ G (the expensive pre-computation,
    /// O(n³)); drops the contact set. Nothing changes on error.
    pub fn factor(&mut self, fixed: &[bool]) -> Result<(), SimError> {
        let start = Instant::now();
        let n = self.dofs();
        let singular = || SimError::NotPositiveDefinite {
            row: 0,
            hint: "the BEM system is singular: fix at least three non-collinear surface \
                   vertices so that no rigid motion is left free"
                .into(),
        };
        if fixed.len() != self.inf.vertices || fixed.iter().filter(|&&f| f).count() < 3 {
            return Err(singular());
        }
        let (mut a, rim, support_area) = self.base_matrix_parts(fixed);
        let mut perm = vec![0usize; n];
        let mut perm_inv = vec![0usize; n];
        let req = StackReq::any_of(&[
            factor::lu_in_place_scratch::<usize, Real>(n, n, Par::Seq, Default::default()),
            solve::solve_in_place_scratch::<usize, Real>(n, n, Par::Seq),
        ]);
        let mut mem = MemBuffer::new(req);
        let (_, p) = factor::lu_in_place(
            a.as_mut(),
            &mut perm,
            &mut perm_inv,
            Par::Seq,
            MemStack::new(&mut mem),
            Default::default(),
        );
        let pivots = (0..n).map(|i| a[(i, i)].abs());
        let (lo, hi) = pivots.fold((Real::INFINITY, 0.0), |(lo, hi): (Real, Real), v| {
            (lo.min(v), hi.max(v))
        });
        if lo.is_nan() || lo <= PIVOT_RATIO * hi {
            return Err(singular());
        }
        let g = &self.inf.g;
        let mut w = Mat::from_fn(n, n, |r, c| g[r * n + c]);
        solve_columns(a.as_ref(), p, w.as_mut());
        if w.col_iter().any(|c| c.iter().any(|v| !v.is_finite())) {
            return Err(singular());
        }
        self.w = Arc::new(w);
        self.generation += 1;
        self.drop_explicit_base_inverse();
        self.inverse = Some(BaseInverse::new(a, perm, perm_inv));
        self.fixed = fixed.to_vec();
        self.rim = rim;
        self.support_area = support_area;
        self.contacts.clear();
        self.capacitance = None;
        self.factorizations += 1;
        self.last_factor_seconds = start.elapsed().as_secs_f64();
        Ok(())
    }

    /// The Woodbury update for a new contact set (vertices not fixed, no repeats): gathers
    /// W_CC and factorises it, O(|C|³). Nothing changes on error.
    pub fn set_contacts(&mut self, contacts: &[usize]) -> Result<(), SimError> {
        if contacts == self.contacts.as_slice() {
            return Ok(());
        }
        if !self.is_factored() {
            return Err(not_factored());
        }
        let mut seen = vec![false; self.inf.vertices];
        for &c in contacts {
            match seen.get_mut(c) {
                Some(s) if !*s && !self.fixed[c] => *s = true,
                _ => {
                    return Err(SimError::BadConstraint {
                        vertex: c,
                        count: self.inf.vertices,
                    });
                }
            }
        }
        self.apply_contacts(contacts)
    }

    /// The Woodbury update for `contacts` (checked by the caller), even if they are the
    /// current ones: W_CC (W̃_CC) and its LU. Nothing changes on error.
    fn apply_contacts(&mut self, contacts: &[usize]) -> Result<(), SimError> {
        let m = 3 * contacts.len();
        let dof = |k: usize| 3 * contacts[k / 3] + k % 3;
        let rims = self.contact_rim_response(contacts);
        let s = match &rims {
            Some(rims) => Mat::from_fn(m, m, |r, c| rims.wt[(dof(r), c)]),
            None => Mat::from_fn(m, m, |r, c| self.w[(dof(r), dof(c))]),
        };
        let lu = (m > 0).then(|| s.partial_piv_lu());
        if let Some(lu) = &lu {
            let u = lu.U();
            let (lo, hi) = (0..m).fold((Real::INFINITY, 0.0), |(lo, hi): (Real, Real), i| {
                (lo.min(u[(i, i)].abs()), hi.max(u[(i, i)].abs()))
            });
            if lo.is_nan() || lo <= PIVOT_RATIO * hi {
                return Err(SimError::NotPositiveDefinite {
                    row: contacts.first().copied().unwrap_or(0),
                    hint: "the contact compliance block is singular".into(),
                });
            }
        }
        self.contacts = contacts.to_vec();
        self.capacitance = lu.map(|lu| Capacitance {
            inverse: lu.inverse(),
            lu,
        });
        if let Some(old) = std::mem::replace(&mut self.rims, rims) {
            self.spare_response = old.wt;
        }
        self.woodbury_updates += 1;
        Ok(())
    }

    /// u_L = W P for known tractions `p` (per dof; entries of fixed vertices ignored).
    pub fn load_response(&self, p: &[Real], out: &mut [Real]) -> Result<(), SimError> {
        if !self.is_factored() {
            return Err(not_factored());
        }
        out.fill(0.0);
        for (c, &pc) in p.iter().enumerate() {
            if pc != 0.0 && !self.fixed[c / 3] {
                axpy(out, pc, self.w.col_as_slice(c));
            }
        }
        Ok(())
    }

    /// Solves with the current contacts held at displacements `targets` (one per contact):
    /// `x` gets u_L + W_{:,C} P_C (free displacements, fixed tractions; contact rows equal
    /// their targets) and `p_contact` the contact tractions. O(n·|C|).
    pub fn solve(
        &self,
        targets: &[Vec3],
        u_load: &[Real],
        x: &mut [Real],
        p_contact: &mut [Real],
    ) -> Result<(), SimError> {
        if !self.is_factored() {
            return Err(not_factored());
        }
        x.copy_from_slice(u_load);
        let m = 3 * self.contacts.len();
        let Some(cap) = &self.capacitance else {
            return Ok(());
        };
        // The gaps U*_C − u_L,C, recomputed per row: no right-hand side is stored.
        let gap = |c: usize| {
            let v = self.contacts[c / 3];
            targets.get(c / 3).map_or(0.0, |t| t[c % 3]) - u_load[3 * v + c % 3]
        };
        for (r, pr) in p_contact.iter_mut().enumerate().take(m) {
            *pr = (0..m).map(|c| cap.inverse[(r, c)] * gap(c)).sum();
            if !pr.is_finite() {
                return Err(SimError::NotPositiveDefinite {
                    row: self.contacts[r / 3],
                    hint: "the contact solve gave a non-finite traction".into(),
                });
            }
            axpy(x, *pr, self.contact_column(r));
        }
        Ok(())
    }

    /// `solve` with contact k held along `normals[k]` only (zero: in all three directions):
    /// its traction is along n, its displacement along n reaches its target's and it moves
    /// freely across n. The held directions' block of W̃_CC (the collocation block, not
    /// symmetric) is formed and factorised by LU per call (`solve::along`), O(r³) for r
    /// held directions, then x = u_L + W̃_{:,C} P_C as in `solve`.
    pub(crate) fn solve_along(
        &self,
        targets: &[Vec3],
        normals: &[Vec3],
        u_load: &[Real],
        out: (&mut [Real], &mut [Real]),
        held: &mut HeldRows,
    ) -> Result<(), SimError> {
        if !self.is_factored() {
            return Err(not_factored());
        }
        let (x, p_contact) = out;
        x.copy_from_slice(u_load);
        let m = 3 * self.contacts.len();
        if m == 0 {
            return Ok(());
        }
        let (Some(normals), Some(p)) = (normals.get(..m / 3), p_contact.get_mut(..m)) else {
            return Err(along_mismatch(normals.len(), m / 3));
        };
        let response = Tractions {
            system: self,
            targets,
            u_load,
        };
        held.solve(&response, normals, p)?;
        for (r, &pr) in p_contact.iter().enumerate().take(m) {
            if pr != 0.0 {
                axpy(x, pr, self.contact_column(r));
            }
        }
        Ok(())
    }

    /// x += W̃_{:,C} `p_contact` + W `loads` (contact tractions, known tractions per dof;
    /// fixed vertices' entries ignored): what `solve` superposes, with loads beside it
    /// (`Bem::solve_points`). O(n·(|C| + loaded dofs)).
    pub(crate) fn add_response(&self, p_contact: &[Real], loads: &[Real], x: &mut [Real]) {
        for (r, &pr) in p_contact.iter().enumerate().take(3 * self.contacts.len()) {
            if pr != 0.0 {
                axpy(x, pr, self.contact_column(r));
            }
        }
        for (c, &pc) in loads.iter().enumerate() {
            if pc != 0.0 && !self.fixed.get(c / 3).copied().unwrap_or(true) {
                axpy(x, pc, self.w.col_as_slice(c));
            }
        }
    }

    /// Column r of W̃_{:,C}: the whole surface's response to a unit traction on contact dof r.
    fn contact_column(&self, r: usize) -> &[Real] {
        match &self.rims {
            Some(rims) => rims.wt.col_as_slice(r),
            None => self.w.col_as_slice(3 * self.contacts[r / 3] + r % 3),
        }
    }

    /// d(Σ_{c∈V} area_c P_c)/dt for the contacts V among `vertices` (others are skipped),
    /// when all their targets move by t: Σ_{c,d∈V} area_c (W̃_CC⁻¹)_{cd}, from the kept
    /// inverse of the capacitance, O(|V|²), with `area(v)` the area vertex v's traction acts
    /// on. `None` without contacts among them.
    pub fn held_traction_stiffness(
        &self,
        vertices: &[usize],
        area: impl Fn(usize) -> Real,
    ) -> Option<Mat3> {
        let cap = self.capacitance.as_ref()?;
        let index: Vec<usize> = vertices
            .iter()
            .filter_map(|&v| self.contacts.iter().position(|&c| c == v))
            .collect();
        if index.is_empty() {
            return None;
        }
        let mut k = [[0.0; 3]; 3];
        for &c in &index {
            let area = area(self.contacts[c]);
            for &d in &index {
                for (r, row) in k.iter_mut().enumerate() {
                    for (l, entry) in row.iter_mut().enumerate() {
                        *entry += area * cap.inverse[(3 * c + r, 3 * d + l)];
                    }
                }
            }
        }
        Some(Mat3::from_cols_array_2d(&k).transpose())
    }

    /// A⁻¹ of the current reordered matrix (fixed and contacts exchanged) by the Woodbury
    /// formula A⁻¹ = A₀⁻¹ − (W_{:,C} + E_C) W_CC⁻¹ (A₀⁻¹)_{C,:} (W̃ for W with contact rims).
    /// O(n³) for A₀⁻¹, formed afresh from `base_matrix`: for checks.
    pub fn explicit_inverse(&self) -> Result<Mat<Real>, SimError> {
        if !self.is_factored() {
            return Err(not_factored());
        }
        let a0_inv = self.base_matrix(&self.fixed).0.partial_piv_lu().inverse();
        let Some(Capacitance { lu, .. }) = &self.capacitance else {
            return Ok(a0_inv);
        };
        let n = self.dofs();
        let m = 3 * self.contacts.len();
        let dof = |k: usize| 3 * self.contacts[k / 3] + k % 3;
        let mut rows = Mat::from_fn(m, n, |r, c| a0_inv[(dof(r), c)]);
        lu.solve_in_place(rows.as_mut());
        let left = Mat::from_fn(n, m, |r, c| {
            let response = match &self.rims {
                Some(rims) => rims.wt[(r, c)],
                None => self.w[(r, dof(c))],
            };
            response + if r == dof(c) { 1.0 } else { 0.0 }
        });
        Ok(a0_inv - left * rows)
    }
}

/// The contacts' response for `solve::along`: the unknowns are the contact tractions P_C
/// (the force is P times the contact's support area, a scalar: along P), A = W̃_CC.
struct Tractions<'a> {
    system: &'a BemSystem,
    targets: &'a [Vec3],
    u_load: &'a [Real],
}

impl ContactResponse for Tractions<'_> {
    const SYMMETRIC: bool = false;

    fn block(&self, j: usize, k: usize) -> Mat3 {
        let row = 3 * self.system.contacts[j];
        match &self.system.rims {
            Some(rims) => block3(rims.wt.as_ref(), row, 3 * k),
            None => block3((*self.system.w).as_ref(), row, 3 * self.system.contacts[k]),
        }
    }

    fn unknown_per_force(&self, _k: usize) -> Mat3 {
        Mat3::IDENTITY
    }

    fn gap(&self, k: usize) -> Vec3 {
        let v = self.system.contacts[k];
        let u = &self.u_load[3 * v..3 * v + 3];
        self.targets.get(k).copied().unwrap_or(Vec3::ZERO) - Vec3::new(u[0], u[1], u[2])
    }
}

/// Entry (r, c) of the reordered matrix: −G for vertices whose traction is unknown, H
/// otherwise. The one definition `reordered`, `factor` and the bordering share.
pub(super) fn base_entry(inf: &Influence, unknown_traction: &[bool], r: usize, c: usize) -> Real {
    let n = inf.dofs();
    if unknown_traction.get(c / 3).copied().unwrap_or(false) {
        -inf.g[r * n + c]
    } else {
        inf.h[r * n + c]
    }
}

/// `solve_along` given fewer directions (or traction slots) than contacts.
fn along_mismatch(given: usize, contacts: usize) -> SimError {
    SimError::BadParameter {
        name: "normals",
        value: format!("{given} directions for {contacts} contacts"),
        reason: "a solve along normals takes one direction (or zero) per contact".into(),
    }
}

pub(super) fn not_factored() -> SimError {
    SimError::Unsupported {
        model: "bem",
        operation: "solving before the fixed vertices are known",
        reason: "the BEM system is factorised for a fixed set; set constraints first".into(),
    }
}

fn axpy(y: &mut [Real], a: Real, x: &[Real]) {
    for (y, x) in y.iter_mut().zip(x) {
        *y += a * x;
    }
}

/// dst (+)= alpha · lhs · rhs, with column blocks of dst on separate threads (faer itself
/// runs sequentially here, so that the haptic-rate updates never wait for a thread pool).
/// For the O(n² r) products of an incision.
pub(super) fn matmul_columns(
    dst: MatMut<'_, Real>,
    accum: Accum,
    lhs: MatRef<'_, Real>,
    rhs: MatRef<'_, Real>,
    alpha: Real,
) {
    let k = dst.ncols();
    #[cfg(feature = "parallel")]
    if k >= 2 * MATMUL_BLOCK {
        let (dl, dr) = dst.split_at_col_mut(k / 2);
        let (rl, rr) = rhs.split_at_col(k / 2);
        rayon::join(
            || matmul_columns(dl, accum, lhs, rl, alpha),
            || matmul_columns(dr, accum, lhs, rr, alpha),
        );
        return;
    }
    debug_assert_eq!(k, rhs.ncols());
    faer::linalg::matmul::matmul(dst, accum, lhs, rhs, alpha, Par::Seq);
}

/// Columns below which a product is not split further (keeps the blocks large enough for
/// the kernels to run at full speed).
#[cfg(feature = "parallel")]
const MATMUL_BLOCK: usize = 128;

/// Right-hand sides below which `solve_columns` does not split (one thread).
pub(super) const SOLVE_BLOCK: usize = 64;

/// Solves L U X = P B in place, column blocks in parallel (faer itself runs sequentially
/// here).
pub(super) fn solve_columns(
    lu: MatRef<'_, Real>,
    perm: faer::perm::PermRef<'_, usize>,
    rhs: MatMut<'_, Real>,
) {
    #[cfg(feature = "parallel")]
    let chunk = rhs
        .ncols()
        .div_ceil(4 * rayon::current_num_threads())
        .max(SOLVE_BLOCK);
    #[cfg(not(feature = "parallel"))]
    let chunk = rhs.ncols();
    split_solve(lu, perm, rhs, chunk);
}

fn split_solve(
    lu: MatRef<'_, Real>,
    perm: faer::perm::PermRef<'_, usize>,
    rhs: MatMut<'_, Real>,
    chunk: usize,
) {
    let k = rhs.ncols();
    if k <= chunk {
        let n = lu.nrows();
        let mut mem = MemBuffer::new(solve::solve_in_place_scratch::<usize, Real>(n, k, Par::Seq));
        solve::solve_in_place_with_conj(
            lu,
            lu,
            perm,
            Conj::No,
            rhs,
            Par::Seq,
            MemStack::new(&mut mem),
        );
        return;
    }
    let (left, right) = rhs.split_at_col_mut(k / 2);
    #[cfg(feature = "parallel")]
    rayon::join(
        || split_solve(lu, perm, left, chunk),
        || split_solve(lu, perm, right, chunk),
    );
    #[cfg(not(feature = "parallel"))]
    {
        split_solve(lu, perm, left, chunk);
        split_solve(lu, perm, right, chunk);
    }
}

/// For the constrained vertices with rim triangles (a triangle with a vertex outside the
/// set), the G share of those triangles, which the vertex's traction no longer acts on:
/// three dense columns (every row) per such vertex, added to A₀'s −G columns.
#[derive(Clone, Debug)]
pub(super) struct RimColumns {
    /// Per vertex, its block of columns in `values`, or `u32::MAX`.
    slot: Vec<u32>,
    values: Mat<Real>,
}

impl Default for RimColumns {
    fn default() -> Self {
        Self {
            slot: Vec::new(),
            values: Mat::zeros(0, 0),
        }
    }
}

impl RimColumns {
    /// The rim columns of `constrained` on `geo`, and the support areas (empty, with no
    /// columns, when the geometry is not the one of the system's `vertices`).
    pub(super) fn compute(
        geo: &Geometry,
        constrained: &[bool],
        vertices: usize,
    ) -> (Self, Vec<Real>) {
        if geo.vertices.len() != vertices {
            return (Self::default(), Vec::new());
        }
        let (rim, area) = geo.traction_supports(constrained);
        let with_rim: Vec<usize> = (0..vertices).filter(|&v| !rim[v].is_empty()).collect();
        let mut slot = vec![u32::MAX; vertices];
        let n = 3 * vertices;
        let mut values = Mat::zeros(n, 3 * with_rim.len());
        let rules = Rules::new();
        for (s, &v) in with_rim.iter().enumerate() {
            slot[v] = s as u32;
            for &(e, corner) in &rim[v] {
                let g = geo.element_g_columns(e, corner, &rules);
                for r in 0..n {
                    for k in 0..3 {
                        values[(r, 3 * s + k)] += g[3 * r + k];
                    }
                }
            }
        }
        (Self { slot, values }, area)
    }

    /// Entry (r, c) (zero outside the rim columns).
    pub(super) fn at(&self, r: usize, c: usize) -> Real {
        match self.slot.get(c / 3) {
            Some(&s) if s != u32::MAX => self.values[(r, 3 * s as usize + c % 3)],
            _ => 0.0,
        }
    }

    fn add_to(&self, a: &mut Mat<Real>) {
        for (v, &s) in self.slot.iter().enumerate() {
            if s == u32::MAX {
                continue;
            }
            for k in 0..3 {
                for r in 0..a.nrows() {
                    a[(r, 3 * v + k)] += self.values[(r, 3 * s as usize + k)];
                }
            }
        }
    }
}
