//! The spring-mass family (survey section 2.2): point masses joined by damped springs,
//! stepped by the shared integrators of `crate::integrate`.
//!
//! Kinds:
//! - `spring-mass`: springs on the edges of a triangle surface (a membrane of `thickness`),
//!   masses lumped from triangle areas; it can be cut (`cut`).
//! - `simplex-spring-mass`: the T2 simplex mesh, dual of the triangulation: one mass at the
//!   centre of each triangle, linked to its 3 neighbours; drawn through the dual triangle
//!   mesh (`simplex`).
//! - `volumetric-spring-mass`: springs on the edges of a tetrahedral mesh, or, with
//!   `parents = true` on a surface, the internal parent-nodes variant (`volumetric`).
//!
//! Spring constants come from E and ν (`stiffness`: van Gelder 1998 or a least-squares fit to
//! linear FEM elements); friction −α m v with α = `material.damping`; spring damping
//! c = β k with β = `material.stiffness_damping`; an optional pressure (`pressure = true`)
//! keeps the volume of a closed surface with the material's bulk modulus.
//!
//! - `springs`: forces and Jacobians; `stiffness`: constants from E, ν; `pressure`
//! - `body`: the particle system; `surface`, `simplex`, `volumetric`: the three builders
//! - `cut`: progressive cutting; `deformable`: the `Deformable` interface

mod body;
pub mod cut;
mod deformable;
pub mod pressure;
pub mod simplex;
pub mod springs;
pub mod stiffness;
mod surface;
mod volumetric;

use std::time::Instant;

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::integrate::{Hold, Integrator, IntegratorSettings, ParticleState, Scheme};
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::model::BuildInput;
use crate::model::registry::parse_params;

pub use body::SpringBody;
pub use simplex::SimplexMesh;
pub use stiffness::StiffnessRule;

/// The three kinds of the family.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Surface,
    Simplex,
    Volumetric,
}

impl Kind {
    pub fn name(self) -> &'static str {
        match self {
            Kind::Surface => "spring-mass",
            Kind::Simplex => "simplex-spring-mass",
            Kind::Volumetric => "volumetric-spring-mass",
        }
    }
}

/// The `[model]` settings of the spring-mass kinds.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpringParams {
    /// Time integration scheme (default `symplectic-euler`).
    #[serde(default)]
    pub integrator: Scheme,
    /// How spring constants follow from E and ν (default `van-gelder`).
    #[serde(default)]
    pub stiffness: StiffnessRule,
    /// Membrane thickness of the surface kinds, in m (default 0.005).
    #[serde(default = "default_thickness")]
    pub thickness: Real,
    /// Volume preservation of a closed surface by an internal pressure. Unset (the
    /// default): on for the surface kinds when the surface is closed (an organ is not an
    /// empty bag: without it a probe that slips between vertices collapses the membrane
    /// around itself), off for the volumetric kind, whose springs fill the volume. `true`
    /// on an open surface is refused.
    #[serde(default)]
    pub pressure: Option<bool>,
    /// Volumetric kind on a surface: build internal parent nodes (default false).
    #[serde(default)]
    pub parents: bool,
    /// Depth of the parent layer as a fraction of the way to the centroid (default 0.5).
    #[serde(default = "default_depth")]
    pub parent_depth: Real,
    /// Implicit Euler: CG iteration cap and relative tolerance (defaults 1000, 1e-6; a step
    /// stopped by the cap is reported as capped).
    #[serde(default = "default_cg_iterations")]
    pub cg_iterations: usize,
    #[serde(default = "default_cg_tolerance")]
    pub cg_tolerance: Real,
    /// `"auto"` (default: as many integrator steps per step as the measured stability limit
    /// needs) or a forced count.
    #[serde(default)]
    pub substeps: crate::integrate::Substeps,
}

fn default_thickness() -> Real {
    0.005
}
fn default_depth() -> Real {
    0.5
}
fn default_cg_iterations() -> usize {
    100
}
fn default_cg_tolerance() -> Real {
    1e-6
}

