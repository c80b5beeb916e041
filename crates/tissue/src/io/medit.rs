//! MEDIT `.mesh` ascii files (INRIA's format, written by TetGen, MMG, CGAL): vertices,
//! triangles, quadrilaterals (fan-split), tetrahedra and their references. Other known
//! sections are skipped with their counts. Indices are 1-based in the file.

use std::fmt::Write as _;
use std::path::Path;
use std::str::SplitWhitespace;

use super::cursor::Cursor;
use crate::error::{IoError, Location};
use crate::math::Vec3;
use crate::mesh::MeshData;

/// Sections whose records are skipped, with the number of tokens per record.
const SKIPPED: &[(&str, usize)] = &[
    ("edges", 3),
    ("corners", 1),
    ("ridges", 1),
    ("requiredvertices", 1),
    ("requirededges", 1),
    ("requiredtriangles", 1),
    ("requiredquadrilaterals", 1),
    ("requiredtetrahedra", 1),
    ("normals", 3),
    ("normalatvertices", 2),
    ("normalattrianglevertices", 3),
    ("normalatquadrilateralvertices", 3),
    ("tangents", 3),
    ("tangentatvertices", 2),
    ("tangentatedges", 3),
    ("hexahedra", 9),
    ("prisms", 7),
    ("pyramids", 6),
];

/// Whitespace tokens over lines, `#` comments removed; the cursor's line is the token's.
struct Tokens<'a> {
    c: Cursor<'a>,
    len: usize,
    line: SplitWhitespace<'a>,
}

impl<'a> Tokens<'a> {
    fn next(&mut self) -> Result<Option<&'a str>, IoError> {
        loop {
            if let Some(t) = self.line.next() {
                return Ok(Some(t));
            }
            match self.c.next_line()? {
                Some(l) => self.line = l.split('#').next().unwrap_or("").split_whitespace(),
                None => return Ok(None),
            }
        }
    }

    fn expect(&mut self, what: &str) -> Result<&'a str, IoError> {
        self.next()?.ok_or_else(|| {
            self.c
                .error(format!("unexpected end of file, expected {what}"))
        })
    }

    fn number<T: std::str::FromStr>(&mut self, what: &str) -> Result<T, IoError> {
        let t = self.expect(what)?;
        self.c.parse(t, what)
    }

    fn real(&mut self, what: &str) -> Result<f64, IoError> {
        let t = self.expect(what)?;
        self.c.parse_real(t, what)
    }

    /// A 1-based vertex index as a 0-based u32.
    fn index(&mut self, what: &str) -> Result<u32, IoError> {
        let i: u64 = self.number(what)?;
        if i == 0 {
            return Err(self
                .c
                .error(format!("{what} is 0; MEDIT indices start at 1")));
        }
        u32::try_from(i - 1).map_err(|_| self.c.error(format!("{what} {i} is too large")))
    }

    /// The record count after a section keyword, and a reservation bound: each record takes
    /// at least two bytes per token, so no header can make us reserve more than the file.
    fn count(&mut self, section: &str, tokens: usize) -> Result<(u64, usize), IoError> {
        let n: u64 = self.number(&format!("the number of {section}"))?;
        let left = self.len.saturating_sub(self.c.position()) / (2 * tokens).max(1);
        Ok((n, n.min(left as u64) as usize))
    }
}

