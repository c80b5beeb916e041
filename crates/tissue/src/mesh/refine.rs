//! Uniform refinement of a tetrahedral mesh: every tetrahedron split into eight at its edge
//! midpoints (four corner tetrahedra and the inner octahedron cut along one diagonal). The
//! body is the same, every edge is halved, and the surface is refined 1 → 4 consistently,
//! so convergence studies can run several discretisations of one body.

use std::collections::HashMap;

use crate::error::MeshError;
use crate::math::tet_signed_volume;

use super::TetMesh;

/// `mesh` with every tetrahedron split into eight; the old vertices keep their numbers and
/// each edge's midpoint is appended once. The inner octahedron is cut along the diagonal
/// between the midpoints of edges ac and bd of each tetrahedron [a, b, c, d]; every child
/// keeps the parent's orientation. Invalid indices are an error naming the tetrahedron.
pub fn split_tets(mesh: &TetMesh) -> Result<TetMesh, MeshError> {
    mesh.validate_indices()?;
    let mut vertices = mesh.vertices.clone();
    let mut mids: HashMap<(u32, u32), u32> = HashMap::new();
    let mut mid = |a: u32, b: u32, vertices: &mut Vec<_>| {
        *mids.entry((a.min(b), a.max(b))).or_insert_with(|| {
            let p = (vertices[a as usize] + vertices[b as usize]) * 0.5;
            vertices.push(p);
            (vertices.len() - 1) as u32
        })
    };
    let mut tets = Vec::with_capacity(8 * mesh.tets.len());
    for &[a, b, c, d] in &mesh.tets {
        let ab = mid(a, b, &mut vertices);
        let ac = mid(a, c, &mut vertices);
        let ad = mid(a, d, &mut vertices);
        let bc = mid(b, c, &mut vertices);
        let bd = mid(b, d, &mut vertices);
        let cd = mid(c, d, &mut vertices);
        for t in [
            [a, ab, ac, ad],
            [ab, b, bc, bd],
            [ac, bc, c, cd],
            [ad, bd, cd, d],
            [ac, bd, ab, bc],
            [ac, bd, bc, cd],
            [ac, bd, cd, ad],
            [ac, bd, ad, ab],
        ] {
            let [p, q, r, s] = t.map(|v| vertices[v as usize]);
            let parent = tet_signed_volume(
                vertices[a as usize],
                vertices[b as usize],
                vertices[c as usize],
                vertices[d as usize],
            );
            // The octahedron's children come out with either orientation.
            let flip = (tet_signed_volume(p, q, r, s) < 0.0) != (parent < 0.0);
            tets.push(if flip { [t[0], t[1], t[3], t[2]] } else { t });
        }
    }
    Ok(TetMesh::new(vertices, tets))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Real, Vec3};
    use crate::mesh::generate::{BoxSplit, box_tets};
    use crate::mesh::{MeshData, tet_quality};

    fn volume(m: &TetMesh) -> Real {
        (0..m.tets.len())
            .map(|t| {
                let [a, b, c, d] = m.corners(t);
                tet_signed_volume(a, b, c, d)
            })
            .sum()
    }

    #[test]
    fn eight_children_fill_each_parent() {
        let m = box_tets(
            Vec3::ZERO,
            Vec3::new(0.03, 0.02, 0.01),
            [3, 2, 1],
            BoxSplit::Six,
        );
        let r = split_tets(&m).unwrap();
        let edges: std::collections::HashSet<(u32, u32)> = m
            .tets
            .iter()
            .flat_map(|t| {
                [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
                    .map(|(i, j)| (t[i].min(t[j]), t[i].max(t[j])))
            })
            .collect();
        assert_eq!(r.tets.len(), 8 * m.tets.len());
        assert_eq!(r.vertices.len(), m.vertices.len() + edges.len());
        assert_eq!(r.vertices[..m.vertices.len()], m.vertices[..]);
        // Same volume, every child positive with an eighth of its parent's volume.
        assert!((volume(&r) - 0.03 * 0.02 * 0.01).abs() < 1e-18);
        for (p, kids) in m.tets.iter().enumerate().zip(r.tets.chunks(8)) {
            let [a, b, c, d] = m.corners(p.0);
            let v = tet_signed_volume(a, b, c, d);
            for k in kids {
                let [p, q, r2, s] = k.map(|i| r.vertices[i as usize]);
                let vk = tet_signed_volume(p, q, r2, s);
                assert!((vk - v / 8.0).abs() < 1e-12 * v, "{vk} vs {}", v / 8.0);
            }
        }
        // The boundary is refined 1 -> 4 and stays closed.
        let s0 = MeshData::from_tets(&m).surface_mesh().unwrap();
        let s1 = MeshData::from_tets(&r).surface_mesh().unwrap();
        assert_eq!(s1.triangles.len(), 4 * s0.triangles.len());
        assert!((s1.signed_volume() - s0.signed_volume()).abs() < 1e-18);
    }

    #[test]
    fn quality_does_not_collapse_and_bad_indices_are_named() {
        let m = box_tets(Vec3::ZERO, Vec3::ONE, [2, 2, 2], BoxSplit::Six);
        let worst = |m: &TetMesh| {
            (0..m.tets.len())
                .map(|t| {
                    let [a, b, c, d] = m.corners(t);
                    tet_quality(a, b, c, d)
                })
                .fold(Real::INFINITY, Real::min)
        };
        let (q0, r) = (worst(&m), split_tets(&m).unwrap());
        let q2 = worst(&split_tets(&r).unwrap());
        // Bey's refinement keeps a bounded number of shape classes: quality stops dropping.
        assert!(
            worst(&r) > 0.5 * q0 && q2 > 0.5 * q0,
            "{q0} {} {q2}",
            worst(&r)
        );
        let bad = TetMesh::new(m.vertices.clone(), vec![[0, 1, 2, 99]]);
        let e = split_tets(&bad).unwrap_err().to_string();
        assert!(e.contains("tetrahedron 0") && e.contains("99"), "{e}");
    }
}
