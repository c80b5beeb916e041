//! `Bem`: the boundary element model behind the `Deformable` interface.
//!
//! Built in two stages: H and G are assembled when the model is built (the surface alone
//! decides them); A₀ is factorised and W = A₀⁻¹ G computed when the fixed set is first known
//! (in `set_constraints`) and again only when it changes. Contacts (prescribed vertices)
//! change the system through the Woodbury capacitance only.

use std::time::Instant;

use serde::Deserialize;

use crate::error::{Error, MeshError, SimError};
use crate::interact::{Constraints, Loads};
use crate::material::Material;
use crate::math::{Real, Vec3, is_finite_vec};
use crate::mesh::SurfaceMesh;
use crate::model::registry::parse_params;
use crate::model::{
    BuildInput, CutInfo, CutPath, Deformable, ModelInfo, Reactions, StepInfo, SurfaceView,
};

use super::assembly::{Element, Influence, assemble};
use super::kelvin::Kelvin;
use super::system::BemSystem;
use super::viscous::{SurfaceGraph, relax};

/// The `[model]` settings of `bem`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BemParams {
    /// Quasi-viscosity α of eq. 13, in s/m (0: static, the target is reached at once).
    #[serde(default)]
    pub alpha: Real,
    /// Prints the assembly's progress to stderr (useful for meshes of thousands of vertices).
    #[serde(default)]
    pub progress: bool,
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
    pub(super) constraints: Constraints,
    /// Contact vertices (prescribed, not fixed), ascending, and their displacements.
    pub(super) contact_targets: Vec<Vec3>,
    pub(super) point_forces: Vec<Vec3>,
    /// Known tractions per dof (point loads over tributary areas), in Pa.
    pub(super) load_traction: Vec<Real>,
    pub(super) u_load: Vec<Real>,
    pub(super) x: Vec<Real>,
    pub(super) p_contact: Vec<Real>,
    /// Traction per vertex after the last step, in Pa.
    pub(super) traction: Vec<Vec3>,
    pub(super) fixed_owner: Vec<bool>,
    pub(super) prescribed_owner: Vec<bool>,
    pub(super) fixed_reactions: Vec<Vec3>,
    pub(super) prescribed_reactions: Vec<Vec3>,
    pub(super) assembly_seconds: Real,
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
        if params.progress {
            let last = std::sync::atomic::AtomicUsize::new(0);
            let report = move |f: f64| {
                let pct = (f * 100.0) as usize;
                if pct / 10 > last.swap(pct / 10, std::sync::atomic::Ordering::Relaxed) {
                    eprintln!("bem: assembling H and G {pct}%");
                }
            };
            Self::new_with_progress(&surface, input.material, params, &report)
        } else {
            Self::new(&surface, input.material, params)
        }
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
        let material = material.validated()?;
        if !(params.alpha.is_finite() && params.alpha >= 0.0) {
            return Err(SimError::BadParameter {
                name: "alpha",
                value: params.alpha.to_string(),
                reason: "the quasi-viscosity must be finite and not negative".into(),
            }
            .into());
        }
        let surface = checked_surface(surface)?;
        let elements = surface
            .triangles
            .iter()
            .enumerate()
            .map(|(t, &tri)| {
                Element::new(&surface.vertices, tri).ok_or(MeshError::DegenerateTriangle {
                    triangle: t,
                    area: 0.0,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let start = Instant::now();
        let kelvin = Kelvin::new(material.mu(), material.poisson_ratio);
        let inf = assemble(&surface.vertices, &elements, &kelvin, progress);
        let assembly_seconds = start.elapsed().as_secs_f64();
        Ok(Self::from_parts(
            surface,
            material,
            params,
            inf,
            assembly_seconds,
        ))
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
            constraints: Constraints::default(),
            contact_targets: Vec::new(),
            point_forces: vec![Vec3::ZERO; n],
            load_traction: vec![0.0; 3 * n],
            u_load: vec![0.0; 3 * n],
            x: vec![0.0; 3 * n],
            p_contact: Vec::new(),
            traction: vec![Vec3::ZERO; n],
            fixed_owner: Vec::new(),
            prescribed_owner: Vec::new(),
            fixed_reactions: Vec::new(),
            prescribed_reactions: Vec::new(),
            assembly_seconds,
            surface,
        }
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

    /// Re-computes u_L = W P_load after a change of loads or of the factorisation.
    fn refresh_load_response(&mut self) -> Result<(), SimError> {
        if self.system.is_factored() {
            self.system
                .load_response(&self.load_traction, &mut self.u_load)?;
        }
        Ok(())
    }

    fn update_distances(&mut self) {
        if self.params.alpha > 0.0 {
            let contacts = self.system.contacts();
            let sources: Vec<usize> = if contacts.is_empty() {
                let f = self.system.fixed();
                (0..f.len()).filter(|&v| f[v]).collect()
            } else {
                contacts.to_vec()
            };
            self.distance = self.graph.distances(&sources);
        }
    }

    /// Static solution from the current constraints and loads: targets, tractions, reactions.
    fn solve_static(&mut self) -> Result<(), SimError> {
        let m = 3 * self.contact_targets.len();
        self.p_contact.resize(m, 0.0);
        self.system.solve(
            &self.contact_targets,
            &self.u_load,
            &mut self.x,
            &mut self.p_contact,
        )?;
        let fixed = self.system.fixed();
        let at = |x: &[Real], v: usize| Vec3::new(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
        for (v, &is_fixed) in fixed.iter().enumerate() {
            let rest = self.surface.vertices[v];
            if is_fixed {
                self.target[v] = rest;
                self.traction[v] = at(&self.x, v);
            } else {
                self.target[v] = rest + at(&self.x, v);
                self.traction[v] = at(&self.load_traction, v);
            }
        }
        for (k, &v) in self.system.contacts().iter().enumerate() {
            self.target[v] = self.surface.vertices[v] + self.contact_targets[k];
            self.traction[v] += at(&self.p_contact, k);
        }
        // The tissue pushes on its support with the load on that vertex minus the traction
        // the support applies over the vertex's area.
        let reaction = |v: usize| self.point_forces[v] - self.traction[v] * self.areas[v];
        for (k, &v) in self.constraints.fixed.iter().enumerate() {
            self.fixed_reactions[k] = if self.fixed_owner[k] {
                reaction(v as usize)
            } else {
                Vec3::ZERO
            };
        }
        for (k, p) in self.constraints.prescribed.iter().enumerate() {
            self.prescribed_reactions[k] = if self.prescribed_owner[k] {
                reaction(p.vertex as usize)
            } else {
                Vec3::ZERO
            };
        }
        Ok(())
    }
}

/// The surface without unused vertices, or the reason it cannot bound a body.
fn checked_surface(s: &SurfaceMesh) -> Result<SurfaceMesh, MeshError> {
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

impl Deformable for Bem {
    fn kind(&self) -> &'static str {
        "bem"
    }

    fn surface(&self) -> SurfaceView<'_> {
        SurfaceView {
            positions: &self.positions,
            triangles: &self.surface.triangles,
        }
    }

    fn rest_surface(&self) -> &[Vec3] {
        &self.surface.vertices
    }

    /// A new fixed set re-factorises (O(n³)); a new contact set costs a Woodbury update.
    /// Reactions go to the first fixed entry of a vertex, else its last prescribed entry.
    fn set_constraints(&mut self, c: &Constraints) -> Result<(), SimError> {
        let disp = c.surface_displacements(&self.surface.vertices)?;
        let n = self.surface.vertices.len();
        let mut fixed = vec![false; n];
        for &v in &c.fixed {
            fixed[v as usize] = true;
        }
        let contacts: Vec<usize> = (0..n).filter(|&v| !fixed[v] && disp[v].is_some()).collect();
        if fixed.as_slice() != self.system.fixed() || !self.system.is_factored() {
            self.system.factor(&fixed)?;
            self.refresh_load_response()?;
        }
        let changed = contacts.as_slice() != self.system.contacts();
        self.system.set_contacts(&contacts)?;
        if changed {
            self.update_distances();
        }
        self.contact_targets = contacts
            .iter()
            .map(|&v| disp[v].unwrap_or(Vec3::ZERO))
            .collect();
        let mut taken = vec![false; n];
        self.fixed_owner = c
            .fixed
            .iter()
            .map(|&v| !std::mem::replace(&mut taken[v as usize], true))
            .collect();
        let mut owner = vec![false; c.prescribed.len()];
        for (k, p) in c.prescribed.iter().enumerate().rev() {
            owner[k] = !std::mem::replace(&mut taken[p.vertex as usize], true);
        }
        self.prescribed_owner = owner;
        self.fixed_reactions = vec![Vec3::ZERO; c.fixed.len()];
        self.prescribed_reactions = vec![Vec3::ZERO; c.prescribed.len()];
        self.constraints = c.clone();
        Ok(())
    }

    /// Point loads become tractions over their vertex's tributary area. Gravity is refused:
    /// a body force needs a volume integral that a surface-only model does not have.
    fn set_loads(&mut self, loads: &Loads) -> Result<(), SimError> {
        if loads.gravity != Vec3::ZERO {
            return Err(SimError::Unsupported {
                model: "bem",
                operation: "gravity",
                reason: "body forces need a volume integral; the BEM discretises only the surface"
                    .into(),
            });
        }
        let n = self.surface.vertices.len();
        let mut forces = vec![Vec3::ZERO; n];
        for &(v, f) in &loads.point_loads {
            let slot = forces.get_mut(v as usize).ok_or(SimError::BadConstraint {
                vertex: v as usize,
                count: n,
            })?;
            if !is_finite_vec(f) {
                return Err(SimError::BadParameter {
                    name: "point_loads",
                    value: format!("surface vertex {v} -> {f}"),
                    reason: "the force is not finite".into(),
                });
            }
            *slot += f;
        }
        for (v, f) in forces.iter().enumerate() {
            let p = *f / self.areas[v];
            self.load_traction[3 * v..3 * v + 3].copy_from_slice(&[p.x, p.y, p.z]);
        }
        self.point_forces = forces;
        self.refresh_load_response()
    }

    /// The static solution; with `alpha > 0`, one step of eq. 13 toward it.
    fn step(&mut self, dt: Real) -> Result<StepInfo, SimError> {
        if self.params.alpha > 0.0 && !(dt.is_finite() && dt > 0.0) {
            return Err(SimError::BadTimeStep { dt });
        }
        self.solve_static()?;
        if self.params.alpha > 0.0 {
            relax(
                &mut self.positions,
                &self.target,
                &self.distance,
                self.params.alpha,
                dt,
            );
        } else {
            self.positions.copy_from_slice(&self.target);
        }
        Ok(StepInfo::default())
    }

    fn reactions(&self) -> Reactions<'_> {
        Reactions {
            fixed: &self.fixed_reactions,
            prescribed: &self.prescribed_reactions,
        }
    }

    fn cut(&mut self, blade: &CutPath) -> Result<CutInfo, SimError> {
        let _ = blade;
        Err(SimError::Unsupported {
            model: "bem",
            operation: "cutting",
            reason: "incisions are not implemented yet for the BEM".into(),
        })
    }

    fn reset(&mut self) {
        self.positions.copy_from_slice(&self.surface.vertices);
        self.target.copy_from_slice(&self.surface.vertices);
        self.traction.iter_mut().for_each(|t| *t = Vec3::ZERO);
        self.fixed_reactions
            .iter_mut()
            .for_each(|r| *r = Vec3::ZERO);
        self.prescribed_reactions
            .iter_mut()
            .for_each(|r| *r = Vec3::ZERO);
    }

    fn info(&self) -> ModelInfo {
        let dofs = self.system.dofs();
        let s = &self.system;
        ModelInfo {
            kind: self.kind(),
            nodes: self.surface.vertices.len(),
            dofs,
            elements: self.surface.triangles.len(),
            surface_vertices: self.surface.vertices.len(),
            memory_bytes: 3 * dofs * dofs * 8,
            precompute_seconds: self.assembly_seconds + s.last_factor_seconds,
            is_static: self.params.alpha == 0.0,
            details: vec![
                ("assembly_s".into(), format!("{:.3}", self.assembly_seconds)),
                ("factor_s".into(), format!("{:.3}", s.last_factor_seconds)),
                ("factorizations".into(), s.factorizations.to_string()),
                ("woodbury_updates".into(), s.woodbury_updates.to_string()),
                ("contacts".into(), s.contacts().len().to_string()),
                ("alpha".into(), self.params.alpha.to_string()),
            ],
        }
    }
}
