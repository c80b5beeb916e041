//! What `fem-condensed` and `fem-precomputed-tensors` share: the linear tetrahedral model
//! condensed onto its surface.
//!
//! With the fixed surface vertices eliminated and the interior dofs i condensed out, the
//! surface dofs s obey C u_s = f̃_s + λ, with C = K_ss − K_si K_ii⁻¹ K_is and the equivalent
//! surface load f̃_s = f_s − K_si K_ii⁻¹ f_i (eq. 4-5 of the survey, Bro-Nielsen). Both
//! come out of the sparse Cholesky of K_ii that `FemStatic` already keeps: holding every
//! surface dof, a unit displacement of surface dof j gives the reactions −C e_j, and zero
//! displacements under the loads give f̃_s. W = C⁻¹ is the surface compliance.
//!
//! The core also holds the per-step state both models need (contact list, targets, surface
//! displacements, reactions in the order the constraints were given) in buffers that are
//! reused, so that a contact update allocates nothing once the largest contact set was seen.

use std::time::Instant;

use faer::linalg::solvers::{DenseSolveCore, Solve};
use faer::{Mat, Side};

use crate::error::SimError;
use crate::interact::{Constraints, Loads, PointContact};
use crate::math::{Mat3, Real, Vec3, is_finite_vec};
use crate::model::{
    ConstraintReactions, CutInfo, CutPath, Deformable, ModelInfo, Progress, Reactions, StepInfo,
    SurfaceView,
};

use super::static_model::{FemStatic, NodalSolution};
use super::surface_nodes::nodal_forces;
use super::system::DofProblem;

use crate::solve::{HeldRows, PointRows, SmallDense, Source, VertexResponse};

const NONE: u32 = u32::MAX;

/// Contacts the step buffers are sized for before any step.
const INITIAL_CONTACTS: usize = 16;

/// The condensed stiffness of the free surface dofs and its rows at the fixed dofs.
pub(crate) struct Condensation {
    /// C over the free surface dofs (3n × 3n), symmetrised.
    pub c: Mat<Real>,
    /// Rows of the condensed operator at the fixed dofs (3|F| × 3n): reactions of the
    /// supports per unit surface displacement.
    pub c_fixed: Mat<Real>,
}

/// The fixed set a precomputation was made for: free vertices and the reverse map.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct FixedSet {
    pub mask: Vec<bool>,
    /// Free (not fixed) surface vertices, ascending.
    pub free: Vec<u32>,
    /// Fixed surface vertices, ascending.
    pub fixed: Vec<u32>,
    /// Surface vertex → index in `free`, or `NONE`.
    pub slot: Vec<u32>,
}

impl FixedSet {
    pub fn new(mask: Vec<bool>) -> Self {
        let (mut free, mut fixed) = (Vec::new(), Vec::new());
        let mut slot = vec![NONE; mask.len()];
        for (v, &m) in mask.iter().enumerate() {
            if m {
                fixed.push(v as u32);
            } else {
                slot[v] = free.len() as u32;
                free.push(v as u32);
            }
        }
        Self {
            mask,
            free,
            fixed,
            slot,
        }
    }
}

/// The problem holding every surface node at `targets(surface vertex)`, with `forces`.
fn surface_held(fem: &FemStatic, forces: &[Real]) -> Result<DofProblem, SimError> {
    let mut dp = DofProblem::new(forces.len());
    for &n in fem.surface_nodes() {
        dp.hold_node(n as usize, Vec3::ZERO)?;
    }
    dp.finish();
    dp.forces.copy_from_slice(forces);
    Ok(dp)
}

