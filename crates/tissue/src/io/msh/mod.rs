//! Gmsh `.msh` meshes: read v1, v2.2 (ascii and binary) and v4.1 ascii; write v2.2 and v4.1
//! ascii (and v2.2 binary).
//!
//! Gmsh node ids may be sparse and unordered; they become compact 0-based indices in file
//! order. Triangles, quads (split in two triangles), linear and 10-node tetrahedra are kept;
//! points, lines and other element kinds are skipped and counted in [`MshReport`]. The
//! physical tag of each kept element goes to `triangle_tags` / `tet_tags` (empty when the file
//! gives none: Gmsh writes physical tag 0 for "no physical group").

mod v1;
mod v2;
mod v4;
mod write;

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use super::cursor::Cursor;
use crate::error::{IoError, Location};
use crate::math::Vec3;
use crate::mesh::MeshData;

pub use write::encode_v2_binary;

/// What a reader left out.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MshReport {
    /// Skipped elements per Gmsh element type number (15 point, 1 line, 8 quadratic line...).
    pub skipped: BTreeMap<i32, usize>,
}

/// Reads a Gmsh file of any supported version.
pub fn parse(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    parse_with_report(bytes, path).map(|(mesh, _)| mesh)
}

/// Reads a Gmsh file and reports the elements it skipped.
pub fn parse_with_report(bytes: &[u8], path: &Path) -> Result<(MeshData, MshReport), IoError> {
    let mut c = Cursor::new(path, bytes);
    let first = c
        .next_nonblank()?
        .ok_or_else(|| IoError::new(path, Location::File, "the file is empty"))?;
    match first {
        "$NOD" => v1::parse(&mut c, bytes.len()),
        "$MeshFormat" => {
            let header = c.expect_line("the mesh format line `version file-type data-size`")?;
            let mut tok = header.split_ascii_whitespace();
            let version = tok.next().unwrap_or("");
            let file_type: i32 = c.parse(tok.next().unwrap_or(""), "the file type (0 or 1)")?;
            let data_size: usize = c.parse(tok.next().unwrap_or(""), "the data size")?;
            if data_size != 8 {
                return Err(c.error(format!(
                    "data size {data_size} is not supported: reals must be 8-byte doubles"
                )));
            }
            let major = version.split('.').next().unwrap_or("");
            match (major, version, file_type) {
                ("2", _, 0 | 1) => v2::parse(&mut c, bytes.len(), file_type == 1),
                (_, "4.1", 0) => v4::parse(&mut c, bytes.len()),
                (_, "4.1", _) => {
                    Err(c.error("binary Gmsh 4.1 is not supported; save as ascii 4.1 or as 2.2"))
                }
                _ => Err(c.error(format!(
                    "Gmsh format version `{version}` (file type {file_type}) is not supported; \
                     supported: 1, 2.x ascii and binary, 4.1 ascii"
                ))),
            }
        }
        other => Err(c.error(format!(
            "not a Gmsh file: expected `$MeshFormat` (v2, v4) or `$NOD` (v1), found `{other}`"
        ))),
    }
}

/// Writes a mesh as Gmsh v2.2 or v4.1 ascii.
pub fn encode(mesh: &MeshData, version: super::MshVersion) -> Result<Vec<u8>, String> {
    match version {
        super::MshVersion::V2 => write::encode_v2(mesh),
        super::MshVersion::V4 => write::encode_v4(mesh),
    }
}

/// Number of nodes of a Gmsh element type, `None` for types this reader does not know.
pub(crate) fn node_count(element_type: i32) -> Option<usize> {
    Some(match element_type {
        15 => 1,
        1 => 2,
        2 | 8 => 3,
        3 | 4 | 26 => 4,
        5 | 16 => 8,
        6 => 6,
        7 | 27 => 5,
        9 | 28 => 6,
        10 | 20 => 9,
        11 | 21 => 10,
        12 => 27,
        13 => 18,
        18 => 15,
        14 => 14,
        17 => 20,
        19 => 13,
        22 => 12,
        23 | 24 => 15,
        25 => 21,
        29 => 20,
        30 => 35,
        31 => 56,
        92 => 64,
        93 => 125,
        _ => return None,
    })
}

/// Gmsh's 10-node tetrahedron lists its last two mid-edge nodes as (2,3), (1,3); VTK and
/// `MeshData` as (1,3), (2,3). Swapping them converts both ways.
pub(crate) fn swap_tet10_order<T: Copy>(mut t: [T; 10]) -> [T; 10] {
    t.swap(8, 9);
    t
}

/// Collects nodes and elements independently of the file version; errors are plain messages
/// that the caller attaches to its line or byte.
pub(crate) struct Builder {
    ids: HashMap<i64, u32>,
    mesh: MeshData,
    triangle_tags: Vec<Option<i32>>,
    tet_tags: Vec<Option<i32>>,
    report: MshReport,
}

