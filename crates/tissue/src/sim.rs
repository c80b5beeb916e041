//! A running simulation: one model, its fixed vertices and loads, the instruments that touch
//! it, and the clock.
//!
//! Each step moves the instruments along their paths, lets scalpels cut, refits the contact
//! hierarchy, turns touched vertices into prescribed ones and steps the model. Static models
//! get an active-set loop inside the step (add vertices that now penetrate a probe, release
//! contacts that would pull the probe in) so that no vertex is left inside a probe and no
//! contact is adhesive. A failed step leaves time and instruments as they were.

use crate::error::SimError;
use crate::interact::bvh::Bvh;
use crate::interact::contact::{
    Contact, PENETRATION_TOLERANCE, PushOnly, hold_points, is_adhesive, owed_depth,
    project_to_sphere, pulls, recovery, settle_carried_faces, vertices_in_ball, vertices_in_shape,
    vertices_near_shape,
};
use crate::interact::fine_points;
use crate::interact::fine_surface::MappedSurface;
use crate::interact::instrument::{Instrument, InstrumentKind};
use crate::interact::plausibility::Plausibility;
use crate::interact::shape::Shape;
use crate::interact::sliding::SlideResidual;
use crate::interact::{Constraints, Loads, PointContact, Prescribed};
use crate::math::{Mat3, Real, Vec3};
use crate::model::{Deformable, StepInfo};
use std::sync::OnceLock;

/// Default cap of the static contact loop (solves per step).
pub const DEFAULT_CONTACT_ITERATIONS: usize = 8;

/// A dynamic model holding frictionless contacts as pushes only (`integrate::Hold::contact`)
/// is also given the vertices within this fraction of the instrument's size outside it
/// (plus twice the instrument's move in the step): they are free until they touch, and
/// touching within the step they are stopped on the instrument at that substep.
pub const CONTACT_MARGIN: Real = 0.05;

/// What one simulation step did.
#[derive(Clone, Debug, PartialEq)]
pub struct StepReport {
    /// Time after the step, in s.
    pub time: Real,
    /// Number of steps done, this one included.
    pub step: u64,
    /// Vertices held by each instrument.
    pub contacts: Vec<usize>,
    /// Force on each instrument, in N.
    pub forces: Vec<Vec3>,
    /// Model solves in this step (1 for dynamic models).
    pub contact_iterations: usize,
    /// False when the static contact loop hit its cap with the contact set still changing.
    pub contact_converged: bool,
    /// The sliding contacts' tangential force beyond Coulomb's bound (all of it when
    /// frictionless) after the last solve, relative to the normal force, worst instrument:
    /// below `SLIDE_TOLERANCE` when a static model's contact loop converged.
    pub slide_residual: Real,
    /// The last inner solve.
    pub info: StepInfo,
}

/// A model with its supports, loads, instruments and clock.
pub struct Simulation {
    model: Box<dyn Deformable>,
    fixed: Vec<u32>,
    loads: Loads,
    instruments: Vec<Instrument>,
    time: Real,
    steps: u64,
    bvh: Bvh,
    /// The model's `CutInfo::topology_version` after the last cut: the triangles may be
    /// re-connected at an unchanged count, so the BVH is rebuilt, not refitted.
    topology_version: u32,
    /// A scalpel was removed since the last step (`Deformable::end_cut` at the next).
    scalpel_removed: bool,
    bvh_topology: u32,
    is_static: bool,
    max_contact_iterations: usize,
    /// Whether the static loop accelerates the fine points' planes (`PlaneRelaxation`).
    accelerate_planes: bool,
    /// The constraints the model holds now (restored when a step fails), with the direction
    /// each prescribed entry is held along only (`Deformable::set_constraints_along`).
    constraints: Constraints,
    normals: Vec<Option<Vec3>>,
    /// Whether the model held the last constraints' directions (false: it held every entry in
    /// all three directions, and frictionless contacts slide by relaxation); before the first
    /// solve, whether its contacts only push (`Simulation::new`).
    along: bool,
    /// How many of their prescribed entries each instrument gave, in order. When the
    /// contact loop stops at its cap, the instruments' contact sets have moved on from
    /// what the model last solved with.
    held: Vec<usize>,
    /// The contact loop's per-vertex release record, kept to reuse its memory.
    returned: Returned,
    /// The bounds a step's result must stay within to be accepted.
    plausibility: Plausibility,
    /// The fine contact surface mapped onto the model's surface, if the scene gives one,
    /// and where all its vertices are after the last step, computed when first asked for
    /// (`fine_surface`, for drawing): a step itself reads only the fine vertices near its
    /// instruments (`fine_points::gather`).
    fine: Option<(MappedSurface, OnceLock<Vec<Vec3>>)>,
}

impl Simulation {
    /// Fixes `fixed` (surface vertices, kept at rest) and applies `loads`.
    pub fn new(
        mut model: Box<dyn Deformable>,
        fixed: Vec<u32>,
        loads: Loads,
    ) -> Result<Self, SimError> {
        let constraints = Constraints::fixed(fixed.clone());
        model.set_constraints(&constraints)?;
        model.set_loads(&loads)?;
        let s = model.surface();
        let bvh = Bvh::build(s.positions, s.triangles);
        let is_static = model.info().is_static;
        // A model whose contacts only push holds them along their normals: assumed before its
        // first solve says so, so that the first step hands it the near faces and owes it a
        // penetration it starts with (`interact::contact::PushOnly`), as every later step does.
        let along = model.contacts_push_only();
        let plausibility = Plausibility::for_body(model.rest_surface());
        Ok(Self {
            model,
            fixed,
            loads,
            instruments: Vec::new(),
            time: 0.0,
            steps: 0,
            bvh,
            topology_version: 0,
            scalpel_removed: false,
            bvh_topology: 0,
            is_static,
            max_contact_iterations: DEFAULT_CONTACT_ITERATIONS,
            accelerate_planes: true,
            constraints,
            held: Vec::new(),
            returned: Returned::default(),
            plausibility,
            fine: None,
            normals: Vec::new(),
            along,
        })
    }