impl Default for SpringParams {
    fn default() -> Self {
        Self {
            integrator: Scheme::default(),
            stiffness: StiffnessRule::default(),
            thickness: default_thickness(),
            pressure: None,
            parents: false,
            parent_depth: default_depth(),
            cg_iterations: default_cg_iterations(),
            cg_tolerance: default_cg_tolerance(),
            substeps: crate::integrate::Substeps::Auto,
        }
    }
}

impl SpringParams {
    fn validated(self) -> Result<Self, SimError> {
        let bad = |name: &'static str, value: Real, reason: &str| {
            Err(SimError::BadParameter {
                name,
                value: value.to_string(),
                reason: reason.into(),
            })
        };
        if !(self.thickness.is_finite() && self.thickness > 0.0) {
            return bad("thickness", self.thickness, "must be a finite value > 0 m");
        }
        if !(self.parent_depth.is_finite() && self.parent_depth > 0.0 && self.parent_depth < 1.0) {
            return bad("parent_depth", self.parent_depth, "must lie in (0, 1)");
        }
        if !(self.cg_tolerance.is_finite() && self.cg_tolerance >= 0.0) {
            return bad(
                "cg_tolerance",
                self.cg_tolerance,
                "must be a finite value >= 0",
            );
        }
        Ok(self)
    }
}

/// How the drawn surface follows the particles.
#[derive(Clone, Debug)]
pub(crate) enum SurfaceLink {
    /// Surface vertex i is particle `nodes[i]`.
    Nodes(Vec<u32>),
    /// Surface vertices rebuilt from the T2 nodes around them.
    Dual(SimplexMesh),
}

/// A spring-mass model of any of the three kinds (see the module doc).
#[derive(Debug)]
pub struct SpringModel {
    kind: Kind,
    material: Material,
    params: SpringParams,
    body: SpringBody,
    /// Rest positions of the particles.
    rest: Vec<Vec3>,
    state: ParticleState,
    integrator: Integrator,
    link: SurfaceLink,
    triangles: Vec<[u32; 3]>,
    surface_rest: Vec<Vec3>,
    surface_positions: Vec<Vec3>,
    /// Tetrahedra (volumetric kinds) for VTU output.
    tets: Vec<[u32; 4]>,
    holds: Vec<Hold>,
    /// Per hold: the (constraint list, index, share) entries its force is reported to.
    constraints: deformable::HeldConstraints,
    loads: crate::interact::Loads,
    fixed_reactions: Vec<Vec3>,
    prescribed_reactions: Vec<Vec3>,
    /// Pending crossings and open tips of the cutter (surface kind).
    cutter: cut::Cutter,
    topology_version: u32,
    precompute_seconds: Real,
    last_info: crate::model::StepInfo,
}

impl SpringModel {
    /// Builds the kind from the registry's input (the `[model]` table is `SpringParams`).
    pub fn from_input(kind: Kind, input: &BuildInput<'_>) -> Result<Self, Error> {
        let params: SpringParams = parse_params(kind.name(), input.params)?;
        let params = params.validated()?;
        let material = input.material.validated()?;
        let start = Instant::now();
        let mut model = match kind {
            Kind::Surface => {
                let s = input.mesh.surface_mesh()?;
                surface::build(&s, material, params)?
            }
            Kind::Simplex => {
                let s = input.mesh.surface_mesh()?;
                simplex::build(&s, material, params)?
            }
            Kind::Volumetric if params.parents => {
                let s = input.mesh.surface_mesh()?;
                volumetric::build_parents(&s, material, params)?
            }
            Kind::Volumetric => {
                let t = input.mesh.tet_mesh(input.source)?;
                volumetric::build(&t, material, params)?
            }
        };
        model.precompute_seconds = start.elapsed().as_secs_f64();
        Ok(model)
    }

