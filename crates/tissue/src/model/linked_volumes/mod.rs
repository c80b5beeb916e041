//! `linked-volumes`: the survey's volumetric spring-mass model (section 2.3.1). The body is
//! voxelised; each occupied voxel is a point mass ρ·V at its centre, linked to its 6, 18 or
//! 26 lattice neighbours by springs and dampers whose stiffness comes from E (`springs`),
//! and integrated by the shared integrators (`crate::integrate`), implicit Euler by default.
//!
//! The rendered surface is the given triangle surface embedded trilinearly in the lattice
//! (`voxel::TrilinearEmbedding`); instrument contacts on surface vertices hold the elements
//! of their cell (moved by the vertex's missing displacement), fixed vertices hold theirs at
//! rest, and the reaction of a held element is shared among the vertices holding it in
//! proportion to their weights. Point loads reach the elements through the transpose of the
//! embedding. Central springs alone fix Poisson's ratio at 1/4; with 18 or 26 neighbours a
//! per-voxel volume term makes the lattice honour the material's ν ≥ 1/4 (`volume_term`).
//!
//! - `springs`: spring lattice, stiffness from E, `ParticleSystem` forces and Jacobians
//! - `volume_term`: the volume energy supplying λ − μ, and the lattice moduli
//! - `deformable`: the `Deformable` interface
//! - `topology`: cut, carve and join on the shared `voxel::VoxelLinks`, springs updated
//!   locally, and the closed voxel-boundary surface drawn afterwards

mod deformable;
pub mod springs;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_solve;
#[cfg(test)]
mod tests_topology;
mod topology;
pub mod volume_term;

use std::time::Instant;

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::integrate::{
    Hold, Integrator, IntegratorSettings, ParticleState, Preconditioner, Scheme,
};
use crate::interact::Constraints;
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;
use crate::model::BuildInput;
use crate::model::registry::parse_params;
use crate::voxel::{
    DrawnBoundary, TrilinearEmbedding, VoxelGrid, VoxelLinks, embedded_body, voxelize_to,
};

pub use springs::{Spring, SpringLattice, family_coefficients};
pub use volume_term::{LatticeModuli, VolumeTerm, lattice_moduli};

/// The `[model]` settings of `linked-volumes`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkedVolumesParams {
    /// Voxel side in m; default: the longest side of the body / `resolution`.
    pub voxel_size: Option<Real>,
    /// Voxels along the body's longest side when `voxel_size` is not given (default 16).
    #[serde(default = "default_resolution")]
    pub resolution: usize,
    /// 6, 18 or 26 (default 26).
    #[serde(default = "default_neighbours")]
    pub neighbours: usize,
    /// Integration scheme (default "implicit-euler").
    #[serde(default = "default_scheme")]
    pub integrator: Scheme,
    /// Integrator steps per model step: `"auto"` (default: as many as the measured stability
    /// limit needs; 1 for implicit Euler) or a forced count (the key's original meaning).
    #[serde(default)]
    pub substeps: crate::integrate::Substeps,
    /// Implicit Euler: CG iteration cap and relative tolerance (defaults 1000, 1e-6; a step
    /// stopped by the cap is reported as capped).
    #[serde(default = "default_cg_iterations")]
    pub cg_iterations: usize,
    #[serde(default = "default_cg_tolerance")]
    pub cg_tolerance: Real,
    /// Implicit Euler: CG's preconditioner, `"block-jacobi"` (default), `"jacobi"` or
    /// `"rest-factor"` (the rest system matrix factorised once: few iterations, but on the
    /// pelvis and brain scenes each costs more than Jacobi's hundred; docs/performance.md).
    #[serde(default = "default_preconditioner")]
    pub preconditioner: Preconditioner,
}

fn default_cg_iterations() -> usize {
    IntegratorSettings::default().cg_max_iterations
}
fn default_cg_tolerance() -> Real {
    IntegratorSettings::default().cg_tolerance
}
fn default_preconditioner() -> Preconditioner {
    Preconditioner::BlockJacobi
}
fn default_resolution() -> usize {
    16
}
fn default_neighbours() -> usize {
    26
}
fn default_scheme() -> Scheme {
    Scheme::ImplicitEuler
}

