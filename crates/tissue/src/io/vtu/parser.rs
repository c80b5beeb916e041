//! The parts of a `.vtu` file as they are read: data arrays decoded to numbers, then the
//! mesh assembled from them with every count checked.

use std::path::Path;

use quick_xml::events::BytesStart;

use super::appended::Appended;
use super::type_size;
use crate::error::{IoError, Location};
use crate::io::vtk::{is_tag_name, pick_tags};
use crate::io::vtk_cells::CellSink;
use crate::math::Vec3;
use crate::mesh::{Field, MeshData};

/// Where a data array sits.
#[derive(Clone, Copy, PartialEq, Debug)]
pub(super) enum Section {
    Points,
    Cells,
    /// PolyData topology: polygons and triangle strips.
    Polys,
    Strips,
    PointData,
    CellData,
    Other,
}

/// How a data array's numbers are stored.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Format {
    Ascii,
    /// Inline base64.
    Binary,
    /// In `<AppendedData>`, at this offset after the `_`.
    Appended(usize),
}

/// The attributes of a `<DataArray>` and where it starts.
pub(super) struct Head {
    pub(super) section: Section,
    pub(super) name: String,
    pub(super) ty: String,
    pub(super) components: usize,
    pub(super) format: Format,
    pub(super) at: usize,
}

pub(super) struct Array {
    pub(super) head: Head,
    pub(super) values: Vec<f64>,
}

/// A `<Piece>`'s counts and where it starts. PolyData cells are numbered verts, lines,
/// polys, strips (VTK's order for their cell data).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Piece {
    pub(super) points: usize,
    /// UnstructuredGrid cells.
    pub(super) cells: usize,
    pub(super) verts: usize,
    pub(super) lines: usize,
    pub(super) polys: usize,
    pub(super) strips: usize,
    pub(super) at: usize,
}

impl Piece {
    fn total(&self) -> usize {
        self.cells + self.verts + self.lines + self.polys + self.strips
    }
}

pub(super) struct Parser<'a> {
    pub(super) path: &'a Path,
    pub(super) bytes: &'a [u8],
    pub(super) big_endian: bool,
    pub(super) header64: bool,
    pub(super) compressed: bool,
    pub(super) appended: Option<Appended<'a>>,
    /// Offsets of all appended arrays: the end of an appended base64 array is the next one.
    pub(super) offsets: Vec<usize>,
    /// A PolyData file (`.vtp`) rather than an UnstructuredGrid.
    pub(super) poly: bool,
    pub(super) piece: Option<Piece>,
    pub(super) arrays: Vec<Array>,
}

