//! Mesh file formats: read any supported file into `MeshData`, write it back out.
//!
//! The format comes from the file extension. Readers never panic on malformed input: every
//! error names the file and the line, byte or element.
//!
//! | format | ext | read | write |
//! |---|---|---|---|
//! | Wavefront OBJ | `.obj` | yes | yes |
//! | STL ascii and binary | `.stl` | yes | yes (binary) |
//! | PLY ascii and binary, custom elements | `.ply` | yes | no |
//! | Gmsh v1, v2 (ascii, binary), v4.1 ascii | `.msh` | yes | v2 and v4.1 ascii |
//! | VTK legacy unstructured grid / polydata | `.vtk` | yes | yes |
//! | VTK XML unstructured grid: ascii, base64, appended raw/base64, zlib | `.vtu` | yes | ascii, base64; `vtu::encode_appended` |
//! | VTK XML PolyData (polygons, triangle strips), same encodings | `.vtp` | yes | ascii, base64 (the surface) |
//! | MEDIT | `.mesh` | yes | yes |
//! | Geomview OFF | `.off` | yes | yes |
//! | TetGen `.node` + `.ele` + `.face` | `.node`, `.ele`, `.face` | yes (the set by stem) | yes |

mod cursor;
pub mod medit;
pub mod msh;
pub mod obj;
pub mod off;
pub mod ply;
pub mod series;
pub mod stl;
pub mod tetgen;
pub mod vtk;
mod vtk_cells;
pub mod vtu;

use std::path::Path;

use crate::error::{IoError, Location};
use crate::mesh::MeshData;

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Obj,
    Stl,
    Ply,
    Msh,
    Vtk,
    Vtu,
    /// VTK XML PolyData: a surface.
    Vtp,
    Medit,
    Off,
    /// A TetGen set `.node` / `.ele` / `.face`, named by any of them.
    TetGen,
}

/// Gmsh file version to write.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MshVersion {
    V2,
    #[default]
    V4,
}

/// Choices a writer can make; `Default` gives the most widely read variant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WriteOptions {
    /// Gmsh version (default: 4.1).
    pub msh_version: MshVersion,
    /// Binary where the format has both (STL binary, VTU base64); default: true.
    pub binary: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        Self {
            msh_version: MshVersion::V4,
            binary: true,
        }
    }
}

impl Format {
    /// The format named by a path's extension.
    pub fn from_path(path: &Path) -> Result<Self, IoError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("obj") => Ok(Format::Obj),
            Some("stl") => Ok(Format::Stl),
            Some("ply") => Ok(Format::Ply),
            Some("msh") => Ok(Format::Msh),
            Some("vtk") => Ok(Format::Vtk),
            Some("vtu") => Ok(Format::Vtu),
            Some("vtp") => Ok(Format::Vtp),
            Some("mesh") => Ok(Format::Medit),
            Some("off") => Ok(Format::Off),
            Some("node" | "ele" | "face") => Ok(Format::TetGen),
            other => Err(IoError::new(
                path,
                Location::File,
                format!(
                    "unknown mesh format `{}`; supported: .obj .stl .ply .msh .vtk .vtu .vtp .mesh .off .node/.ele/.face",
                    other.unwrap_or("")
                ),
            )),
        }
    }

    pub fn can_write(self) -> bool {
        !matches!(self, Format::Ply)
    }
}

/// Reads a mesh file of any supported format.
pub fn read(path: impl AsRef<Path>) -> Result<MeshData, IoError> {
    let path = path.as_ref();
    let format = Format::from_path(path)?;
    if format == Format::TetGen {
        let mesh = tetgen::read(path)?;
        check_indices(&mesh, path)?;
        return Ok(mesh);
    }
    let bytes = std::fs::read(path).map_err(|e| IoError::os(path, "read the file", e))?;
    parse(format, &bytes, path)
}

