//! Unit tests of the Gmsh reader and writers on small hand-made files.

use std::path::Path;

use super::*;

fn p() -> &'static Path {
    Path::new("t.msh")
}

#[test]
fn tet10_order_swaps_the_last_two_edges() {
    let g: [u32; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9];
    assert_eq!(swap_tet10_order(g), [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]);
    assert_eq!(swap_tet10_order(swap_tet10_order(g)), g);
}

#[test]
fn v2_ascii_quad_is_split_and_lines_skipped() {
    let f = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n5 0 0 0\n6 1 0 0\n7 1 1 0\n8 0 1 0\n$EndNodes\n\
             $Elements\n3\n1 1 2 0 1 5 6\n2 3 2 9 1 5 6 7 8\n3 15 0 8\n$EndElements\n";
    let (m, r) = parse_with_report(f.as_bytes(), p()).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.triangle_tags, vec![9, 9]);
    assert_eq!(r.skipped.get(&1), Some(&1));
    assert_eq!(r.skipped.get(&15), Some(&1));
}

#[test]
fn binary_v2_big_endian_reads() {
    let mut f = b"$MeshFormat\n2.2 1 8\n".to_vec();
    f.extend(1i32.to_be_bytes());
    f.extend(b"\n$EndMeshFormat\n$Nodes\n3\n");
    for (id, x) in [(4i32, 0.5f64), (2, 1.5), (9, 2.5)] {
        f.extend(id.to_be_bytes());
        for v in [x, 0.0, -x] {
            f.extend(v.to_be_bytes());
        }
    }
    f.extend(b"\n$EndNodes\n$Elements\n1\n");
    for v in [2i32, 1, 1, 1, 7, 9, 2, 4] {
        f.extend(v.to_be_bytes());
    }
    f.extend(b"\n$EndElements\n");
    let m = parse(&f, p()).unwrap();
    assert_eq!(m.vertices[2].to_array(), [2.5, 0.0, -2.5]);
    assert_eq!(m.triangles, vec![[2, 1, 0]]);
    assert_eq!(m.triangle_tags, vec![7]);
}

#[test]
fn binary_v2_unknown_type_is_an_error_at_its_byte() {
    let mut f = b"$MeshFormat\n2.2 1 8\n".to_vec();
    f.extend(1i32.to_le_bytes());
    f.extend(b"\n$EndMeshFormat\n$Elements\n1\n");
    let at = f.len();
    for v in [77i32, 1, 0, 1] {
        f.extend(v.to_le_bytes());
    }
    let e = parse(&f, p()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with(&format!("t.msh: byte {at}: unknown element type 77")),
        "{e}"
    );
}

#[test]
fn v4_entity_tags_follow_physical_tags() {
    let m = MeshData {
        vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
        triangles: vec![[0, 1, 2], [0, 1, 3]],
        triangle_tags: vec![5, 0],
        tets: vec![[0, 1, 2, 3]],
        tet_tags: vec![-2],
        ..MeshData::default()
    };
    let text = String::from_utf8(encode(&m, crate::io::MshVersion::V4).unwrap()).unwrap();
    assert!(text.contains("\n0 0 2 1\n5 "), "{text}");
    assert!(text.contains("\n6 0.0 0.0 0.0 1.0 1.0 1.0 0 0\n"), "{text}");
    assert_eq!(parse(text.as_bytes(), p()).unwrap(), m);
}
