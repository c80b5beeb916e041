//! `chainmail`: 3D ChainMail (Gibson 1997) on a voxel lattice, with per-voxel limits
//! (enhanced ChainMail, Schill et al. 1998), elastic relaxation, cutting, carving and
//! joining.
//!
//! The body is voxelised (`voxel::voxelize_surface`) or taken from an image; each occupied
//! voxel is an element linked to its six face neighbours (`lattice`). There are no forces
//! and no time integration: an instrument moves the elements under its contact and the
//! move propagates as a wavefront only as far as links are violated; between interactions
//! the elements relax toward the rest shape (`relax_iterations` Gauss-Seidel sweeps of
//! rate `relax_rate` per step, so relaxation speed is per step, not per second), after
//! which a propagation from the displaced elements restores any limit relaxation broke.
//!
//! The rendered surface is the given triangle surface embedded trilinearly in the lattice
//! (`voxel::TrilinearEmbedding`), or marching tetrahedra over the voxels when the model is
//! built from a grid alone; after a cut, carve or join, the closed boundary of the linked
//! voxels (`voxel::boundary`). A prescribed surface vertex moves the elements of its cell by
//! the vertex's missing displacement (weighted when cells are shared); fixed vertices pin
//! their cell's elements at rest.
//!
//! Instrument force (ChainMail has no stresses): the force on a prescribed vertex is
//! `force_stiffness` · depth · (the vertex's share of surface area), pointing back toward
//! the vertex's rest position, where depth is how much deeper (or shallower) the target
//! lies than the vertex's own rest position in the rest configuration's distance map,
//! computed at build (a Winkler bed: pressure proportional to penetration). The default
//! stiffness is E / (largest depth of the body) in Pa/m: pressing a body in by its whole
//! half-thickness costs about E, which is right for a slab pressed from both faces and
//! twice E·strain for one pressed against a fixed base (`tests_probe`: a block on a fixed
//! base reads 2.20 times E·A·strain). The force lives on the surface that the prescribed
//! vertex moves: a coarse surface's vertex carries its whole area share into the contact
//! (the liver's cone point, 9.1e-5 m², where the elastic reference's patch is about 3 mm
//! across). Fixed reactions are reported as zero (no stresses).
//!
//! A prescribed vertex is held in full: the lattice pins a moved element in all three
//! directions through the propagation and the relaxation, so the model cannot hold a
//! vertex along a direction only (a frictionless plate); docs/compare.md, "Session 19:
//! `chainmail`".
//!
//! - `lattice`: elements, links, limits, propagation, relaxation, link edits
//! - `deformable`: the `Deformable` interface, cut, carve and join

mod deformable;
pub mod lattice;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_probe;

use std::time::Instant;

use serde::Deserialize;

use crate::error::{Error, SimError};
use crate::interact::Constraints;
use crate::material::Material;
use crate::math::{Real, Vec3};
use crate::mesh::SurfaceMesh;
use crate::model::BuildInput;
use crate::model::registry::parse_params;
use crate::voxel::{
    DistanceMap, DrawnBoundary, TrilinearEmbedding, VoxelGrid, embedded_body, voxelize_to,
};

pub use lattice::{Lattice, Limits, Propagation};

/// The `[model]` settings of `chainmail`.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChainMailParams {
    /// Voxel side in m; default: the longest side of the body / `resolution`.
    pub voxel_size: Option<Real>,
    /// Voxels along the body's longest side when `voxel_size` is not given (default 24).
    #[serde(default = "default_resolution")]
    pub resolution: usize,
    /// Shortest link / rest length (default 0.9).
    #[serde(default = "default_compression")]
    pub compression: Real,
    /// Longest link / rest length (default 1.1).
    #[serde(default = "default_stretch")]
    pub stretch: Real,
    /// Largest sideways offset / rest length (default 0.1).
    #[serde(default = "default_shear")]
    pub shear: Real,
    /// Relaxation sweeps per step (default 4).
    #[serde(default = "default_relax_iterations")]
    pub relax_iterations: usize,
    /// Fraction of the way to the relaxed position per sweep, in (0, 1] (default 0.5).
    #[serde(default = "default_relax_rate")]
    pub relax_rate: Real,
    /// Force per depth per area, Pa/m; default E / largest depth.
    pub force_stiffness: Option<Real>,
}

