//! `Bem`: the boundary element model's data and construction.
//!
//! Built in two stages: H and G are assembled when the model is built (the surface alone
//! decides them); A₀ is factorised and W = A₀⁻¹ G computed when the fixed set is first known
//! (in `set_constraints`) and again only when it changes. Contacts (prescribed vertices)
//! change the system through the Woodbury capacitance only.

use std::time::Instant;

use serde::Deserialize;

use crate::error::{Error, MeshError, SimError};
use crate::interact::PointContact;
use crate::material::Material;
use crate::math::{Real, Vec3, is_finite_vec};
use crate::mesh::SurfaceMesh;
use crate::model::ConstraintReactions;
use crate::model::registry::parse_params;
use crate::model::{BuildInput, Progress};
use crate::solve::{HeldRows, PointRows};

use super::assembly::{Geometry, Influence, assemble};
use super::body_force::GravityResponse;
use super::contact_rims::DEFAULT_RIM_CACHE_BYTES;
use super::incision_worker::IncisionWorker;
use super::system::BemSystem;
use super::viscous::SurfaceGraph;

/// The `[model]` settings of `bem`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BemParams {
    /// Quasi-viscosity α of eq. 13, in s/m (0: static, the target is reached at once).
    pub alpha: Real,
    /// Contacts' tractions discontinuous at the contact rim, as the fixed vertices' are (on
    /// by default): a contact's traction acts on its fully constrained triangles only, as
    /// quadratic FEM's does (block indentation at 1026 surface vertices: force gap 10.3% →
    /// 4.4%). A static update costs O(n·contacts) either way; a contact change solves A₀
    /// for the contact-rim triangles not seen before (3 columns each, cached up to
    /// `DEFAULT_RIM_CACHE_BYTES`), so a probe moving onto new triangles pays O(n²) per new
    /// triangle once (see `background_rim_solves`). Off: the hat functions' continuous
    /// tractions, whose load reaches half a ring past the contact (stiffer by O(h)), with
    /// no rim solves at all.
    pub discontinuous_contacts: bool,
    /// With `discontinuous_contacts`: solve the rim triangles a contact change reaches on a
    /// worker thread instead of before the step goes on. Until they land (about 6 ms per
    /// triangle corner on a 2194-vertex surface), the contact set keeps the continuous
    /// rule; a later step switches it over. Unset, it follows the driver
    /// (`Deformable::set_real_time`): on in the viewer and the haptic loop, off in `tissue
    /// run`, where a step's result must not depend on timing.
    pub background_rim_solves: Option<bool>,
    /// The byte budget of the rim cache, in MiB (default 256, `DEFAULT_RIM_CACHE_BYTES`).
    /// In real time the worker keeps half of it solved around the probe; all the pairs of a
    /// 2194-vertex surface take about 2000 MiB.
    pub rim_cache_mib: Option<Real>,
    /// Deprecated and ignored (scenes that set it still load): models built from a scene
    /// report their assembly and factorisation through `Deformable::set_progress`.
    pub progress: bool,
}

impl Default for BemParams {
    fn default() -> Self {
        Self {
            alpha: 0.0,
            discontinuous_contacts: true,
            background_rim_solves: None,
            rim_cache_mib: None,
            progress: false,
        }
    }
}

impl BemParams {
    /// The default settings with the contacts' tractions continuous across their rim (the
    /// hat functions': no rim solves, O(h) stiffer).
    pub fn continuous() -> Self {
        Self {
            discontinuous_contacts: false,
            ..Self::default()
        }
    }
}

