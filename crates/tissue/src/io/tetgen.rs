//! TetGen's `.node` / `.ele` / `.face` files. Reading any of the three reads the set with
//! the same stem: the `.node` vertices, the `.ele` tetrahedra (4 or 10 nodes; a region
//! attribute becomes the tetrahedron's tag) and the `.face` triangles (a boundary marker
//! becomes the triangle's tag) where those files exist. Indices may start at 0 or 1, as the
//! first node says; of 10-node tetrahedra the corners are kept. Writing `x.ele` (or `.node`) writes `x.node`, `x.ele` and, when the
//! mesh has triangles, `x.face`, 0-based.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::cursor::Cursor;
use crate::error::{IoError, Location};
use crate::math::Vec3;
use crate::mesh::MeshData;

/// The three files of a set, by stem.
fn files(path: &Path) -> [PathBuf; 3] {
    ["node", "ele", "face"].map(|e| path.with_extension(e))
}

/// Reads the `.node` file and the `.ele` / `.face` files next to it.
pub fn read(path: &Path) -> Result<MeshData, IoError> {
    let [node, ele, face] = files(path);
    let bytes = std::fs::read(&node).map_err(|e| IoError::os(&node, "read the file", e))?;
    let (mut mesh, base) = parse_node(&bytes, &node)?;
    let read_opt = |p: &Path| -> Result<Option<Vec<u8>>, IoError> {
        match std::fs::read(p) {
            Ok(b) => Ok(Some(b)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(IoError::os(p, "read the file", e)),
        }
    };
    if let Some(b) = read_opt(&ele)? {
        parse_ele(&b, &ele, base, &mut mesh)?;
    }
    if let Some(b) = read_opt(&face)? {
        parse_face(&b, &face, base, &mut mesh)?;
    }
    if !mesh.has_volume() && mesh.triangles.is_empty() {
        return Err(IoError::new(
            &node,
            Location::File,
            format!(
                "neither {} nor {} holds elements",
                ele.display(),
                face.display()
            ),
        ));
    }
    Ok(mesh)
}

fn lines<'a>(c: &mut Cursor<'a>, what: &str) -> Result<Vec<&'a str>, IoError> {
    let l = loop {
        let l = c.expect_line(what)?;
        let l = l.split('#').next().unwrap_or("").trim();
        if !l.is_empty() {
            break l;
        }
    };
    Ok(l.split_whitespace().collect())
}

/// `.node`: `n dim attrs markers`, then `id x y z [attrs] [marker]`. Returns the first id.
pub fn parse_node(bytes: &[u8], path: &Path) -> Result<(MeshData, u32), IoError> {
    let mut c = Cursor::new(path, bytes);
    let h = lines(&mut c, "the node count line")?;
    let n: usize = c.parse(h.first().copied().unwrap_or(""), "the node count")?;
    let dim: usize = c.parse(h.get(1).copied().unwrap_or("3"), "the dimension")?;
    if dim != 3 {
        return Err(c.error(format!("dimension {dim}: only 3-D nodes are read")));
    }
    let mut mesh = MeshData::default();
    let mut base = 0;
    for k in 0..n {
        let t = lines(&mut c, "a node")?;
        if t.len() < 4 {
            return Err(c.error(format!(
                "a node needs an id and 3 coordinates, found {} values",
                t.len()
            )));
        }
        let id: u32 = c.parse(t[0], "a node id")?;
        if k == 0 {
            if id > 1 {
                return Err(c.error(format!("the first node is numbered {id}; expected 0 or 1")));
            }
            base = id;
        }
        if id as usize != k + base as usize {
            return Err(c.error(format!(
                "node {id} out of order: expected {}",
                k + base as usize
            )));
        }
        let x = c.parse_real(t[1], "a coordinate")?;
        let y = c.parse_real(t[2], "a coordinate")?;
        let z = c.parse_real(t[3], "a coordinate")?;
        mesh.vertices.push(Vec3::new(x, y, z));
    }
    Ok((mesh, base))
}

fn index(c: &Cursor, tok: &str, base: u32, n: usize) -> Result<u32, IoError> {
    let v: u32 = c.parse(tok, "a node index")?;
    let i = v.checked_sub(base).filter(|&i| (i as usize) < n);
    i.ok_or_else(|| {
        c.error(format!(
            "node {v} does not exist: the .node file numbers {n} nodes from {base}"
        ))
    })
}

/// `.ele`: `n nodes_per_tet attrs`, then `id n1 .. nk [attr]`.
pub fn parse_ele(bytes: &[u8], path: &Path, base: u32, mesh: &mut MeshData) -> Result<(), IoError> {
    let mut c = Cursor::new(path, bytes);
    let h = lines(&mut c, "the element count line")?;
    let n: usize = c.parse(h.first().copied().unwrap_or(""), "the element count")?;
    let per: usize = c.parse(h.get(1).copied().unwrap_or("4"), "nodes per tetrahedron")?;
    let attrs: usize = c.parse(h.get(2).copied().unwrap_or("0"), "the attribute count")?;
    if per != 4 && per != 10 {
        return Err(c.error(format!(
            "{per} nodes per tetrahedron; TetGen writes 4 or 10"
        )));
    }
    // The header's attribute count is the file's word: saturate rather than overflow (the
    // fuzzer gave 2^64 - 1), and the line-length check below refuses it.
    let values = attrs.saturating_add(1 + per);
    let nv = mesh.vertices.len();
    for _ in 0..n {
        let t = lines(&mut c, "a tetrahedron")?;
        if t.len() < values {
            return Err(c.error(format!("expected {values} values, found {}", t.len())));
        }
        let mut ids = [0u32; 10];
        for k in 0..per {
            ids[k] = index(&c, t[1 + k], base, nv)?;
        }
        // Of a 10-node tetrahedron only the corners are kept: TetGen's mid-edge order is
        // not VTK's, and the models here are linear.
        mesh.tets.push([ids[0], ids[1], ids[2], ids[3]]);
        if attrs > 0 {
            let a = c.parse_real(t[1 + per], "a region attribute")?;
            mesh.tet_tags.push(a as i32);
        }
    }
    Ok(())
}

