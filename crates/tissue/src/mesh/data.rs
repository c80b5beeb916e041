//! `MeshData`: everything a mesh file can hold, before a model picks what it needs.

use crate::error::MeshError;
use crate::math::{Real, Vec3};
use crate::mesh::boundary::boundary_surface;
use crate::mesh::{SurfaceMesh, TetMesh};

/// Per-vertex values carried with a mesh (displacement, stress...), written to VTK/VTU.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    pub name: String,
    /// Values per vertex: 1 for a scalar, 3 for a vector.
    pub components: usize,
    /// `components` values per vertex, vertex after vertex.
    pub values: Vec<Real>,
}

/// Material constants stored in a mesh file (OpenSurgSim PLY `material` element), SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialRecord {
    pub density: Real,
    pub poisson_ratio: Real,
    pub young_modulus: Real,
}

/// The contents of a mesh file: vertices and whatever elements and annotations it had.
///
/// Quadratic tetrahedra use VTK's node order: the four corners, then the mid-edge nodes of
/// edges (0,1), (1,2), (0,2), (0,3), (1,3), (2,3). Readers of other conventions convert.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeshData {
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub tets: Vec<[u32; 4]>,
    pub tets10: Vec<[u32; 10]>,
    /// Physical tag per triangle (Gmsh physical group, VTK/MEDIT reference); empty if none.
    pub triangle_tags: Vec<i32>,
    /// Physical tag per linear tetrahedron; empty if none.
    pub tet_tags: Vec<i32>,
    /// Vertices the file marks as fixed (OpenSurgSim `boundary_condition`).
    pub fixed_vertices: Vec<u32>,
    pub material: Option<MaterialRecord>,
    pub point_data: Vec<Field>,
}

impl MeshData {
    /// A surface-only mesh.
    pub fn from_surface(s: &SurfaceMesh) -> Self {
        Self {
            vertices: s.vertices.clone(),
            triangles: s.triangles.clone(),
            ..Self::default()
        }
    }

    /// A volume-only mesh.
    pub fn from_tets(t: &TetMesh) -> Self {
        Self {
            vertices: t.vertices.clone(),
            tets: t.tets.clone(),
            ..Self::default()
        }
    }

    pub fn has_volume(&self) -> bool {
        !self.tets.is_empty() || !self.tets10.is_empty()
    }

    /// The linear tetrahedral mesh: the 4-node tetrahedra plus the corners of the 10-node ones.
    /// Vertices are kept as they are (mid-edge nodes stay, unused).
    pub fn tet_mesh(&self, source_desc: &str) -> Result<TetMesh, MeshError> {
        if !self.has_volume() {
            return Err(MeshError::NeedsVolume {
                source_desc: source_desc.to_string(),
            });
        }
        let mut tets = self.tets.clone();
        tets.extend(self.tets10.iter().map(|t| [t[0], t[1], t[2], t[3]]));
        let mesh = TetMesh::new(self.vertices.clone(), tets);
        mesh.validate_indices()?;
        Ok(mesh)
    }

    /// The surface a user sees: the boundary of the volume if there is one, else the triangles.
    pub fn surface_mesh(&self) -> Result<SurfaceMesh, MeshError> {
        if self.has_volume() {
            let tets = self.tet_mesh("")?;
            return Ok(boundary_surface(&tets).surface);
        }
        if self.triangles.is_empty() {
            return Err(MeshError::Empty {
                what: "triangles or tetrahedra",
            });
        }
        let s = SurfaceMesh::new(self.vertices.clone(), self.triangles.clone());
        s.validate_indices()?;
        Ok(s)
    }

    /// Looks up a point field by name.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.point_data.iter().find(|f| f.name == name)
    }
}
