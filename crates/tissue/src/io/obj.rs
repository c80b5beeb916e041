//! Wavefront OBJ surfaces: `v` and `f` are read (polygons fan-split into triangles), every
//! other statement a modelling tool may write (`vn`, `vt`, `g`, `o`, `s`, `usemtl`, `mtllib`,
//! `l`...) is ignored. The writer emits `v` and `f` only, with shortest round-trip floats.

use std::fmt::Write as _;
use std::path::Path;

use super::cursor::Cursor;
use crate::error::{IoError, Location};
use crate::math::Vec3;
use crate::mesh::MeshData;

/// Reads an OBJ file's vertices and faces.
pub fn parse(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let mut c = Cursor::new(path, bytes);
    let mut mesh = MeshData::default();
    // Positive indices may legally point at vertices defined later in the file, so the
    // largest one is checked at the end, remembering its line for the error.
    let mut max_index: Option<(u64, usize)> = None;
    let mut polygon: Vec<u32> = Vec::new();
    while let Some(raw) = c.next_line()? {
        let line = raw.split('#').next().unwrap_or("");
        let mut tokens = line.split_whitespace();
        match tokens.next() {
            Some("v") => {
                let [x, y, z] = parse_xyz(&c, &mut tokens)?;
                // A fourth (w) component is allowed and meaningless for a surface.
                mesh.vertices.push(Vec3::new(x, y, z));
            }
            Some("f") | Some("fo") => {
                polygon.clear();
                for tok in tokens {
                    let v = face_index(&c, tok, mesh.vertices.len())?;
                    let one_based = u64::from(v) + 1;
                    if max_index.is_none_or(|(m, _)| one_based > m) {
                        max_index = Some((one_based, c.line()));
                    }
                    polygon.push(v);
                }
                if polygon.len() < 3 {
                    return Err(c.error(format!(
                        "a face needs at least 3 vertices, found {}",
                        polygon.len()
                    )));
                }
                fan_split(&polygon, &mut mesh.triangles);
            }
            _ => {}
        }
    }
    if let Some((m, line)) = max_index
        && m > mesh.vertices.len() as u64
    {
        return Err(IoError::new(
            path,
            Location::Line(line),
            format!(
                "face refers to vertex {m}, but the file has {} vertices",
                mesh.vertices.len()
            ),
        ));
    }
    Ok(mesh)
}

fn parse_xyz<'a>(
    c: &Cursor<'a>,
    tokens: &mut dyn Iterator<Item = &'a str>,
) -> Result<[f64; 3], IoError> {
    let mut out = [0.0; 3];
    for (k, slot) in out.iter_mut().enumerate() {
        let tok = tokens
            .next()
            .ok_or_else(|| c.error(format!("a vertex needs x, y and z, found {k} values")))?;
        *slot = c.parse_real(tok, "a vertex coordinate")?;
    }
    Ok(out)
}

/// The 0-based vertex of one face token (`v`, `v/vt`, `v/vt/vn`, `v//vn`); negative indices
/// count back from the last vertex defined so far.
fn face_index(c: &Cursor<'_>, tok: &str, defined: usize) -> Result<u32, IoError> {
    let head = tok.split('/').next().unwrap_or("");
    let i: i64 = c.parse(head, "a vertex index")?;
    let zero_based = match i {
        0 => return Err(c.error("vertex index 0 in a face: OBJ indices start at 1")),
        i if i > 0 => i - 1,
        i => {
            let r = defined as i64 + i;
            if r < 0 {
                return Err(c.error(format!(
                    "relative vertex index {i} reaches before the first vertex ({defined} defined so far)"
                )));
            }
            r
        }
    };
    u32::try_from(zero_based).map_err(|_| c.error(format!("vertex index {i} is too large")))
}