/// Condenses K onto the free surface dofs, one K_ii solve per column; `progress` gets the
/// fraction done.
pub(crate) fn condense(
    fem: &mut FemStatic,
    set: &FixedSet,
    progress: &dyn Fn(f64),
) -> Result<Condensation, SimError> {
    let nodes = fem.surface_nodes().to_vec();
    let dofs = fem.displacements().len();
    let mut dp = surface_held(fem, &vec![0.0; dofs])?;
    let n3 = 3 * set.free.len();
    let mut c = Mat::<Real>::zeros(n3, n3);
    let mut c_fixed = Mat::<Real>::zeros(3 * set.fixed.len(), n3);
    for (a, &v) in set.free.iter().enumerate() {
        let node = nodes[v as usize] as usize;
        for k in 0..3 {
            dp.targets[3 * node + k] = 1.0;
            let NodalSolution { reactions, .. } = fem.solve_dofs(&dp)?;
            dp.targets[3 * node + k] = 0.0;
            let col = 3 * a + k;
            for (b, &w) in set.free.iter().enumerate() {
                let r = reactions[nodes[w as usize] as usize];
                for l in 0..3 {
                    c[(3 * b + l, col)] = -r[l];
                }
            }
            for (b, &w) in set.fixed.iter().enumerate() {
                let r = reactions[nodes[w as usize] as usize];
                for l in 0..3 {
                    c_fixed[(3 * b + l, col)] = -r[l];
                }
            }
        }
        progress((a + 1) as f64 / set.free.len() as f64);
    }
    // C is symmetric in exact arithmetic; the solves leave roundoff that would break LLT's
    // assumption that reading one triangle suffices.
    for j in 0..n3 {
        for i in 0..j {
            let m = 0.5 * (c[(i, j)] + c[(j, i)]);
            c[(i, j)] = m;
            c[(j, i)] = m;
        }
    }
    Ok(Condensation { c, c_fixed })
}

/// W = C⁻¹ by a dense LLT; a C that is not positive definite means the fixed set leaves a
/// rigid motion free.
pub(crate) fn compliance(c: &Mat<Real>) -> Result<Mat<Real>, SimError> {
    let llt = c
        .llt(Side::Lower)
        .map_err(|_| SimError::NotPositiveDefinite {
            row: 0,
            hint: "the condensed surface stiffness is singular: fix at least three \
               non-collinear surface vertices of every piece"
                .into(),
        })?;
    let mut w = llt.inverse();
    let n = w.nrows();
    for j in 0..n {
        for i in 0..j {
            let m = 0.5 * (w[(i, j)] + w[(j, i)]);
            w[(i, j)] = m;
            w[(j, i)] = m;
        }
    }
    Ok(w)
}

/// Constraints, loads and the surface state shared by both models.
pub(crate) struct SurfaceCore {
    pub fem: FemStatic,
    pub set: FixedSet,
    /// Rows of the condensed operator at the fixed dofs (see `Condensation`).
    pub c_fixed: Mat<Real>,
    /// Nodal forces on all dofs, and their condensed form on the free surface dofs.
    pub forces: Vec<Real>,
    pub f_cond: Vec<Real>,
    /// Support reactions with the surface at rest.
    pub r_fixed0: Vec<Real>,
    pub loads: Loads,
    /// Contact (prescribed, not fixed) vertices as indices into `set.free`, and the target
    /// displacement of each (3 per contact).
    pub contacts: Vec<u32>,
    pub targets: Vec<Real>,
    /// Per contact: the direction it is held along only (`set_constraints_along`), or zero
    /// for a contact held in all three directions.
    pub normals: Vec<Vec3>,
    contact_of: Vec<u32>,
    /// The fixed mask of the constraints being set (scratch).
    pub mask: Vec<bool>,
    /// Displacements of the free surface vertices (3n), and a trial copy.
    pub us: Vec<Real>,
    pub us_trial: Vec<Real>,
    /// Forces the contacts apply to the tissue (3 per contact).
    pub lambda: Vec<Real>,
    /// The contact block and its right-hand side, solved in place.
    pub small: SmallDense,
    /// The held directions of a solve with contacts held along their normals, and the
    /// contacts' unknowns it gives (3 per contact; `ContactResponse`).
    pub held: HeldRows,
    pub unknowns: Vec<Real>,
    /// Fine-surface points pushed by instruments (`Deformable::set_point_contacts`), their
    /// pushes after the last step, and the rows of their problem (`solve::points`).
    pub points: Vec<PointContact>,
    pub point_lambda: Vec<Real>,
    pub point_rows: PointRows,
    /// Per point, its row in `point_rows` (`None`: all its vertices are fixed).
    point_row: Vec<Option<usize>>,
    /// The forces of the last point solve per free vertex (scratch).
    pub point_forces: Vec<(usize, Vec3)>,
    surface_positions: Vec<Vec3>,
    surface_reaction: Vec<Vec3>,
    reactions: ConstraintReactions,
    pub precompute_seconds: Real,
    pub rebuilds: usize,
    pub last_rebuild_seconds: Real,
    /// Where a re-condensation reports how far it has gone.
    pub progress: Progress,
}