/// Reads a MEDIT ascii mesh.
pub fn parse(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let mut t = Tokens {
        c: Cursor::new(path, bytes),
        len: bytes.len(),
        line: "".split_whitespace(),
    };
    let mut mesh = MeshData::default();
    let mut seen_version = false;
    while let Some(key) = t.next()? {
        match key.to_ascii_lowercase().as_str() {
            "meshversionformatted" => {
                let v: u32 = t.number("the format version")?;
                if !(1..=4).contains(&v) {
                    return Err(t.c.error(format!("unsupported MEDIT version {v}")));
                }
                seen_version = true;
            }
            "dimension" => {
                let d: u32 = t.number("the dimension")?;
                if d != 3 {
                    return Err(t
                        .c
                        .error(format!("dimension {d}: only 3D meshes are supported")));
                }
            }
            "vertices" => {
                let (n, cap) = t.count("vertices", 4)?;
                mesh.vertices.reserve(cap);
                for _ in 0..n {
                    let p = [t.real("x")?, t.real("y")?, t.real("z")?];
                    let _: i64 = t.number("a vertex reference")?;
                    mesh.vertices.push(Vec3::from_array(p));
                }
            }
            "triangles" | "quadrilaterals" => {
                let k = if key.eq_ignore_ascii_case("triangles") {
                    3
                } else {
                    4
                };
                let (n, cap) = t.count(&key.to_ascii_lowercase(), k + 1)?;
                mesh.triangles.reserve(cap * (k - 2));
                mesh.triangle_tags.reserve(cap * (k - 2));
                let mut poly = [0u32; 4];
                for _ in 0..n {
                    for v in poly.iter_mut().take(k) {
                        *v = t.index("a vertex index")?;
                    }
                    let tag: i32 = t.number("an element reference")?;
                    let before = mesh.triangles.len();
                    super::obj::fan_split(&poly[..k], &mut mesh.triangles);
                    mesh.triangle_tags.resize(
                        mesh.triangle_tags.len() + mesh.triangles.len() - before,
                        tag,
                    );
                }
            }
            "tetrahedra" => {
                let (n, cap) = t.count("tetrahedra", 5)?;
                mesh.tets.reserve(cap);
                mesh.tet_tags.reserve(cap);
                for _ in 0..n {
                    let mut tet = [0u32; 4];
                    for v in &mut tet {
                        *v = t.index("a vertex index")?;
                    }
                    mesh.tets.push(tet);
                    mesh.tet_tags.push(t.number("an element reference")?);
                }
            }
            "end" => break,
            other => {
                let Some(&(name, per)) = SKIPPED.iter().find(|(s, _)| *s == other) else {
                    return Err(t
                        .c
                        .error(format!("unknown or unsupported MEDIT keyword `{key}`")));
                };
                let (n, _) = t.count(name, per)?;
                for _ in 0..n.saturating_mul(per as u64) {
                    t.expect(&format!("the data of section `{key}`"))?;
                }
            }
        }
    }
    if !seen_version {
        return Err(IoError::new(
            path,
            Location::Line(1),
            "not a MEDIT file: no `MeshVersionFormatted`",
        ));
    }
    // Reference 0 means "no reference"; all-zero tags are no tags.
    if mesh.triangle_tags.iter().all(|&r| r == 0) {
        mesh.triangle_tags.clear();
    }
    if mesh.tet_tags.iter().all(|&r| r == 0) {
        mesh.tet_tags.clear();
    }
    Ok(mesh)
}

/// Tags of `n` elements: the given ones, or zeros when there are none.
fn tags<'m>(
    tags: &'m [i32],
    n: usize,
    kind: &str,
) -> Result<Box<dyn Iterator<Item = i32> + 'm>, String> {
    match tags.len() {
        0 => Ok(Box::new(std::iter::repeat_n(0, n))),
        m if m == n => Ok(Box::new(tags.iter().copied())),
        m => Err(format!("{m} {kind} tags for {n} {kind}s")),
    }
}