impl Default for LinkedVolumesParams {
    fn default() -> Self {
        Self {
            voxel_size: None,
            resolution: default_resolution(),
            neighbours: default_neighbours(),
            integrator: default_scheme(),
            substeps: crate::integrate::Substeps::Auto,
            cg_iterations: default_cg_iterations(),
            cg_tolerance: default_cg_tolerance(),
            preconditioner: default_preconditioner(),
        }
    }
}

/// The linked-volumes model (see the module doc).
#[derive(Debug)]
pub struct LinkedVolumes {
    params: LinkedVolumesParams,
    /// Which voxels exist and which links hold (shared with `chainmail`).
    topology: VoxelLinks,
    /// Voxel index → element id (`u32::MAX` for empty voxels).
    element_of: Vec<u32>,
    /// Spring coefficients per family, in units of the spring modulus (`family_coefficients`).
    coef: [Real; 3],
    /// The springs' modulus (Pa): E alone, or less with the volume term (`lattice_moduli`).
    spring_modulus: Real,
    /// Vertices of the given (or marching) surface; the voxel boundary drawn after a
    /// topology edit is numbered after them.
    original_vertices: usize,
    /// The voxel boundary drawn after edits.
    drawn: DrawnBoundary,
    topology_version: u32,
    material: Material,
    system: SpringLattice,
    rest: Vec<Vec3>,
    state: ParticleState,
    integrator: Integrator,
    embedding: TrilinearEmbedding,
    triangles: Vec<[u32; 3]>,
    surface: Vec<Vec3>,
    spacing: Vec3,
    constraints: Constraints,
    /// Per prescribed entry: the unit normal of a frictionless contact that only pushes
    /// (`Deformable::set_constraints_along`), or `None`: held in full.
    normals: Vec<Option<Vec3>>,
    fixed_vertex: Vec<bool>,
    fixed_elements: Vec<u32>,
    gravity: Vec3,
    point_loads: Vec<(u32, Vec3)>,
    holds: Vec<Hold>,
    fixed_reactions: Vec<Vec3>,
    prescribed_reactions: Vec<Vec3>,
    steps: u64,
    precompute_seconds: Real,
}

