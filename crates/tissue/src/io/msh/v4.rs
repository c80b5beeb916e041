//! Gmsh v4.1 ascii. Nodes and elements come in blocks, one per geometric entity; the
//! physical groups are attached to the entities in `$Entities`, so an element's physical tag
//! is the first physical tag of the entity its block belongs to.

use std::collections::HashMap;

use super::v1::read_xyz;
use super::{Builder, MshReport, capped, expect_marker, shorten, skip_section};
use crate::error::{IoError, Location};
use crate::io::cursor::Cursor;
use crate::math::Vec3;
use crate::mesh::MeshData;

/// Physical tag of each entity (dimension, entity tag) that has one.
type Physical = HashMap<(i64, i64), i32>;

/// Parses the rest of a v4.1 ascii file; the format line has been read.
pub(super) fn parse(c: &mut Cursor<'_>, len: usize) -> Result<(MeshData, MshReport), IoError> {
    expect_marker(c, "$EndMeshFormat")?;
    let mut b = Builder::new(0);
    let mut physical = Physical::new();
    while let Some(l) = c.next_nonblank()? {
        match l {
            "$Entities" => physical = entities(c)?,
            "$Nodes" => nodes(c, &mut b, len)?,
            "$Elements" => elements(c, &mut b, &physical)?,
            _ => match l.strip_prefix('$') {
                Some(name) => skip_section(c, name)?,
                None => {
                    return Err(c.error(format!("expected a `$` section, found `{}`", shorten(l))));
                }
            },
        }
    }
    Ok(b.finish())
}

/// A data line of a block: must not be a section marker.
fn data_line<'a>(c: &mut Cursor<'a>, what: &str) -> Result<&'a str, IoError> {
    let l = c.expect_line(what)?;
    if l.starts_with('$') {
        return Err(c.error(format!("expected {what}, found `{}`", shorten(l))));
    }
    Ok(l)
}

fn entities(c: &mut Cursor<'_>) -> Result<Physical, IoError> {
    let l = data_line(c, "the entity counts `points curves surfaces volumes`")?;
    let counts: [usize; 4] = c.parse_n(&mut l.split_ascii_whitespace(), "the entity counts")?;
    let mut physical = Physical::new();
    for (dim, &n) in counts.iter().enumerate() {
        for _ in 0..n {
            let l = data_line(c, &format!("an entity of dimension {dim}"))?;
            let mut tok = l.split_ascii_whitespace();
            let tag: i64 = c.parse(tok.next().unwrap_or(""), "an entity tag")?;
            // A point has its coordinates, the others a bounding box.
            let reals = if dim == 0 { 3 } else { 6 };
            for _ in 0..reals {
                c.parse::<f64>(tok.next().unwrap_or(""), "an entity coordinate")?;
            }
            let np: usize = c.parse(tok.next().unwrap_or(""), "the physical tag count")?;
            for k in 0..np {
                let p: i32 = c.parse(tok.next().unwrap_or(""), "a physical tag")?;
                if k == 0 {
                    physical.insert((dim as i64, tag), p);
                }
            }
        }
    }
    expect_marker(c, "$EndEntities")?;
    Ok(physical)
}

fn nodes(c: &mut Cursor<'_>, b: &mut Builder, len: usize) -> Result<(), IoError> {
    let l = data_line(c, "the node header `blocks nodes min-tag max-tag`")?;
    let [blocks, total, _, _]: [usize; 4] =
        c.parse_n(&mut l.split_ascii_whitespace(), "the node header")?;
    let header_line = c.line();
    b.reserve_nodes(capped(total, len - c.position(), 8));
    let mut seen = 0usize;
    let mut tags: Vec<i64> = Vec::new();
    for _ in 0..blocks {
        let l = data_line(c, "a node block header `dim entity parametric count`")?;
        let [_, _, _, n]: [usize; 4] =
            c.parse_n(&mut l.split_ascii_whitespace(), "the node block header")?;
        tags.clear();
        tags.reserve(capped(n, len - c.position(), 2));
        while tags.len() < n {
            let l = data_line(c, "node tags")?;
            for t in l.split_ascii_whitespace() {
                tags.push(c.parse(t, "a node tag")?);
            }
            if tags.len() > n {
                return Err(c.error(format!(
                    "the block declares {n} nodes but lists {} tags",
                    tags.len()
                )));
            }
        }
        for &id in &tags {
            let l = data_line(c, "node coordinates `x y z`")?;
            let [x, y, z] = read_xyz(c, &mut l.split_ascii_whitespace())?;
            b.add_node(id, Vec3::new(x, y, z)).map_err(|m| c.error(m))?;
        }
        seen += n;
    }
    if seen != total {
        return Err(IoError::new(
            c.path(),
            Location::Line(header_line),
            format!("the header declares {total} nodes but the blocks hold {seen}"),
        ));
    }
    expect_marker(c, "$EndNodes")
}

fn elements(c: &mut Cursor<'_>, b: &mut Builder, physical: &Physical) -> Result<(), IoError> {
    let l = data_line(c, "the element header `blocks elements min-tag max-tag`")?;
    let [blocks, total, _, _]: [usize; 4] =
        c.parse_n(&mut l.split_ascii_whitespace(), "the element header")?;
    let header_line = c.line();
    let mut seen = 0usize;
    let mut ids = Vec::new();
    for _ in 0..blocks {
        let l = data_line(c, "an element block header `dim entity type count`")?;
        let [dim, entity, ty, n]: [i64; 4] =
            c.parse_n(&mut l.split_ascii_whitespace(), "the element block header")?;
        let ty = i32::try_from(ty).map_err(|_| c.error(format!("bad element type {ty}")))?;
        let n = usize::try_from(n).map_err(|_| c.error(format!("bad element count {n}")))?;
        let phys = physical.get(&(dim, entity)).copied();
        for _ in 0..n {
            let l = data_line(c, "an element line `tag node-tags...`")?;
            let mut tok = l.split_ascii_whitespace();
            c.parse::<i64>(tok.next().unwrap_or(""), "an element tag")?;
            ids.clear();
            for t in tok {
                ids.push(c.parse::<i64>(t, "a node tag")?);
            }
            b.add_element(ty, phys, &ids).map_err(|m| c.error(m))?;
        }
        seen += n;
    }
    if seen != total {
        return Err(IoError::new(
            c.path(),
            Location::Line(header_line),
            format!("the header declares {total} elements but the blocks hold {seen}"),
        ));
    }
    expect_marker(c, "$EndElements")
}
