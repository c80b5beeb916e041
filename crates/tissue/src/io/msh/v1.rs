//! Gmsh v1 (`$NOD` / `$ELM`), the format of SOFA's classic meshes. An element line reads
//! `id type physical-region elementary-region node-count node-ids...`.

use super::{Builder, MshReport, capped, expect_marker, shorten, skip_section};
use crate::error::IoError;
use crate::io::cursor::Cursor;
use crate::math::Vec3;
use crate::mesh::MeshData;

/// Parses the rest of a v1 file; the `$NOD` line has been read.
pub(super) fn parse(c: &mut Cursor<'_>, len: usize) -> Result<(MeshData, MshReport), IoError> {
    let n = read_count(c, "the node count")?;
    let mut b = Builder::new(capped(n, len - c.position(), 8));
    read_nodes(c, &mut b, n, "$ENDNOD")?;
    while let Some(l) = c.next_nonblank()? {
        if l.eq_ignore_ascii_case("$ELM") {
            read_elements(c, &mut b)?;
        } else if let Some(name) = l.strip_prefix('$') {
            skip_section(c, name)?;
        } else {
            return Err(c.error(format!("expected a `$` section, found `{}`", shorten(l))));
        }
    }
    Ok(b.finish())
}

/// A count on its own line.
pub(super) fn read_count(c: &mut Cursor<'_>, what: &str) -> Result<usize, IoError> {
    let l = c.expect_line(what)?;
    c.parse(l, what)
}

/// `n` ascii lines `id x y z` (v1 and v2), then the end marker.
pub(super) fn read_nodes(
    c: &mut Cursor<'_>,
    b: &mut Builder,
    n: usize,
    end: &str,
) -> Result<(), IoError> {
    for k in 0..n {
        let l = c.expect_line("a node line `id x y z`")?;
        if l.starts_with('$') {
            return Err(c.error(format!(
                "the section declares {n} nodes but `{}` follows node {k}",
                shorten(l)
            )));
        }
        let mut tok = l.split_ascii_whitespace();
        let id: i64 = c.parse(tok.next().unwrap_or(""), "a node id")?;
        let [x, y, z] = read_xyz(c, &mut tok)?;
        b.add_node(id, Vec3::new(x, y, z)).map_err(|m| c.error(m))?;
    }
    expect_marker(c, end)
}

/// Three finite coordinates.
pub(super) fn read_xyz<'a>(
    c: &Cursor<'a>,
    tok: &mut dyn Iterator<Item = &'a str>,
) -> Result<[f64; 3], IoError> {
    let mut p = [0.0; 3];
    for (k, v) in p.iter_mut().enumerate() {
        let t = tok
            .next()
            .ok_or_else(|| c.error(format!("expected 3 coordinates, found {k}")))?;
        *v = c.parse_real(t, "a coordinate")?;
    }
    Ok(p)
}

fn read_elements(c: &mut Cursor<'_>, b: &mut Builder) -> Result<(), IoError> {
    let n = read_count(c, "the element count")?;
    let mut nodes = Vec::new();
    for k in 0..n {
        let l = c.expect_line("an element line")?;
        if l.starts_with('$') {
            return Err(c.error(format!(
                "the section declares {n} elements but `{}` follows element {k}",
                shorten(l)
            )));
        }
        let mut tok = l.split_ascii_whitespace();
        let [_id, ty, phys, _elem, count]: [i64; 5] = c.parse_n(
            &mut tok,
            "an element header `id type physical elementary nodes`",
        )?;
        let ty = i32::try_from(ty).map_err(|_| c.error(format!("bad element type {ty}")))?;
        let phys = i32::try_from(phys)
            .map_err(|_| c.error(format!("physical region {phys} is out of range")))?;
        nodes.clear();
        for t in tok.by_ref() {
            nodes.push(c.parse::<i64>(t, "a node id")?);
        }
        if usize::try_from(count).ok() != Some(nodes.len()) {
            return Err(c.error(format!(
                "the element declares {count} nodes but lists {}",
                nodes.len()
            )));
        }
        b.add_element(ty, Some(phys), &nodes)
            .map_err(|m| c.error(m))?;
    }
    expect_marker(c, "$ENDELM")
}
