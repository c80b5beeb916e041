//! The legacy reader: header, then keyword sections, ascii tokens or big-endian binary blocks.

use std::path::Path;

use super::{decode_name, is_tag_name, pick_tags};
use crate::error::{IoError, Location};
use crate::io::cursor::Cursor;
use crate::io::vtk_cells::CellSink;
use crate::math::Vec3;
use crate::mesh::{Field, MeshData};

/// Reads a VTK legacy file.
pub fn parse(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let mut r = Reader::new(path, bytes);
    let magic = r.c.expect_line("the header `# vtk DataFile Version x.y`")?;
    let version = magic
        .strip_prefix("# vtk DataFile Version")
        .ok_or_else(|| {
            r.c.error("not a VTK legacy file: expected `# vtk DataFile Version x.y`")
        })?;
    let major: u32 = version
        .trim()
        .split('.')
        .next()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    r.c.next_line()?
        .ok_or_else(|| r.c.error("unexpected end of file, expected the title"))?;
    r.binary = match r
        .c
        .expect_line("ASCII or BINARY")?
        .to_ascii_uppercase()
        .as_str()
    {
        "ASCII" => false,
        "BINARY" => true,
        other => {
            return Err(r
                .c
                .error(format!("expected ASCII or BINARY, found `{other}`")));
        }
    };
    let l = r.c.expect_line("DATASET")?;
    let mut tok = l.split_ascii_whitespace();
    let kind = tok.nth(1).unwrap_or("").to_ascii_uppercase();
    if tok.next().is_some() || !l.to_ascii_uppercase().starts_with("DATASET ") {
        return Err(r.c.error(format!(
            "expected `DATASET UNSTRUCTURED_GRID` or `DATASET POLYDATA`, found `{l}`"
        )));
    }
    let poly = match kind.as_str() {
        "UNSTRUCTURED_GRID" => false,
        "POLYDATA" => true,
        other => {
            return Err(r.c.error(format!(
                "dataset `{other}` is not supported: only UNSTRUCTURED_GRID and POLYDATA"
            )));
        }
    };
    r.new_cells = major >= 5;
    r.sections(poly)?;
    r.finish(poly)
}

/// Which attribute block the data arrays belong to.
#[derive(Clone, Copy, PartialEq)]
enum Attach {
    None,
    Point,
    Cell,
}

/// A cell list as read: offsets into the connectivity, and the line that declared it.
#[derive(Default)]
struct CellArray {
    offsets: Vec<usize>,
    conn: Vec<u32>,
    line: usize,
}

impl CellArray {
    fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    fn cell(&self, i: usize) -> &[u32] {
        match (self.offsets.get(i), self.offsets.get(i + 1)) {
            (Some(&a), Some(&b)) => self.conn.get(a..b).unwrap_or(&[]),
            _ => &[],
        }
    }
}

struct Reader<'a> {
    c: Cursor<'a>,
    len: usize,
    /// Tokens of an ascii data line not yet used.
    pending: std::str::SplitAsciiWhitespace<'a>,
    binary: bool,
    new_cells: bool,
    points: Vec<Vec3>,
    cells: CellArray,
    types: Vec<u8>,
    types_line: usize,
    /// POLYDATA: (keyword, cells) in file order.
    poly: Vec<(String, CellArray)>,
    attach: Attach,
    point_data: Vec<Field>,
    tags: Option<Vec<i32>>,
}

impl<'a> Reader<'a> {
    fn new(path: &'a Path, bytes: &'a [u8]) -> Self {
        Self {
            c: Cursor::new(path, bytes),
            len: bytes.len(),
            pending: "".split_ascii_whitespace(),
            binary: false,
            new_cells: false,
            points: Vec::new(),
            cells: CellArray::default(),
            types: Vec::new(),
            types_line: 0,
            poly: Vec::new(),
            attach: Attach::None,
            point_data: Vec::new(),
            tags: None,
        }
    }

