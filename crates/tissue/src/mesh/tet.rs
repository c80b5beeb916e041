//! Tetrahedral volume meshes: the mechanical mesh of the volumetric models.

use crate::error::MeshError;
use crate::math::{Real, Vec3, tet_signed_volume};
use crate::mesh::surface::{bounds_of, check_element, validate_vertices};

/// A linear (4-node) tetrahedral mesh. A tetrahedron (a, b, c, d) is positively oriented
/// when (b-a)·((c-a)×(d-a)) > 0.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TetMesh {
    pub vertices: Vec<Vec3>,
    pub tets: Vec<[u32; 4]>,
}

impl TetMesh {
    pub fn new(vertices: Vec<Vec3>, tets: Vec<[u32; 4]>) -> Self {
        Self { vertices, tets }
    }

    /// The mesh without the vertices no tetrahedron uses (a vertex without stiffness or mass
    /// makes a model singular), the others kept in their order. Tet indices must be in range
    /// (`validate_for_simulation` checks that).
    pub fn compacted(&self) -> TetMesh {
        let mut map = vec![u32::MAX; self.vertices.len()];
        for &v in self.tets.iter().flatten() {
            if let Some(m) = map.get_mut(v as usize) {
                *m = 0;
            }
        }
        let mut vertices = Vec::new();
        for (v, slot) in map.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = vertices.len() as u32;
                vertices.push(self.vertices[v]);
            }
        }
        let tets = self
            .tets
            .iter()
            .map(|t| t.map(|v| map.get(v as usize).copied().unwrap_or(u32::MAX)))
            .collect();
        TetMesh::new(vertices, tets)
    }

    /// Checks indices, repeated corners and coordinates.
    pub fn validate_indices(&self) -> Result<(), MeshError> {
        validate_vertices(&self.vertices)?;
        if self.tets.is_empty() {
            return Err(MeshError::Empty { what: "tetrahedra" });
        }
        let n = self.vertices.len();
        for (t, tet) in self.tets.iter().enumerate() {
            check_element("tetrahedron", t, tet, n)?;
        }
        Ok(())
    }

    /// Checks everything a solver needs: valid indices and no inverted or flat tetrahedron.
    /// A tetrahedron is flat when its volume is below `1e-12` of its longest edge cubed.
    pub fn validate_for_simulation(&self) -> Result<(), MeshError> {
        self.validate_indices()?;
        for t in 0..self.tets.len() {
            let [a, b, c, d] = self.corners(t);
            let v = tet_signed_volume(a, b, c, d);
            let l = [b - a, c - a, d - a, c - b, d - b, d - c]
                .iter()
                .map(|e| e.length())
                .fold(0.0, Real::max);
            if v.abs() <= 1e-12 * l * l * l {
                return Err(MeshError::DegenerateTet {
                    tet: t,
                    volume: v,
                    quality: 0.0,
                });
            }
            if v < 0.0 {
                return Err(MeshError::InvertedTet { tet: t, volume: v });
            }
        }
        Ok(())
    }

    #[inline]
    pub fn corners(&self, t: usize) -> [Vec3; 4] {
        let [a, b, c, d] = self.tets[t];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
            self.vertices[d as usize],
        ]
    }

    /// Signed volume of tetrahedron `t`, in m³.
    #[inline]
    pub fn tet_volume(&self, t: usize) -> Real {
        let [a, b, c, d] = self.corners(t);
        tet_signed_volume(a, b, c, d)
    }

    /// Sum of signed tetrahedron volumes, in m³.
    pub fn volume(&self) -> Real {
        (0..self.tets.len()).map(|t| self.tet_volume(t)).sum()
    }

    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        bounds_of(&self.vertices)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compacting_drops_unused_vertices_and_keeps_the_geometry() {
        let v = vec![
            Vec3::ZERO,
            Vec3::splat(9.0),
            Vec3::X,
            Vec3::Y,
            Vec3::splat(-9.0),
            Vec3::Z,
        ];
        let mesh = TetMesh::new(v, vec![[0, 2, 3, 5]]);
        let c = mesh.compacted();
        assert_eq!(c.vertices, vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z]);
        assert_eq!(c.tets, vec![[0, 1, 2, 3]]);
        assert!((c.volume() - 1.0 / 6.0).abs() < 1e-15);
    }
}