/// Parses bytes already in memory; `path` only names the source in errors.
pub fn parse(format: Format, bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let mesh = match format {
        Format::Obj => obj::parse(bytes, path)?,
        Format::Stl => stl::parse(bytes, path)?,
        Format::Ply => ply::parse(bytes, path)?,
        Format::Msh => msh::parse(bytes, path)?,
        Format::Vtk => vtk::parse(bytes, path)?,
        Format::Vtu | Format::Vtp => vtu::parse(bytes, path)?,
        Format::Medit => medit::parse(bytes, path)?,
        Format::Off => off::parse(bytes, path)?,
        Format::TetGen => {
            return Err(IoError::new(
                path,
                Location::File,
                "a TetGen set spans .node, .ele and .face files: read it with io::read",
            ));
        }
    };
    check_indices(&mesh, path)?;
    Ok(mesh)
}

/// Writes a mesh with default options; the format comes from the extension.
pub fn write(path: impl AsRef<Path>, mesh: &MeshData) -> Result<(), IoError> {
    write_with(path, mesh, &WriteOptions::default())
}

/// Writes a mesh. Surface-only formats (OBJ, STL) given a volume mesh get its boundary.
pub fn write_with(
    path: impl AsRef<Path>,
    mesh: &MeshData,
    options: &WriteOptions,
) -> Result<(), IoError> {
    let path = path.as_ref();
    let format = Format::from_path(path)?;
    if format == Format::TetGen {
        return tetgen::write(path, mesh);
    }
    let bytes = encode(format, mesh, options).map_err(|m| IoError::new(path, Location::File, m))?;
    std::fs::write(path, bytes).map_err(|e| IoError::os(path, "write the file", e))
}

/// Encodes a mesh in a format; the error says why the mesh does not fit the format.
pub fn encode(format: Format, mesh: &MeshData, options: &WriteOptions) -> Result<Vec<u8>, String> {
    match format {
        Format::Obj => obj::encode(&surface_for_writing(mesh)?),
        Format::Stl => stl::encode(&surface_for_writing(mesh)?, options.binary),
        Format::Ply => Err("writing PLY is not supported; use .obj, .stl, .vtk or .vtu".into()),
        Format::Msh => msh::encode(mesh, options.msh_version),
        Format::Vtk => vtk::encode(mesh),
        Format::Vtu => vtu::encode(mesh, options.binary),
        Format::Vtp => vtu::encode_poly(&surface_for_writing(mesh)?, options.binary),
        Format::Medit => medit::encode(mesh),
        Format::Off => off::encode(&surface_for_writing(mesh)?),
        Format::TetGen => Err("a TetGen set is three files: write it with io::write".into()),
    }
}

fn surface_for_writing(mesh: &MeshData) -> Result<MeshData, String> {
    if mesh.has_volume() {
        let s = mesh.surface_mesh().map_err(|e| e.to_string())?;
        Ok(MeshData::from_surface(&s))
    } else {
        Ok(mesh.clone())
    }
}

/// Every element index must name a vertex: checked once here for every reader.
fn check_indices(mesh: &MeshData, path: &Path) -> Result<(), IoError> {
    let n = mesh.vertices.len();
    let bad = |kind: &str, e: usize, i: u32| {
        IoError::new(
            path,
            Location::Element(e),
            format!("{kind} {e} refers to vertex {i}, but the file has {n} vertices"),
        )
    };
    for (e, t) in mesh.triangles.iter().enumerate() {
        if let Some(&i) = t.iter().find(|&&i| i as usize >= n) {
            return Err(bad("triangle", e, i));
        }
    }
    for (e, t) in mesh.tets.iter().enumerate() {
        if let Some(&i) = t.iter().find(|&&i| i as usize >= n) {
            return Err(bad("tetrahedron", e, i));
        }
    }
    for (e, t) in mesh.tets10.iter().enumerate() {
        if let Some(&i) = t.iter().find(|&&i| i as usize >= n) {
            return Err(bad("10-node tetrahedron", e, i));
        }
    }
    if let Some(&i) = mesh.fixed_vertices.iter().find(|&&i| i as usize >= n) {
        return Err(IoError::new(
            path,
            Location::File,
            format!("fixed vertex {i} does not exist: the file has {n} vertices"),
        ));
    }
    for (v, p) in mesh.vertices.iter().enumerate() {
        if !crate::math::is_finite_vec(*p) {
            return Err(IoError::new(
                path,
                Location::File,
                format!(
                    "vertex {v} has a non-finite coordinate ({}, {}, {})",
                    p.x, p.y, p.z
                ),
            ));
        }
    }
    Ok(())
}
