//! The one interface every model implements.

use crate::error::SimError;
use crate::interact::{Constraints, Loads, PointContact};
use crate::math::{Mat3, Real, Vec3, is_finite_vec, segment_triangle};

use super::Progress;

/// The surface as it is now: what to draw and what instruments touch.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceView<'a> {
    pub positions: &'a [Vec3],
    pub triangles: &'a [[u32; 3]],
}

/// The surface as a contact search near the reach last set (`Deformable::set_contact_reach`)
/// needs it: `positions[v]` is where vertex `v` is now whenever `slack` is empty or
/// `slack[v] == 0`; otherwise the vertex is within `slack[v]` of `positions[v]`, and both are
/// outside every ball of the reach. Every vertex that can be inside the reach, every vertex of
/// a triangle that has one, and every vertex the model holds are exact.
#[derive(Clone, Copy, Debug)]
pub struct ContactSurface<'a> {
    pub positions: &'a [Vec3],
    pub triangles: &'a [[u32; 3]],
    /// Per vertex, how far it may be from `positions` (m); empty: every vertex exact.
    pub slack: &'a [Real],
}

/// The mechanical volume mesh as it is now, for models that have one (written to VTU).
#[derive(Clone, Copy, Debug)]
pub struct VolumeView<'a> {
    pub positions: &'a [Vec3],
    pub rest_positions: &'a [Vec3],
    pub tets: &'a [[u32; 4]],
}

/// Forces the tissue exerts on its constraints, in N, in the order the constraints were
/// given. For an instrument, the force it feels is the sum over its prescribed vertices;
/// for supports, the sum over fixed vertices balances the applied loads.
#[derive(Clone, Copy, Debug, Default)]
pub struct Reactions<'a> {
    pub fixed: &'a [Vec3],
    pub prescribed: &'a [Vec3],
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepInfo {
    /// Iterations of the inner solver (0 for a direct solve or an explicit step).
    pub iterations: usize,
    /// Final relative residual of an iterative solver (0 for a direct solve).
    pub residual: Real,
    /// True when an iterative solver stopped at its iteration cap before reaching its
    /// tolerance: the step is less accurate than the model's setting asks, and the caller
    /// (`tissue run`'s summary, the viewer) says so instead of passing it off as converged.
    pub capped: bool,
    /// Internal steps the model took to cover `dt` (explicit models split a step that is
    /// above their stability limit); 0 where the model does not step in time (static models)
    /// or does not report it, 1 for a single step.
    pub substeps: u32,
}

/// A description of a built model, for `tissue run` summaries and comparisons.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ModelInfo {
    /// The model kind, as in `tissue models`.
    pub kind: &'static str,
    /// Mechanical nodes (tetrahedron nodes, masses, control points, voxels).
    pub nodes: usize,
    /// Unknowns of the mechanical system.
    pub dofs: usize,
    /// Mechanical elements (tetrahedra, springs, links...).
    pub elements: usize,
    /// Vertices of the rendered surface.
    pub surface_vertices: usize,
    /// Memory held by the model's rest data and factorisations, in bytes (estimate).
    pub memory_bytes: usize,
    /// Time spent building the model (assembly, factorisation, pre-computation), in s.
    pub precompute_seconds: Real,
    /// True for models that solve for equilibrium in `step` (time plays no role).
    pub is_static: bool,
    /// Model-specific facts as (name, value) pairs, e.g. ("order", "quadratic").
    pub details: Vec<(String, String)>,
}

impl ModelInfo {
    /// Detail names whose values are notices: facts that change how a run must be read,
    /// which `tissue run` lists in `summary.json` and the viewer says once.
    pub const NOTICE_DETAILS: [&'static str; 1] = [
        // `hybrid`: its region came to cover the organ (it is whole-organ tensor-mass).
        "whole_organ",
    ];

    /// The details that are notices (`NOTICE_DETAILS`), in the order the model gives them.
    pub fn notices(&self) -> impl Iterator<Item = &str> {
        self.details
            .iter()
            .filter(|(k, _)| Self::NOTICE_DETAILS.contains(&k.as_str()))
            .map(|(_, v)| v.as_str())
    }
}

/// A scalpel sweep: the blade segment (tip, heel) at the start and at the end of the motion.
/// The cut surface is the ruled quad between them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutPath {
    pub start: [Vec3; 2],
    pub end: [Vec3; 2],
}

impl CutPath {
    /// The swept quad as two triangles.
    pub fn triangles(&self) -> [[Vec3; 3]; 2] {
        let [s0, s1] = self.start;
        let [e0, e1] = self.end;
        [[s0, s1, e1], [s0, e1, e0]]
    }

    /// The swept quad's bounding box, padded for `segment_triangle`'s 1e-12 tolerance.
    fn bounds(&self) -> (Vec3, Vec3) {
        let [s0, s1] = self.start;
        let [e0, e1] = self.end;
        let lo = s0.min(s1).min(e0.min(e1));
        let hi = s0.max(s1).max(e0.max(e1));
        let pad = Vec3::splat(1e-9 * (hi - lo).length());
        (lo - pad, hi + pad)
    }