impl LinkedVolumes {
    /// Builds from the scene input: the surface (or the tet mesh's boundary) is voxelised.
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let start = Instant::now();
        let params: LinkedVolumesParams = parse_params("linked-volumes", input.params)?;
        let surface = input.mesh.surface_mesh()?;
        check_size(&params)?;
        let grid = voxelize_to(&surface, params.voxel_size, params.resolution)?;
        let mut model = Self::new(grid, Some(surface), input.material, params)?;
        // The build time includes the voxelisation.
        model.precompute_seconds = start.elapsed().as_secs_f64();
        Ok(model)
    }

    /// Builds on a voxel grid (its largest connected part); without a surface, marching
    /// tetrahedra over the voxels is drawn.
    pub fn new(
        mut grid: VoxelGrid,
        surface: Option<SurfaceMesh>,
        material: Material,
        params: LinkedVolumesParams,
    ) -> Result<Self, Error> {
        let start = Instant::now();
        check_size(&params)?;
        let material = material.validated()?;
        let coef = family_coefficients(params.neighbours)?;
        let moduli = lattice_moduli(&material, params.neighbours)?;
        let (surface, mut embedding) = embedded_body(&mut grid, surface)?;
        // Compact element ids over the occupied voxels.
        let mut id = vec![u32::MAX; grid.len()];
        let mut rest = Vec::new();
        for (v, slot) in id.iter_mut().enumerate() {
            if grid.is_occupied(v) {
                *slot = rest.len() as u32;
                rest.push(grid.centre_of(v));
            }
        }
        embedding.remap(&id);
        let s = grid.spacing;
        let volume = s.x * s.y * s.z;
        let topology = VoxelLinks::new(&grid, params.neighbours);
        let spring_modulus = moduli.spring_modulus;
        let springs = topology
            .each_link()
            .map(|(a, b, d)| spring_for(&material, spring_modulus, coef, s, [id[a], id[b]], d))
            .collect();
        let masses = vec![material.density * volume; rest.len()];
        let system = SpringLattice::new(springs, masses, material.damping)
            .with_volume_term(&rest, moduli, volume);
        let nv = surface.vertices.len();
        // Built now so that the first edit, too, only redraws near itself.
        let mut drawn = DrawnBoundary::new();
        drawn.prepare(&topology, Some(&id));
        Ok(Self {
            topology,
            element_of: id,
            coef,
            spring_modulus,
            original_vertices: nv,
            drawn,
            topology_version: 0,
            params,
            material,
            system,
            state: ParticleState::at_rest(rest.clone()),
            rest,
            integrator: {
                // A forced count is the model's own loop (held targets interpolated there);
                // under auto the shared integrator splits the step itself.
                let mut i = Integrator::with_settings(
                    params.integrator,
                    IntegratorSettings {
                        cg_max_iterations: params.cg_iterations,
                        cg_tolerance: params.cg_tolerance,
                        preconditioner: params.preconditioner,
                        ..IntegratorSettings::default()
                    },
                );
                if let crate::integrate::Substeps::Fixed(_) = params.substeps {
                    i.settings.substeps = crate::integrate::Substeps::Fixed(1);
                }
                i
            },
            embedding,
            triangles: surface.triangles,
            surface: surface.vertices,
            spacing: s,
            constraints: Constraints::default(),
            normals: Vec::new(),
            fixed_vertex: vec![false; nv],
            fixed_elements: Vec::new(),
            gravity: Vec3::ZERO,
            point_loads: Vec::new(),
            holds: Vec::new(),
            fixed_reactions: Vec::new(),
            prescribed_reactions: Vec::new(),
            steps: 0,
            precompute_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The particle system (springs, masses, external forces).
    pub fn system(&self) -> &SpringLattice {
        &self.system
    }

    /// Element positions and velocities.
    pub fn state(&self) -> &ParticleState {
        &self.state
    }

    /// Element rest positions.
    pub fn rest(&self) -> &[Vec3] {
        &self.rest
    }

    fn refresh_surface(&mut self) {
        self.embedding
            .apply(&self.state.x, &self.rest, &mut self.surface);
    }
}

/// The spring between elements `ids` (voxels a, b = a's neighbour in direction d).
/// The spring of link direction `d` between elements `ids`, from the lattice's spring modulus
/// (E for springs alone, less when the volume term supplies part of λ).
fn spring_for(
    material: &Material,
    spring_modulus: Real,
    coef: [Real; 3],
    s: Vec3,
    ids: [u32; 2],
    d: usize,
) -> Spring {
    let family = if d < 6 {
        0
    } else if d < 18 {
        1
    } else {
        2
    };
    let o = crate::voxel::topology::OFFSETS[d.min(25)];
    let l = (Vec3::new(o[0] as Real, o[1] as Real, o[2] as Real) * s).length();
    let k = coef[family] * spring_modulus * s.x * s.y * s.z / (l * l);
    Spring {
        a: ids[0],
        b: ids[1],
        k,
        rest: l,
        c: material.stiffness_damping * k,
    }
}

fn check_size(p: &LinkedVolumesParams) -> Result<(), SimError> {
    let bad = |name: &'static str, value: String, reason: &str| {
        Err(SimError::BadParameter {
            name,
            value,
            reason: reason.into(),
        })
    };
    if p.resolution == 0 || p.resolution > 1000 {
        return bad(
            "resolution",
            p.resolution.to_string(),
            "must be in 1..=1000",
        );
    }
    if let crate::integrate::Substeps::Fixed(n) = p.substeps
        && !(1..=10_000).contains(&n)
    {
        return bad("substeps", n.to_string(), "must be in 1..=10000");
    }
    if let Some(h) = p.voxel_size.filter(|h| !(h.is_finite() && *h > 0.0)) {
        return bad("voxel_size", h.to_string(), "must be finite and > 0");
    }
    if !(p.cg_tolerance.is_finite() && p.cg_tolerance >= 0.0) {
        return bad(
            "cg_tolerance",
            p.cg_tolerance.to_string(),
            "must be a finite value >= 0",
        );
    }
    if p.cg_iterations > 1_000_000 {
        return bad(
            "cg_iterations",
            p.cg_iterations.to_string(),
            "must be at most 1000000",
        );
    }
    family_coefficients(p.neighbours).map(|_| ())
}
