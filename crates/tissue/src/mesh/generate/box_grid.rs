//! A box (or beam) of hexahedral cells, each split into 5 or 6 tetrahedra.

use crate::math::{Vec3, tet_signed_volume};
use crate::mesh::TetMesh;

/// How each hexahedral cell is split.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoxSplit {
    /// Five tetrahedra (four corners and a central one), mirrored in alternate cells so that
    /// the faces of neighbouring cells match.
    Five,
    /// Six tetrahedra around the cell's main diagonal (Kuhn split); conforming as is.
    Six,
}

/// A box from `min` to `max` with `cells[i]` cells along axis i, every tetrahedron positively
/// oriented. Vertex (i, j, k) of the grid has index i + (n0+1)·(j + (n1+1)·k).
pub fn box_tets(min: Vec3, max: Vec3, cells: [usize; 3], split: BoxSplit) -> TetMesh {
    let [nx, ny, nz] = cells.map(|c| c.max(1));
    let step = (max - min) / Vec3::new(nx as f64, ny as f64, nz as f64);
    let id = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
    let mut vertices = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                vertices.push(min + step * Vec3::new(i as f64, j as f64, k as f64));
            }
        }
    }
    // Cell corners: 0 (0,0,0) 1 (1,0,0) 2 (1,1,0) 3 (0,1,0) 4 (0,0,1) 5 (1,0,1) 6 (1,1,1) 7 (0,1,1).
    const SIX: [[usize; 4]; 6] = [
        [0, 1, 2, 6],
        [0, 1, 5, 6],
        [0, 4, 5, 6],
        [0, 4, 7, 6],
        [0, 3, 7, 6],
        [0, 3, 2, 6],
    ];
    const FIVE_EVEN: [[usize; 4]; 5] = [
        [0, 1, 3, 4],
        [2, 1, 3, 6],
        [5, 1, 4, 6],
        [7, 3, 4, 6],
        [1, 3, 4, 6],
    ];
    const FIVE_ODD: [[usize; 4]; 5] = [
        [1, 0, 2, 5],
        [3, 0, 2, 7],
        [4, 0, 5, 7],
        [6, 2, 5, 7],
        [0, 2, 5, 7],
    ];
    let mut tets = Vec::with_capacity(nx * ny * nz * if split == BoxSplit::Six { 6 } else { 5 });
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let c = [
                    id(i, j, k),
                    id(i + 1, j, k),
                    id(i + 1, j + 1, k),
                    id(i, j + 1, k),
                    id(i, j, k + 1),
                    id(i + 1, j, k + 1),
                    id(i + 1, j + 1, k + 1),
                    id(i, j + 1, k + 1),
                ];
                let pattern: &[[usize; 4]] = match split {
                    BoxSplit::Six => &SIX,
                    BoxSplit::Five if (i + j + k) % 2 == 0 => &FIVE_EVEN,
                    BoxSplit::Five => &FIVE_ODD,
                };
                for p in pattern {
                    let mut t = p.map(|q| c[q]);
                    let v = |n: u32| vertices[n as usize];
                    if tet_signed_volume(v(t[0]), v(t[1]), v(t[2]), v(t[3])) < 0.0 {
                        t.swap(2, 3);
                    }
                    tets.push(t);
                }
            }
        }
    }
    TetMesh::new(vertices, tets)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::boundary_surface;

    #[test]
    fn splits_fill_the_box_conformingly() {
        for split in [BoxSplit::Five, BoxSplit::Six] {
            let m = box_tets(Vec3::ZERO, Vec3::new(2.0, 1.0, 0.5), [4, 3, 2], split);
            assert!((0..m.tets.len()).all(|t| m.tet_volume(t) > 0.0));
            assert!((m.volume() - 1.0).abs() < 1e-12);
            // A conforming split has no interior face used once: the boundary encloses the box
            // and consists of 2 triangles per boundary quad.
            let b = boundary_surface(&m);
            assert_eq!(b.surface.triangles.len(), 2 * 2 * (4 * 3 + 3 * 2 + 4 * 2));
            assert!((b.surface.signed_volume() - 1.0).abs() < 1e-12);
        }
    }
}
