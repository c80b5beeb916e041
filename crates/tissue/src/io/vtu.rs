//! VTK XML unstructured grids (`.vtu`): read ascii and inline base64 (`format="binary"`,
//! uncompressed) data arrays of any numeric type, either byte order and header size; write
//! ascii or base64 files that ParaView opens.
//!
//! Cells kept are those of the legacy reader (see `vtk`): triangles, quads and polygons
//! (split), tetrahedra and quadratic tetrahedra. PointData arrays become fields; an integer
//! CellData array named like a tag becomes the element tags. Compressed or appended data is
//! refused with an error naming the file and line.

use std::fmt::Write;
use std::path::Path;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};

use super::vtk::{is_tag_name, pick_tags};
use crate::error::{IoError, Location};
use crate::math::Vec3;
use crate::mesh::{Field, MeshData};

/// Where a data array sits.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Section {
    Points,
    Cells,
    PointData,
    CellData,
    Other,
}

/// The attributes of a `<DataArray>` and where it starts.
struct Head {
    section: Section,
    name: String,
    ty: String,
    components: usize,
    binary: bool,
    at: usize,
}

struct Array {
    head: Head,
    values: Vec<f64>,
}

struct Parser<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    big_endian: bool,
    header64: bool,
    piece: Option<(usize, usize, usize)>,
    arrays: Vec<Array>,
}

