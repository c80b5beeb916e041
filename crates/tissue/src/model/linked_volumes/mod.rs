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

mod deformable;
pub mod springs;
#[cfg(test)]
mod tests;
pub mod volume_term;

use std::time::Instant;

use serde::Deserialize;

use crate::error::{Error, MeshError, SimError};
use crate::integrate::{Hold, Integrator, ParticleState, Scheme};
use crate::interact::Constraints;
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;
use crate::model::BuildInput;
use crate::model::registry::parse_params;
use crate::voxel::{TrilinearEmbedding, VoxelGrid, keep_largest, marching_surface, voxelize_to};

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
    /// Integrator steps per model step (default 1).
    #[serde(default = "one")]
    pub substeps: usize,
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
fn one() -> usize {
    1
}

impl Default for LinkedVolumesParams {
    fn default() -> Self {
        Self {
            voxel_size: None,
            resolution: default_resolution(),
            neighbours: default_neighbours(),
            integrator: default_scheme(),
            substeps: 1,
        }
    }
}

/// The linked-volumes model (see the module doc).
#[derive(Debug)]
pub struct LinkedVolumes {
    params: LinkedVolumesParams,
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
        if keep_largest(&mut grid) == 0 {
            return Err(MeshError::Empty {
                what: "occupied voxels",
            }
            .into());
        }
        let surface = surface.unwrap_or_else(|| marching_surface(&grid));
        let mut embedding = TrilinearEmbedding::build(&grid, &surface.vertices)?;
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
        let (nx, ny, nz) = (
            grid.dims[0] as i64,
            grid.dims[1] as i64,
            grid.dims[2] as i64,
        );
        let mut springs = Vec::new();
        for v in 0..grid.len() {
            let a = id[v];
            if a == u32::MAX {
                continue;
            }
            let [i, j, k] = grid.coords(v).map(|c| c as i64);
            // Each pair once: offsets that are lexicographically positive.
            for dk in -1i64..=1 {
                for dj in -1i64..=1 {
                    for di in -1i64..=1 {
                        if (dk, dj, di) <= (0, 0, 0) {
                            continue;
                        }
                        let family =
                            (di != 0) as usize + (dj != 0) as usize + (dk != 0) as usize - 1;
                        if coef[family] == 0.0 {
                            continue;
                        }
                        let (p, q, r) = (i + di, j + dj, k + dk);
                        if p < 0 || q < 0 || r < 0 || p >= nx || q >= ny || r >= nz {
                            continue;
                        }
                        let b = id[(p + nx * (q + ny * r)) as usize];
                        if b == u32::MAX {
                            continue;
                        }
                        let l = (Vec3::new(di as Real, dj as Real, dk as Real) * s).length();
                        let kk = coef[family] * moduli.spring_modulus * volume / (l * l);
                        springs.push(Spring {
                            a,
                            b,
                            k: kk,
                            rest: l,
                            c: material.stiffness_damping * kk,
                        });
                    }
                }
            }
        }
        let masses = vec![material.density * volume; rest.len()];
        let system = SpringLattice::new(springs, masses, material.damping)
            .with_volume_term(&rest, moduli, volume);
        let nv = surface.vertices.len();
        Ok(Self {
            params,
            material,
            system,
            state: ParticleState::at_rest(rest.clone()),
            rest,
            integrator: Integrator::new(params.integrator),
            embedding,
            triangles: surface.triangles,
            surface: surface.vertices,
            spacing: s,
            constraints: Constraints::default(),
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
    if p.substeps == 0 || p.substeps > 10_000 {
        return bad("substeps", p.substeps.to_string(), "must be in 1..=10000");
    }
    if let Some(h) = p.voxel_size.filter(|h| !(h.is_finite() && *h > 0.0)) {
        return bad("voxel_size", h.to_string(), "must be finite and > 0");
    }
    family_coefficients(p.neighbours).map(|_| ())
}
