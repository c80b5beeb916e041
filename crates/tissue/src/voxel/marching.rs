//! A surface from the voxels when none was given (an image): the 0.5 level set of the
//! occupancy, linearly interpolated over a tetrahedral split of the lattice of voxel
//! centres (marching tetrahedra, the table-free form of marching cubes).
//!
//! Each lattice cube (eight neighbouring centres) is split into six tetrahedra along its
//! main diagonal (the Kuhn split: the same diagonal in every cube, so neighbouring cubes
//! split their shared faces alike and the surface is closed). In a tetrahedron with both
//! occupied and empty corners the level set is one triangle (one corner differs) or a quad
//! (two and two); its vertices are the midpoints of the occupied-empty edges, shared
//! between tetrahedra by edge. Voxels beyond the grid count as empty, so the surface is
//! closed even where the object touches the grid's border. Triangles face outward.

use std::collections::HashMap;

use crate::math::Vec3;
use crate::mesh::SurfaceMesh;

use super::VoxelGrid;

/// The closed, outward surface of the occupied voxels (empty if none is occupied).
pub fn marching_surface(grid: &VoxelGrid) -> SurfaceMesh {
    let [nx, ny, nz] = grid.dims.map(|d| d as i64);
    let occupied = |p: [i64; 3]| {
        p.iter().all(|&c| c >= 0)
            && p[0] < nx
            && p[1] < ny
            && p[2] < nz
            && grid.is_occupied((p[0] + nx * (p[1] + ny * p[2])) as usize)
    };
    let centre =
        |p: [i64; 3]| grid.origin + Vec3::new(p[0] as f64, p[1] as f64, p[2] as f64) * grid.spacing;
    // The six Kuhn tetrahedra: paths from corner 0 to corner 7 through the axis orders.
    const ORDERS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut by_edge: HashMap<([i64; 3], [i64; 3]), u32> = HashMap::new();
    let mut vertex_on = |a: [i64; 3], b: [i64; 3], vertices: &mut Vec<Vec3>| {
        let key = if a < b { (a, b) } else { (b, a) };
        *by_edge.entry(key).or_insert_with(|| {
            vertices.push((centre(a) + centre(b)) * 0.5);
            (vertices.len() - 1) as u32
        })
    };
    for k in -1..nz {
        for j in -1..ny {
            for i in -1..nx {
                let base = [i, j, k];
                let cube_has =
                    (0..8).map(|c| occupied([i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)]));
                let count = cube_has.filter(|&x| x).count();
                if count == 0 || count == 8 {
                    continue;
                }
                for order in ORDERS {
                    let mut corners = [base; 4];
                    for s in 0..3 {
                        corners[s + 1] = corners[s];
                        corners[s + 1][order[s]] += 1;
                    }
                    let (inside, outside): (Vec<[i64; 3]>, Vec<[i64; 3]>) =
                        corners.iter().partition(|&&p| occupied(p));
                    let poly: Vec<u32> = match (inside.len(), outside.len()) {
                        (1, 3) | (3, 1) => {
                            let (one, three) = if inside.len() == 1 {
                                (inside[0], &outside)
                            } else {
                                (outside[0], &inside)
                            };
                            three
                                .iter()
                                .map(|&p| vertex_on(one, p, &mut vertices))
                                .collect()
                        }
                        (2, 2) => vec![
                            vertex_on(inside[0], outside[0], &mut vertices),
                            vertex_on(inside[0], outside[1], &mut vertices),
                            vertex_on(inside[1], outside[1], &mut vertices),
                            vertex_on(inside[1], outside[0], &mut vertices),
                        ],
                        _ => continue,
                    };
                    // Outward: along the direction from the occupied to the empty corners.
                    let dir = outside.iter().map(|&p| centre(p)).sum::<Vec3>()
                        / outside.len() as f64
                        - inside.iter().map(|&p| centre(p)).sum::<Vec3>() / inside.len() as f64;
                    for t in 1..poly.len() - 1 {
                        let tri = [poly[0], poly[t], poly[t + 1]];
                        let [a, b, c] = tri.map(|v| vertices[v as usize]);
                        let n = (b - a).cross(c - a);
                        triangles.push(if n.dot(dir) >= 0.0 {
                            tri
                        } else {
                            [tri[0], tri[2], tri[1]]
                        });
                    }
                }
            }
        }
    }
    SurfaceMesh::new(vertices, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::topology::{edge_faces, euler_characteristic};

    #[test]
    fn a_voxel_box_gives_a_closed_outward_sphere_like_surface() {
        let g = VoxelGrid::filled([4, 3, 5], 0.1);
        let s = marching_surface(&g);
        let ef = edge_faces(&s.triangles);
        assert_eq!(ef.border_edges().count(), 0);
        assert_eq!(ef.non_manifold_edges().count(), 0);
        assert_eq!(euler_characteristic(&s.triangles), 2);
        // Between the box of the centres and the box of the voxel faces.
        let v = s.signed_volume();
        assert!(v > 0.3 * 0.2 * 0.4 && v < g.volume(), "{v}");
    }

    #[test]
    fn a_single_voxel_and_two_parts() {
        let mut g = VoxelGrid::new([5, 1, 1], Vec3::ONE, Vec3::ZERO);
        g.labels[0] = 1;
        g.labels[4] = 1;
        let s = marching_surface(&g);
        assert_eq!(euler_characteristic(&s.triangles), 4);
        assert!(s.signed_volume() > 0.0);
    }
}