impl SurfaceCore {
    pub fn new(fem: FemStatic) -> Self {
        let ns = fem.surface_nodes().len();
        let dofs = fem.displacements().len();
        Self {
            surface_positions: fem.rest_surface().to_vec(),
            set: FixedSet::new(vec![false; ns]),
            c_fixed: Mat::zeros(0, 0),
            forces: vec![0.0; dofs],
            f_cond: Vec::new(),
            r_fixed0: Vec::new(),
            loads: Loads::default(),
            contacts: Vec::new(),
            targets: Vec::new(),
            normals: Vec::new(),
            contact_of: vec![NONE; ns],
            mask: vec![false; ns],
            us: Vec::new(),
            us_trial: Vec::new(),
            lambda: Vec::new(),
            small: SmallDense::new(3 * INITIAL_CONTACTS),
            held: HeldRows::default(),
            unknowns: Vec::new(),
            points: Vec::new(),
            point_lambda: Vec::new(),
            point_rows: PointRows::default(),
            point_row: Vec::new(),
            point_forces: Vec::new(),
            surface_reaction: vec![Vec3::ZERO; ns],
            reactions: ConstraintReactions::default(),
            precompute_seconds: 0.0,
            rebuilds: 0,
            last_rebuild_seconds: 0.0,
            progress: Progress::silent(),
            fem,
        }
    }

    pub fn surface_count(&self) -> usize {
        self.set.mask.len()
    }

    /// Checks every vertex and target of `c` (nothing changes on error) and writes its fixed
    /// mask into `self.mask`; true when that differs from the condensed fixed set.
    pub fn check(&mut self, c: &Constraints) -> Result<bool, SimError> {
        let ns = self.surface_count();
        let bad = |v: u32| SimError::BadConstraint {
            vertex: v as usize,
            count: ns,
        };
        for p in &c.prescribed {
            if p.vertex as usize >= ns {
                return Err(bad(p.vertex));
            }
            if !is_finite_vec(p.position) {
                return Err(SimError::BadParameter {
                    name: "prescribed",
                    value: format!("surface vertex {} -> {}", p.vertex, p.position),
                    reason: "the target position is not finite".into(),
                });
            }
        }
        if let Some(&v) = c.fixed.iter().find(|&&v| v as usize >= ns) {
            return Err(bad(v));
        }
        self.mask.iter_mut().for_each(|m| *m = false);
        for &v in &c.fixed {
            self.mask[v as usize] = true;
        }
        Ok(!self.ready() || self.mask != self.set.mask)
    }

    /// Installs a new fixed set with its condensation (the caller derived its own data).
    pub fn install(&mut self, set: FixedSet, cond: &Condensation, started: Instant) {
        self.c_fixed = cond.c_fixed.clone();
        self.us = vec![0.0; 3 * set.free.len()];
        self.us_trial = self.us.clone();
        self.set = set;
        let seconds = started.elapsed().as_secs_f64();
        self.last_rebuild_seconds = seconds;
        self.precompute_seconds += seconds;
        self.rebuilds += 1;
    }

    /// True once a fixed set was condensed.
    pub fn ready(&self) -> bool {
        self.rebuilds > 0
    }

    /// Records the constraints (validated by `fixed_mask`, same fixed set as installed):
    /// contact list and targets, reaction owners. Reuses every buffer.
    pub fn record(&mut self, c: &Constraints) {
        self.record_along(c, &[]);
    }

    /// `record`, with the direction each prescribed entry is held along only (`None`,
    /// missing: all three directions).
    pub fn record_along(&mut self, c: &Constraints, normals: &[Option<Vec3>]) {
        let rest = self.fem.rest_surface();
        self.contacts.clear();
        self.targets.clear();
        self.normals.clear();
        for (entry, p) in c.prescribed.iter().enumerate() {
            let v = p.vertex as usize;
            if self.set.mask[v] {
                continue;
            }
            let d = p.position - rest[v];
            let k = self.contact_of[v];
            // A vertex prescribed twice takes its last target.
            let k = if k == NONE {
                self.contact_of[v] = self.contacts.len() as u32;
                self.contacts.push(self.set.slot[v]);
                self.targets.extend_from_slice(&[0.0; 3]);
                self.normals.push(Vec3::ZERO);
                self.contacts.len() - 1
            } else {
                k as usize
            };
            self.targets[3 * k..3 * k + 3].copy_from_slice(&[d.x, d.y, d.z]);
            self.normals[k] = normals
                .get(entry)
                .copied()
                .flatten()
                .map_or(Vec3::ZERO, |n| n.normalize_or_zero());
        }
        for &a in &self.contacts {
            self.contact_of[self.set.free[a as usize] as usize] = NONE;
        }
        self.reactions.set(c);
        self.lambda.clear();
        self.lambda.resize(self.targets.len(), 0.0);
        self.unknowns.clear();
        self.unknowns.resize(self.targets.len(), 0.0);
        self.points.clear();
        self.point_lambda.clear();
    }

