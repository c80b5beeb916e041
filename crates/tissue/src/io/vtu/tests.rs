//! Unit tests of the `.vtu` reader on small hand-made files.

use std::path::Path;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;

use super::*;
use crate::math::Vec3;

#[test]
fn separately_encoded_header_and_big_endian() {
    // UInt32 big-endian header encoded apart from the data, as some writers do.
    let data: Vec<u8> = [1.5f32, -2.0, 0.25]
        .iter()
        .flat_map(|v| v.to_be_bytes())
        .collect();
    let header = STANDARD.encode(12u32.to_be_bytes());
    let body = STANDARD.encode(&data);
    let f = format!(
        "<VTKFile type=\"UnstructuredGrid\" byte_order=\"BigEndian\"><UnstructuredGrid>\
         <Piece NumberOfPoints=\"1\" NumberOfCells=\"0\"><Points>\
         <DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"binary\">{header}{body}</DataArray>\
         </Points></Piece></UnstructuredGrid></VTKFile>"
    );
    let m = parse(f.as_bytes(), Path::new("b.vtu")).unwrap();
    assert_eq!(m.vertices, vec![Vec3::new(1.5, -2.0, 0.25)]);
}

#[test]
fn lz4_and_lzma_are_refused_by_line() {
    for c in ["vtkLZ4DataCompressor", "vtkLZMADataCompressor"] {
        let f = format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" compressor=\"{c}\">\n</VTKFile>"
        );
        let e = parse(f.as_bytes(), Path::new("c.vtu")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with(&format!("c.vtu:2: compressor `{c}` is not supported")),
            "{e}"
        );
    }
}
