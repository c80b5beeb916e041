//! The `.vtu` writer.

use std::fmt::Write;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;

use crate::mesh::MeshData;

/// The numbers of one data array, in the type it is written as.
enum Values<'a> {
    F64(&'a [f64]),
    I64(Vec<i64>),
    I32(Vec<i32>),
    U8(Vec<u8>),
}

fn data_array(
    out: &mut String,
    ty: &str,
    name: &str,
    components: usize,
    values: Values<'_>,
    binary: bool,
) {
    let _ = write!(
        out,
        "        <DataArray type=\"{ty}\" Name=\"{}\"",
        quick_xml::escape::escape(name)
    );
    if components != 1 {
        let _ = write!(out, " NumberOfComponents=\"{components}\"");
    }
    let _ = writeln!(
        out,
        " format=\"{}\">",
        if binary { "binary" } else { "ascii" }
    );
    if binary {
        let mut raw: Vec<u8> = Vec::new();
        match &values {
            Values::F64(v) => v.iter().for_each(|x| raw.extend(x.to_le_bytes())),
            Values::I64(v) => v.iter().for_each(|x| raw.extend(x.to_le_bytes())),
            Values::I32(v) => v.iter().for_each(|x| raw.extend(x.to_le_bytes())),
            Values::U8(v) => raw.extend_from_slice(v),
        }
        let mut all = (raw.len() as u64).to_le_bytes().to_vec();
        all.extend(raw);
        let _ = writeln!(out, "          {}", STANDARD.encode(all));
    } else {
        let items: Vec<String> = match &values {
            Values::F64(v) => v.iter().map(|x| format!("{x:?}")).collect(),
            Values::I64(v) => v.iter().map(i64::to_string).collect(),
            Values::I32(v) => v.iter().map(i32::to_string).collect(),
            Values::U8(v) => v.iter().map(u8::to_string).collect(),
        };
        let per_line = if components > 1 { components } else { 12 };
        for row in items.chunks(per_line.max(1)) {
            let _ = writeln!(out, "          {}", row.join(" "));
        }
    }
    out.push_str("        </DataArray>\n");
}

/// Writes a `.vtu` unstructured grid (Float64 points, Int64 connectivity and offsets, UInt8
/// types, Int32 `tag` cell data when the mesh has tags), ascii or base64 with UInt64 headers.
pub fn encode(mesh: &MeshData, binary: bool) -> Result<Vec<u8>, String> {
    let n = mesh.vertices.len();
    for f in &mesh.point_data {
        if f.components == 0 || Some(f.values.len()) != f.components.checked_mul(n) {
            return Err(format!(
                "field `{}` has {} values, expected {} components x {n} vertices",
                f.name,
                f.values.len(),
                f.components
            ));
        }
    }
    let cells: Vec<&[u32]> = mesh
        .triangles
        .iter()
        .map(|t| &t[..])
        .chain(mesh.tets.iter().map(|t| &t[..]))
        .chain(mesh.tets10.iter().map(|t| &t[..]))
        .collect();
    let mut out = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n  <UnstructuredGrid>\n",
    );
    let _ = writeln!(
        out,
        "    <Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{}\">",
        cells.len()
    );
    out.push_str("      <PointData>\n");
    for f in &mesh.point_data {
        data_array(
            &mut out,
            "Float64",
            &f.name,
            f.components,
            Values::F64(&f.values),
            binary,
        );
    }
    out.push_str("      </PointData>\n      <CellData>\n");
    if !mesh.triangle_tags.is_empty() || !mesh.tet_tags.is_empty() {
        let tag = |t: &[i32], i| t.get(i).copied().unwrap_or(0);
        let tags: Vec<i32> = (0..mesh.triangles.len())
            .map(|i| tag(&mesh.triangle_tags, i))
            .chain((0..mesh.tets.len()).map(|i| tag(&mesh.tet_tags, i)))
            .chain(std::iter::repeat_n(0, mesh.tets10.len()))
            .collect();
        data_array(&mut out, "Int32", "tag", 1, Values::I32(tags), binary);
    }
    out.push_str("      </CellData>\n      <Points>\n");
    data_array(
        &mut out,
        "Float64",
        "Points",
        3,
        Values::F64(crate::math::flatten(&mesh.vertices)),
        binary,
    );
    out.push_str("      </Points>\n      <Cells>\n");
    let conn: Vec<i64> = cells
        .iter()
        .flat_map(|c| c.iter().map(|&v| i64::from(v)))
        .collect();
    let mut end = 0i64;
    let offsets: Vec<i64> = cells
        .iter()
        .map(|c| {
            end += c.len() as i64;
            end
        })
        .collect();
    let types: Vec<u8> = cells
        .iter()
        .map(|c| match c.len() {
            3 => 5,
            4 => 10,
            _ => 24,
        })
        .collect();
    data_array(
        &mut out,
        "Int64",
        "connectivity",
        1,
        Values::I64(conn),
        binary,
    );
    data_array(
        &mut out,
        "Int64",
        "offsets",
        1,
        Values::I64(offsets),
        binary,
    );
    data_array(&mut out, "UInt8", "types", 1, Values::U8(types), binary);
    out.push_str("      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n");
    Ok(out.into_bytes())
}