    /// Whether some contact is held along a direction only.
    pub fn holds_along(&self) -> bool {
        self.normals.iter().any(|n| *n != Vec3::ZERO)
    }

    /// Condenses `self.forces` onto the surface: f̃_s = f_s − K_si K_ii⁻¹ f_i on free dofs,
    /// and the support reactions of the surface at rest.
    pub fn condense_loads(&mut self) -> Result<(), SimError> {
        let dp = surface_held(&self.fem, &self.forces)?;
        let r = self.fem.solve_dofs(&dp)?.reactions;
        let nodes = self.fem.surface_nodes();
        let pick = |list: &[u32]| -> Vec<Real> {
            list.iter()
                .flat_map(|&v| r[nodes[v as usize] as usize].to_array())
                .collect()
        };
        self.f_cond = pick(&self.set.free);
        self.r_fixed0 = pick(&self.set.fixed);
        Ok(())
    }

    /// Takes the trial surface displacements and `lambda` as the new state: positions and
    /// reactions (−λ on contacts, r_F0 − C_F u_s on supports).
    pub fn accept(&mut self) {
        std::mem::swap(&mut self.us, &mut self.us_trial);
        let rest = self.fem.rest_surface();
        for (p, x) in self.surface_positions.iter_mut().zip(rest) {
            *p = *x;
        }
        self.surface_reaction
            .iter_mut()
            .for_each(|r| *r = Vec3::ZERO);
        for (a, &v) in self.set.free.iter().enumerate() {
            let d = Vec3::new(self.us[3 * a], self.us[3 * a + 1], self.us[3 * a + 2]);
            self.surface_positions[v as usize] += d;
        }
        for (k, &a) in self.contacts.iter().enumerate() {
            let v = self.set.free[a as usize] as usize;
            let l = &self.lambda[3 * k..3 * k + 3];
            self.surface_reaction[v] = -Vec3::new(l[0], l[1], l[2]);
        }
        for (b, &v) in self.set.fixed.iter().enumerate() {
            let mut r = [0.0; 3];
            for (l, out) in r.iter_mut().enumerate() {
                let row = 3 * b + l;
                let cu: Real = (0..self.us.len())
                    .map(|j| self.c_fixed[(row, j)] * self.us[j])
                    .sum();
                *out = self.r_fixed0.get(row).copied().unwrap_or(0.0) - cu;
            }
            self.surface_reaction[v as usize] = Vec3::from_array(r);
        }
        let surface_reaction = &self.surface_reaction;
        self.reactions.distribute(|v| surface_reaction[v as usize]);
    }

    pub fn surface_positions(&self) -> &[Vec3] {
        &self.surface_positions
    }

