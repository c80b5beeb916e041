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
