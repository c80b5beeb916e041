//! STL triangle soups, ascii and binary, welded into an indexed mesh by merging exactly
//! coincident vertices. The writer emits binary (normals computed) or ascii.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use super::cursor::Cursor;
use crate::error::{IoError, Location};
use crate::math::Vec3;
use crate::mesh::MeshData;

const HEADER: usize = 80;
const TRIANGLE_BYTES: usize = 50;

/// Reads an ascii or binary STL file.
pub fn parse(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    // Many binary files start their header with "solid" too, so the exact binary size decides
    // first; a text file never contains a NUL byte while binary counts and floats nearly
    // always do.
    if binary_size_matches(bytes) {
        return parse_binary(bytes, path);
    }
    let starts_solid = bytes.trim_ascii_start().starts_with(b"solid");
    if starts_solid && !bytes.contains(&0) {
        parse_ascii(bytes, path)
    } else {
        parse_binary(bytes, path)
    }
}

fn binary_size_matches(bytes: &[u8]) -> bool {
    match bytes.get(HEADER..HEADER + 4) {
        Some(c) => {
            let n = u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as u64;
            n * TRIANGLE_BYTES as u64 + (HEADER + 4) as u64 == bytes.len() as u64
        }
        None => false,
    }
}

/// Builds the indexed mesh, giving each distinct position the index of its first appearance.
struct Welder {
    mesh: MeshData,
    index: HashMap<[u64; 3], u32>,
}

impl Welder {
    fn with_capacity(triangles: usize) -> Self {
        let mut mesh = MeshData::default();
        mesh.triangles.reserve(triangles);
        Self {
            mesh,
            index: HashMap::with_capacity(triangles / 2),
        }
    }

    fn vertex(&mut self, p: Vec3) -> u32 {
        // Adding 0.0 turns -0.0 into 0.0 so the two zeros (equal as numbers) weld.
        let key = [
            (p.x + 0.0).to_bits(),
            (p.y + 0.0).to_bits(),
            (p.z + 0.0).to_bits(),
        ];
        let next = self.mesh.vertices.len() as u32;
        *self.index.entry(key).or_insert_with(|| {
            self.mesh.vertices.push(p);
            next
        })
    }

    fn triangle(&mut self, corners: [Vec3; 3]) {
        let t = corners.map(|p| self.vertex(p));
        self.mesh.triangles.push(t);
    }
}

fn parse_binary(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let mut c = Cursor::new(path, bytes);
    c.take(HEADER)
        .map_err(|_| truncated(path, bytes.len(), "the 80-byte header and triangle count"))?;
    let count = le_u32(
        c.take(4)
            .map_err(|_| truncated(path, bytes.len(), "the 80-byte header and triangle count"))?,
    );
    let needed = (HEADER + 4) as u64 + u64::from(count) * TRIANGLE_BYTES as u64;
    if needed != bytes.len() as u64 {
        return Err(IoError::new(
            path,
            Location::Byte(HEADER as u64),
            format!(
                "binary STL header says {count} triangles ({needed} bytes), but the file has {} bytes",
                bytes.len()
            ),
        ));
    }
    let mut w = Welder::with_capacity(count as usize);
    for t in 0..count as usize {
        let rec = c.take(TRIANGLE_BYTES)?;
        let mut corners = [Vec3::ZERO; 3];
        for (k, p) in corners.iter_mut().enumerate() {
            // The stored normal (first 12 bytes) is ignored: it is recomputed when needed.
            let at = 12 + 12 * k;
            let f = |o: usize| f64::from(f32::from_bits(le_u32(&rec[at + o..at + o + 4])));
            *p = Vec3::new(f(0), f(4), f(8));
            if !crate::math::is_finite_vec(*p) {
                let offset = (HEADER + 4 + t * TRIANGLE_BYTES + at) as u64;
                return Err(IoError::new(
                    path,
                    Location::Byte(offset),
                    format!("triangle {t} has a non-finite vertex coordinate"),
                ));
            }
        }
        w.triangle(corners);
    }
    Ok(w.mesh)
}

fn truncated(path: &Path, len: usize, what: &str) -> IoError {
    IoError::new(
        path,
        Location::Byte(len as u64),
        format!("the file ends after {len} bytes, before {what} of a binary STL"),
    )
}

/// Reads 4 little-endian bytes; callers pass slices of exactly 4 bytes.
fn le_u32(b: &[u8]) -> u32 {
    let mut a = [0u8; 4];
    for (d, s) in a.iter_mut().zip(b) {
        *d = *s;
    }
    u32::from_le_bytes(a)
}