impl Parser<'_> {
    pub(super) fn line_of(&self, at: usize) -> usize {
        1 + self
            .bytes
            .get(..at)
            .unwrap_or(self.bytes)
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
    }

    pub(super) fn error(&self, at: usize, message: impl Into<String>) -> IoError {
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

    pub(super) fn open(
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
                self.poly = match get("type") {
                    Some("UnstructuredGrid") => false,
                    Some("PolyData") => true,
                    other => {
                        return Err(self.error(
                            at,
                            format!(
                                "VTKFile type `{}` is not supported: only UnstructuredGrid \
                                 (.vtu) and PolyData (.vtp)",
                                other.unwrap_or("")
                            ),
                        ));
                    }
                };
                self.compressed = match get("compressor").unwrap_or("") {
                    "" => false,
                    "vtkZLibDataCompressor" => true,
                    c => {
                        return Err(self.error(
                            at,
                            format!(
                                "compressor `{c}` is not supported; save with zlib compression or none"
                            ),
                        ));
                    }
                };
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
                let count = |k: &str, required: bool| -> Result<usize, IoError> {
                    match get(k) {
                        None if !required => Ok(0),
                        v => v.unwrap_or("").trim().parse().map_err(|_| {
                            self.error(
                                at,
                                format!("Piece {k} should be a count, found `{}`", v.unwrap_or("")),
                            )
                        }),
                    }
                };
                let poly = self.poly;
                self.piece = Some(Piece {
                    points: count("NumberOfPoints", true)?,
                    cells: if poly {
                        0
                    } else {
                        count("NumberOfCells", true)?
                    },
                    verts: if poly {
                        count("NumberOfVerts", false)?
                    } else {
                        0
                    },
                    lines: if poly {
                        count("NumberOfLines", false)?
                    } else {
                        0
                    },
                    polys: if poly {
                        count("NumberOfPolys", false)?
                    } else {
                        0
                    },
                    strips: if poly {
                        count("NumberOfStrips", false)?
                    } else {
                        0
                    },
                    at,
                });
            }
            "DataArray" => {
                let section = match parent {
                    Some("Points") => Section::Points,
                    Some("Cells") => Section::Cells,
                    Some("Polys") => Section::Polys,
                    Some("Strips") => Section::Strips,
                    Some("PointData") => Section::PointData,
                    Some("CellData") => Section::CellData,
                    _ => Section::Other,
                };
                let format = match get("format").unwrap_or("ascii") {
                    "ascii" => Format::Ascii,
                    "binary" => Format::Binary,
                    "appended" => {
                        let v = get("offset").unwrap_or("");
                        let offset = v.trim().parse().map_err(|_| {
                            self.error(
                                at,
                                format!("an appended DataArray needs an offset, found `{v}`"),
                            )
                        })?;
                        self.offsets.push(offset);
                        Format::Appended(offset)
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
                    // ParaView puts String arrays in FieldData and sometimes in point or
                    // cell data: they carry nothing a mesh needs, so only the geometry must
                    // be numeric.
                    if matches!(
                        section,
                        Section::Points | Section::Cells | Section::Polys | Section::Strips
                    ) {
                        return Err(self.error(at, format!("unsupported DataArray type `{ty}`")));
                    }
                    return Ok(None);
                }
                return Ok(Some(Head {
                    section,
                    name: get("Name").unwrap_or("").to_string(),
                    ty,
                    components,
                    format,
                    at,
                }));
            }
            _ => {}
        }
        Ok(None)
    }

    fn array(&self, section: Section, name: Option<&str>) -> Option<&Array> {
        self.arrays
            .iter()
            .find(|a| a.head.section == section && name.is_none_or(|n| a.head.name == n))
    }

    /// The connectivity and cell ends of `count` cells in `section`, every index checked.
    fn topology(
        &self,
        section: Section,
        count: usize,
        piece: &Piece,
    ) -> Result<(Vec<u32>, Vec<usize>), IoError> {
        if count == 0 {
            return Ok((Vec::new(), Vec::new()));
        }
        let npts = piece.points;
        let what = match section {
            Section::Polys => "Polys",
            Section::Strips => "Strips",
            _ => "Cells",
        };
        let array = |name: &str| -> Result<&Array, IoError> {
            self.array(section, Some(name))
                .ok_or_else(|| self.error(piece.at, format!("the {what} have no `{name}` array")))
        };
        let (c, o) = (array("connectivity")?, array("offsets")?);
        if o.values.len() != count {
            return Err(self.error(
                o.head.at,
                format!(
                    "{what} offsets has {} values, but the Piece needs {count}",
                    o.values.len()
                ),
            ));
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
        let mut ends = Vec::with_capacity(count);
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
        Ok((conn, ends))
    }

    pub(super) fn finish(self) -> Result<MeshData, IoError> {
        let Some(piece) = self.piece else {
            return Err(IoError::new(
                self.path,
                Location::File,
                "no <Piece> element: not an unstructured grid or polygon data",
            ));
        };
        let (npts, piece_at) = (piece.points, piece.at);
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
            Some(a) if a.head.components != 3 => {
                return Err(self.error(
                    a.head.at,
                    format!(
                        "Points has NumberOfComponents = {}, but points in space need 3",
                        a.head.components
                    ),
                ));
            }
            Some(a) => return Err(count_error(a, "Points", npts.saturating_mul(3))),
            None if npts == 0 => &Array {
                head: Head {
                    section: Section::Points,
                    name: String::new(),
                    ty: String::new(),
                    components: 3,
                    format: Format::Ascii,
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
        let mut sink = CellSink::default();
        let add = |sink: &mut CellSink, mesh: &mut MeshData, cell, ty, c: &[u32]| {
            sink.add(mesh, cell, ty, c)
                .map_err(|m| IoError::new(self.path, Location::Element(cell), m))
        };
        if self.poly {
            // Cell numbers run through verts and lines (skipped) before polys and strips.
            let first = piece.verts + piece.lines;
            for (section, count, ty, base) in [
                (Section::Polys, piece.polys, 7u8, first),
                (Section::Strips, piece.strips, 6u8, first + piece.polys),
            ] {
                let (conn, ends) = self.topology(section, count, &piece)?;
                let mut start = 0usize;
                for (k, &end) in ends.iter().enumerate() {
                    let c = conn.get(start..end).unwrap_or(&[]);
                    start = end;
                    add(&mut sink, &mut mesh, base + k, ty, c)?;
                }
            }
        } else {
            let ncells = piece.cells;
            let (conn, ends) = self.topology(Section::Cells, ncells, &piece)?;
            let types: Vec<u8> = if ncells == 0 {
                Vec::new()
            } else {
                let t = self
                    .array(Section::Cells, Some("types"))
                    .ok_or_else(|| self.error(piece_at, "the Cells have no `types` array"))?;
                if t.values.len() != ncells {
                    return Err(count_error(t, "types", ncells));
                }
                t.values
                    .iter()
                    .map(|&v| {
                        if (0.0..=255.0).contains(&v) {
                            v as u8
                        } else {
                            0
                        }
                    })
                    .collect()
            };
            let mut start = 0usize;
            for (i, (&end, &ty)) in ends.iter().zip(&types).enumerate() {
                let c = conn.get(start..end).unwrap_or(&[]);
                start = end;
                add(&mut sink, &mut mesh, i, ty, c)?;
            }
        }
        let ncells = piece.total();
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
            mesh.triangle_tags = pick_tags(&tags, &sink.tri_cells);
            mesh.tet_tags = pick_tags(&tags, &sink.tet_cells);
        }
        Ok(mesh)
    }
}
