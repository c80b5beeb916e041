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

pub(super) struct Parser<'a> {
    pub(super) path: &'a Path,
    pub(super) bytes: &'a [u8],
    pub(super) big_endian: bool,
    pub(super) header64: bool,
    pub(super) compressed: bool,
    pub(super) appended: Option<Appended<'a>>,
    /// Offsets of all appended arrays: the end of an appended base64 array is the next one.
    pub(super) offsets: Vec<usize>,
    pub(super) piece: Option<(usize, usize, usize)>,
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
                if get("type") != Some("UnstructuredGrid") {
                    return Err(self.error(
                        at,
                        format!(
                            "VTKFile type `{}` is not supported: only UnstructuredGrid",
                            get("type").unwrap_or("")
                        ),
                    ));
                }
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
                let count = |k: &str| -> Result<usize, IoError> {
                    let v = get(k).unwrap_or("");
                    v.trim().parse().map_err(|_| {
                        self.error(at, format!("Piece {k} should be a count, found `{v}`"))
                    })
                };
                self.piece = Some((count("NumberOfPoints")?, count("NumberOfCells")?, at));
            }
            "DataArray" => {
                let section = match parent {
                    Some("Points") => Section::Points,
                    Some("Cells") => Section::Cells,
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
                    if matches!(section, Section::Points | Section::Cells) {
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

    pub(super) fn finish(self) -> Result<MeshData, IoError> {
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
        let mut sink = CellSink::default();
        let mut start = 0usize;
        for (i, (&end, &ty)) in offsets.iter().zip(&types).enumerate() {
            let c = conn.get(start..end).unwrap_or(&[]);
            start = end;
            sink.add(&mut mesh, i, ty, c)
                .map_err(|m| IoError::new(self.path, Location::Element(i), m))?;
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
            mesh.triangle_tags = pick_tags(&tags, &sink.tri_cells);
            mesh.tet_tags = pick_tags(&tags, &sink.tet_cells);
        }
        Ok(mesh)
    }
}
