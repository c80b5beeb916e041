//! Object File Format (Geomview OFF) surfaces: `OFF`, then vertex, face and edge counts, the
//! vertices, and faces as `n i1 .. in` (polygons fan-split into triangles, per-face colours
//! after the indices ignored). `#` starts a comment. The writer emits triangles.

use std::fmt::Write as _;
use std::path::Path;

use super::cursor::Cursor;
use crate::error::IoError;
use crate::math::Vec3;
use crate::mesh::MeshData;

pub fn parse(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let mut c = Cursor::new(path, bytes);
    let next = |c: &mut Cursor, what: &str| -> Result<String, IoError> {
        loop {
            let l = c.expect_line(what)?;
            let l = l.split('#').next().unwrap_or("").trim();
            if !l.is_empty() {
                return Ok(l.to_string());
            }
        }
    };
    let first = next(&mut c, "the `OFF` keyword")?;
    // The counts may follow the keyword on the same line.
    let rest = match first.strip_prefix("OFF") {
        Some(r) => r.trim().to_string(),
        None if first.starts_with("COFF")
            || first.starts_with("NOFF")
            || first.starts_with("4OFF") =>
        {
            return Err(c.error(format!(
                "`{first}`: only plain OFF (3-D vertices, no per-vertex colours or normals) is read"
            )));
        }
        None => return Err(c.error(format!("expected `OFF`, found `{first}`"))),
    };
    let counts = if rest.is_empty() {
        next(&mut c, "the vertex, face and edge counts")?
    } else {
        rest
    };
    let mut t = counts.split_whitespace();
    let [nv, nf]: [usize; 2] = c.parse_n(&mut t, "the vertex and face counts")?;
    let mut mesh = MeshData::default();
    for _ in 0..nv {
        let l = next(&mut c, "a vertex")?;
        let mut t = l.split_whitespace();
        let mut xyz = [0.0; 3];
        for (k, slot) in xyz.iter_mut().enumerate() {
            let tok = t
                .next()
                .ok_or_else(|| c.error(format!("a vertex needs 3 coordinates, found {k}")))?;
            *slot = c.parse_real(tok, "a coordinate")?;
        }
        mesh.vertices.push(Vec3::from(xyz));
    }
    for _ in 0..nf {
        let l = next(&mut c, "a face")?;
        let mut t = l.split_whitespace();
        let n: usize = c.parse(t.next().unwrap_or(""), "the face's vertex count")?;
        if n < 3 {
            return Err(c.error(format!("a face needs at least 3 vertices, found {n}")));
        }
        // The count is the file's word: the line's length bounds what it can list.
        let mut ids = Vec::with_capacity(n.min(l.len()));
        for k in 0..n {
            let tok = t
                .next()
                .ok_or_else(|| c.error(format!("the face lists {k} of its {n} vertices")))?;
            let v: u32 = c.parse(tok, "a vertex index")?;
            if v as usize >= nv {
                return Err(c.error(format!(
                    "face refers to vertex {v}, but the file has {nv} vertices"
                )));
            }
            ids.push(v);
        }
        for k in 1..n - 1 {
            mesh.triangles.push([ids[0], ids[k], ids[k + 1]]);
        }
    }
    Ok(mesh)
}

pub fn encode(mesh: &MeshData) -> Result<Vec<u8>, String> {
    let mut s = String::new();
    let _ = writeln!(s, "OFF\n# written by tissue");
    let _ = writeln!(s, "{} {} 0", mesh.vertices.len(), mesh.triangles.len());
    for (i, v) in mesh.vertices.iter().enumerate() {
        if !crate::math::is_finite_vec(*v) {
            return Err(format!("vertex {i} has a non-finite coordinate"));
        }
        let _ = writeln!(s, "{:?} {:?} {:?}", v.x, v.y, v.z);
    }
    for [a, b, c] in &mesh.triangles {
        let _ = writeln!(s, "3 {a} {b} {c}");
    }
    Ok(s.into_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_polygons() {
        let text = b"OFF\n# a square and a triangle\n5 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n4 0 1 2 3\n3 0 1 4 255 0 0\n";
        let m = parse(text, Path::new("t.off")).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.vertices.len(), 5);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
        let again = parse(&encode(&m).unwrap_or_default(), Path::new("u.off"))
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(again, m);
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse(b"OFF\n2 1 0\n0 0 0\n1 0 0\n3 0 1 7\n", Path::new("bad.off"));
        let e = e.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.starts_with("bad.off:5:") && e.contains("vertex 7"), "{e}");
        let e = parse(b"OFF 3 1 0\n0 0\n", Path::new("b.off"));
        let e = e.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(
            e.starts_with("b.off:2:") && e.contains("3 coordinates"),
            "{e}"
        );
    }
}