/// Splits a convex polygon into triangles around its first vertex.
pub(crate) fn fan_split(polygon: &[u32], out: &mut Vec<[u32; 3]>) {
    if let Some((&first, rest)) = polygon.split_first() {
        out.extend(rest.windows(2).map(|w| [first, w[0], w[1]]));
    }
}

/// Writes `v` and `f` lines; coordinates use the shortest text that reads back to the same f64.
pub fn encode(mesh: &MeshData) -> Result<Vec<u8>, String> {
    let mut s = String::with_capacity(32 * mesh.vertices.len() + 24 * mesh.triangles.len());
    s.push_str("# written by tissue\n");
    for (i, v) in mesh.vertices.iter().enumerate() {
        if !crate::math::is_finite_vec(*v) {
            return Err(format!("vertex {i} has a non-finite coordinate"));
        }
        // Debug formatting of f64 is the shortest round-trip text (and uses exponents for
        // very large or small values, which every OBJ reader accepts).
        let _ = writeln!(s, "v {:?} {:?} {:?}", v.x, v.y, v.z);
    }
    for [a, b, c] in &mesh.triangles {
        let _ = writeln!(
            s,
            "f {} {} {}",
            u64::from(*a) + 1,
            u64::from(*b) + 1,
            u64::from(*c) + 1
        );
    }
    Ok(s.into_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("t.obj")
    }

    #[test]
    fn all_face_forms_and_relative_indices() {
        let src = b"# c\r\nmtllib missing.mtl\r\no x\r\nv 0 0 0\r\nv 1 0 0 1.0\r\nv 1 1 0\r\nv 0 1 0\r\n\
vt 0 0\r\nvn 0 0 1\r\ng grp\r\ns 1\r\nusemtl m\r\nf 1 2 3\r\nf 1/1 3/1 4/1\r\nf 1/1/1 2/1/1 3/1/1\r\n\
f 1//1 3//1 4//1\r\nf -4 -3 -2 -1\r\nl 1 2\r\n";
        let m = parse(src, p()).unwrap();
        assert_eq!(m.vertices.len(), 4);
        assert_eq!(m.vertices[1], Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(
            m.triangles,
            vec![
                [0, 1, 2],
                [0, 2, 3],
                [0, 1, 2],
                [0, 2, 3],
                [0, 1, 2],
                [0, 2, 3]
            ]
        );
    }

    #[test]
    fn errors_name_the_line() {
        let cases: [(&[u8], &str); 7] = [
            (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "t.obj:4:"),
            (b"v 0 0 0\nv 1 x 0\n", "t.obj:2:"),
            (b"v 0 0 0\nv 1 0\n", "t.obj:2:"),
            (b"v 0 0 0\nv 1 0 0\nf 1 2\n", "t.obj:3:"),
            (b"v 0 0 0\nf 1 2 3\nv 1 0 0\nv 0 0 1\n", ""),
            (b"v 0 0 0\nv 1 0 0\n\nf 1 2 7\n", "t.obj:4:"),
            (b"v 0 0 0\nf -1 -2 -3\n", "t.obj:2:"),
        ];
        for (src, want) in cases {
            let r = parse(src, p());
            if want.is_empty() {
                // Forward references are allowed when the vertices do come later.
                assert_eq!(r.unwrap().triangles, vec![[0, 1, 2]]);
            } else {
                let e = r.unwrap_err().to_string();
                assert!(e.starts_with(want), "{e} should start with {want}");
            }
        }
    }

    #[test]
    fn writer_round_trips_exactly() {
        let m = MeshData {
            vertices: vec![
                Vec3::new(0.1, -2.5e-300, 1e300),
                Vec3::new(1.0 / 3.0, 0.0, -0.0),
                Vec3::new(12345.678, 1e-7, 2.0_f64.sqrt()),
            ],
            triangles: vec![[0, 1, 2], [2, 1, 0]],
            ..MeshData::default()
        };
        let back = parse(&encode(&m).unwrap(), p()).unwrap();
        assert_eq!(back, m);
    }
}