    /// Assembles a model from its parts (the builders call this).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn assemble(
        kind: Kind,
        material: Material,
        params: SpringParams,
        body: SpringBody,
        rest: Vec<Vec3>,
        link: SurfaceLink,
        triangles: Vec<[u32; 3]>,
        tets: Vec<[u32; 4]>,
    ) -> Self {
        let settings = IntegratorSettings {
            cg_max_iterations: params.cg_iterations,
            cg_tolerance: params.cg_tolerance,
            substeps: params.substeps,
            ..IntegratorSettings::default()
        };
        let mut m = Self {
            kind,
            material,
            params,
            body,
            state: ParticleState::at_rest(rest.clone()),
            rest,
            integrator: Integrator::with_settings(params.integrator, settings),
            link,
            triangles,
            surface_rest: Vec::new(),
            surface_positions: Vec::new(),
            tets,
            holds: Vec::new(),
            constraints: Default::default(),
            loads: Default::default(),
            fixed_reactions: Vec::new(),
            prescribed_reactions: Vec::new(),
            cutter: Default::default(),
            topology_version: 0,
            precompute_seconds: 0.0,
            last_info: Default::default(),
        };
        m.surface_rest = m.surface_of(&m.rest.clone());
        m.surface_positions = m.surface_rest.clone();
        m.body
            .set_split_damping(m.integrator.scheme != Scheme::ImplicitEuler, &m.rest);
        m
    }

    pub fn kind_of(&self) -> Kind {
        self.kind
    }
    pub fn params(&self) -> SpringParams {
        self.params
    }
    pub fn material(&self) -> &Material {
        &self.material
    }
    pub fn body(&self) -> &SpringBody {
        &self.body
    }
    pub fn rest_positions(&self) -> &[Vec3] {
        &self.rest
    }
    pub fn state(&self) -> &ParticleState {
        &self.state
    }
    /// The time integration scheme in use.
    pub fn scheme(&self) -> Scheme {
        self.integrator.scheme
    }
    /// Changes the scheme (the next step starts afresh).
    pub fn set_scheme(&mut self, scheme: Scheme) {
        self.integrator.scheme = scheme;
        self.integrator.invalidate();
        self.body
            .set_split_damping(scheme != Scheme::ImplicitEuler, &self.rest);
    }
    /// The particles each surface vertex follows (`None` for the simplex kind).
    pub fn surface_nodes(&self) -> Option<&[u32]> {
        match &self.link {
            SurfaceLink::Nodes(n) => Some(n),
            SurfaceLink::Dual(_) => None,
        }
    }
    /// The T2 mesh of the simplex kind.
    pub fn simplex_mesh(&self) -> Option<&SimplexMesh> {
        match &self.link {
            SurfaceLink::Dual(s) => Some(s),
            SurfaceLink::Nodes(_) => None,
        }
    }

    /// Replaces positions and velocities; lengths must match and values be finite.
    pub fn set_state(&mut self, x: &[Vec3], v: &[Vec3]) -> Result<(), SimError> {
        let n = self.rest.len();
        if x.len() != n || v.len() != n || !x.iter().chain(v).all(|p| p.is_finite()) {
            return Err(SimError::BadParameter {
                name: "state",
                value: format!("{} positions, {} velocities", x.len(), v.len()),
                reason: format!("needs {n} finite positions and velocities"),
            });
        }
        self.state.x.copy_from_slice(x);
        self.state.v.copy_from_slice(v);
        self.integrator.invalidate();
        self.update_surface();
        Ok(())
    }

    /// One integration step with the current holds; on error the state is kept.
    pub fn advance(&mut self, dt: Real) -> Result<crate::model::StepInfo, SimError> {
        let info = self
            .integrator
            .step(&mut self.body, &mut self.state, &self.holds, dt)?;
        self.update_surface();
        self.distribute_reactions();
        self.last_info = info;
        Ok(info)
    }

    /// Surface positions for particle positions `x`.
    pub(crate) fn surface_of(&self, x: &[Vec3]) -> Vec<Vec3> {
        match &self.link {
            SurfaceLink::Nodes(nodes) => nodes.iter().map(|&n| x[n as usize]).collect(),
            SurfaceLink::Dual(s) => {
                let mut out = vec![Vec3::ZERO; s.vertex_count()];
                s.vertices_into(x, &mut out);
                out
            }
        }
    }

    fn update_surface(&mut self) {
        match &self.link {
            SurfaceLink::Nodes(nodes) => {
                self.surface_positions.resize(nodes.len(), Vec3::ZERO);
                for (s, &n) in self.surface_positions.iter_mut().zip(nodes) {
                    *s = self.state.x[n as usize];
                }
            }
            SurfaceLink::Dual(s) => s.vertices_into(&self.state.x, &mut self.surface_positions),
        }
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_damping;
