//! Voxel grids: the lattice that the voxel models (`chainmail`, `linked-volumes`) are built
//! on, made from a closed triangle surface or from a medical image.
//!
//! - `VoxelGrid`: dimensions, spacing, origin and a label per voxel (0 = empty, otherwise
//!   the voxel's material class, an index into a model's table of limits or stiffnesses)
//! - `voxelize`: a closed surface filled by winding number along lattice rows
//! - `select`: an image thresholded or a set of labels selected
//! - `components`: face-connected parts, keep the largest or the one holding a voxel
//! - `distance`: the signed distance map at rest (chamfer), for penetration depths
//! - `embed`: a given surface moved by trilinear interpolation of voxel displacements
//! - `marching`: a surface from the voxels when none was given (marching tetrahedra)
//! - `topology`: which voxels and links exist; cut, carve and join (both models)
//! - `boundary`: the closed surface of the linked voxels, drawn after a topology edit
//! - `drawn`: that surface kept between edits and redrawn only where an edit reaches
//!
//! Voxel (i, j, k) has its centre at `origin + (i·sx, j·sy, k·sz)`, as in `VoxelImage`.

pub mod boundary;
pub mod components;
pub mod distance;
pub mod drawn;
pub mod embed;
pub mod marching;
pub mod select;
pub mod topology;
pub mod voxelize;

use crate::math::{Real, Vec3};

pub use boundary::{BoundarySurface, boundary_surface};
pub use components::{Components, components, keep_component_at, keep_largest};
pub use distance::DistanceMap;
pub use drawn::{DrawnBoundary, DrawnSurface};
pub use embed::{TrilinearEmbedding, embedded_body};
pub use marching::marching_surface;
pub use select::{from_image_labels, from_image_threshold};
pub use topology::VoxelLinks;
pub use voxelize::{voxelize_surface, voxelize_to};

/// A label per voxel on an axis-aligned lattice.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelGrid {
    /// Voxel counts along x, y, z.
    pub dims: [usize; 3],
    /// Distance between voxel centres along x, y, z, in m.
    pub spacing: Vec3,
    /// Centre of voxel (0, 0, 0), in m.
    pub origin: Vec3,
    /// One label per voxel, x fastest: 0 is empty, k > 0 is occupied by material class k.
    pub labels: Vec<u8>,
}

impl VoxelGrid {
    /// An empty grid (all labels 0).
    pub fn new(dims: [usize; 3], spacing: Vec3, origin: Vec3) -> Self {
        let n = dims[0].saturating_mul(dims[1]).saturating_mul(dims[2]);
        Self {
            dims,
            spacing,
            origin,
            labels: vec![0; n],
        }
    }

    /// A box of `dims` voxels, all occupied with label 1 (tests, benchmarks).
    pub fn filled(dims: [usize; 3], spacing: Real) -> Self {
        let mut g = Self::new(dims, Vec3::splat(spacing), Vec3::ZERO);
        g.labels.fill(1);
        g
    }

    pub fn len(&self) -> usize {
        self.labels.len()
    }

    pub fn is_empty(&self) -> bool {
        self.labels.is_empty()
    }

    /// Linear index of voxel (i, j, k), or `None` outside the grid.
    pub fn index(&self, i: usize, j: usize, k: usize) -> Option<usize> {
        let [nx, ny, nz] = self.dims;
        (i < nx && j < ny && k < nz).then(|| i + nx * (j + ny * k))
    }

    /// (i, j, k) of a linear index.
    pub fn coords(&self, index: usize) -> [usize; 3] {
        let [nx, ny, _] = self.dims;
        [index % nx, (index / nx) % ny, index / (nx * ny)]
    }

    /// Centre of voxel (i, j, k), in m.
    pub fn centre(&self, i: usize, j: usize, k: usize) -> Vec3 {
        self.origin + Vec3::new(i as Real, j as Real, k as Real) * self.spacing
    }

    /// Centre of the voxel with linear index `index`, in m.
    pub fn centre_of(&self, index: usize) -> Vec3 {
        let [i, j, k] = self.coords(index);
        self.centre(i, j, k)
    }

    pub fn is_occupied(&self, index: usize) -> bool {
        self.labels.get(index).is_some_and(|&l| l != 0)
    }

    /// Number of occupied voxels.
    pub fn occupied(&self) -> usize {
        self.labels.iter().filter(|&&l| l != 0).count()
    }

    /// Occupied volume, in m³.
    pub fn volume(&self) -> Real {
        self.occupied() as Real * self.spacing.x * self.spacing.y * self.spacing.z
    }

    /// Voxel holding point `p` (nearest centre), or `None` outside the grid.
    pub fn voxel_at(&self, p: Vec3) -> Option<usize> {
        let q = ((p - self.origin) / self.spacing).round();
        if !(q.x >= 0.0 && q.y >= 0.0 && q.z >= 0.0) {
            return None;
        }
        self.index(q.x as usize, q.y as usize, q.z as usize)
    }

    /// Sets every occupied voxel inside the ball (centre, radius) to `label` (0 carves).
    pub fn paint_ball(&mut self, centre: Vec3, radius: Real, label: u8) -> usize {
        let mut changed = 0;
        for idx in 0..self.labels.len() {
            if self.labels[idx] != 0 && self.centre_of(idx).distance(centre) <= radius {
                self.labels[idx] = label;
                changed += 1;
            }
        }
        changed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_round_trip_and_locate_points() {
        let g = VoxelGrid::new(
            [3, 4, 5],
            Vec3::new(0.1, 0.2, 0.3),
            Vec3::new(1.0, 0.0, -1.0),
        );
        for idx in 0..g.len() {
            let [i, j, k] = g.coords(idx);
            assert_eq!(g.index(i, j, k), Some(idx));
            assert_eq!(g.voxel_at(g.centre(i, j, k) + Vec3::splat(0.04)), Some(idx));
        }
        assert_eq!(g.index(3, 0, 0), None);
        assert_eq!(g.voxel_at(Vec3::new(0.0, 0.0, 0.0)), None);
        assert_eq!(g.voxel_at(Vec3::NAN), None);
    }
}