    pub fn reactions(&self) -> crate::model::Reactions<'_> {
        self.reactions.reactions()
    }

    /// Indices into `contacts` of the vertices whose reactions the prescribed entries
    /// `entries` report (fixed ones are not contacts); `None` when the range is out of
    /// bounds.
    pub fn contacts_of_entries(&self, entries: std::ops::Range<usize>) -> Option<Vec<usize>> {
        let vertices = self.reactions.owned_prescribed(entries)?;
        Some(
            vertices
                .iter()
                .filter_map(|&v| {
                    let slot = *self.set.slot.get(v as usize)?;
                    self.contacts.iter().position(|&a| a == slot)
                })
                .collect(),
        )
    }

    /// Back to rest: zero surface displacements and contact forces.
    pub fn reset(&mut self) {
        self.us_trial.iter_mut().for_each(|v| *v = 0.0);
        self.lambda.iter_mut().for_each(|v| *v = 0.0);
        self.point_lambda.iter_mut().for_each(|v| *v = 0.0);
        self.accept();
    }

    /// Displacements of every mechanical node for the current surface state:
    /// the interior from K_ii⁻¹ (f_i − K_is u_s), one sparse solve.
    pub fn node_displacements(&mut self) -> Result<Vec<Vec3>, SimError> {
        let mut dp = surface_held(&self.fem, &self.forces)?;
        let nodes = self.fem.surface_nodes();
        for (a, &v) in self.set.free.iter().enumerate() {
            let n = nodes[v as usize] as usize;
            dp.targets[3 * n..3 * n + 3].copy_from_slice(&self.us[3 * a..3 * a + 3]);
        }
        Ok(self.fem.solve_dofs(&dp)?.displacements)
    }

    /// Sets the loads (checked, condensed); nothing changes on error.
    pub fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        let f = nodal_forces(loads, self.fem.surface_nodes(), |g| {
            self.fem.gravity_load(g)
        })?;
        let old = std::mem::replace(&mut self.forces, f);
        if self.ready()
            && let Err(e) = self.condense_loads()
        {
            self.forces = old;
            return Err(e);
        }
        self.loads = loads.clone();
        Ok(())
    }

    /// The memory of the shared parts: K and its factor (via `FemStatic`), C_F, buffers.
    pub fn memory_bytes(&self) -> usize {
        self.fem.info().memory_bytes
            + self.c_fixed.nrows() * self.c_fixed.ncols() * 8
            + (self.us.len() * 2 + self.f_cond.len()) * 8
    }
}

/// What `fem-condensed` and `fem-precomputed-tensors` each do their own way; the rest of
/// `Deformable` is written once, below, for both.
pub(crate) trait SurfaceResponse: Send {
    const KIND: &'static str;
    /// The progress label of a rebuild.
    const REBUILD_STAGE: &'static str;
    /// Why the model cannot cut.
    const NO_CUT_REASON: &'static str;

    fn core(&self) -> &SurfaceCore;
    fn core_mut(&mut self) -> &mut SurfaceCore;
    /// Derives and keeps what the model answers from, given the compliance W of a new fixed
    /// set; nothing changes on error.
    fn adopt_compliance(&mut self, w: Mat<Real>) -> Result<(), SimError>;
    /// Refreshes the surface displacements under the loads alone.
    fn update_u0(&mut self);
    /// Solves for the core's contacts, writing `us_trial` and `lambda`; a contact with a
    /// direction in `SurfaceCore::normals` is held along it only (`solve::along`).
    fn solve_contacts(&mut self) -> Result<(), SimError>;
    /// The contacts' system as `solve_contacts` forms it (3m × 3m, all of it): A a = t − u₀
    /// for the contacts' unknowns a.
    fn contact_block(&self) -> Mat<Real>;
    /// The force contact k applies to the tissue per unit of its unknown: λ_k = F_k a_k.
    fn contact_force_map(&self, k: usize) -> Mat3;
    /// W_ab: the displacement of free surface vertex a per unit force on free vertex b.
    fn compliance_between(&self, a: usize, b: usize) -> Mat3;
    /// The displacement of free surface vertex a under the loads alone.
    fn free_displacement(&self, a: usize) -> Vec3;
    /// `us_trial` = u₀ + Σ_b W_{:,b} f_b for the forces `core().point_forces` (per free
    /// vertex, each vertex once).
    fn superpose_forces(&mut self);
    /// Bytes held beyond the core.
    fn own_memory_bytes(&self) -> usize;
    /// Model-specific facts for `info()`.
    fn details(&self) -> Vec<(String, String)>;

    /// At construction: condenses for `fixed` (nothing to do when it is empty; the first
    /// `set_constraints` condenses then).
    fn install_fixed(&mut self, fixed: &[u32], progress: &dyn Fn(f64)) -> Result<(), SimError> {
        if fixed.is_empty() {
            return Ok(());
        }
        let c = Constraints::fixed(fixed.to_vec());
        self.core_mut().check(&c)?;
        self.rebuild(progress)?;
        self.core_mut().record(&c);
        self.core_mut().reset();
        Ok(())
    }

