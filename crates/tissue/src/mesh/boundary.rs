//! The boundary surface of a tetrahedral mesh, oriented outward.

use std::collections::HashMap;

use crate::mesh::{SurfaceMesh, TetMesh};

/// Faces of a positively oriented tetrahedron (a, b, c, d), each counter-clockwise seen from
/// outside; face k is the one opposite corner k.
pub const TET_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// The boundary of a tetrahedral mesh as its own compact surface.
#[derive(Clone, Debug, PartialEq)]
pub struct Boundary {
    /// Boundary triangles over compacted vertices, outward for positive tetrahedra.
    pub surface: SurfaceMesh,
    /// For each surface vertex, the tet-mesh node it is.
    pub nodes: Vec<u32>,
    /// For each surface triangle, the tetrahedron it belongs to.
    pub face_tets: Vec<u32>,
}

/// Faces used by exactly one tetrahedron. Inverted tetrahedra have their faces flipped so that
/// the boundary stays outward. Faces are listed in tetrahedron order.
pub fn boundary_surface(mesh: &TetMesh) -> Boundary {
    let mut count: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.tets.len() * 2);
    for tet in &mesh.tets {
        for f in TET_FACES {
            *count
                .entry(sorted([tet[f[0]], tet[f[1]], tet[f[2]]]))
                .or_insert(0) += 1;
        }
    }
    let mut node_to_surface = vec![u32::MAX; mesh.vertices.len()];
    let mut nodes = Vec::new();
    let mut triangles = Vec::new();
    let mut face_tets = Vec::new();
    for (t, tet) in mesh.tets.iter().enumerate() {
        let positive = mesh.tet_volume(t) >= 0.0;
        for f in TET_FACES {
            let mut tri = [tet[f[0]], tet[f[1]], tet[f[2]]];
            if count[&sorted(tri)] != 1 {
                continue;
            }
            if !positive {
                tri.swap(1, 2);
            }
            for v in &mut tri {
                let slot = &mut node_to_surface[*v as usize];
                if *slot == u32::MAX {
                    *slot = nodes.len() as u32;
                    nodes.push(*v);
                }
                *v = *slot;
            }
            triangles.push(tri);
            face_tets.push(t as u32);
        }
    }
    let vertices = nodes.iter().map(|&n| mesh.vertices[n as usize]).collect();
    Boundary {
        surface: SurfaceMesh::new(vertices, triangles),
        nodes,
        face_tets,
    }
}

#[inline]
pub(crate) fn sorted(mut f: [u32; 3]) -> [u32; 3] {
    f.sort_unstable();
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    #[test]
    fn single_tet_boundary_is_outward_and_closed() {
        let m = TetMesh::new(
            vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            vec![[0, 1, 2, 3]],
        );
        let b = boundary_surface(&m);
        assert_eq!(b.surface.triangles.len(), 4);
        assert!((b.surface.signed_volume() - 1.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn shared_face_is_interior() {
        // Two tetrahedra sharing face (1, 2, 3), on both sides of it.
        let v = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE];
        let m = TetMesh::new(v, vec![[0, 1, 2, 3], [4, 1, 3, 2]]);
        assert!(m.tet_volume(1) > 0.0);
        let b = boundary_surface(&m);
        assert_eq!(b.surface.triangles.len(), 6);
        assert!((b.surface.signed_volume() - m.volume()).abs() < 1e-14);
    }
}