fn default_resolution() -> usize {
    24
}
fn default_compression() -> Real {
    0.9
}
fn default_stretch() -> Real {
    1.1
}
fn default_shear() -> Real {
    0.1
}
fn default_relax_iterations() -> usize {
    4
}
fn default_relax_rate() -> Real {
    0.5
}

impl Default for ChainMailParams {
    fn default() -> Self {
        Self {
            voxel_size: None,
            resolution: default_resolution(),
            compression: default_compression(),
            stretch: default_stretch(),
            shear: default_shear(),
            relax_iterations: default_relax_iterations(),
            relax_rate: default_relax_rate(),
            force_stiffness: None,
        }
    }
}

impl ChainMailParams {
    fn check(&self) -> Result<(), SimError> {
        let bad = |name: &'static str, value: Real, reason: &str| {
            Err(SimError::BadParameter {
                name,
                value: value.to_string(),
                reason: reason.into(),
            })
        };
        if !(self.compression > 0.0 && self.compression < 1.0) {
            return bad("compression", self.compression, "must be in (0, 1)");
        }
        if !(self.stretch > 1.0 && self.stretch.is_finite()) {
            return bad("stretch", self.stretch, "must be finite and > 1");
        }
        if !(self.shear >= 0.0 && self.shear.is_finite()) {
            return bad("shear", self.shear, "must be finite and >= 0");
        }
        if !(self.relax_rate > 0.0 && self.relax_rate <= 1.0) {
            return bad("relax_rate", self.relax_rate, "must be in (0, 1]");
        }
        if self.resolution == 0 || self.resolution > 1000 {
            return bad("resolution", self.resolution as Real, "must be in 1..=1000");
        }
        if let Some(h) = self.voxel_size.filter(|h| !(h.is_finite() && *h > 0.0)) {
            return bad("voxel_size", h, "must be finite and > 0");
        }
        if let Some(k) = self
            .force_stiffness
            .filter(|k| !(k.is_finite() && *k >= 0.0))
        {
            return bad("force_stiffness", k, "must be finite and >= 0");
        }
        Ok(())
    }

    /// The limits every voxel gets.
    pub fn limits(&self) -> Limits {
        Limits {
            compression: self.compression,
            stretch: self.stretch,
            shear: self.shear,
        }
    }
}

/// The ChainMail model (see the module doc).
#[derive(Clone, Debug)]
pub struct ChainMail {
    params: ChainMailParams,
    lattice: Lattice,
    embedding: TrilinearEmbedding,
    triangles: Vec<[u32; 3]>,
    surface: Vec<Vec3>,
    /// Vertices of the given (or marching) surface; the voxel boundary drawn after a
    /// topology edit is numbered after them.
    original_vertices: usize,
    /// The voxel boundary drawn after edits.
    drawn: DrawnBoundary,
    distance: DistanceMap,
    vertex_area: Vec<Real>,
    force_stiffness: Real,
    constraints: Constraints,
    /// Elements pinned by fixed vertices, and those pinned in the last step.
    fixed_elements: Vec<u32>,
    fixed_vertex: Vec<bool>,
    pinned: Vec<u32>,
    fixed_reactions: Vec<Vec3>,
    prescribed_reactions: Vec<Vec3>,
    last: Propagation,
    steps: u64,
    topology_version: u32,
    precompute_seconds: Real,
}

impl ChainMail {
    /// Builds from the scene input: the surface (or the tet mesh's boundary) is voxelised.
    pub fn from_input(input: &BuildInput<'_>) -> Result<Self, Error> {
        let start = Instant::now();
        let params: ChainMailParams = parse_params("chainmail", input.params)?;
        params.check()?;
        let surface = input.mesh.surface_mesh()?;
        let grid = voxelize_to(&surface, params.voxel_size, params.resolution)?;
        let mut model = Self::new(grid, Some(surface), input.material, params)?;
        // The build time includes the voxelisation.
        model.precompute_seconds = start.elapsed().as_secs_f64();
        Ok(model)
    }

