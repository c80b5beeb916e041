//! Gmsh v2.x, ascii and binary. An ascii element line reads
//! `id type tag-count tags... node-ids...` (the first tag is the physical group). Binary files
//! check their byte order with the integer 1 after the format line, store nodes as
//! `int id, double x y z` and elements in blocks headed by `int type, count, tag-count`.

use super::v1::{read_count, read_nodes};
use super::{Builder, MshReport, capped, expect_marker, node_count, shorten, skip_section};
use crate::error::IoError;
use crate::io::cursor::Cursor;
use crate::math::Vec3;
use crate::mesh::MeshData;

#[derive(Clone, Copy)]
struct Endian {
    big: bool,
}

impl Endian {
    fn i32(self, b: &[u8]) -> i32 {
        let mut a = [0u8; 4];
        a.copy_from_slice(b.get(..4).unwrap_or(&[0; 4]));
        if self.big {
            i32::from_be_bytes(a)
        } else {
            i32::from_le_bytes(a)
        }
    }

    fn f64(self, b: &[u8]) -> f64 {
        let mut a = [0u8; 8];
        a.copy_from_slice(b.get(..8).unwrap_or(&[0; 8]));
        if self.big {
            f64::from_be_bytes(a)
        } else {
            f64::from_le_bytes(a)
        }
    }
}

/// Parses the rest of a v2 file; the format line has been read.
pub(super) fn parse(
    c: &mut Cursor<'_>,
    len: usize,
    binary: bool,
) -> Result<(MeshData, MshReport), IoError> {
    let endian = if binary {
        let at = c.position();
        let raw = c.take(4)?;
        let endian = if raw == 1i32.to_le_bytes() {
            Endian { big: false }
        } else if raw == 1i32.to_be_bytes() {
            Endian { big: true }
        } else {
            return Err(IoError::new(
                c.path(),
                crate::error::Location::Byte(at as u64),
                format!(
                    "the binary endianness check should be the integer 1, found bytes {raw:02x?}"
                ),
            ));
        };
        c.skip_newline();
        Some(endian)
    } else {
        None
    };
    expect_marker(c, "$EndMeshFormat")?;
    let mut b = Builder::new(0);
    while let Some(l) = c.next_nonblank()? {
        match (l, endian) {
            ("$Nodes", None) => {
                let n = read_count(c, "the node count")?;
                b.reserve_nodes(capped(n, len - c.position(), 8));
                read_nodes(c, &mut b, n, "$EndNodes")?;
            }
            ("$Nodes", Some(e)) => binary_nodes(c, &mut b, len, e)?,
            ("$Elements", None) => ascii_elements(c, &mut b)?,
            ("$Elements", Some(e)) => binary_elements(c, &mut b, e)?,
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

fn ascii_elements(c: &mut Cursor<'_>, b: &mut Builder) -> Result<(), IoError> {
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
        let [_id, ty, ntags]: [i64; 3] =
            c.parse_n(&mut tok, "an element header `id type tag-count`")?;
        let ty = i32::try_from(ty).map_err(|_| c.error(format!("bad element type {ty}")))?;
        let mut phys = None;
        for k in 0..ntags.max(0) {
            let t = tok.next().ok_or_else(|| {
                c.error(format!(
                    "the element declares {ntags} tags but has only {k}"
                ))
            })?;
            let v: i32 = c.parse(t, "an integer tag")?;
            if k == 0 {
                phys = Some(v);
            }
        }
        nodes.clear();
        for t in tok.by_ref() {
            nodes.push(c.parse::<i64>(t, "a node id")?);
        }
        b.add_element(ty, phys, &nodes).map_err(|m| c.error(m))?;
    }
    expect_marker(c, "$EndElements")
}

fn binary_nodes(c: &mut Cursor<'_>, b: &mut Builder, len: usize, e: Endian) -> Result<(), IoError> {
    let n = read_count(c, "the node count")?;
    let left = len - c.position();
    if n.saturating_mul(28) > left {
        return Err(c.byte_error(format!(
            "the section declares {n} binary nodes ({} bytes) but only {left} bytes are left",
            n.saturating_mul(28)
        )));
    }
    b.reserve_nodes(n);
    for _ in 0..n {
        let at = c.position();
        let r = c.take(28)?;
        let id = e.i32(r);
        let p = [e.f64(&r[4..]), e.f64(&r[12..]), e.f64(&r[20..])];
        if p.iter().any(|v| !v.is_finite()) {
            return Err(byte_error(
                c,
                at,
                format!("node {id} has a non-finite coordinate"),
            ));
        }
        b.add_node(i64::from(id), Vec3::from_array(p))
            .map_err(|m| byte_error(c, at, m))?;
    }
    c.skip_newline();
    expect_marker(c, "$EndNodes")
}

fn binary_elements(c: &mut Cursor<'_>, b: &mut Builder, e: Endian) -> Result<(), IoError> {
    let n = read_count(c, "the element count")?;
    let mut done = 0usize;
    let mut nodes = Vec::new();
    while done < n {
        let at = c.position();
        let h = c.take(12)?;
        let (ty, count, ntags) = (e.i32(h), e.i32(&h[4..]), e.i32(&h[8..]));
        let nn = node_count(ty).ok_or_else(|| {
            byte_error(c, at, format!("unknown element type {ty}: its node count is unknown, so the binary block cannot be skipped"))
        })?;
        let count = usize::try_from(count)
            .ok()
            .filter(|&k| k > 0 && k <= n - done);
        let (Some(count), Ok(ntags)) = (count, usize::try_from(ntags)) else {
            return Err(byte_error(
                c,
                at,
                format!(
                    "bad element block header: type {ty}, {} elements, {ntags} tags ({} of {n} elements left)",
                    e.i32(&h[4..]),
                    n - done
                ),
            ));
        };
        let ints = 1 + ntags + nn;
        for _ in 0..count {
            let at = c.position();
            let r = c.take(ints.saturating_mul(4))?;
            let phys = (ntags > 0).then(|| e.i32(&r[4..]));
            nodes.clear();
            nodes.extend(
                r[4 * (1 + ntags)..]
                    .chunks_exact(4)
                    .map(|q| i64::from(e.i32(q))),
            );
            b.add_element(ty, phys, &nodes)
                .map_err(|m| byte_error(c, at, m))?;
        }
        done += count;
    }
    c.skip_newline();
    expect_marker(c, "$EndElements")
}

fn byte_error(c: &Cursor<'_>, at: usize, message: impl Into<String>) -> IoError {
    IoError::new(c.path(), crate::error::Location::Byte(at as u64), message)
}