    /// Makes `surface` (tied to the model's rest surface) the surface instruments touch:
    /// contacts are found on its vertices and handed to the model's surface vertices by the
    /// map's weights (`interact::fine_surface`). Refused when its map names a vertex the
    /// model's surface does not have.
    pub fn set_fine_surface(&mut self, surface: MappedSurface) -> Result<(), SimError> {
        let count = self.model.rest_surface().len();
        for j in 0..surface.len() {
            let (tri, _) = surface
                .tie(j)
                .ok_or(SimError::BadConstraint { vertex: j, count })?;
            if let Some(&v) = tri.iter().find(|&&v| v as usize >= count) {
                return Err(SimError::BadConstraint {
                    vertex: v as usize,
                    count,
                });
            }
        }
        self.fine = Some((surface, OnceLock::new()));
        Ok(())
    }

    /// What the scene should be told about its instruments' contact (`interact::slip`): a
    /// frictionless probe or capsule small against the surface edges near its path, or,
    /// with a fine contact surface, against that surface's own edges (with the
    /// `visual_levels` that would fix it). Empty when nothing is to be said.
    pub fn contact_warnings(&self) -> Vec<String> {
        if let Some((fine, _)) = &self.fine {
            return self
                .instruments
                .iter()
                .enumerate()
                .filter_map(|(i, inst)| {
                    crate::interact::slip::fine_slip_warning(
                        i,
                        inst,
                        &fine.rest,
                        &fine.triangles,
                        fine.levels,
                    )
                })
                .collect();
        }
        let s = self.model.contact_surface();
        self.instruments
            .iter()
            .enumerate()
            .filter_map(|(i, inst)| {
                crate::interact::slip::slip_warning(i, inst, s.positions, s.triangles)
            })
            .collect()
    }

    /// The fine contact surface and where its vertices are now, if the scene gives one.
    pub fn fine_surface(&self) -> Option<(&MappedSurface, &[Vec3])> {
        self.fine.as_ref().map(|(m, now)| {
            let now = now.get_or_init(|| {
                let mut p = Vec::new();
                m.positions(
                    self.model.rest_surface(),
                    self.model.surface().positions,
                    &mut p,
                );
                p
            });
            (m, now.as_slice())
        })
    }

    /// Replaces the plausibility bounds (the scene adds the material's force bound).
    pub fn set_plausibility(&mut self, bounds: Plausibility) {
        self.plausibility = bounds;
    }

    pub fn plausibility(&self) -> &Plausibility {
        &self.plausibility
    }

    /// Adds an instrument, placed where its path is now.
    pub fn add_instrument(&mut self, mut instrument: Instrument) {
        instrument.position = instrument.position_at(self.time);
        self.instruments.push(instrument);
    }

    /// Removes instrument `index`; what it held is let go from the next step on.
    pub fn remove_instrument(&mut self, index: usize) -> Option<Instrument> {
        // The model keeps its constraints until the next step; their split among the
        // instruments no longer holds.
        self.held.clear();
        let removed = (index < self.instruments.len()).then(|| self.instruments.remove(index));
        if removed
            .as_ref()
            .is_some_and(|i| matches!(i.kind(), InstrumentKind::Scalpel { .. }))
        {
            self.scalpel_removed = true;
        }
        removed
    }

    /// Caps the solves per step of the static contact loop (at least 1).
    pub fn set_max_contact_iterations(&mut self, n: usize) {
        self.max_contact_iterations = n.max(1);
    }

    pub fn max_contact_iterations(&self) -> usize {
        self.max_contact_iterations
    }

    /// Whether a static model's contact loop moves its fine points' planes by Aitken's
    /// acceleration (the default) or one plain round at a time: the same fixed point, by
    /// fewer solves (`interact::fine_points::PlaneRelaxation`). Off, for comparisons.
    pub fn set_accelerated_planes(&mut self, on: bool) {
        self.accelerate_planes = on;
    }

    /// Replaces the loads (gravity, point loads).
    pub fn set_loads(&mut self, loads: Loads) -> Result<(), SimError> {
        self.model.set_loads(&loads)?;
        self.loads = loads;
        Ok(())
    }

    pub fn time(&self) -> Real {
        self.time
    }

    /// Bumped by cuts that changed the model's topology (the model's own count): anything
    /// drawn from the surface's connectivity is rebuilt when it changes.
    pub fn topology_version(&self) -> u32 {
        self.topology_version
    }

    pub fn steps(&self) -> u64 {
        self.steps
    }

    pub fn model(&self) -> &dyn Deformable {
        self.model.as_ref()
    }

    /// The model, e.g. to reset it. Changing its constraints here is undone by the next step.
    pub fn model_mut(&mut self) -> &mut dyn Deformable {
        self.model.as_mut()
    }