impl Parser<'_> {
    fn line_of(&self, at: usize) -> usize {
        1 + self
            .bytes
            .get(..at)
            .unwrap_or(self.bytes)
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    }

    fn error(&self, at: usize, message: impl Into<String>) -> IoError {
        IoError::new(self.path, Location::Line(self.line_of(at)), message)
    }

    fn attrs(&self, e: &BytesStart<'_>, at: usize) -> Result<Vec<(String, String)>, IoError> {
        let mut out = Vec::new();
        for a in e.attributes() {
            let a = a.map_err(|err| self.error(at, format!("bad XML attribute: {err}")))?;
            let key = String::from_utf8_lossy(a.key.local_name().as_ref()).into_owned();
            let value = a
                .unescape_value()
                .map_err(|err| self.error(at, format!("bad XML attribute `{key}`: {err}")))?;
            out.push((key, value.into_owned()));
        }
        Ok(out)
    }

    fn open(
        &mut self,
        e: &BytesStart<'_>,
        at: usize,
        parent: Option<&str>,
    ) -> Result<Option<Head>, IoError> {
        let name = String::from_utf8_lossy(e.local_name().as_ref()).into_owned();
        let attrs = self.attrs(e, at)?;
        let get = |k: &str| attrs.iter().find(|(a, _)| a == k).map(|(_, v)| v.as_str());
        match name.as_str() {
            "VTKFile" => {
                if get("type") != Some("UnstructuredGrid") {
                    return Err(self.error(
                        at,
                        format!(
                            "VTKFile type `{}` is not supported: only UnstructuredGrid",
                            get("type").unwrap_or("")
                        ),
                    ));
                }
                if let Some(c) = get("compressor").filter(|c| !c.is_empty()) {
                    return Err(self.error(at, format!("compressed data ({c}) is not supported; save uncompressed (ascii or binary)")));
                }
                self.big_endian = get("byte_order") == Some("BigEndian");
                self.header64 = match get("header_type") {
                    None | Some("UInt32") => false,
                    Some("UInt64") => true,
                    Some(o) => {
                        return Err(self.error(at, format!("header_type `{o}` is not supported")));
                    }
                };
            }
            "Piece" => {
                if self.piece.is_some() {
                    return Err(self.error(at, "several Pieces are not supported"));
                }
                let count = |k: &str| -> Result<usize, IoError> {
                    let v = get(k).unwrap_or("");
                    v.trim().parse().map_err(|_| {
                        self.error(at, format!("Piece {k} should be a count, found `{v}`"))
                    })
                };
                self.piece = Some((count("NumberOfPoints")?, count("NumberOfCells")?, at));
            }
            "AppendedData" => {
                return Err(self.error(
                    at,
                    "appended data is not supported; save with ascii or binary (inline) data",
                ));
            }
            "DataArray" => {
                let section = match parent {
                    Some("Points") => Section::Points,
                    Some("Cells") => Section::Cells,
                    Some("PointData") => Section::PointData,
                    Some("CellData") => Section::CellData,
                    _ => Section::Other,
                };
                let binary = match get("format").unwrap_or("ascii") {
                    "ascii" => false,
                    "binary" => true,
                    "appended" => {
                        return Err(self.error(at, "appended data is not supported; save with ascii or binary (inline) data"));
                    }
                    o => return Err(self.error(at, format!("unknown DataArray format `{o}`"))),
                };
                let components = match get("NumberOfComponents") {
                    None => 1,
                    Some(v) => v
                        .trim()
                        .parse()
                        .ok()
                        .filter(|&k: &usize| k > 0)
                        .ok_or_else(|| {
                            self.error(
                                at,
                                format!(
                                    "NumberOfComponents should be a positive count, found `{v}`"
                                ),
                            )
                        })?,
                };
                let ty = get("type").unwrap_or("").to_string();
                if type_size(&ty).is_none() {
                    return Err(self.error(at, format!("unsupported DataArray type `{ty}`")));
                }
                return Ok(Some(Head {
                    section,
                    name: get("Name").unwrap_or("").to_string(),
                    ty,
                    components,
                    binary,
                    at,
                }));
            }
            _ => {}
        }
        Ok(None)
    }

    fn decode(&self, head: &Head, text: &[u8]) -> Result<Vec<f64>, IoError> {
        let size = type_size(&head.ty).unwrap_or(8);
        if !head.binary {
            let text = std::str::from_utf8(text)
                .map_err(|_| self.error(head.at, "the data is not UTF-8 text"))?;
            return text
                .split_ascii_whitespace()
                .map(|t| {
                    t.parse::<f64>().map_err(|_| {
                        self.error(
                            head.at,
                            format!("DataArray `{}`: expected a number, found `{t}`", head.name),
                        )
                    })
                })
                .collect();
        }
        let clean: Vec<u8> = text
            .iter()
            .copied()
            .filter(|b| !b.is_ascii_whitespace())
            .collect();
        let hsize: usize = if self.header64 { 8 } else { 4 };
        // Uncompressed data is one base64 stream of header and data; some writers encode the
        // header on its own, leaving padding in the middle.
        let raw = match STANDARD.decode(&clean) {
            Ok(r) => r,
            Err(first) => {
                let split = hsize.div_ceil(3) * 4;
                let (h, d) = clean.split_at(split.min(clean.len()));
                match (STANDARD.decode(h), STANDARD.decode(d)) {
                    (Ok(mut h), Ok(d)) if h.len() == hsize => {
                        h.extend(d);
                        h
                    }
                    _ => {
                        return Err(self.error(
                            head.at,
                            format!("DataArray `{}`: bad base64 data: {first}", head.name),
                        ));
                    }
                }
            }
        };
        let Some(header) = raw.get(..hsize) else {
            return Err(self.error(
                head.at,
                format!(
                    "DataArray `{}`: the binary data is shorter than its header",
                    head.name
                ),
            ));
        };
        let nbytes = decode_uint(header, self.big_endian);
        let data = usize::try_from(nbytes)
            .ok()
            .and_then(|n| raw.get(hsize..hsize.checked_add(n)?));
        let Some(data) = data.filter(|d| d.len() % size == 0) else {
            return Err(self.error(
                head.at,
                format!(
                    "DataArray `{}`: the header announces {nbytes} bytes of {} but {} follow",
                    head.name,
                    head.ty,
                    raw.len() - hsize
                ),
            ));
        };
        Ok(data
            .chunks_exact(size)
            .map(|b| decode_value(b, &head.ty, self.big_endian))
            .collect())
    }

    fn array(&self, section: Section, name: Option<&str>) -> Option<&Array> {
        self.arrays
            .iter()
            .find(|a| a.head.section == section && name.is_none_or(|n| a.head.name == n))
    }

    fn finish(self) -> Result<MeshData, IoError> {
        let Some((npts, ncells, piece_at)) = self.piece else {
            return Err(IoError::new(
                self.path,
                Location::File,
                "no <Piece> element: not an unstructured grid",
            ));
        };
        let count_error = |a: &Array, what: &str, need: usize| {
            self.error(
                a.head.at,
                format!(
                    "{what} has {} values, but the Piece needs {need}",
                    a.values.len()
                ),
            )
        };
        let points = match self.array(Section::Points, None) {
            Some(a) if a.values.len() == npts.saturating_mul(3) && a.head.components == 3 => a,
            Some(a) => return Err(count_error(a, "Points", npts.saturating_mul(3))),
            None if npts == 0 => &Array {
                head: Head {
                    section: Section::Points,
                    name: String::new(),
                    ty: String::new(),
                    components: 3,
                    binary: false,
                    at: 0,
                },
                values: Vec::new(),
            },
            None => return Err(self.error(piece_at, "the Piece has no Points")),
        };
        let mut mesh = MeshData {
            vertices: points
                .values
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect(),
            ..MeshData::default()
        };
        let cell_array = |name: &str| -> Result<&Array, IoError> {
            self.array(Section::Cells, Some(name))
                .ok_or_else(|| self.error(piece_at, format!("the Cells have no `{name}` array")))
        };
        let (conn, offsets, types) = if ncells == 0 {
            (Vec::new(), Vec::new(), Vec::new())
        } else {
            let (c, o, t) = (
                cell_array("connectivity")?,
                cell_array("offsets")?,
                cell_array("types")?,
            );
            for a in [o, t] {
                if a.values.len() != ncells {
                    return Err(count_error(a, &a.head.name, ncells));
                }
            }
            let index =
                |v: f64| (v >= 0.0 && v.fract() == 0.0 && (v as usize) < npts).then_some(v as u32);
            let conn: Vec<u32> = c
                .values
                .iter()
                .map(|&v| {
                    index(v).ok_or_else(|| {
                        self.error(
                            c.head.at,
                            format!(
                                "connectivity refers to point {v}, but the Piece has {npts} points"
                            ),
                        )
                    })
                })
                .collect::<Result<_, _>>()?;
            let mut prev = 0usize;
            let mut ends = Vec::with_capacity(ncells);
            for (k, &v) in o.values.iter().enumerate() {
                if !(v >= prev as f64 && v.fract() == 0.0 && v as usize <= conn.len()) {
                    return Err(self.error(
                        o.head.at,
                        format!(
                            "offset {k} = {v} is not increasing within the {} connectivity entries",
                            conn.len()
                        ),
                    ));
                }
                prev = v as usize;
                ends.push(prev);
            }
            let types = t
                .values
                .iter()
                .map(|&v| {
                    if (0.0..=255.0).contains(&v) {
                        v as u8
                    } else {
                        0
                    }
                })
                .collect();
            (conn, ends, types)
        };
        let mut tri_cells = Vec::new();
        let mut tet_cells = Vec::new();
        let mut start = 0usize;
        for (i, (&end, &ty)) in offsets.iter().zip(&types).enumerate() {
            let c = conn.get(start..end).unwrap_or(&[]);
            start = end;
            let need = match ty {
                5 => 3,
                9 | 10 => 4,
                24 => 10,
                _ => 0,
            };
            if need > 0 && c.len() != need {
                return Err(IoError::new(
                    self.path,
                    Location::Element(i),
                    format!(
                        "cell {i} of type {ty} needs {need} points, found {}",
                        c.len()
                    ),
                ));
            }
            match ty {
                5 | 7 | 9 => {
                    for w in c.get(1..).unwrap_or(&[]).windows(2) {
                        mesh.triangles.push([c[0], w[0], w[1]]);
                        tri_cells.push(i);
                    }
                }
                10 => {
                    mesh.tets.push([c[0], c[1], c[2], c[3]]);
                    tet_cells.push(i);
                }
                24 => {
                    let mut t = [0u32; 10];
                    t.copy_from_slice(c);
                    mesh.tets10.push(t);
                }
                _ => {}
            }
        }
        for a in self
            .arrays
            .iter()
            .filter(|a| a.head.section == Section::PointData)
        {
            if a.values.len() != npts.saturating_mul(a.head.components) {
                return Err(count_error(
                    a,
                    &format!("PointData `{}`", a.head.name),
                    npts.saturating_mul(a.head.components),
                ));
            }
            mesh.point_data.push(Field {
                name: a.head.name.clone(),
                components: a.head.components,
                values: a.values.clone(),
            });
        }
        let tag = self.arrays.iter().find(|a| {
            a.head.section == Section::CellData
                && a.head.components == 1
                && is_tag_name(&a.head.name)
                && !a.head.ty.starts_with("Float")
        });
        if let Some(a) = tag {
            if a.values.len() != ncells {
                return Err(count_error(
                    a,
                    &format!("CellData `{}`", a.head.name),
                    ncells,
                ));
            }
            let tags: Vec<i32> = a.values.iter().map(|&v| v as i32).collect();
            mesh.triangle_tags = pick_tags(&tags, &tri_cells);
            mesh.tet_tags = pick_tags(&tags, &tet_cells);
        }
        Ok(mesh)
    }
}