fn parse_ascii(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let mut c = Cursor::new(path, bytes);
    // A facet takes at least ~60 bytes of text; the bound only limits the reservation.
    let mut w = Welder::with_capacity(bytes.len() / 64);
    let mut solids = 0usize;
    while let Some(line) = c.next_nonblank()? {
        let mut t = line.split_whitespace();
        if t.next() != Some("solid") {
            if solids > 0 {
                return Err(c.error(format!(
                    "expected `solid` or the end of the file, found `{line}`"
                )));
            }
            return Err(c.error(format!("an ascii STL starts with `solid`, found `{line}`")));
        }
        solids += 1;
        loop {
            let line = c.expect_line("`facet` or `endsolid`")?;
            let mut t = line.split_whitespace();
            match t.next() {
                Some("endsolid") => break,
                Some("facet") => {
                    let l = c.expect_line("`outer loop`")?;
                    expect_words(&c, l, &["outer", "loop"])?;
                    let mut corners = [Vec3::ZERO; 3];
                    for p in &mut corners {
                        let l = c.expect_line("`vertex x y z`")?;
                        let mut t = l.split_whitespace();
                        if t.next() != Some("vertex") {
                            return Err(c.error(format!("expected `vertex x y z`, found `{l}`")));
                        }
                        let [x, y, z] = c.parse_n::<f64, 3>(&mut t, "a vertex")?;
                        *p = Vec3::new(x, y, z);
                        if !crate::math::is_finite_vec(*p) {
                            return Err(c.error("the vertex has a non-finite coordinate"));
                        }
                    }
                    let l = c.expect_line("`endloop`")?;
                    expect_words(&c, l, &["endloop"])?;
                    let l = c.expect_line("`endfacet`")?;
                    expect_words(&c, l, &["endfacet"])?;
                    w.triangle(corners);
                }
                _ => return Err(c.error(format!("expected `facet` or `endsolid`, found `{line}`"))),
            }
        }
    }
    if solids == 0 {
        return Err(IoError::new(path, Location::File, "the file is empty"));
    }
    Ok(w.mesh)
}

fn expect_words(c: &Cursor<'_>, line: &str, words: &[&str]) -> Result<(), IoError> {
    if line.split_whitespace().eq(words.iter().copied()) {
        Ok(())
    } else {
        Err(c.error(format!("expected `{}`, found `{line}`", words.join(" "))))
    }
}

fn corners(mesh: &MeshData, t: usize) -> Result<[Vec3; 3], String> {
    let tri = mesh.triangles.get(t).ok_or("no such triangle")?;
    let mut out = [Vec3::ZERO; 3];
    for (o, &i) in out.iter_mut().zip(tri) {
        *o = *mesh
            .vertices
            .get(i as usize)
            .ok_or_else(|| format!("triangle {t} refers to vertex {i}, which does not exist"))?;
        if !crate::math::is_finite_vec(*o) {
            return Err(format!("vertex {i} has a non-finite coordinate"));
        }
    }
    Ok(out)
}

fn normal([a, b, c]: [Vec3; 3]) -> Vec3 {
    (b - a).cross(c - a).normalize_or_zero()
}

/// Writes the triangles as STL. Binary stores single precision, so a round trip is exact only
/// for coordinates representable as f32; ascii writes the shortest round-trip f64 text.
pub fn encode(mesh: &MeshData, binary: bool) -> Result<Vec<u8>, String> {
    let n = mesh.triangles.len();
    if binary {
        let count =
            u32::try_from(n).map_err(|_| format!("{n} triangles do not fit a binary STL"))?;
        let mut out = Vec::with_capacity(HEADER + 4 + n * TRIANGLE_BYTES);
        // The header must not start with "solid": some readers would take the file for text.
        out.extend_from_slice(b"binary STL written by tissue");
        out.resize(HEADER, b' ');
        out.extend_from_slice(&count.to_le_bytes());
        for t in 0..n {
            let p = corners(mesh, t)?;
            for v in std::iter::once(normal(p)).chain(p) {
                for x in [v.x, v.y, v.z] {
                    out.extend_from_slice(&(x as f32).to_le_bytes());
                }
            }
            out.extend_from_slice(&0u16.to_le_bytes());
        }
        Ok(out)
    } else {
        let mut s = String::with_capacity(200 * n + 32);
        s.push_str("solid tissue\n");
        for t in 0..n {
            let p = corners(mesh, t)?;
            let nn = normal(p);
            let _ = writeln!(s, "  facet normal {:?} {:?} {:?}", nn.x, nn.y, nn.z);
            s.push_str("    outer loop\n");
            for v in p {
                let _ = writeln!(s, "      vertex {:?} {:?} {:?}", v.x, v.y, v.z);
            }
            s.push_str("    endloop\n  endfacet\n");
        }
        s.push_str("endsolid tissue\n");
        Ok(s.into_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> MeshData {
        // Vertices in order of first appearance, all exactly representable in f32.
        MeshData {
            vertices: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 0.0, 1.5),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]],
            ..MeshData::default()
        }
    }

    #[test]
    fn both_encodings_round_trip_and_weld() {
        let m = tetra();
        for binary in [true, false] {
            let bytes = encode(&m, binary).unwrap();
            if binary {
                assert_eq!(bytes.len(), 84 + 4 * 50);
            }
            let back = parse(&bytes, Path::new("t.stl")).unwrap();
            assert_eq!(back, m, "binary = {binary}");
        }
    }

    #[test]
    fn binary_normal_is_the_unit_face_normal() {
        let bytes = encode(&tetra(), true).unwrap();
        let f = |o: usize| f32::from_le_bytes([bytes[o], bytes[o + 1], bytes[o + 2], bytes[o + 3]]);
        // Triangle 0 = (0,0,0), (0,1,0), (1,0,0): normal -z.
        assert_eq!([f(84), f(88), f(92)], [0.0, 0.0, -1.0]);
    }

    #[test]
    fn binary_with_solid_header_is_binary() {
        let mut bytes = encode(&tetra(), true).unwrap();
        bytes[..11].copy_from_slice(b"solid thing");
        let back = parse(&bytes, Path::new("t.stl")).unwrap();
        assert_eq!(back, tetra());
    }

    #[test]
    fn negative_zero_welds_with_zero() {
        let src =
            b"solid\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n\
endloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex -0.0 0 0\nvertex 0 1 0\nvertex 1 1 0\n\
endloop\nendfacet\nendsolid\n";
        let m = parse(src, Path::new("t.stl")).unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }
}