    pub fn fixed(&self) -> &[u32] {
        &self.fixed
    }

    pub fn loads(&self) -> &Loads {
        &self.loads
    }

    pub fn instruments(&self) -> &[Instrument] {
        &self.instruments
    }

    /// Force on each instrument after the last step, in N.
    pub fn instrument_forces(&self) -> Vec<Vec3> {
        self.instruments.iter().map(|i| i.force).collect()
    }

    /// Instrument `index`'s tangent stiffness after the last step (dF/dx for a small move
    /// of the instrument with its contacts held, N/m), where the model gives it in closed
    /// form (`Deformable::prescribed_stiffness`); `None` otherwise or without contacts.
    pub fn instrument_stiffness(&self, index: usize) -> Option<Mat3> {
        let start: usize = self.held.get(..index)?.iter().sum();
        let count = *self.held.get(index)?;
        if count == 0 {
            return None;
        }
        self.model.prescribed_stiffness(start..start + count)
    }

    /// Sum of the reactions at the fixed vertices after the last step, in N.
    pub fn fixed_reaction_total(&self) -> Vec3 {
        self.model.reactions().fixed.iter().copied().sum()
    }

    /// Moves instrument `index` to a live position from the next step on (viewer, haptic
    /// device); `None` returns it to its path.
    pub fn set_instrument_position(
        &mut self,
        index: usize,
        position: Option<Vec3>,
    ) -> Result<(), SimError> {
        let count = self.instruments.len();
        let bad = |reason: String| SimError::BadParameter {
            name: "instrument",
            value: index.to_string(),
            reason,
        };
        if position.is_some_and(|p| !crate::math::is_finite_vec(p)) {
            return Err(bad("the position is not finite".into()));
        }
        let inst = self
            .instruments
            .get_mut(index)
            .ok_or_else(|| bad(format!("there are {count} instruments")))?;
        inst.set_live_position(position);
        Ok(())
    }