    /// True if every blade position is finite.
    pub fn is_finite(&self) -> bool {
        self.start
            .iter()
            .chain(&self.end)
            .all(|p| is_finite_vec(*p))
    }

    /// The error a model's `cut` gives for a blade that is not finite.
    pub fn check(&self) -> Result<(), SimError> {
        if self.is_finite() {
            return Ok(());
        }
        Err(SimError::BadParameter {
            name: "cut",
            value: format!("{self:?}"),
            reason: "the blade positions are not finite".into(),
        })
    }

    /// Where the segment p→q crosses the swept quad, as a fraction of p→q.
    pub fn crossing(&self, p: Vec3, q: Vec3) -> Option<Real> {
        // Models test every link or vertex of a body against a blade that touches few of
        // them: a box test first.
        let (lo, hi) = self.bounds();
        if p.min(q).cmpgt(hi).any() || p.max(q).cmplt(lo).any() {
            return None;
        }
        self.triangles()
            .into_iter()
            .find_map(|t| segment_triangle(p, q, t))
    }
}

/// What a cut changed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CutInfo {
    pub removed_elements: usize,
    pub added_vertices: usize,
    /// Bumped on every topological change; anything built from the topology rebuilds.
    pub topology_version: u32,
}

/// A deformable model of soft tissue.
///
/// Constraints and loads refer to surface vertices (indices into `surface().positions`).
/// `step` either integrates over `dt` (dynamic models) or solves for equilibrium (static
/// models, which ignore `dt`). On failure the model keeps its last good state.
pub trait Deformable: Send {
    /// The kind name, as in `tissue models`.
    fn kind(&self) -> &'static str;

    /// The current surface.
    fn surface(&self) -> SurfaceView<'_>;

    /// Surface positions at rest, to compute displacements.
    fn rest_surface(&self) -> &[Vec3];