    fn remaining(&self) -> usize {
        self.len.saturating_sub(self.c.position())
    }

    /// The next keyword line; ascii values left over from the last array are an error.
    fn header(&mut self) -> Result<Option<&'a str>, IoError> {
        if let Some(t) = self.pending.next() {
            return Err(self.c.error(format!(
                "unexpected `{t}`: more values than the section declares"
            )));
        }
        self.c.next_nonblank()
    }

    fn expect_header(&mut self, what: &str) -> Result<&'a str, IoError> {
        self.header()?.ok_or_else(|| {
            self.c
                .error(format!("unexpected end of file, expected {what}"))
        })
    }

    /// `n` numbers of type `ty`, ascii or big-endian binary.
    fn values(&mut self, n: usize, ty: &str, what: &str) -> Result<Vec<f64>, IoError> {
        let size =
            type_size(ty).ok_or_else(|| self.c.error(format!("unsupported data type `{ty}`")))?;
        if self.binary {
            let bytes = self.c.take(n.saturating_mul(size))?;
            let v = bytes.chunks_exact(size).map(|b| decode_be(b, ty)).collect();
            self.c.skip_newline();
            return Ok(v);
        }
        let mut out = Vec::with_capacity(n.min(self.remaining() / 2 + 1));
        while out.len() < n {
            let t = match self.pending.next() {
                Some(t) => t,
                None => {
                    let l = self.c.next_nonblank()?.ok_or_else(|| {
                        self.c.error(format!(
                            "unexpected end of file: {what} has {} of {n} values",
                            out.len()
                        ))
                    })?;
                    self.pending = l.split_ascii_whitespace();
                    continue;
                }
            };
            let v: f64 = self.c.parse(t, what).map_err(|_| {
                self.c.error(format!(
                    "expected a number for {what} (value {} of {n}), found `{t}`",
                    out.len() + 1
                ))
            })?;
            out.push(v);
        }
        Ok(out)
    }

    fn count(&self, t: Option<&str>, what: &str) -> Result<usize, IoError> {
        self.c.parse(t.unwrap_or(""), what)
    }

    fn sections(&mut self, poly: bool) -> Result<(), IoError> {
        while let Some(l) = self.header()? {
            let mut tok = l.split_ascii_whitespace();
            let key = tok.next().unwrap_or("").to_ascii_uppercase();
            match key.as_str() {
                "POINTS" => {
                    let n = self.count(tok.next(), "the point count")?;
                    let ty = tok.next().unwrap_or("float");
                    let v = self.values(n.saturating_mul(3), ty, "POINTS")?;
                    self.points = v
                        .chunks_exact(3)
                        .map(|p| Vec3::new(p[0], p[1], p[2]))
                        .collect();
                }
                "CELLS" if !poly => {
                    let a = self.count(tok.next(), "the cell count")?;
                    let b = self.count(tok.next(), "the cell list size")?;
                    self.cells = self.cell_array(a, b, "CELLS")?;
                }
                "POLYGONS" | "VERTICES" | "LINES" | "TRIANGLE_STRIPS" if poly => {
                    let a = self.count(tok.next(), "the cell count")?;
                    let b = self.count(tok.next(), "the cell list size")?;
                    let cells = self.cell_array(a, b, &key)?;
                    self.poly.push((key, cells));
                }
                "CELL_TYPES" if !poly => {
                    let n = self.count(tok.next(), "the cell type count")?;
                    self.types_line = self.c.line();
                    let v = self.values(n, "int", "CELL_TYPES")?;
                    self.types = v
                        .iter()
                        .map(|&t| {
                            if (0.0..=255.0).contains(&t) {
                                t as u8
                            } else {
                                0
                            }
                        })
                        .collect();
                }
                "POINT_DATA" | "CELL_DATA" => {
                    let n = self.count(tok.next(), "the tuple count")?;
                    let point = key == "POINT_DATA";
                    let expected = if point {
                        self.points.len()
                    } else {
                        self.cell_count(poly)
                    };
                    if n != expected {
                        return Err(self.c.error(format!(
                            "{key} declares {n} tuples but the file has {expected} {}",
                            if point { "points" } else { "cells" }
                        )));
                    }
                    self.attach = if point { Attach::Point } else { Attach::Cell };
                }
                "METADATA" => self.skip_metadata()?,
                _ => self.attribute(&key, tok)?,
            }
        }
        Ok(())
    }

    fn cell_count(&self, poly: bool) -> usize {
        if poly {
            self.poly.iter().map(|(_, c)| c.len()).sum()
        } else {
            self.cells.len()
        }
    }

    /// A cell list: classic `n size` followed by `k i1..ik` per cell, or (version 5+)
    /// `offsets-count connectivity-count` followed by OFFSETS and CONNECTIVITY arrays.
    fn cell_array(&mut self, a: usize, b: usize, what: &str) -> Result<CellArray, IoError> {
        let line = self.c.line();
        let npts = self.points.len();
        let index = |r: &Self, v: f64| -> Result<u32, IoError> {
            if v >= 0.0 && v.fract() == 0.0 && (v as usize) < npts {
                Ok(v as u32)
            } else {
                Err(IoError::new(
                    r.c.path(),
                    Location::Line(line),
                    format!(
                        "{what} refers to point {v}, but the file has {npts} points (POINTS must come first)"
                    ),
                ))
            }
        };
        let mut cells = CellArray {
            line,
            ..CellArray::default()
        };
        if self.new_cells {
            let l = self.expect_header("OFFSETS")?;
            let mut t = l.split_ascii_whitespace();
            if !t.next().unwrap_or("").eq_ignore_ascii_case("OFFSETS") {
                return Err(self
                    .c
                    .error(format!("expected `OFFSETS type`, found `{l}`")));
            }
            let offsets = self.values(a, t.next().unwrap_or("vtktypeint64"), "OFFSETS")?;
            let l = self.expect_header("CONNECTIVITY")?;
            let mut t = l.split_ascii_whitespace();
            if !t.next().unwrap_or("").eq_ignore_ascii_case("CONNECTIVITY") {
                return Err(self
                    .c
                    .error(format!("expected `CONNECTIVITY type`, found `{l}`")));
            }
            let conn = self.values(b, t.next().unwrap_or("vtktypeint64"), "CONNECTIVITY")?;
            let mut prev = 0usize;
            for (k, &o) in offsets.iter().enumerate() {
                let ok = o >= 0.0
                    && o.fract() == 0.0
                    && o as usize >= prev
                    && o as usize <= b
                    && (k > 0 || o == 0.0);
                if !ok {
                    return Err(IoError::new(
                        self.c.path(),
                        Location::Line(line),
                        format!("{what}: offset {k} = {o} is not increasing within 0..={b}"),
                    ));
                }
                prev = o as usize;
            }
            if a > 0 && prev != b {
                return Err(IoError::new(
                    self.c.path(),
                    Location::Line(line),
                    format!(
                        "{what}: the last offset is {prev} but the connectivity has {b} entries"
                    ),
                ));
            }
            cells.offsets = offsets.iter().map(|&o| o as usize).collect();
            cells.conn = conn
                .iter()
                .map(|&v| index(self, v))
                .collect::<Result<_, _>>()?;
            return Ok(cells);
        }
        let list = self.values(b, "int", what)?;
        cells.offsets.reserve(a.min(b) + 1);
        cells.offsets.push(0);
        let mut at = 0usize;
        for k in 0..a {
            let Some(&n) = list.get(at) else {
                return Err(IoError::new(
                    self.c.path(),
                    Location::Line(line),
                    format!(
                        "{what} declares {a} cells in {b} values, but the values end after {k} cells"
                    ),
                ));
            };
            let n = if n >= 0.0 && n.fract() == 0.0 {
                n as usize
            } else {
                usize::MAX
            };
            let Some(ids) = list.get(at + 1..(at + 1).saturating_add(n)) else {
                return Err(IoError::new(
                    self.c.path(),
                    Location::Line(line),
                    format!(
                        "{what}: cell {k} declares {n} points but only {} values are left of the declared size {b}",
                        list.len() - at - 1
                    ),
                ));
            };
            for &v in ids {
                cells.conn.push(index(self, v)?);
            }
            at += 1 + n;
            cells.offsets.push(cells.conn.len());
        }
        if at != b {
            return Err(IoError::new(
                self.c.path(),
                Location::Line(line),
                format!("{what} declares a size of {b} values but its {a} cells use {at}"),
            ));
        }
        Ok(cells)
    }

    /// SCALARS, VECTORS, FIELD... of the current POINT_DATA or CELL_DATA block.
    fn attribute(
        &mut self,
        key: &str,
        mut tok: std::str::SplitAsciiWhitespace<'a>,
    ) -> Result<(), IoError> {
        let n = match self.attach {
            Attach::Point => self.points.len(),
            Attach::Cell => {
                self.cells.len() + self.poly.iter().map(|(_, c)| c.len()).sum::<usize>()
            }
            Attach::None => {
                return Err(self
                    .c
                    .error(format!("unknown or misplaced keyword `{key}`")));
            }
        };
        let name = decode_name(tok.next().unwrap_or(""));
        let (components, ty) = match key {
            "SCALARS" => {
                let ty = tok.next().unwrap_or("float").to_string();
                let k = match tok.next() {
                    Some(t) => self.c.parse(t, "the component count")?,
                    None => 1,
                };
                self.lookup_table_line()?;
                (k, ty)
            }
            "VECTORS" | "NORMALS" => (3, tok.next().unwrap_or("float").to_string()),
            "TENSORS" | "TENSORS6" => {
                let k = if key == "TENSORS" { 9 } else { 6 };
                (k, tok.next().unwrap_or("float").to_string())
            }
            "TEXTURE_COORDINATES" => {
                let k = self.count(tok.next(), "the dimension")?;
                (k, tok.next().unwrap_or("float").to_string())
            }
            "COLOR_SCALARS" => {
                let k = self.count(tok.next(), "the component count")?;
                (
                    k,
                    if self.binary {
                        "unsigned_char"
                    } else {
                        "float"
                    }
                    .to_string(),
                )
            }
            "LOOKUP_TABLE" => {
                let size = self.count(tok.next(), "the table size")?;
                let ty = if self.binary {
                    "unsigned_char"
                } else {
                    "float"
                };
                self.values(size.saturating_mul(4), ty, "LOOKUP_TABLE")?;
                return Ok(());
            }
            "FIELD" => {
                let arrays = self.count(tok.next(), "the array count")?;
                for _ in 0..arrays {
                    let l = self.expect_header("a field array `name components tuples type`")?;
                    let mut t = l.split_ascii_whitespace();
                    let name = decode_name(t.next().unwrap_or(""));
                    let k = self.count(t.next(), "the component count")?;
                    let tuples = self.count(t.next(), "the tuple count")?;
                    let ty = t.next().unwrap_or("float");
                    let v = self.values(k.saturating_mul(tuples), ty, &name)?;
                    if tuples == n {
                        self.store(name, k, ty, v);
                    }
                }
                return Ok(());
            }
            _ => return Err(self.c.error(format!("unknown keyword `{key}`"))),
        };
        let v = self.values(n.saturating_mul(components), &ty, &name)?;
        self.store(name, components, &ty, v);
        Ok(())
    }

    /// After SCALARS comes `LOOKUP_TABLE name`; some ascii writers leave it out, and then the
    /// line read is already data.
    fn lookup_table_line(&mut self) -> Result<(), IoError> {
        let l = self.expect_header("LOOKUP_TABLE or the values")?;
        if !l.to_ascii_uppercase().starts_with("LOOKUP_TABLE") {
            if self.binary {
                return Err(self.c.error("expected `LOOKUP_TABLE name` after SCALARS"));
            }
            self.pending = l.split_ascii_whitespace();
        }
        Ok(())
    }

    fn store(&mut self, name: String, components: usize, ty: &str, values: Vec<f64>) {
        match self.attach {
            Attach::Point if components > 0 => self.point_data.push(Field {
                name,
                components,
                values,
            }),
            Attach::Cell if components == 1 && is_tag_name(&name) && is_integer_type(ty) => {
                self.tags = Some(values.iter().map(|&v| v as i32).collect());
            }
            _ => {}
        }
    }

    /// METADATA ends at the first blank line.
    fn skip_metadata(&mut self) -> Result<(), IoError> {
        while let Some(l) = self.c.next_line()? {
            if l.trim().is_empty() {
                break;
            }
        }
        Ok(())
    }

    fn finish(self, poly: bool) -> Result<MeshData, IoError> {
        let mut mesh = MeshData {
            vertices: self.points,
            point_data: self.point_data,
            ..MeshData::default()
        };
        let mut sink = CellSink::default();
        let path = self.c.path();
        if poly {
            // VTK numbers polydata cells verts, lines, polygons, strips whatever the file order.
            let count = |k: &str| -> usize {
                self.poly
                    .iter()
                    .filter(|(n, _)| n == k)
                    .map(|(_, c)| c.len())
                    .sum()
            };
            let mut base = count("VERTICES") + count("LINES");
            for (_, cells) in self.poly.iter().filter(|(k, _)| k == "POLYGONS") {
                for i in 0..cells.len() {
                    // A polygon (type 7) never fails: any point count is fan-split.
                    let _ = sink.add(&mut mesh, base + i, 7, cells.cell(i));
                }
                base += cells.len();
            }
        } else {
            if self.types.len() != self.cells.len() {
                return Err(IoError::new(
                    path,
                    Location::Line(self.types_line.max(self.cells.line).max(1)),
                    format!(
                        "CELL_TYPES lists {} types but CELLS has {} cells",
                        self.types.len(),
                        self.cells.len()
                    ),
                ));
            }
            for (i, &ty) in self.types.iter().enumerate() {
                sink.add(&mut mesh, i, ty, self.cells.cell(i))
                    .map_err(|m| IoError::new(path, Location::Element(i), m))?;
            }
        }
        if let Some(tags) = self.tags {
            mesh.triangle_tags = pick_tags(&tags, &sink.tri_cells);
            mesh.tet_tags = pick_tags(&tags, &sink.tet_cells);
        }
        Ok(mesh)
    }
}