    /// Advances by `dt` seconds. On error, time and instruments stay as they were and the
    /// model gets its previous constraints back.
    pub fn step(&mut self, dt: Real) -> Result<StepReport, SimError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(SimError::BadTimeStep { dt });
        }
        let mut next = self.instruments.clone();
        let result = self.advance(dt, &mut next).and_then(|report| {
            let state = self
                .plausibility
                .check(self.model.as_ref(), &next, report.step);
            state.map(|()| report)
        });
        match result {
            Ok(report) => {
                self.instruments = next;
                self.time = report.time;
                self.steps = report.step;
                Ok(report)
            }
            Err(e) => {
                // Best effort: the model already kept its last good state; give it back the
                // constraints that belong to that state.
                let _ = self
                    .model
                    .set_constraints_along(&self.constraints, &self.normals);
                Err(e)
            }
        }
    }

    fn advance(&mut self, dt: Real, next: &mut [Instrument]) -> Result<StepReport, SimError> {
        let t1 = self.time + dt;
        // A stroke the model still holds opens when its scalpel is gone; an incision
        // finished off the thread changes the surface before this step's search.
        if std::mem::take(&mut self.scalpel_removed) {
            let info = self.model.end_cut()?;
            self.topology_version = self.topology_version.max(info.topology_version);
        }
        if let Some(info) = self.model.finish_background()? {
            self.topology_version = self.topology_version.max(info.topology_version);
        }
        for (inst, old) in next.iter_mut().zip(&self.instruments) {
            inst.position = inst.position_at(t1);
            if let Some(cut) = inst.sweep(old.position) {
                let info = self.model.cut(&cut)?;
                self.topology_version = self.topology_version.max(info.topology_version);
            }
        }
        self.set_reach(next);
        self.refresh_bvh();
        let n = self.model.contact_surface().positions.len();
        let mut taken = vec![false; n];
        let mut returned = std::mem::take(&mut self.returned);
        returned.reset(n);
        for &v in &self.fixed {
            if let Some(t) = taken.get_mut(v as usize) {
                *t = true;
            }
        }
        self.place_contacts(t1, next, &mut taken);

        let cap = if self.is_static {
            self.max_contact_iterations.max(1)
        } else {
            1
        };
        let mut iterations = 0;
        let mut converged = true;
        let mut slide;
        let info = loop {
            iterations += 1;
            let (constraints, normals) = self.constraints_for(next);
            self.along = self.model.set_constraints_along(&constraints, &normals)?;
            let points: Vec<PointContact> = next
                .iter()
                .flat_map(|i| i.points.iter().map(|p| p.contact))
                .collect();
            if !self.model.set_point_contacts(&points)? {
                return Err(SimError::Unsupported {
                    model: self.model.kind(),
                    operation: "point contacts",
                    reason: "it does not solve a fine surface's points (internal)".into(),
                });
            }
            let info = self.model.step(dt)?;
            self.constraints = constraints;
            self.normals = normals;
            self.held.clear();
            self.held.extend(next.iter().map(|i| i.contacts.len()));
            self.collect_forces(next);
            // Sliding moves the targets for the next solve (a dynamic model's next step).
            slide = self.relax_sliding(next);
            if !self.is_static {
                // The next step refits at its start, where its search needs the tree.
                break info;
            }
            // The active set below searches the surface this solve left.
            self.refresh_bvh();
            let changed = self.update_active_set(next, &mut taken, &mut returned);
            if !changed && slide.converged() {
                break info;
            }
            if iterations >= cap {
                converged = !changed;
                break info;
            }
        };
        self.returned = returned;
        if let Some((_, now)) = &mut self.fine {
            now.take();
        }
        Ok(StepReport {
            time: t1,
            step: self.steps + 1,
            contacts: next.iter().map(|i| self.held_count(i)).collect(),
            forces: next.iter().map(|i| i.force).collect(),
            contact_iterations: iterations,
            contact_converged: converged,
            slide_residual: slide.relative(),
            info,
        })
    }

    /// Tells the model where this step's contact searches look: each instrument's reach
    /// (its shape's bounding ball, or the grasper's ball, grown past the contact
    /// tolerances); everywhere for a half-space or a fine surface (which reads every
    /// vertex). A scalpel touches nothing.
    fn set_reach(&mut self, next: &[Instrument]) {
        let mut balls = Vec::with_capacity(next.len());
        let mut everywhere = self.fine.is_some();
        for (k, inst) in next.iter().enumerate() {
            let ball = match *inst.kind() {
                InstrumentKind::Scalpel { .. } => continue,
                InstrumentKind::Grasper { .. } => Some((inst.position, inst.radius())),
                _ => inst.shape().and_then(|s| s.bounds(inst.position)),
            };
            // A push-only model is also handed the vertices within the contact margin
            // (`place_contacts`): the search must see their exact positions too.
            let margin = match (self.pushes_only(inst), inst.shape()) {
                (true, Some(shape)) => {
                    let moved = self
                        .instruments
                        .get(k)
                        .map_or(0.0, |o| inst.position.distance(o.position));
                    CONTACT_MARGIN * shape.size() + 2.0 * moved
                }
                _ => 0.0,
            };
            match ball {
                Some((c, r)) => balls.push((c, r * (1.0 + 4.0 * PENETRATION_TOLERANCE) + margin)),
                None => everywhere = true,
            }
        }
        self.model
            .set_contact_reach((!everywhere).then_some(balls.as_slice()));
    }

    fn refresh_bvh(&mut self) {
        let s = self.model.contact_surface();
        if s.triangles.len() == self.bvh.triangle_count()
            && self.bvh_topology == self.topology_version
        {
            self.bvh.refit(s.positions, s.triangles);
        } else {
            self.bvh = Bvh::build(s.positions, s.triangles);
            self.bvh_topology = self.topology_version;
        }
    }

    /// The contact sets at the start of a step, from the surface as the last step left it.
    fn place_contacts(&self, t1: Real, next: &mut [Instrument], taken: &mut [bool]) {
        let s = self.model.contact_surface();
        let (positions, triangles) = (s.positions, s.triangles);
        let dt = t1 - self.time;
        for (inst, old) in next.iter_mut().zip(&self.instruments) {
            let (c, r) = (inst.position, inst.radius());
            inst.slider.begin_step();
            inst.relaxation.reset();
            match *inst.kind() {
                InstrumentKind::Probe
                | InstrumentKind::Capsule { .. }
                | InstrumentKind::Plane { .. }
                | InstrumentKind::Box { .. } => {
                    let Some(shape) = inst.shape() else { continue };
                    if self.exact_points(inst) {
                        // The fine surface's points near the instrument, each on its plane
                        // (`interact::fine_points`); the model solves which push.
                        inst.contacts.clear();
                        if let Some((fine, _)) = &self.fine {
                            let margin = CONTACT_MARGIN * shape.size()
                                + 2.0 * inst.position.distance(old.position);
                            let (rest, coarse) =
                                (self.model.rest_surface(), self.model.surface().positions);
                            inst.points = fine_points::gather(
                                fine,
                                rest,
                                coarse,
                                &shape,
                                inst.position,
                                margin,
                                !self.is_static,
                            );
                            // A dynamic model's step gives a plane's move as velocity: a
                            // point the step starts inside the instrument gets its plane
                            // through where it is, moved with the instrument, taking the
                            // depth back no faster than the instrument moves (as the face
                            // planes, `contact::owed_depth`). A static solve has no inertia
                            // and puts it on the instrument.
                            if !self.is_static {
                                for p in &mut inst.points {
                                    let q = fine.position(p.fine as usize, rest, coarse);
                                    let recover = recovery(old.position, inst.position, dt);
                                    let owed = owed_depth(&shape, old.position, q, recover);
                                    p.contact.target -= p.contact.normal * owed;
                                }
                            }
                        }
                        inst.reactions.clear();
                        continue;
                    }
                    let surface = Surface {
                        bvh: &self.bvh,
                        positions,
                        triangles,
                        rest: self.model.rest_surface(),
                        fine: self.fine.as_ref().map(|(m, _)| m),
                    };
                    // Near vertices (or a fine surface's near faces) are handed over free.
                    let push_only = self.pushes_only(inst).then(|| PushOnly {
                        margin: CONTACT_MARGIN * shape.size()
                            + 2.0 * inst.position.distance(old.position),
                        from: old.position,
                        recover: recovery(old.position, inst.position, dt),
                    });
                    let carry = self.carries_faces(inst, old, &shape);
                    inst.contacts =
                        keep_and_find(&surface, inst, old, &shape, taken, push_only, carry);
                }
                InstrumentKind::Grasper {
                    grasp_at,
                    release_at,
                } => {
                    if !inst.grasp_done && t1 >= grasp_at {
                        inst.grasp_done = true;
                        let inside =
                            vertices_in_ball(&self.bvh, positions, triangles, c, r, &|v| {
                                is_taken(taken, v)
                            });
                        inst.grasped = inside
                            .iter()
                            .map(|k| (k.vertex, positions[k.vertex as usize] - c))
                            .collect();
                    }
                    if release_at.is_some_and(|t| t1 >= t) {
                        inst.grasped.clear();
                    }
                    inst.contacts = inst
                        .grasped
                        .iter()
                        .filter(|(v, _)| !is_taken(taken, *v))
                        .map(|&(vertex, offset)| Contact::on_surface(vertex, c + offset))
                        .collect();
                    mark(taken, &inst.contacts);
                }
                InstrumentKind::Scalpel { .. } => inst.contacts.clear(),
            }
            inst.reactions = vec![Vec3::ZERO; inst.contacts.len()];
        }
    }

    /// Whether this instrument's contact with the fine surface is solved exactly on its
    /// points (`interact::fine_points`): a model that solves point contacts, static or with
    /// push-only contacts (the shared integrator's kinds: gathered once at the step's start,
    /// projected within it, `integrate::PointHold`), a frictionless pushing instrument. The
    /// others use the coarse vertices' planes.
    fn exact_points(&self, inst: &Instrument) -> bool {
        self.fine.is_some()
            && (self.is_static || self.model.contacts_push_only())
            && inst.friction() == Some(0.0)
            && inst.shape().is_some()
            && self.model.holds_point_contacts()
    }

    /// Whether the model holds this instrument's contacts as pushes only, settled within its
    /// step (`Deformable::contacts_push_only`, the dynamic kinds on the shared integrator):
    /// it held the last constraints' directions and the instrument is frictionless.
    fn pushes_only(&self, inst: &Instrument) -> bool {
        self.along && self.model.contacts_push_only() && inst.friction() == Some(0.0)
    }

    /// Whether a fine surface's face contacts that did not pull are carried into the next
    /// step, their targets moved with the instrument along their normals, rather than found
    /// again from where the faces are: where the contact is then settled by force (a static
    /// model's active set, which lets go of a face that pulls) and the instrument moved by
    /// less than its size. Found again, a face pressed by a retreating probe was let go at
    /// once, sprang back in one static solve past the probe's centre, and was then pushed out
    /// over its top (the liver pulled the retreating probe down, 0.085 N at the end).
    fn carries_faces(&self, inst: &Instrument, old: &Instrument, shape: &Shape) -> bool {
        self.fine.is_some()
            && (self.is_static || self.pushes_only(inst))
            && inst.position.distance(old.position) <= shape.size()
    }

    /// The vertices an instrument holds: its contacts, less those a push-only hold left
    /// free through the step (near the instrument, not touching it).
    fn held_count(&self, inst: &Instrument) -> usize {
        if !inst.points.is_empty() {
            inst.point_pushes.iter().filter(|&&l| l > 0.0).count()
        } else if self.pushes_only(inst) {
            inst.reactions.iter().filter(|f| **f != Vec3::ZERO).count()
        } else {
            inst.contacts.len()
        }
    }

    /// Fixed vertices plus every instrument's contacts, in instrument order.
    /// The constraints for the instruments' contacts, and the direction each is held along
    /// only: the instrument's normal for a frictionless contact on its surface (the model
    /// may hold it along that alone and let it slide across), none for the others.
    fn constraints_for(&self, next: &[Instrument]) -> (Constraints, Vec<Option<Vec3>>) {
        let mut normals = Vec::new();
        for inst in next {
            let shape = inst.shape().filter(|_| inst.friction() == Some(0.0));
            normals.extend(inst.contacts.iter().map(|k| match (&shape, k.face) {
                (Some(shape), None) => Some(k.normal(shape, inst.position)),
                // A face contact holds its vertex where it keeps the fine surface's points
                // on the instrument; frictionless, only along their normal, so the face
                // slides across (held in full, the coarse vertex dragged the fine surface
                // sideways: a tangential force 38 % of the push on the liver).
                (Some(_), Some(n)) => Some(n),
                _ => None,
            }));
        }
        let constraints = Constraints {
            fixed: self.fixed.clone(),
            prescribed: next
                .iter()
                .flat_map(|i| &i.contacts)
                .map(|k| Prescribed {
                    vertex: k.vertex,
                    position: k.target,
                })
                .collect(),
        };
        (constraints, normals)
    }

    /// Splits the prescribed reactions among the instruments and sums them.
    fn collect_forces(&self, next: &mut [Instrument]) {
        let all = self.model.reactions().prescribed;
        let mut at = 0;
        for inst in next.iter_mut() {
            let n = inst.contacts.len();
            inst.reactions = (at..at + n)
                .map(|j| all.get(j).copied().unwrap_or(Vec3::ZERO))
                .collect();
            inst.force = inst.reactions.iter().copied().sum();
            at += n;
        }
        let pushes = self.model.point_reactions();
        let mut at = 0;
        for inst in next.iter_mut() {
            let n = inst.points.len();
            inst.point_pushes = (at..at + n)
                .map(|j| pushes.get(j).copied().unwrap_or(0.0))
                .collect();
            // The tissue pushes the instrument back along −n at every point it rests on.
            for (p, &l) in inst.points.iter().zip(&inst.point_pushes) {
                inst.force -= l * p.contact.normal;
            }
            at += n;
        }
    }

    /// One relaxation of every pushing instrument's sliding contacts (`interact::sliding`);
    /// the worst residual, relative to its instrument's push.
    fn relax_sliding(&self, next: &mut [Instrument]) -> SlideResidual {
        let rest = self.model.rest_surface();
        let mut worst = SlideResidual::default();
        let mut start = 0;
        for inst in next.iter_mut() {
            let count = inst.contacts.len();
            let range = start..start + count;
            start += count;
            let Some(shape) = inst.shape() else { continue };
            // Sticking instruments (the default) hold their contacts where they touched.
            let Some(friction) = inst.friction() else {
                continue;
            };
            if friction == 0.0 && self.along {
                // Held along their normals only: the model let them slide and their
                // reactions have no tangential part. Each target goes to where its vertex
                // slid to, on the instrument (the tangent plane it was held on leaves the
                // surface of a curved one), and the loop solves again while they move.
                let positions = self.model.contact_surface().positions;
                let mut r = SlideResidual::default();
                for (k, f) in inst.contacts.iter_mut().zip(&inst.reactions) {
                    let normal = k.normal(&shape, inst.position);
                    r.push += (-f.dot(normal)).max(0.0);
                    if k.face.is_some() {
                        continue;
                    }
                    let Some(&p) = positions.get(k.vertex as usize) else {
                        continue;
                    };
                    let target = shape.closest(inst.position, p, normal).point;
                    r.moved = r.moved.max(target.distance(k.target) / shape.size());
                    k.target = target;
                }
                worst.merge(r);
                continue;
            }
            let model = &self.model;
            let at = inst.position;
            let r = inst.slider.relax(
                &mut inst.contacts,
                &inst.reactions,
                &shape,
                at,
                friction,
                rest,
                || model.prescribed_stiffness(range),
            );
            worst.merge(r);
        }
        worst
    }

    /// The fine points' planes moved to where the last solve left the points, and the points
    /// that came near added (`interact::fine_points`). Returns whether the solve must be
    /// taken again: a plane moved by more than `POINT_MOVE` of the instrument's size, or a
    /// point the model did not hold now penetrates.
    fn update_points(&self, next: &mut [Instrument]) -> bool {
        let Some((fine, _)) = &self.fine else {
            return false;
        };
        if !next.iter().any(|i| self.exact_points(i)) {
            return false;
        }
        let (rest, coarse) = (self.model.rest_surface(), self.model.surface().positions);
        let position = |v: u32| fine.position(v as usize, rest, coarse);
        let mut changed = false;
        for inst in next.iter_mut() {
            let Some(shape) = inst.shape() else { continue };
            if !self.exact_points(inst) {
                continue;
            }
            let margin = CONTACT_MARGIN * shape.size();
            let mut new =
                fine_points::gather(fine, rest, coarse, &shape, inst.position, margin, false);
            let (moved, entered) = fine_points::change(&inst.points, &new, &position);
            if entered || moved > POINT_MOVE * shape.size() {
                changed = true;
                if entered || !self.accelerate_planes {
                    inst.relaxation.reset();
                } else {
                    inst.relaxation
                        .relax(&inst.points, &mut new, &shape, inst.position);
                }
                inst.points = new;
                inst.point_pushes = vec![0.0; inst.points.len()];
            }
        }
        changed
    }

    /// One round of the static active set: release adhesive probe contacts, add vertices
    /// that now penetrate a probe. Returns whether anything changed.
    ///
    /// Held vertices stick to their point of the sphere, so the vertices at the rim of the
    /// patch can pull while held and, released all at once, spring back inside the ball:
    /// the loop then cycles between the two sets until its cap (`bem`'s default contact
    /// rule did so on most steps of a press). A vertex taken back after a release in this
    /// step is kept for the rest of the step (`Returned`): the loop ends, and in the presses
    /// measured it ended with every contact pushing (a returned vertex may keep a pull).
    fn update_active_set(
        &self,
        next: &mut [Instrument],
        taken: &mut [bool],
        returned: &mut Returned,
    ) -> bool {
        let mut changed = self.update_points(next);
        let s = self.model.contact_surface();
        for inst in next.iter_mut() {
            let Some(shape) = inst.shape() else { continue };
            if self.exact_points(inst) {
                continue;
            }
            let c = inst.position;
            let scale = force_scale(&inst.reactions);
            let before = inst.contacts.len();
            let mut kept = Vec::with_capacity(before);
            for (k, f) in inst.contacts.iter().zip(&inst.reactions) {
                if pulls(*f, k.normal(&shape, c), scale) && !returned.is_back(k.vertex) {
                    returned.release(k.vertex);
                    if let Some(t) = taken.get_mut(k.vertex as usize) {
                        *t = false;
                    }
                } else {
                    kept.push(*k);
                }
            }
            let surface = Surface {
                bvh: &self.bvh,
                positions: s.positions,
                triangles: s.triangles,
                rest: self.model.rest_surface(),
                fine: self.fine.as_ref().map(|(m, _)| m),
            };
            // Faces held at the last solve rest on the instrument while they do not pull.
            let resting: Vec<u32> = kept
                .iter()
                .filter(|k| k.face.is_some())
                .map(|k| k.vertex)
                .collect();
            let held: Vec<u32> = kept.iter().map(|k| k.vertex).collect();
            let released = kept.len() != before;
            let moved = surface.find(&shape, c, &mut kept, taken, &resting, None);
            for k in &kept {
                if held.binary_search(&k.vertex).is_err() {
                    returned.take(k.vertex);
                }
            }
            let same = !released && kept.len() == before;
            let moved = moved > FACE_MOVE * shape.size();
            changed |= !same || moved;
            if !same {
                // The reactions belong to the solved set: kept when the set stays.
                inst.contacts = kept;
                inst.reactions = vec![Vec3::ZERO; inst.contacts.len()];
            } else if moved {
                inst.contacts = kept;
            }
        }
        changed
    }
}

