//! The legacy writer: ASCII unstructured grid.

use std::fmt::Write;

use super::encode_name;
use crate::mesh::MeshData;

/// Writes an ASCII unstructured grid (version 4.2 layout): triangles, tetrahedra and 10-node
/// tetrahedra, a `tag` cell scalar when the mesh has tags, and the point fields (1, 2 or 4
/// components as SCALARS, 3 as VECTORS, others as a FIELD array).
pub fn encode(mesh: &MeshData) -> Result<Vec<u8>, String> {
    let n = mesh.vertices.len();
    let cells = mesh.triangles.len() + mesh.tets.len() + mesh.tets10.len();
    let size = 4 * mesh.triangles.len() + 5 * mesh.tets.len() + 11 * mesh.tets10.len();
    let mut out = format!(
        "# vtk DataFile Version 4.2\ntissue mesh\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {n} double\n"
    );
    for p in &mesh.vertices {
        let _ = writeln!(out, "{:?} {:?} {:?}", p.x, p.y, p.z);
    }
    let _ = writeln!(out, "CELLS {cells} {size}");
    let conn = mesh
        .triangles
        .iter()
        .map(|t| &t[..])
        .chain(mesh.tets.iter().map(|t| &t[..]))
        .chain(mesh.tets10.iter().map(|t| &t[..]));
    for c in conn {
        let _ = write!(out, "{}", c.len());
        for v in c {
            let _ = write!(out, " {v}");
        }
        out.push('\n');
    }
    let _ = writeln!(out, "CELL_TYPES {cells}");
    for (ty, k) in [
        (5, mesh.triangles.len()),
        (10, mesh.tets.len()),
        (24, mesh.tets10.len()),
    ] {
        for _ in 0..k {
            let _ = writeln!(out, "{ty}");
        }
    }
    if !mesh.triangle_tags.is_empty() || !mesh.tet_tags.is_empty() {
        let _ = writeln!(
            out,
            "CELL_DATA {cells}\nSCALARS tag int 1\nLOOKUP_TABLE default"
        );
        for (tags, k) in [
            (&mesh.triangle_tags, mesh.triangles.len()),
            (&mesh.tet_tags, mesh.tets.len()),
        ] {
            for i in 0..k {
                let _ = writeln!(out, "{}", tags.get(i).copied().unwrap_or(0));
            }
        }
        for _ in 0..mesh.tets10.len() {
            out.push_str("0\n");
        }
    }
    if !mesh.point_data.is_empty() {
        let _ = writeln!(out, "POINT_DATA {n}");
    }
    for f in &mesh.point_data {
        if f.components == 0 || Some(f.values.len()) != f.components.checked_mul(n) {
            return Err(format!(
                "field `{}` has {} values, expected {} components x {n} vertices",
                f.name,
                f.values.len(),
                f.components
            ));
        }
        let name = encode_name(&f.name);
        match f.components {
            3 => {
                let _ = writeln!(out, "VECTORS {name} double");
            }
            1 | 2 | 4 => {
                let _ = writeln!(
                    out,
                    "SCALARS {name} double {}\nLOOKUP_TABLE default",
                    f.components
                );
            }
            k => {
                let _ = writeln!(out, "FIELD FieldData 1\n{name} {k} {n} double");
            }
        }
        for row in f.values.chunks(f.components) {
            let line: Vec<String> = row.iter().map(|v| format!("{v:?}")).collect();
            let _ = writeln!(out, "{}", line.join(" "));
        }
    }
    Ok(out.into_bytes())
}
