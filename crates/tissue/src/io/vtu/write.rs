//! The `.vtu` writer: ascii, inline base64, or (for round-trip tests and compact output)
//! appended raw data, optionally zlib-compressed as ParaView writes it.

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

/// How array data is stored.
enum Mode {
    Ascii,
    Base64,
    /// Raw bytes collected for `<AppendedData>`; compressed in zlib blocks when asked.
    Appended {
        data: Vec<u8>,
        compress: bool,
    },
}

/// VTK's default block size for compressed arrays.
const BLOCK: usize = 1 << 15;

/// The header and blocks of a zlib-compressed array (UInt64 header words).
fn compress(raw: &[u8]) -> Vec<u8> {
    use std::io::Write as _;
    let blocks: Vec<Vec<u8>> = raw
        .chunks(BLOCK)
        .map(|c| {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            // Writing to a Vec cannot fail.
            let _ = z.write_all(c);
            z.finish().unwrap_or_default()
        })
        .collect();
    let mut out = Vec::new();
    for w in [blocks.len(), BLOCK, raw.len() % BLOCK]
        .into_iter()
        .chain(blocks.iter().map(Vec::len))
    {
        out.extend((w as u64).to_le_bytes());
    }
    blocks.iter().for_each(|b| out.extend(b));
    out
}

fn data_array(
    out: &mut String,
    ty: &str,
    name: &str,
    components: usize,
    values: Values<'_>,
    mode: &mut Mode,
) {
    let _ = write!(
        out,
        "        <DataArray type=\"{ty}\" Name=\"{}\"",
        quick_xml::escape::escape(name)
    );
    if components != 1 {
        let _ = write!(out, " NumberOfComponents=\"{components}\"");
    }
    let mut raw: Vec<u8> = Vec::new();
    if !matches!(mode, Mode::Ascii) {
        match &values {
            Values::F64(v) => v.iter().for_each(|x| raw.extend(x.to_le_bytes())),
            Values::I64(v) => v.iter().for_each(|x| raw.extend(x.to_le_bytes())),
            Values::I32(v) => v.iter().for_each(|x| raw.extend(x.to_le_bytes())),
            Values::U8(v) => raw.extend_from_slice(v),
        }
    }
    if let Mode::Appended { data, compress: z } = mode {
        let _ = writeln!(out, " format=\"appended\" offset=\"{}\"/>", data.len());
        if *z {
            data.extend(compress(&raw));
        } else {
            data.extend((raw.len() as u64).to_le_bytes());
            data.extend(raw);
        }
        return;
    }
    let binary = matches!(mode, Mode::Base64);
    let _ = writeln!(
        out,
        " format=\"{}\">",
        if binary { "binary" } else { "ascii" }
    );
    if binary {
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
    let mode = if binary { Mode::Base64 } else { Mode::Ascii };
    write(mesh, mode, false)
}

/// Writes a `.vtp` polygon data file of the mesh's triangles (Int32 `tag` cell data when
/// they have tags); the caller passes a surface (a volume's tetrahedra are not written).
pub fn encode_poly(mesh: &MeshData, binary: bool) -> Result<Vec<u8>, String> {
    let mode = if binary { Mode::Base64 } else { Mode::Ascii };
    write(mesh, mode, true)
}

/// Writes a `.vtu` with all arrays in one raw `<AppendedData>` section (UInt64 headers), as
/// ParaView does by default; `compress` zlib-compresses each array in 32 KiB blocks.
pub fn encode_appended(mesh: &MeshData, compress: bool) -> Result<Vec<u8>, String> {
    write(
        mesh,
        Mode::Appended {
            data: Vec::new(),
            compress,
        },
        false,
    )
}

fn write(mesh: &MeshData, mut mode: Mode, poly: bool) -> Result<Vec<u8>, String> {
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
    let (tets, tets10): (&[[u32; 4]], &[[u32; 10]]) = if poly {
        (&[], &[])
    } else {
        (&mesh.tets, &mesh.tets10)
    };
    let cells: Vec<&[u32]> = mesh
        .triangles
        .iter()
        .map(|t| &t[..])
        .chain(tets.iter().map(|t| &t[..]))
        .chain(tets10.iter().map(|t| &t[..]))
        .collect();
    let kind = if poly { "PolyData" } else { "UnstructuredGrid" };
    let compressor = match mode {
        Mode::Appended { compress: true, .. } => " compressor=\"vtkZLibDataCompressor\"",
        _ => "",
    };
    let mut out = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"{kind}\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\"{compressor}>\n  <{kind}>\n",
    );
    if poly {
        let _ = writeln!(
            out,
            "    <Piece NumberOfPoints=\"{n}\" NumberOfVerts=\"0\" NumberOfLines=\"0\" NumberOfStrips=\"0\" NumberOfPolys=\"{}\">",
            cells.len()
        );
    } else {
        let _ = writeln!(
            out,
            "    <Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{}\">",
            cells.len()
        );
    }
    out.push_str("      <PointData>\n");
    for f in &mesh.point_data {
        data_array(
            &mut out,
            "Float64",
            &f.name,
            f.components,
            Values::F64(&f.values),
            &mut mode,
        );
    }
    out.push_str("      </PointData>\n      <CellData>\n");
    if !mesh.triangle_tags.is_empty() || !mesh.tet_tags.is_empty() {
        let tag = |t: &[i32], i| t.get(i).copied().unwrap_or(0);
        let tags: Vec<i32> = (0..mesh.triangles.len())
            .map(|i| tag(&mesh.triangle_tags, i))
            .chain((0..tets.len()).map(|i| tag(&mesh.tet_tags, i)))
            .chain(std::iter::repeat_n(0, tets10.len()))
            .collect();
        data_array(&mut out, "Int32", "tag", 1, Values::I32(tags), &mut mode);
    }
    out.push_str("      </CellData>\n      <Points>\n");
    data_array(
        &mut out,
        "Float64",
        "Points",
        3,
        Values::F64(crate::math::flatten(&mesh.vertices)),
        &mut mode,
    );
    out.push_str(if poly {
        "      </Points>\n      <Polys>\n"
    } else {
        "      </Points>\n      <Cells>\n"
    });
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
        &mut mode,
    );
    data_array(
        &mut out,
        "Int64",
        "offsets",
        1,
        Values::I64(offsets),
        &mut mode,
    );
    if poly {
        out.push_str("      </Polys>\n    </Piece>\n  </PolyData>\n");
    } else {
        data_array(&mut out, "UInt8", "types", 1, Values::U8(types), &mut mode);
        out.push_str("      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n");
    }
    let mut bytes = out.into_bytes();
    if let Mode::Appended { data, .. } = mode {
        bytes.extend(b"  <AppendedData encoding=\"raw\">\n   _");
        bytes.extend(data);
        bytes.extend(b"\n  </AppendedData>\n");
    }
    bytes.extend(b"</VTKFile>\n");
    Ok(bytes)
}