fn is_integer_type(ty: &str) -> bool {
    !matches!(ty.to_ascii_lowercase().as_str(), "float" | "double")
}

/// Bytes per value of a legacy data type.
fn type_size(ty: &str) -> Option<usize> {
    Some(match ty.to_ascii_lowercase().as_str() {
        "unsigned_char" | "char" => 1,
        "unsigned_short" | "short" => 2,
        "unsigned_int" | "int" | "float" => 4,
        "unsigned_long" | "long" | "vtktypeint64" | "vtktypeuint64" | "vtkidtype" | "double" => 8,
        _ => return None,
    })
}

fn decode_be(b: &[u8], ty: &str) -> f64 {
    let mut a = [0u8; 8];
    let n = b.len().min(8);
    a[8 - n..].copy_from_slice(&b[..n]);
    let u = u64::from_be_bytes(a);
    match (ty.to_ascii_lowercase().as_str(), n) {
        ("float", _) => f64::from(f32::from_bits(u as u32)),
        ("double", _) => f64::from_bits(u),
        ("char", _) => f64::from(u as u8 as i8),
        ("short", _) => f64::from(u as u16 as i16),
        ("int", _) => f64::from(u as u32 as i32),
        (t, 8) if !t.starts_with("unsigned") && t != "vtktypeuint64" => u as i64 as f64,
        _ => u as f64,
    }
}