/// Linear elastostatics by collocation BEM on the surface mesh.
pub struct Bem {
    pub(super) params: BemParams,
    pub(super) material: Material,
    pub(super) surface: SurfaceMesh,
    pub(super) positions: Vec<Vec3>,
    /// The static solution (eq. 13's target).
    pub(super) target: Vec<Vec3>,
    /// Tributary area of each vertex (a third of each adjacent triangle), in m².
    pub(super) areas: Vec<Real>,
    pub(super) graph: SurfaceGraph,
    pub(super) distance: Vec<Real>,
    pub(super) system: BemSystem,
    /// The constraints of the last `set_constraints` and the reaction of each entry.
    pub(super) reactions: ConstraintReactions,
    /// Contact vertices (prescribed, not fixed), ascending, and their displacements.
    pub(super) contact_targets: Vec<Vec3>,
    /// Per contact, the direction it is held along only (`set_constraints_along`), or zero
    /// for a contact held in all three directions.
    pub(super) contact_normals: Vec<Vec3>,
    /// The held directions' block of a solve with contacts held along their normals.
    pub(super) held: HeldRows,
    /// Fine-surface points pushed by instruments (`Deformable::set_point_contacts`), their
    /// pushes after the last step (N), the rows of their problem (`solve::points`), each
    /// point's row (`None`: all its vertices fixed), and their pushes as known tractions
    /// per dof (`points`).
    pub(super) points: Vec<PointContact>,
    pub(super) point_lambda: Vec<Real>,
    pub(super) point_rows: PointRows,
    pub(super) point_row: Vec<Option<usize>>,
    pub(super) point_traction: Vec<Real>,
    pub(super) point_forces: Vec<Vec3>,
    /// Known tractions per dof (point loads over tributary areas), in Pa.
    pub(super) load_traction: Vec<Real>,
    pub(super) u_load: Vec<Real>,
    pub(super) x: Vec<Real>,
    pub(super) p_contact: Vec<Real>,
    /// Traction per vertex after the last step, in Pa.
    pub(super) traction: Vec<Vec3>,
    pub(super) assembly_seconds: Real,
    /// Where the assembly and factorisation report (`Deformable::set_progress`).
    pub(super) progress: Progress,
    /// H and G not assembled yet (`from_input` defers the assembly to the first
    /// `set_constraints`, so that it reports to the handle set after construction).
    pub(super) pending_assembly: bool,
    /// Incisions made (`CutInfo::topology_version`).
    pub(super) cuts: u32,
    /// Gravity (m/s²) and its particular solution and response (`body_force`).
    pub(super) gravity: Vec3,
    pub(super) body: Option<GravityResponse>,
    /// The contacts' targets for the homogeneous problem (u* − u_p), reused per step.
    pub(super) homogeneous_targets: Vec<Vec3>,
    /// A scalpel sweep too short to open a groove yet: its first and last blade positions.
    pub(super) pending_cut: Option<([Vec3; 2], [Vec3; 2])>,
    /// Masks `set_constraints` reuses, so that moving targets allocate nothing.
    pub(super) scratch: ConstraintScratch,
    /// Stepped against a wall clock (`Deformable::set_real_time`): incisions are computed
    /// in the background (`incisions`).
    pub(super) real_time: bool,
    pub(super) incisions: IncisionWorker,
}

/// The constraints of the last `set_constraints` call, per vertex (see
/// `Bem::stage_constraints`).
#[derive(Debug, Default)]
pub(super) struct ConstraintScratch {
    pub fixed: Vec<bool>,
    /// Held displacement of each non-fixed vertex with a prescribed target.
    pub held: Vec<Option<Vec3>>,
    /// The direction each held vertex is held along only (zero: all three directions).
    pub along: Vec<Vec3>,
    /// The vertices with `held`, ascending.
    pub contacts: Vec<usize>,
}

impl std::fmt::Debug for Bem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bem")
            .field("vertices", &self.surface.vertices.len())
            .field("triangles", &self.surface.triangles.len())
            .finish()
    }
}

