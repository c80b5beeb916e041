//! VTK legacy files (`.vtk`): read ASCII and BINARY (big-endian) unstructured grids and
//! polydata; write ASCII unstructured grids.
//!
//! Cells kept: triangles (5), quads (9) and polygons (7) split in triangles, tetrahedra (10),
//! quadratic tetrahedra (24, already in `MeshData`'s node order); other cells are skipped.
//! Both the classic `CELLS n size` layout and version 5.1's `OFFSETS` / `CONNECTIVITY` are
//! read. POINT_DATA arrays become `point_data` fields; an integer CELL_DATA scalar whose name
//! contains `tag`, `ref` or `physical` becomes `triangle_tags` / `tet_tags` (empty when all
//! zero, as in Gmsh). The writer always writes an unstructured grid, also for surfaces.
mod read;
#[cfg(test)]
mod tests;
mod write;

pub use read::parse;
pub use write::encode;

use std::fmt::Write as _;

/// The tags of the kept cells; empty when all are 0 (no group).
pub(crate) fn pick_tags(tags: &[i32], cells: &[usize]) -> Vec<i32> {
    let t: Vec<i32> = cells
        .iter()
        .map(|&c| tags.get(c).copied().unwrap_or(0))
        .collect();
    if t.iter().all(|&v| v == 0) {
        Vec::new()
    } else {
        t
    }
}

/// Cell data named like a region tag (`tag`, `gmsh:physical`, `ref`...).
pub(crate) fn is_tag_name(name: &str) -> bool {
    let n = name.to_ascii_lowercase();
    n.contains("tag") || n.contains("physical") || n.contains("ref")
}

/// VTK writes names with `%xx` escapes for spaces and other special bytes.
fn decode_name(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = b
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok())
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (b[i], hex) {
            (b'%', Some(v)) => {
                out.push(v);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn encode_name(s: &str) -> String {
    let mut out = String::new();
    for b in s.bytes() {
        if b.is_ascii_graphic() && b != b'%' {
            out.push(b as char);
        } else {
            let _ = write!(out, "%{b:02X}");
        }
    }
    if out.is_empty() {
        "unnamed".into()
    } else {
        out
    }
}