    /// The held contacts and the points together (`solve::points`): one row per held
    /// direction, one per point with a free vertex, on the compliance between their
    /// vertices; the forces superposed on the loads' response. Writes `us_trial`, the
    /// contacts' `lambda` (their held part: a point's push on a contact vertex is the
    /// point's) and `point_lambda`.
    fn solve_points(&mut self) -> Result<(), SimError> {
        const AXES: [Vec3; 3] = [Vec3::X, Vec3::Y, Vec3::Z];
        let mut rows = std::mem::take(&mut self.core_mut().point_rows);
        let core = self.core_mut();
        rows.clear();
        for (k, &a) in core.contacts.iter().enumerate() {
            let t = Vec3::from_slice(&core.targets[3 * k..3 * k + 3]);
            match core.normals[k] {
                n if n == Vec3::ZERO => AXES
                    .iter()
                    .for_each(|&e| rows.push_held(a as usize, e, e.dot(t))),
                n => rows.push_held(a as usize, n, n.dot(t)),
            }
        }
        core.point_row.clear();
        for p in &core.points {
            let slot = |v: u32| {
                let v = v as usize;
                (!core.set.mask[v]).then(|| core.set.slot[v] as usize)
            };
            let added = rows.push_point(p.vertices.map(slot), p.weights, p.normal, p.reach());
            core.point_row.push(added.then(|| rows.len() - 1));
        }
        let solved = rows.solve(&Compliance(&*self)).map(|l| l.to_vec());
        let core = self.core_mut();
        let lambda = match solved {
            Ok(l) => l,
            Err(e) => {
                core.point_rows = rows;
                return Err(e);
            }
        };
        let mut r = 0;
        for (k, n) in core.normals.iter().enumerate() {
            let dirs = if *n == Vec3::ZERO {
                &AXES[..]
            } else {
                std::slice::from_ref(n)
            };
            let mut f = Vec3::ZERO;
            for &e in dirs {
                f += e * lambda[r];
                r += 1;
            }
            core.lambda[3 * k..3 * k + 3].copy_from_slice(&f.to_array());
        }
        core.point_lambda.clear();
        core.point_lambda
            .extend(core.point_row.iter().map(|r| r.map_or(0.0, |r| lambda[r])));
        let forces = &mut core.point_forces;
        forces.clear();
        rows.forces(|s, f| forces.push((s.vertex, f)));
        forces.sort_unstable_by_key(|f| f.0);
        forces.dedup_by(|next, kept| {
            let same = next.0 == kept.0;
            if same {
                kept.1 += next.1;
            }
            same
        });
        core.point_rows = rows;
        self.superpose_forces();
        Ok(())
    }

    /// Condenses for the fixed mask in `core().mask` and pre-computes; nothing changes on
    /// error.
    fn rebuild(&mut self, progress: &dyn Fn(f64)) -> Result<(), SimError> {
        let started = Instant::now();
        let set = FixedSet::new(self.core().mask.clone());
        let cond = condense(&mut self.core_mut().fem, &set, progress)?;
        self.adopt_compliance(compliance(&cond.c)?)?;
        self.core_mut().install(set, &cond, started);
        self.core_mut().condense_loads()?;
        self.update_u0();
        Ok(())
    }
}

