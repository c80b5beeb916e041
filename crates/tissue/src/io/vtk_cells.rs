//! VTK cell types into `MeshData`: shared by the legacy (`.vtk`) and XML (`.vtu`) readers.

use crate::mesh::MeshData;

/// Triangles and tetrahedra read so far, with the cell each came from (to pick their tags).
#[derive(Default)]
pub(crate) struct CellSink {
    pub tri_cells: Vec<usize>,
    pub tet_cells: Vec<usize>,
}

impl CellSink {
    /// Adds cell `cell` of VTK type `ty` with point ids `c`: triangles, polygons and quads are
    /// fan-split, triangle strips (6) unrolled with every other triangle turned so that all
    /// keep the strip's orientation, tetrahedra (10) and quadratic tetrahedra (24, already in
    /// VTK order) kept, every other type skipped. The error says why the cell does not fit its type.
    pub fn add(
        &mut self,
        mesh: &mut MeshData,
        cell: usize,
        ty: u8,
        c: &[u32],
    ) -> Result<(), String> {
        let need = match ty {
            5 => 3,
            9 | 10 => 4,
            24 => 10,
            _ => 0,
        };
        if need > 0 && c.len() != need {
            return Err(format!(
                "cell {cell} of type {ty} needs {need} points, found {}",
                c.len()
            ));
        }
        match ty {
            5 | 7 | 9 => {
                for w in c.get(1..).unwrap_or(&[]).windows(2) {
                    mesh.triangles.push([c[0], w[0], w[1]]);
                    self.tri_cells.push(cell);
                }
            }
            6 => {
                for (i, w) in c.windows(3).enumerate() {
                    mesh.triangles.push(if i % 2 == 0 {
                        [w[0], w[1], w[2]]
                    } else {
                        [w[1], w[0], w[2]]
                    });
                    self.tri_cells.push(cell);
                }
            }
            10 => {
                mesh.tets.push([c[0], c[1], c[2], c[3]]);
                self.tet_cells.push(cell);
            }
            24 => {
                let mut t = [0u32; 10];
                t.copy_from_slice(c);
                mesh.tets10.push(t);
            }
            _ => {}
        }
        Ok(())
    }
}