    /// Builds on a voxel grid (labels are material classes; every class gets
    /// `params.limits()` until `set_class_limits`). Without a surface, marching tetrahedra
    /// over the voxels is drawn. Only the largest connected part is kept.
    pub fn new(
        mut grid: VoxelGrid,
        surface: Option<SurfaceMesh>,
        material: Material,
        params: ChainMailParams,
    ) -> Result<Self, Error> {
        let start = Instant::now();
        params.check()?;
        let (surface, embedding) = embedded_body(&mut grid, surface)?;
        let classes = grid.labels.iter().copied().max().unwrap_or(1) as usize + 1;
        let lattice = Lattice::new(&grid, &vec![params.limits(); classes]);
        let distance = DistanceMap::of(&grid);
        let force_stiffness = params
            .force_stiffness
            .unwrap_or(material.young_modulus / distance.max_depth().max(1e-12));
        let mut vertex_area = vec![0.0; surface.vertices.len()];
        for (t, tri) in surface.triangles.iter().enumerate() {
            let [a, b, c] = surface.corners(t);
            let share = 0.5 * (b - a).cross(c - a).length() / 3.0;
            for &v in tri {
                vertex_area[v as usize] += share;
            }
        }
        // Built now so that the first edit, too, only redraws near itself.
        let mut drawn = DrawnBoundary::new();
        drawn.prepare(&lattice.topology, None);
        Ok(Self {
            params,
            lattice,
            embedding,
            triangles: surface.triangles,
            original_vertices: surface.vertices.len(),
            drawn,
            surface: surface.vertices,
            distance,
            force_stiffness,
            constraints: Constraints::default(),
            fixed_elements: Vec::new(),
            fixed_vertex: vec![false; vertex_area.len()],
            vertex_area,
            pinned: Vec::new(),
            fixed_reactions: Vec::new(),
            prescribed_reactions: Vec::new(),
            last: Propagation::default(),
            steps: 0,
            topology_version: 0,
            precompute_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The lattice (element positions, links), for inspection and tests.
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// Per-class limits for inhomogeneous tissue (`limits[c]` for voxel label c).
    pub fn set_class_limits(&mut self, limits: &[Limits]) {
        self.lattice.set_limits(limits);
    }

    /// What the last step's propagation did.
    pub fn last_propagation(&self) -> Propagation {
        self.last
    }

    /// The depth map's value at a point of the rest configuration (m, positive inside).
    pub fn rest_depth(&self, p: Vec3) -> Real {
        self.distance.depth_at(p)
    }

    /// The force on the instrument holding vertex `v` at `target`: `force_stiffness` · (how
    /// much deeper the target lies than the vertex's own rest position, in the rest depth
    /// map) · the vertex's area, pointing back toward its rest position. The depth is
    /// measured from the vertex's rest depth, not from zero: the map's zero is the voxel
    /// surface, which lies up to a voxel from the given surface (−2.2 to +3.9 mm at the
    /// liver's vertices, voxel 2.7 mm), and reading the target's depth alone charged a
    /// vertex moved by a micrometre for millimetres, and one outside the voxel surface
    /// less the further it was pressed.
    fn instrument_force(&self, v: usize, target: Vec3) -> Vec3 {
        if self.fixed_vertex[v] {
            return Vec3::ZERO;
        }
        let rest = self.embedding.rest[v];
        let back = rest - target;
        let depth = (self.distance.depth_at(target) - self.distance.depth_at(rest)).abs();
        self.force_stiffness * depth * self.vertex_area[v] * back.normalize_or_zero()
    }

    fn refresh_surface(&mut self) {
        self.embedding
            .apply(&self.lattice.x, &self.lattice.rest, &mut self.surface);
    }
}