/// `.face`: `n markers`, then `id a b c [marker]`.
pub fn parse_face(
    bytes: &[u8],
    path: &Path,
    base: u32,
    mesh: &mut MeshData,
) -> Result<(), IoError> {
    let mut c = Cursor::new(path, bytes);
    let h = lines(&mut c, "the face count line")?;
    let n: usize = c.parse(h.first().copied().unwrap_or(""), "the face count")?;
    let markers: usize = c.parse(h.get(1).copied().unwrap_or("0"), "the marker flag")?;
    let nv = mesh.vertices.len();
    for _ in 0..n {
        let t = lines(&mut c, "a face")?;
        if t.len() < 4 + markers.min(1) {
            return Err(c.error(format!(
                "expected {} values, found {}",
                4 + markers.min(1),
                t.len()
            )));
        }
        let f = [
            index(&c, t[1], base, nv)?,
            index(&c, t[2], base, nv)?,
            index(&c, t[3], base, nv)?,
        ];
        mesh.triangles.push(f);
        if markers > 0 {
            mesh.triangle_tags.push(c.parse(t[4], "a boundary marker")?);
        }
    }
    Ok(())
}

/// Encodes the set: `[node, ele, face]` texts (ele and face empty when there is nothing).
pub fn encode(mesh: &MeshData) -> Result<[String; 3], String> {
    if !mesh.tets10.is_empty() {
        return Err("writing 10-node tetrahedra to TetGen is not supported".into());
    }
    let mut node = String::new();
    let _ = writeln!(node, "{} 3 0 0", mesh.vertices.len());
    for (i, v) in mesh.vertices.iter().enumerate() {
        if !crate::math::is_finite_vec(*v) {
            return Err(format!("vertex {i} has a non-finite coordinate"));
        }
        let _ = writeln!(node, "{i} {:?} {:?} {:?}", v.x, v.y, v.z);
    }
    let mut ele = String::new();
    if !mesh.tets.is_empty() {
        let tagged = mesh.tet_tags.len() == mesh.tets.len();
        let _ = writeln!(ele, "{} 4 {}", mesh.tets.len(), u8::from(tagged));
        for (i, [a, b, c, d]) in mesh.tets.iter().enumerate() {
            let _ = write!(ele, "{i} {a} {b} {c} {d}");
            if tagged {
                let _ = write!(ele, " {}", mesh.tet_tags[i]);
            }
            ele.push('\n');
        }
    }
    let mut face = String::new();
    if !mesh.triangles.is_empty() {
        let tagged = mesh.triangle_tags.len() == mesh.triangles.len();
        let _ = writeln!(face, "{} {}", mesh.triangles.len(), u8::from(tagged));
        for (i, [a, b, c]) in mesh.triangles.iter().enumerate() {
            let _ = write!(face, "{i} {a} {b} {c}");
            if tagged {
                let _ = write!(face, " {}", mesh.triangle_tags[i]);
            }
            face.push('\n');
        }
    }
    Ok([node, ele, face])
}

/// Writes `x.node`, and `x.ele` / `x.face` when there is something to put in them.
pub fn write(path: &Path, mesh: &MeshData) -> Result<(), IoError> {
    let texts = encode(mesh).map_err(|m| IoError::new(path, Location::File, m))?;
    for (p, text) in files(path).iter().zip(texts) {
        if !text.is_empty() {
            std::fs::write(p, text).map_err(|e| IoError::os(p, "write the file", e))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_through_files_and_one_based_input() {
        let dir = std::env::temp_dir().join(format!("tissue-tetgen-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
        let mesh = MeshData {
            vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE],
            tets: vec![[0, 1, 2, 3], [1, 2, 3, 4]],
            tet_tags: vec![1, 2],
            triangles: vec![[0, 2, 1]],
            triangle_tags: vec![7],
            ..MeshData::default()
        };
        let p = dir.join("m.ele");
        write(&p, &mesh).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(read(&p).unwrap_or_else(|e| panic!("{e}")), mesh);
        // 1-based, comments, no .face.
        std::fs::write(
            dir.join("o.node"),
            "# c\n4 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n",
        )
        .unwrap_or_else(|e| panic!("{e}"));
        std::fs::write(dir.join("o.ele"), "1 4 0\n1 1 2 3 4\n").unwrap_or_else(|e| panic!("{e}"));
        let m = read(&dir.join("o.node")).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
        std::fs::write(dir.join("b.node"), "2 3 0 0\n0 0 0 0\n1 1 0 0\n")
            .unwrap_or_else(|e| panic!("{e}"));
        std::fs::write(dir.join("b.ele"), "1 4 0\n0 0 1 2 3\n").unwrap_or_else(|e| panic!("{e}"));
        let e = read(&dir.join("b.ele"))
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            e.contains("b.ele:2:") && e.contains("node 2 does not exist"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