/// Reads a `.vtu` file.
pub fn parse(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let mut p = Parser {
        path,
        bytes,
        big_endian: false,
        header64: false,
        piece: None,
        arrays: Vec::new(),
    };
    let mut reader = Reader::from_reader(bytes);
    let mut stack: Vec<String> = Vec::new();
    let mut current: Option<Head> = None;
    let mut text: Vec<u8> = Vec::new();
    let mut seen_root = false;
    loop {
        let before = reader.buffer_position() as usize;
        let event = reader
            .read_event()
            .map_err(|e| p.error(reader.error_position() as usize, format!("XML error: {e}")))?;
        match event {
            Event::Start(e) | Event::Empty(e) if current.is_some() => {
                return Err(p.error(
                    before,
                    format!(
                        "unexpected <{}> inside a DataArray",
                        String::from_utf8_lossy(e.name().as_ref())
                    ),
                ));
            }
            Event::Start(e) => {
                if !seen_root && e.local_name().as_ref() != b"VTKFile" {
                    return Err(p.error(
                        before,
                        "not a VTK XML file: the root element is not <VTKFile>",
                    ));
                }
                seen_root = true;
                current = p.open(&e, before, stack.last().map(String::as_str))?;
                text.clear();
                stack.push(String::from_utf8_lossy(e.local_name().as_ref()).into_owned());
            }
            Event::Empty(e) => {
                if let Some(head) = p.open(&e, before, stack.last().map(String::as_str))? {
                    p.arrays.push(Array {
                        head,
                        values: Vec::new(),
                    });
                }
            }
            Event::Text(t) if current.is_some() => text.extend_from_slice(&t),
            Event::CData(t) if current.is_some() => text.extend_from_slice(&t),
            Event::GeneralRef(_) if current.is_some() => {
                return Err(p.error(before, "unexpected entity reference inside a DataArray"));
            }
            Event::End(_) => {
                stack.pop();
                if let Some(head) = current.take() {
                    let values = p.decode(&head, &text)?;
                    p.arrays.push(Array { head, values });
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if !seen_root {
        return Err(IoError::new(
            path,
            Location::File,
            "not a VTK XML file: no <VTKFile> element",
        ));
    }
    if let Some(open) = stack.last() {
        return Err(p.error(
            bytes.len(),
            format!("unexpected end of file inside <{open}>"),
        ));
    }
    p.finish()
}

fn type_size(ty: &str) -> Option<usize> {
    Some(match ty {
        "Int8" | "UInt8" => 1,
        "Int16" | "UInt16" => 2,
        "Int32" | "UInt32" | "Float32" => 4,
        "Int64" | "UInt64" | "Float64" => 8,
        _ => return None,
    })
}

fn decode_uint(b: &[u8], big: bool) -> u64 {
    let mut a = [0u8; 8];
    let n = b.len().min(8);
    if big {
        a[8 - n..].copy_from_slice(&b[..n]);
        u64::from_be_bytes(a)
    } else {
        a[..n].copy_from_slice(&b[..n]);
        u64::from_le_bytes(a)
    }
}

fn decode_value(b: &[u8], ty: &str, big: bool) -> f64 {
    let u = decode_uint(b, big);
    match ty {
        "Int8" => f64::from(u as u8 as i8),
        "Int16" => f64::from(u as u16 as i16),
        "Int32" => f64::from(u as u32 as i32),
        "Int64" => u as i64 as f64,
        "Float32" => f64::from(f32::from_bits(u as u32)),
        "Float64" => f64::from_bits(u),
        _ => u as f64,
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separately_encoded_header_and_big_endian() {
        // UInt32 big-endian header encoded apart from the data, as some writers do.
        let data: Vec<u8> = [1.5f32, -2.0, 0.25]
            .iter()
            .flat_map(|v| v.to_be_bytes())
            .collect();
        let header = STANDARD.encode(12u32.to_be_bytes());
        let body = STANDARD.encode(&data);
        let f = format!(
            "<VTKFile type=\"UnstructuredGrid\" byte_order=\"BigEndian\"><UnstructuredGrid>\
             <Piece NumberOfPoints=\"1\" NumberOfCells=\"0\"><Points>\
             <DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"binary\">{header}{body}</DataArray>\
             </Points></Piece></UnstructuredGrid></VTKFile>"
        );
        let m = parse(f.as_bytes(), Path::new("b.vtu")).unwrap();
        assert_eq!(m.vertices, vec![Vec3::new(1.5, -2.0, 0.25)]);
    }

    #[test]
    fn compressed_files_are_refused_by_line() {
        let f = "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" compressor=\"vtkZLibDataCompressor\">\n</VTKFile>";
        let e = parse(f.as_bytes(), Path::new("c.vtu")).unwrap_err();
        assert!(e.to_string().starts_with("c.vtu:2: compressed data"), "{e}");
    }
}