impl Builder {
    /// `capacity` should already be capped by the bytes left in the file.
    pub fn new(capacity: usize) -> Self {
        let mut mesh = MeshData::default();
        mesh.vertices.reserve(capacity);
        Self {
            ids: HashMap::with_capacity(capacity),
            mesh,
            triangle_tags: Vec::new(),
            tet_tags: Vec::new(),
            report: MshReport::default(),
        }
    }

    pub fn reserve_nodes(&mut self, n: usize) {
        self.mesh.vertices.reserve(n);
        self.ids.reserve(n);
    }

    pub fn add_node(&mut self, id: i64, p: Vec3) -> Result<(), String> {
        let index = u32::try_from(self.mesh.vertices.len())
            .map_err(|_| "more than 4 billion nodes".to_string())?;
        if self.ids.insert(id, index).is_some() {
            return Err(format!("node id {id} is defined twice"));
        }
        self.mesh.vertices.push(p);
        Ok(())
    }

    fn index(&self, id: i64) -> Result<u32, String> {
        self.ids
            .get(&id)
            .copied()
            .ok_or_else(|| format!("element refers to node id {id}, which is not defined"))
    }

    fn indices<const N: usize>(&self, nodes: &[i64]) -> Result<[u32; N], String> {
        let mut out = [0u32; N];
        for (slot, &id) in out.iter_mut().zip(nodes) {
            *slot = self.index(id)?;
        }
        Ok(out)
    }

    /// Adds one element given by Gmsh type, physical tag (`None` or 0 = no physical group)
    /// and node ids. A known type with the wrong number of nodes is an error.
    pub fn add_element(&mut self, ty: i32, tag: Option<i32>, nodes: &[i64]) -> Result<(), String> {
        if let Some(n) = node_count(ty)
            && n != nodes.len()
        {
            return Err(format!(
                "element of type {ty} needs {n} nodes, found {}",
                nodes.len()
            ));
        }
        let tag = tag.filter(|&t| t != 0);
        match ty {
            2 => {
                let t = self.indices::<3>(nodes)?;
                self.mesh.triangles.push(t);
                self.triangle_tags.push(tag);
            }
            3 => {
                let [a, b, c, d] = self.indices::<4>(nodes)?;
                self.mesh.triangles.push([a, b, c]);
                self.mesh.triangles.push([a, c, d]);
                self.triangle_tags.extend([tag, tag]);
            }
            4 => {
                let t = self.indices::<4>(nodes)?;
                self.mesh.tets.push(t);
                self.tet_tags.push(tag);
            }
            11 => {
                let t = self.indices::<10>(nodes)?;
                self.mesh.tets10.push(swap_tet10_order(t));
            }
            _ => {
                // Skipped elements must still name existing nodes: a dangling id is a broken
                // file whatever the element kind.
                for &id in nodes {
                    self.index(id)?;
                }
                *self.report.skipped.entry(ty).or_insert(0) += 1;
            }
        }
        Ok(())
    }

    pub fn finish(mut self) -> (MeshData, MshReport) {
        self.mesh.triangle_tags = resolve_tags(&self.triangle_tags);
        self.mesh.tet_tags = resolve_tags(&self.tet_tags);
        (self.mesh, self.report)
    }
}

/// No tag anywhere: empty; otherwise missing tags become 0.
fn resolve_tags(tags: &[Option<i32>]) -> Vec<i32> {
    if tags.iter().all(Option::is_none) {
        Vec::new()
    } else {
        tags.iter().map(|t| t.unwrap_or(0)).collect()
    }
}

/// How many items of `item_size` bytes the rest of the file could hold at most, so that a
/// header claiming a huge count cannot make us reserve a huge buffer.
pub(crate) fn capped(count: usize, remaining: usize, item_size: usize) -> usize {
    count.min(remaining / item_size.max(1))
}

/// Skips an unknown `$Section` up to its `$EndSection` (any case). Binary sections may hold
/// bytes that are not text; such lines are passed over.
pub(crate) fn skip_section(c: &mut Cursor<'_>, name: &str) -> Result<(), IoError> {
    let end = format!("$End{name}");
    loop {
        match c.next_line() {
            Ok(Some(l)) if l.trim().eq_ignore_ascii_case(&end) => return Ok(()),
            Ok(Some(_)) | Err(_) => {}
            Ok(None) => {
                return Err(c.error(format!("unexpected end of file: missing `{end}`")));
            }
        }
    }
}

/// Reads the next non-blank line and checks it is `expected` (any case).
pub(crate) fn expect_marker(c: &mut Cursor<'_>, expected: &str) -> Result<(), IoError> {
    let l = c.expect_line(&format!("`{expected}`"))?;
    if l.eq_ignore_ascii_case(expected) {
        Ok(())
    } else {
        Err(c.error(format!("expected `{expected}`, found `{}`", shorten(l))))
    }
}

/// A line quoted in an error, cut to a readable length.
pub(crate) fn shorten(s: &str) -> String {
    if s.len() <= 60 {
        s.to_string()
    } else {
        let cut = (0..=60).rev().find(|&i| s.is_char_boundary(i)).unwrap_or(0);
        format!("{}...", &s[..cut])
    }
}

#[cfg(test)]
mod tests;