/// A pushing instrument's contacts at the start of a step: the previous ones that still touch
/// and did not pull, moved with the instrument (sticking, μ > 0) or projected onto it
/// (frictionless), then the vertices newly inside it.
///
/// With `push_only` (contacts held as pushes only) the previous contacts and the vertices
/// outside the instrument by less than its margin are kept or added too, targets at the
/// instrument's nearest point.
fn keep_and_find(
    surface: &Surface,
    inst: &Instrument,
    old: &Instrument,
    shape: &Shape,
    taken: &mut [bool],
    push_only: Option<PushOnly>,
    carry_faces: bool,
) -> Vec<Contact> {
    let margin = push_only.map(|o| o.margin);
    let positions = surface.positions;
    let c = inst.position;
    if let (None, Shape::Sphere { radius: r }, None) = (inst.friction(), shape, surface.fine) {
        // A sticking probe keeps the contact rule it had before sliding contact existed,
        // to the last rounding (explicit kinds' scenes are sensitive to it over thousands
        // of steps): the previous contacts still on the sphere that did not pull, their
        // vertices projected radially onto it. "On the sphere" allows for the probe's own
        // motion since the last step: a vertex held on the old sphere above its equator is
        // outside the new one by up to that much when the probe moves on, and dropping it
        // while it pushed let it spring into the probe and be taken again, every other step
        // (a 4 mm probe descending 8 µm a step on the brain scene at dt = 1 ms: the force
        // halved and doubled each step, and the warp factor was refactorised at each change).
        // Only a step's motion, not a jump (the viewer parks its probe far away and brings it
        // back): a contact carried across a jump dragged its vertex along, 1.8 m.
        let moved = c.distance(old.position).min(CONTACT_MARGIN * r);
        let scale = force_scale(&old.reactions);
        let mut contacts: Vec<Contact> = old
            .contacts
            .iter()
            .zip(&old.reactions)
            .filter(|(k, f)| {
                !is_taken(taken, k.vertex) && !is_adhesive(**f, k.target, old.position, scale)
            })
            .filter_map(|(k, _)| {
                let p = *positions.get(k.vertex as usize)?;
                (p.distance(c) <= r * (1.0 + PENETRATION_TOLERANCE) + moved).then(|| {
                    Contact::on_surface(
                        k.vertex,
                        project_to_sphere(p, c, *r, k.target - old.position),
                    )
                })
            })
            .collect();
        mark(taken, &contacts);
        surface.find(shape, c, &mut contacts, taken, &[], None);
        return contacts;
    }
    let slack = PENETRATION_TOLERANCE * shape.size();
    let shift = c - old.position;
    // Keep the previous contacts still on the shape that did not stick, so a resting probe
    // does not let go and grab again every step.
    let scale = force_scale(&old.reactions);
    let mut contacts: Vec<Contact> = old
        .contacts
        .iter()
        .zip(&old.reactions)
        .filter(|(k, f)| {
            !is_taken(taken, k.vertex) && !pulls(**f, k.normal(shape, old.position), scale)
        })
        .filter(|(k, _)| k.face.is_none() && surface.fine.is_none())
        .filter_map(|(k, _)| {
            let p = *positions.get(k.vertex as usize)?;
            let fallback = k.target - old.position;
            // A sliding contact with friction may stick: it is carried along and let go by
            // its force (when it pulls), not by where its vertex is: the instrument's motion
            // just moved its trailing side away from the vertices it drags.
            let frictional = inst.friction().is_some_and(|mu| mu > 0.0);
            let touching = shape.closest(c, p, fallback).depth <= margin.unwrap_or(slack);
            (touching || frictional).then(|| {
                let base = match inst.friction() {
                    // Sticking contact: the vertex, where it is, onto the
                    // instrument (the contact rule from before sliding contact existed).
                    None => p,
                    // Frictional: the target, where the last solve (or sliding) left it,
                    // carried along with the instrument.
                    Some(_) if frictional => k.target + shift,
                    // Frictionless: where sliding left it.
                    Some(_) => k.target,
                };
                Contact::on_surface(k.vertex, shape.closest(c, base, fallback).point)
            })
        })
        .collect();
    // Face contacts that did not pull are carried along with the instrument where the caller
    // settles them by force (`Simulation::carries_faces`); else found again from the faces,
    // where they are now, those that did not pull keeping their faces held while they rest
    // on the instrument.
    if carry_faces {
        let carried: Vec<Contact> = old
            .contacts
            .iter()
            .zip(&old.reactions)
            .filter(|(k, f)| {
                !is_taken(taken, k.vertex) && !pulls(**f, k.normal(shape, old.position), scale)
            })
            // Where contacts only push, those that held nothing (planes the vertex never
            // reached) are not carried on into the tissue: the margin hands them over again
            // from where their faces are.
            .filter(|(_, f)| margin.is_none() || **f != Vec3::ZERO)
            .filter_map(|(k, _)| {
                let n = k.face?;
                Some(Contact {
                    vertex: k.vertex,
                    target: k.target + n * n.dot(shift),
                    face: Some(n),
                })
            })
            .collect();
        contacts.extend(carried);
        contacts.sort_unstable_by_key(|k| k.vertex);
        // A static model's active set lets go of a face that then pulls; for a model whose
        // contacts only push, a plane carried on past its fine points is drawn back.
        if let (Some(fine), Some(_)) = (surface.fine, margin) {
            settle_carried_faces(fine, surface.rest, positions, shape, c, &mut contacts);
        }
        mark(taken, &contacts);
    }
    let mut resting: Vec<u32> = old
        .contacts
        .iter()
        .zip(&old.reactions)
        .filter(|(k, f)| k.face.is_some() && !pulls(**f, k.normal(shape, old.position), scale))
        .map(|(k, _)| k.vertex)
        .collect();
    resting.sort_unstable();
    mark(taken, &contacts);
    surface.find(shape, c, &mut contacts, taken, &resting, push_only);
    if let (Some(margin), None) = (margin, surface.fine) {
        let near = vertices_near_shape(
            surface.bvh,
            positions,
            surface.triangles,
            shape,
            c,
            margin,
            &|v| is_taken(taken, v),
        );
        mark(taken, &near);
        contacts.extend(near);
        contacts.sort_unstable_by_key(|k| k.vertex);
    }
    contacts
}