    /// The volume mesh, for models that have tetrahedra.
    fn volume(&self) -> Option<VolumeView<'_>> {
        None
    }

    /// Replaces all constraints. Fixed wins where a vertex is both fixed and prescribed.
    fn set_constraints(&mut self, constraints: &Constraints) -> Result<(), SimError>;

    /// `set_constraints`, with a direction per prescribed entry (`normals[k]`, a unit vector,
    /// or `None` and missing entries: held in all three directions). An entry with a
    /// direction n is held along n only: its vertex's displacement along n reaches its
    /// target's, it moves freely across n, and its reaction lies along n (a frictionless
    /// contact on the instrument's tangent plane). Returns whether the model did so; one
    /// that cannot (the default) holds every entry in all three directions and returns
    /// false, and the caller relaxes the targets itself (`interact::sliding`). See
    /// docs/contact.md for the kinds that do.
    fn set_constraints_along(
        &mut self,
        constraints: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        let _ = normals;
        self.set_constraints(constraints).map(|()| false)
    }

    /// `set_constraints_along` with every entry given a direction held along it both ways
    /// (its displacement along n equals its target's, it moves freely across n, its reaction
    /// may pull), also on a kind whose directional holds are contacts that only push
    /// (`contacts_push_only`): a frictionless plate bonded to the tissue along its normal,
    /// as `tissue compare`'s reference holds its plate. Returns whether the model did so; one
    /// that cannot holds every entry in full and returns false (the default for the
    /// push-only kinds; the others' `set_constraints_along` already holds both ways).
    fn set_constraints_two_sided(
        &mut self,
        constraints: &Constraints,
        normals: &[Option<Vec3>],
    ) -> Result<bool, SimError> {
        if self.contacts_push_only() {
            self.set_constraints(constraints).map(|()| false)
        } else {
            self.set_constraints_along(constraints, normals)
        }
    }

    /// Whether the model solves `set_point_contacts` (false by default).
    fn holds_point_contacts(&self) -> bool {
        false
    }

    /// Points tied to surface vertices (a fine contact surface's) that an instrument may push
    /// but not pull, frictionless, solved exactly with the model's own response: a
    /// complementarity problem in which each point either rests on its instrument's plane and
    /// is pushed, or is off it and free (`solve::lcp`). Held from the next step on, beside the
    /// constraints; `set_constraints` and `set_constraints_along` clear them. Returns false
    /// (the default, and then nothing is held) when the model cannot: the caller then uses the
    /// coarse vertices' planes (`interact::contact::hold_points`).
    fn set_point_contacts(&mut self, points: &[PointContact]) -> Result<bool, SimError> {
        Ok(points.is_empty())
    }

    /// The push λ ≥ 0 along its normal on each point of the last `set_point_contacts`, in N,
    /// after the last step (the instrument feels −λ n).
    fn point_reactions(&self) -> &[Real] {
        &[]
    }

    /// Whether the entries `set_constraints_along` holds along a direction are contacts that
    /// only push (`integrate::Hold::contact`: the dynamic kinds on the shared integrator):
    /// each (sub)step puts a vertex that went past its target's tangent plane back on it and
    /// leaves one that moves away free, so the active set is settled inside the step and
    /// the reaction never pulls. The caller then hands over the vertices near an instrument
    /// too (`sim::CONTACT_MARGIN`), free until they touch. False (the default): held both
    /// ways, and the caller releases pulling contacts itself.
    fn contacts_push_only(&self) -> bool {
        false
    }

    /// The kinetic energy of the model's masses, ½ Σ m v², in J; `None` (the default) for a
    /// model without velocities (static, or position-based). With `stop_motion`, what a
    /// caller needs for dynamic relaxation (`compare::drive`'s kinetic damping).
    fn kinetic_energy(&self) -> Option<Real> {
        None
    }

    /// Sets every velocity to zero and keeps the positions, constraints and loads: the next
    /// step starts from rest where the model is now. Dynamic relaxation's kinetic damping
    /// calls it at each peak of the kinetic energy; it adds no force, so an equilibrium is
    /// the same with or without it. Returns whether the model did (false, the default,
    /// where `kinetic_energy` is `None`).
    fn stop_motion(&mut self) -> bool {
        false
    }

    /// Replaces the external loads (gravity, point loads).
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError>;

    /// Advances the model by `dt` seconds (or solves for equilibrium).
    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError>;

    /// Forces at the constraints after the last step.
    fn reactions(&self) -> Reactions<'_>;

    /// Cuts along a scalpel sweep; models that cannot cut say so.
    fn cut(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        let _ = blade;
        Err(SimError::Unsupported {
            model: self.kind(),
            operation: "cutting",
            reason: "its topology is fixed when it is built".into(),
        })
    }

    /// The scalpel was taken away: a model that joins a stroke's sweeps and opens them when
    /// the blade leaves the tissue (`bem`) opens what it holds now, so a cut that ends with
    /// the blade inside is not lost. `Simulation` calls it at the start of the step after
    /// a scalpel was removed.
    fn end_cut(&mut self) -> Result<CutInfo, SimError> {
        Ok(CutInfo::default())
    }

    /// Swaps in work the model finished off the calling thread that changes its surface (in
    /// real time, `bem` computes an incision's system update on a worker while it goes on
    /// answering steps on the uncut surface). `Simulation` calls it at the start of every
    /// step, before its contact search; `Some` when the surface changed. An error is the
    /// background work's: the model keeps its last good state.
    fn finish_background(&mut self) -> Result<Option<CutInfo>, SimError> {
        Ok(None)
    }

    /// What the model is computing off the calling thread, for a status line (`None`: nothing).
    fn background(&self) -> Option<String> {
        None
    }

    /// Returns to the rest state, keeping constraints and loads.
    fn reset(&mut self);

    /// Where long pre-computations (done when built or when the fixed set changes) report
    /// their progress. Models without any ignore it.
    fn set_progress(&mut self, progress: Progress) {
        let _ = progress;
    }

    /// Whether the caller steps against a wall clock (the viewer, a haptic loop). A model
    /// may then answer a step from a cheaper approximation while it finishes expensive work
    /// off the calling thread, instead of making the step wait for it. Off (the default),
    /// a step's result never depends on timing. Models without such work ignore it.
    fn set_real_time(&mut self, on: bool) {
        let _ = on;
    }

    /// The stiffness the prescribed entries `entries` (indices into the `prescribed` list of
    /// the last `set_constraints`) show together, in N/m: dF/dt, where F is the sum of their
    /// reactions and t a translation of all their targets, everything else held (the other
    /// constraints, the contact set, the loads). An instrument's tangent stiffness, which a
    /// haptic loop needs between full updates. `None` for models that cannot give it in
    /// closed form; the loop then estimates it from successive updates.
    fn prescribed_stiffness(&self, entries: std::ops::Range<usize>) -> Option<Mat3> {
        let _ = entries;
        None
    }

    /// Where the next contact searches look: balls (centre, radius, m), or `None` for
    /// everywhere. Models whose surface costs to compute where nobody looks (`hybrid`: the
    /// pre-computed rest's dense G·u) then compute only what `contact_surface` must give
    /// exactly; the others ignore it.
    fn set_contact_reach(&mut self, _reach: Option<&[(Vec3, Real)]>) {}

    /// The surface for a contact search within the reach set by `set_contact_reach` (see
    /// `ContactSurface`). The default is `surface()`, every vertex exact.
    fn contact_surface(&self) -> ContactSurface<'_> {
        let s = self.surface();
        ContactSurface {
            positions: s.positions,
            triangles: s.triangles,
            slack: &[],
        }
    }

    /// A small integer label per surface vertex for models made of parts, for a viewer to
    /// colour them (each kind's doc says what its labels mean: `hybrid`: 0 the pre-computed
    /// rest, 1 the cut region's border, 2 the cuttable region). `None` for one-part models.
    fn vertex_labels(&self) -> Option<Vec<u8>> {
        None
    }

    fn info(&self) -> ModelInfo;
}
