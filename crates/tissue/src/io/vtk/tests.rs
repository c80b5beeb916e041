//! Unit tests of the legacy reader on small hand-made files.

use std::path::Path;

use super::*;

fn p() -> &'static Path {
    Path::new("t.vtk")
}

#[test]
fn version_5_offsets_and_polydata() {
    let f = "# vtk DataFile Version 5.1\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 float\n0 0 0 1 0 0 0 1 0 0 0 1\n\
             CELLS 3 6\nOFFSETS vtktypeint64\n0 4 6\nCONNECTIVITY vtktypeint64\n0 1 2 3 0 1\nCELL_TYPES 2\n10\n3\n\
             CELL_DATA 2\nSCALARS gmsh:physical int 1\nLOOKUP_TABLE default\n7 8\n";
    let m = parse(f.as_bytes(), p()).unwrap();
    assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
    assert_eq!(m.tet_tags, vec![7]);
    let f = "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 4 float\n0 0 0 1 0 0 1 1 0 0 1 0\n\
             LINES 1 3\n2 0 1\nPOLYGONS 1 5\n4 0 1 2 3\nCELL_DATA 2\nSCALARS ref int\nLOOKUP_TABLE default\n0 3\n";
    let m = parse(f.as_bytes(), p()).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.triangle_tags, vec![3, 3]);
}

#[test]
fn binary_big_endian_points_and_scalars() {
    let mut f =
        b"# vtk DataFile Version 3.0\nb\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 3 double\n"
            .to_vec();
    for v in [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] {
        f.extend(v.to_be_bytes());
    }
    f.extend(b"\nCELLS 1 4\n");
    for v in [3i32, 0, 1, 2] {
        f.extend(v.to_be_bytes());
    }
    f.extend(b"\nCELL_TYPES 1\n");
    f.extend(5i32.to_be_bytes());
    f.extend(b"\nPOINT_DATA 3\nSCALARS s float\nLOOKUP_TABLE default\n");
    for v in [0.5f32, -1.0, 2.0] {
        f.extend(v.to_be_bytes());
    }
    let m = parse(&f, p()).unwrap();
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    assert_eq!(m.point_data[0].values, vec![0.5, -1.0, 2.0]);
}

#[test]
fn names_with_spaces_survive() {
    assert_eq!(decode_name(&encode_name("von Mises %")), "von Mises %");
}

#[test]
fn metadata_field_arrays_and_a_missing_lookup_table() {
    let f = "# vtk DataFile Version 5.1\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 2 float\n0 0 0 1 2 3\n\
             METADATA\nINFORMATION 1\nNAME L2_NORM_RANGE LOCATION vtkDataArray\nDATA 2 0 3.74\n\n\
             CELLS 0 0\nOFFSETS vtktypeint64\nCONNECTIVITY vtktypeint64\nCELL_TYPES 0\n\
             POINT_DATA 2\nSCALARS s double\n1.5 2.5\nFIELD FieldData 2\nw 2 2 int\n1 2 3 4\nother 1 1 float\n9\n";
    let m = parse(f.as_bytes(), p()).unwrap();
    assert_eq!(m.vertices.len(), 2);
    assert_eq!(m.point_data.len(), 2);
    assert_eq!(
        (m.point_data[0].name.as_str(), &m.point_data[0].values),
        ("s", &vec![1.5, 2.5])
    );
    assert_eq!(
        (m.point_data[1].components, &m.point_data[1].values),
        (2, &vec![1.0, 2.0, 3.0, 4.0])
    );
}