/// The surface contacts are found on: the model's (its BVH, positions, triangles, rest
/// positions) and the fine surface mapped onto it, if any.
struct Surface<'a> {
    bvh: &'a Bvh,
    positions: &'a [Vec3],
    triangles: &'a [[u32; 3]],
    rest: &'a [Vec3],
    fine: Option<&'a MappedSurface>,
}

impl Surface<'_> {
    /// Adds to `contacts` (this instrument's) what newly touches `shape` at `at`: the fine
    /// surface's vertices when there is one, else the model's vertices. `resting`: sorted
    /// face-contact vertices of the last solve that did not pull; `push_only`: on a fine
    /// surface, for a model whose contacts only push, how far outside the instrument its
    /// faces are handed over free and where the instrument started the step
    /// (`contact::hold_points`). Returns the largest move of a face target, in m.
    fn find(
        &self,
        shape: &Shape,
        at: Vec3,
        contacts: &mut Vec<Contact>,
        taken: &mut [bool],
        resting: &[u32],
        push_only: Option<PushOnly>,
    ) -> Real {
        let kept = |v: u32| resting.binary_search(&v).is_ok();
        let moved = if let Some(fine) = self.fine {
            hold_points(
                fine,
                self.rest,
                self.positions,
                shape,
                at,
                contacts,
                &|v| is_taken(taken, v),
                &kept,
                push_only,
            )
        } else {
            let fresh =
                vertices_in_shape(self.bvh, self.positions, self.triangles, shape, at, &|v| {
                    is_taken(taken, v)
                });
            mark(taken, &fresh);
            contacts.extend(fresh);
            contacts.sort_unstable_by_key(|k| k.vertex);
            0.0
        };
        mark(taken, contacts);
        moved
    }
}