impl Bem {
    /// Builds from the registry's input: the mesh's triangles, or the boundary of its
    /// tetrahedra when it has a volume.
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let params: BemParams = parse_params("bem", input.params)?;
        let surface = input.mesh.surface_mesh()?;
        Self::build(&surface, input.material, params, None)
    }

    pub fn new(
        surface: &SurfaceMesh,
        material: Material,
        params: BemParams,
    ) -> Result<Self, Error> {
        Self::new_with_progress(surface, material, params, &|_| {})
    }

    /// Checks the surface (closed, manifold, outward, no degenerate triangle), drops unused
    /// vertices and assembles H and G; `progress` gets the fraction done.
    pub fn new_with_progress(
        surface: &SurfaceMesh,
        material: Material,
        params: BemParams,
        progress: &(dyn Fn(f64) + Sync),
    ) -> Result<Self, Error> {
        Self::build(surface, material, params, Some(progress))
    }

    /// Checks and builds; assembles now with `progress`, or (`None`) defers the assembly to
    /// `assemble_pending`.
    fn build(
        surface: &SurfaceMesh,
        material: Material,
        params: BemParams,
        progress: Option<&(dyn Fn(f64) + Sync)>,
    ) -> Result<Self, Error> {
        let material = material.validated()?;
        if !(params.alpha.is_finite() && params.alpha >= 0.0) {
            return Err(SimError::BadParameter {
                name: "alpha",
                value: params.alpha.to_string(),
                reason: "the quasi-viscosity must be finite and not negative".into(),
            }
            .into());
        }
        let rim_cache_bytes = match params.rim_cache_mib {
            None => DEFAULT_RIM_CACHE_BYTES,
            Some(mib) if mib.is_finite() && (0.0..=(1u64 << 30) as Real).contains(&mib) => {
                (mib * (1u64 << 20) as Real) as usize
            }
            Some(mib) => {
                return Err(SimError::BadParameter {
                    name: "rim_cache_mib",
                    value: mib.to_string(),
                    reason: "the rim cache's budget must be a finite size in MiB, not negative"
                        .into(),
                }
                .into());
            }
        };
        let surface = checked_surface(surface)?;
        let geometry = Geometry::new(&surface, &material)?;
        let kelvin = geometry.kelvin;
        let n = surface.vertices.len();
        let (inf, assembly_seconds) = match progress {
            Some(report) => {
                let start = Instant::now();
                let inf = assemble(&geometry.vertices, &geometry.elements, &kelvin, report);
                (inf, start.elapsed().as_secs_f64())
            }
            // Zero-filled pages are only touched by the assembly.
            None => (
                Influence {
                    vertices: n,
                    h: vec![0.0; 9 * n * n],
                    g: vec![0.0; 9 * n * n],
                },
                0.0,
            ),
        };
        let mut model = Self::from_parts(surface, material, params, inf, assembly_seconds);
        model.pending_assembly = progress.is_none();
        model.system.set_geometry(Some(geometry));
        model.system.set_contact_rims(params.discontinuous_contacts);
        model
            .system
            .set_rim_background(params.background_rim_solves.unwrap_or(false));
        model.system.set_rim_cache_budget(rim_cache_bytes);
        Ok(model)
    }

    /// Assembles H and G if `from_input` deferred it, reporting to the progress handle.
    pub(super) fn assemble_pending(&mut self) {
        if !self.pending_assembly {
            return;
        }
        let Some(geo) = self.system.geometry() else {
            return;
        };
        let start = Instant::now();
        let progress = self.progress.clone();
        let report = move |f: f64| progress.report("bem: assembling H and G", f);
        let inf = assemble(&geo.vertices, &geo.elements, &geo.kelvin, &report);
        self.system.set_influence(inf);
        self.assembly_seconds = start.elapsed().as_secs_f64();
        self.pending_assembly = false;
    }

    pub(super) fn from_parts(
        surface: SurfaceMesh,
        material: Material,
        params: BemParams,
        inf: Influence,
        assembly_seconds: Real,
    ) -> Self {
        let n = surface.vertices.len();
        let mut areas = vec![0.0; n];
        for t in 0..surface.triangles.len() {
            let [a, b, c] = surface.corners(t);
            let third = 0.5 * (b - a).cross(c - a).length() / 3.0;
            for v in surface.triangles[t] {
                areas[v as usize] += third;
            }
        }
        Self {
            params,
            material,
            positions: surface.vertices.clone(),
            target: surface.vertices.clone(),
            graph: SurfaceGraph::new(&surface.vertices, &surface.triangles),
            distance: vec![0.0; n],
            areas,
            system: BemSystem::new(inf),
            reactions: ConstraintReactions::default(),
            contact_targets: Vec::new(),
            contact_normals: Vec::new(),
            held: HeldRows::default(),
            points: Vec::new(),
            point_lambda: Vec::new(),
            point_rows: PointRows::default(),
            point_row: Vec::new(),
            point_traction: vec![0.0; 3 * n],
            point_forces: vec![Vec3::ZERO; n],
            load_traction: vec![0.0; 3 * n],
            u_load: vec![0.0; 3 * n],
            x: vec![0.0; 3 * n],
            p_contact: Vec::new(),
            traction: vec![Vec3::ZERO; n],
            assembly_seconds,
            progress: Progress::silent(),
            pending_assembly: false,
            cuts: 0,
            gravity: Vec3::ZERO,
            body: None,
            homogeneous_targets: Vec::new(),
            pending_cut: None,
            scratch: ConstraintScratch::default(),
            real_time: false,
            incisions: IncisionWorker::default(),
            surface,
        }
    }

    /// Switches `discontinuous_contacts` on a built model (no re-factorisation: the contact
    /// set is re-applied with the new rule).
    pub fn set_discontinuous_contacts(&mut self, on: bool) -> Result<(), SimError> {
        self.params.discontinuous_contacts = on;
        let contacts = self.system.contacts().to_vec();
        self.system.set_contact_rims(on);
        if self.system.is_factored() {
            self.system.set_contacts(&contacts)?;
        }
        Ok(())
    }

    /// Switches `background_rim_solves` on a built model (the current contacts stay as they
    /// are until their next change or `finish_contact_rims`).
    pub fn set_background_rim_solves(&mut self, on: bool) {
        self.params.background_rim_solves = Some(on);
        self.system.set_rim_background(on);
    }

    /// Threads for background rim solves (default and most: one per core; at least one;
    /// each runs only in the time the simulation leaves idle).
    pub fn set_rim_solve_threads(&mut self, threads: usize) {
        self.system.set_rim_threads(threads);
    }

    /// Waits for the background rim solves the current contacts need and switches them to
    /// the discontinuous rule; the next step gives what the blocking rule gives.
    pub fn finish_contact_rims(&mut self) -> Result<(), SimError> {
        self.system.finish_rim_solves()
    }

    /// Solves ahead for the contact-rim triangles of `vertices` (see
    /// `BemSystem::warm_rim_cache`); returns the (triangle, corner) pairs solved.
    pub fn warm_contact_rims(&mut self, vertices: &[usize]) -> usize {
        self.system.warm_rim_cache(vertices)
    }

    /// `warm_contact_rims` for the vertices within `rings` edges of the current contacts:
    /// where a moving probe goes next. Meant for idle time between contact changes.
    pub fn warm_contact_rims_near(&mut self, rings: usize) -> usize {
        let around = self.graph.within_rings(self.system.contacts(), rings);
        self.system.warm_rim_cache(&around)
    }

    /// The byte budget of the contact-rim cache (`BemSystem::set_rim_cache_budget`).
    pub fn set_rim_cache_budget(&mut self, bytes: usize) {
        self.system.set_rim_cache_budget(bytes);
    }

    pub fn params(&self) -> &BemParams {
        &self.params
    }
    pub fn material(&self) -> &Material {
        &self.material
    }
    /// H, G, W and the contact state.
    pub fn system(&self) -> &BemSystem {
        &self.system
    }
    /// Tributary area per surface vertex, in m².
    pub fn areas(&self) -> &[Real] {
        &self.areas
    }
    /// Traction per surface vertex after the last step (what the surroundings apply), in Pa.
    pub fn tractions(&self) -> &[Vec3] {
        &self.traction
    }
    /// Displacements of the static solution of the last step, in m.
    pub fn static_displacements(&self) -> Vec<Vec3> {
        self.target
            .iter()
            .zip(&self.surface.vertices)
            .map(|(t, r)| *t - *r)
            .collect()
    }
}