impl<T: SurfaceResponse> Deformable for T {
    fn kind(&self) -> &'static str {
        T::KIND
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: self.core().surface_positions(),
            triangles: self.core().fem.surface().triangles,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        self.core().fem.rest_surface()
    }

    /// Contacts may change every step at the cost of a small dense solve; a new fixed set
    /// re-condenses (see `info()` for its cost).
    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        if self.core_mut().check(c)? {
            let progress = self.core().progress.clone();
            self.rebuild(&|f| progress.report(T::REBUILD_STAGE, f))?;
        }
        self.core_mut().record(c);
        Ok(())
    }

    fn set_constraints_along(
        &mut self,
        c: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        if self.core_mut().check(c)? {
            let progress = self.core().progress.clone();
            self.rebuild(&|f| progress.report(T::REBUILD_STAGE, f))?;
        }
        self.core_mut().record_along(c, normals);
        Ok(true)
    }

    fn holds_point_contacts(&self) -> bool {
        true
    }

    /// Checked (a vertex that does not exist, a non-finite number: an error naming the
    /// point), then held from the next step on, solved with the held contacts
    /// (`SurfaceResponse::solve_points`). A point whose vertices are all fixed is held by
    /// the support: it is not pushed (λ = 0).
    fn set_point_contacts(&mut self, points: &[PointContact]) -> Result<bool, SimError> {
        let count = self.core().surface_count();
        for p in points {
            p.check(count)?;
        }
        let core = self.core_mut();
        core.points.clear();
        core.points.extend_from_slice(points);
        core.point_lambda.clear();
        core.point_lambda.resize(points.len(), 0.0);
        Ok(true)
    }

    fn point_reactions(&self) -> &[Real] {
        &self.core().point_lambda
    }

    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        self.core_mut().set_loads(loads)?;
        if self.core().ready() {
            self.update_u0();
        }
        Ok(())
    }

    fn step(&mut self, _dt: Real) -> Result<StepInfo, SimError> {
        if !self.core().ready() {
            return Err(SimError::NotPositiveDefinite {
                row: 0,
                hint: format!(
                    "{} has no fixed surface vertices: fix at least three non-collinear ones \
                     before stepping",
                    T::KIND
                ),
            });
        }
        // Without points, the contacts' own solve: the 1 kHz haptic path is unchanged.
        let mut info = StepInfo::default();
        if self.core().points.is_empty() {
            self.solve_contacts()?;
        } else {
            self.solve_points()?;
            info.iterations = self.core().point_rows.rounds;
        }
        self.core_mut().accept();
        Ok(info)
    }

    fn reactions(&self) -> Reactions<'_> {
        self.core().reactions()
    }

    /// The reactions are −λ_k = −F_k a_k with A a = t − u₀: linear in the targets, so the
    /// stiffness is −Σ_{k∈V} F_k (A⁻¹ E_V)_k, E_V the unit translation of V's targets. A
    /// fresh O(m³) factorisation of the contact block: once per full update, not per tick.
    fn prescribed_stiffness(&self, entries: std::ops::Range<usize>) -> Option<Mat3> {
        // A contact held along its normal only has a stiffness along it alone: not in the
        // closed form below (the haptic loop then estimates it from successive updates).
        // Nor does one beside points (their pushes change with the targets too).
        if self.core().holds_along() || !self.core().points.is_empty() {
            return None;
        }
        let selected = self.core().contacts_of_entries(entries)?;
        if selected.is_empty() {
            return None;
        }
        let a = self.contact_block();
        let mut e = Mat::<Real>::zeros(a.nrows(), 3);
        for &k in &selected {
            for l in 0..3 {
                e[(3 * k + l, l)] = 1.0;
            }
        }
        let x = a.partial_piv_lu().solve(&e);
        let mut k_total = Mat3::ZERO;
        for &k in &selected {
            let block = Mat3::from_cols_array_2d(&std::array::from_fn(|c| {
                std::array::from_fn(|r| x[(3 * k + r, c)])
            }));
            k_total -= self.contact_force_map(k) * block;
        }
        k_total.is_finite().then_some(k_total)
    }

    fn cut(&mut self, _blade: &CutPath) -> Result<CutInfo, SimError> {
        Err(SimError::Unsupported {
            model: T::KIND,
            operation: "cutting",
            reason: T::NO_CUT_REASON.into(),
        })
    }

    fn set_progress(&mut self, progress: Progress) {
        self.core_mut().progress = progress;
    }

    fn reset(&mut self) {
        self.core_mut().reset();
    }

    fn info(&self) -> ModelInfo {
        let core = self.core();
        let mut info = core.fem.info();
        info.kind = T::KIND;
        info.is_static = true;
        // The unknowns solved at run time: the free surface's (the interior and the held
        // vertices are condensed out once, before the simulation).
        info.dofs = core.us.len();
        info.memory_bytes = core.memory_bytes() + self.own_memory_bytes();
        info.precompute_seconds += core.precompute_seconds;
        info.details = self.details();
        info.details.extend([
            ("rebuilds".into(), core.rebuilds.to_string()),
            (
                "last_rebuild_s".into(),
                format!("{:.4}", core.last_rebuild_seconds),
            ),
        ]);
        info
    }
}

/// A model's compliance between free surface vertices, for `solve::points`: a force is a
/// force whether a held contact or a point applies it.
struct Compliance<'a, T: ?Sized>(&'a T);

impl<T: SurfaceResponse + ?Sized> VertexResponse for Compliance<'_, T> {
    const SYMMETRIC: bool = true;

    fn response(&self, j: usize, source: Source) -> Mat3 {
        self.0.compliance_between(j, source.vertex)
    }

    fn free(&self, j: usize) -> Vec3 {
        self.0.free_displacement(j)
    }
}