/// A face hold that moves its targets by less than this fraction of the instrument's size
/// does not keep the static contact loop going (the sliding relaxation moves face targets a
/// little each round; the face hold puts them back).
const FACE_MOVE: Real = 1e-6;

/// A fine point's plane that moves by less than this fraction of the instrument's size does
/// not keep the static contact loop going. Moving each plane to where its point now is
/// nearest a curved instrument converges linearly: a point that slid turns its plane, and
/// the turned push moves it again (the instrument's curvature against the tissue's
/// tangential stiffness; each round 0.2 to 0.45 times the last on the liver pressed by a
/// 5 mm probe). At 1e-4 of the probe (0.5 µm) the three step sizes of the liver test agree
/// to 1e-5 of the force, in 2.3 to 4.3 solves per step.
const POINT_MOVE: Real = 1e-4;

/// Per surface vertex, within one step's contact loop: released as adhesive, and taken
/// again after that (then held to the end of the step).
#[derive(Default)]
struct Returned {
    state: Vec<u8>,
}

impl Returned {
    const RELEASED: u8 = 1;
    const BACK: u8 = 2;

    /// Nothing released, for `vertices` surface vertices.
    fn reset(&mut self, vertices: usize) {
        self.state.clear();
        self.state.resize(vertices, 0);
    }

    fn release(&mut self, v: u32) {
        if let Some(s) = self.state.get_mut(v as usize) {
            *s = Self::RELEASED;
        }
    }

    fn take(&mut self, v: u32) {
        if let Some(s) = self
            .state
            .get_mut(v as usize)
            .filter(|s| **s == Self::RELEASED)
        {
            *s = Self::BACK;
        }
    }

    fn is_back(&self, v: u32) -> bool {
        self.state.get(v as usize) == Some(&Self::BACK)
    }
}

fn is_taken(taken: &[bool], v: u32) -> bool {
    taken.get(v as usize).copied().unwrap_or(true)
}

fn mark(taken: &mut [bool], contacts: &[Contact]) {
    for k in contacts {
        if let Some(t) = taken.get_mut(k.vertex as usize) {
            *t = true;
        }
    }
}

/// The largest contact force magnitude: the scale below which a pull is rounding.
fn force_scale(reactions: &[Vec3]) -> Real {
    reactions.iter().map(|f| f.length()).fold(0.0, Real::max)
}