/// The surface without unused vertices, or the reason it cannot bound a body.
pub(super) fn checked_surface(s: &SurfaceMesh) -> Result<SurfaceMesh, MeshError> {
    s.validate_indices()?;
    if s.triangles.is_empty() {
        return Err(MeshError::Empty { what: "triangles" });
    }
    // Unused vertices would give zero columns; the others keep their order, so a surface
    // without unused vertices keeps its numbering.
    let mut map = vec![u32::MAX; s.vertices.len()];
    for (t, tri) in s.triangles.iter().enumerate() {
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            return Err(MeshError::RepeatedVertex {
                element_kind: "triangle",
                element: t,
                vertex: tri[1] as usize,
            });
        }
        for &v in tri {
            map[v as usize] = 0;
        }
    }
    let mut vertices = Vec::new();
    for (v, slot) in map.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = vertices.len() as u32;
            vertices.push(s.vertices[v]);
        }
    }
    let triangles: Vec<[u32; 3]> = s
        .triangles
        .iter()
        .map(|t| t.map(|v| map[v as usize]))
        .collect();
    if let Some((v, p)) = vertices
        .iter()
        .enumerate()
        .find(|(_, p)| !is_finite_vec(**p))
    {
        return Err(MeshError::NonFiniteVertex {
            vertex: v,
            x: p.x,
            y: p.y,
            z: p.z,
        });
    }
    let mut edges = std::collections::HashMap::new();
    for tri in &triangles {
        for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
            *edges.entry((a.min(b), a.max(b))).or_insert(0usize) += 1;
        }
    }
    let unmap = |v: u32| map.iter().position(|&m| m == v).unwrap_or(v as usize);
    let border: Vec<_> = edges.iter().filter(|&(_, &c)| c == 1).collect();
    if let Some(&(&(a, b), _)) = border.first() {
        return Err(MeshError::NotClosed {
            border_edges: border.len(),
            a: unmap(a),
            b: unmap(b),
        });
    }
    if let Some((&(a, b), &faces)) = edges.iter().find(|&(_, &c)| c > 2) {
        return Err(MeshError::NonManifoldEdge {
            a: unmap(a),
            b: unmap(b),
            faces,
        });
    }
    let out = SurfaceMesh::new(vertices, triangles);
    let volume = out.signed_volume();
    if volume.is_nan() || volume <= 0.0 {
        return Err(MeshError::Invalid(format!(
            "the surface encloses a signed volume of {volume:.3e} m³: the BEM needs a closed \
             surface with outward normals"
        )));
    }
    Ok(out)
}