/// Writes vertices (reference 0), triangles and tetrahedra with their tags (0 when none).
pub fn encode(mesh: &MeshData) -> Result<Vec<u8>, String> {
    if !mesh.tets10.is_empty() {
        return Err("MEDIT output of 10-node tetrahedra is not supported; use .vtu or .msh".into());
    }
    let mut s = String::with_capacity(
        40 * mesh.vertices.len() + 32 * mesh.triangles.len() + 40 * mesh.tets.len() + 100,
    );
    s.push_str("MeshVersionFormatted 2\n\nDimension 3\n\n");
    let _ = writeln!(s, "Vertices\n{}", mesh.vertices.len());
    for (i, v) in mesh.vertices.iter().enumerate() {
        if !crate::math::is_finite_vec(*v) {
            return Err(format!("vertex {i} has a non-finite coordinate"));
        }
        let _ = writeln!(s, "{:?} {:?} {:?} 0", v.x, v.y, v.z);
    }
    if !mesh.triangles.is_empty() {
        let _ = writeln!(s, "\nTriangles\n{}", mesh.triangles.len());
        let refs = tags(&mesh.triangle_tags, mesh.triangles.len(), "triangle")?;
        for ([a, b, c], r) in mesh.triangles.iter().zip(refs) {
            let _ = writeln!(
                s,
                "{} {} {} {r}",
                u64::from(*a) + 1,
                u64::from(*b) + 1,
                u64::from(*c) + 1
            );
        }
    }
    if !mesh.tets.is_empty() {
        let _ = writeln!(s, "\nTetrahedra\n{}", mesh.tets.len());
        let refs = tags(&mesh.tet_tags, mesh.tets.len(), "tetrahedron")?;
        for (tet, r) in mesh.tets.iter().zip(refs) {
            let [a, b, c, d] = tet.map(|i| u64::from(i) + 1);
            let _ = writeln!(s, "{a} {b} {c} {d} {r}");
        }
    }
    s.push_str("\nEnd\n");
    Ok(s.into_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p() -> &'static Path {
        Path::new("t.mesh")
    }

    #[test]
    fn reads_sections_case_insensitively() {
        let src =
            b"MeshVersionFormatted 1\n# comment\nDimension\n3\nVERTICES\n5\n0 0 0 1\n1 0 0 1\n\
0 1 0 1\n0 0 1 1\n1 1 1 0\nEdges 1\n1 2 7\nCorners\n1 1\nquadrilaterals\n1\n1 2 5 3 9\n\
Triangles\n1\n1 3 2 4\nTetrahedra 1\n1 2 3 4 -2\nRequiredVertices\n2\n1\n2\nEnd\n";
        let m = parse(src, p()).unwrap();
        assert_eq!(m.vertices.len(), 5);
        assert_eq!(m.vertices[4], Vec3::new(1.0, 1.0, 1.0));
        assert_eq!(m.triangles, vec![[0, 1, 4], [0, 4, 2], [0, 2, 1]]);
        assert_eq!(m.triangle_tags, vec![9, 9, 4]);
        assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
        assert_eq!(m.tet_tags, vec![-2]);
    }

    #[test]
    fn errors_name_the_line() {
        let cases: [(&[u8], &str); 6] = [
            (b"MeshVersionFormatted 2\nDimension 3\nVertices\nEnd\n", "t.mesh:4:"),
            (b"MeshVersionFormatted 2\nDimension 2\n", "t.mesh:2:"),
            (b"MeshVersionFormatted 2\nDimension 3\nVertices\n1\n0 0 0 0\nTriangles\n1\n1 1 0 0\n", "t.mesh:8:"),
            (b"MeshVersionFormatted 2\nDimension 3\nVertices\n2\n0 0 0 0\n", "t.mesh:5:"),
            (b"MeshVersionFormatted 2\nDimension 3\nVertices\n1\n0 x 0 0\n", "t.mesh:5:"),
            (b"MeshVersionFormatted 2\nDimension 3\n\nFoo 3\n", "t.mesh:4:"),
        ];
        for (src, want) in cases {
            let e = parse(src, p()).unwrap_err().to_string();
            assert!(e.starts_with(want), "{e} should start with {want}");
        }
    }

    #[test]
    fn writer_round_trips_with_and_without_tags() {
        let mut m = MeshData {
            vertices: vec![
                Vec3::new(0.1, 0.2, 0.3),
                Vec3::new(1.0 / 3.0, -1e-9, 0.0),
                Vec3::new(0.0, 1.0, 7e12),
                Vec3::new(0.0, 0.0, 1.0),
            ],
            triangles: vec![[0, 1, 2], [1, 2, 3]],
            tets: vec![[0, 1, 2, 3]],
            ..MeshData::default()
        };
        assert_eq!(parse(&encode(&m).unwrap(), p()).unwrap(), m);
        m.triangle_tags = vec![3, -1];
        m.tet_tags = vec![12];
        assert_eq!(parse(&encode(&m).unwrap(), p()).unwrap(), m);
        m.tet_tags = vec![1, 2];
        assert!(encode(&m).is_err());
    }
}
