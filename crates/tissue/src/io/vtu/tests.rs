//! Unit tests of the `.vtu` reader on small hand-made files.

use std::path::Path;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;

use super::*;
use crate::error::Location;
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

/// A one-point file whose Points array is appended; `data` follows the `_`.
fn appended_file(attrs: &str, encoding: &str, data: &[u8]) -> Vec<u8> {
    let mut f = format!(
        "<VTKFile type=\"UnstructuredGrid\" {attrs}>\n<UnstructuredGrid>\n\
         <Piece NumberOfPoints=\"1\" NumberOfCells=\"0\"><Points>\n\
         <DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/>\n\
         </Points></Piece></UnstructuredGrid>\n<AppendedData encoding=\"{encoding}\">_"
    )
    .into_bytes();
    f.extend(data);
    f.extend(b"</AppendedData></VTKFile>");
    f
}

#[test]
fn appended_raw_big_endian_uint64() {
    let mut data = 12u64.to_be_bytes().to_vec();
    data.extend([1.0f32, 2.5, -4.0].iter().flat_map(|v| v.to_be_bytes()));
    // Binary bytes that look like markup must not disturb the reader.
    data.extend(b"<</>&");
    let f = appended_file(
        "byte_order=\"BigEndian\" header_type=\"UInt64\"",
        "raw",
        &data,
    );
    let m = parse(&f, Path::new("r.vtu")).unwrap();
    assert_eq!(m.vertices, vec![Vec3::new(1.0, 2.5, -4.0)]);
}

#[test]
fn concatenated_padded_base64_streams_decode() {
    // 4-byte header alone pads with "==", then the 12 data bytes.
    let data: Vec<u8> = [0.5f32, 0.25, 8.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let text = format!(
        "{}{}",
        STANDARD.encode(12u32.to_le_bytes()),
        STANDARD.encode(&data)
    );
    assert_eq!(text.matches('=').count(), 2);
    let f = appended_file("", "base64", text.as_bytes());
    let m = parse(&f, Path::new("b.vtu")).unwrap();
    assert_eq!(m.vertices, vec![Vec3::new(0.5, 0.25, 8.0)]);
    let raw = data::decode_base64(text.as_bytes()).unwrap();
    assert_eq!(raw.len(), 16);
}

#[test]
fn string_field_data_is_skipped() {
    let f = "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><FieldData>\
             <DataArray type=\"String\" Name=\"Info\" NumberOfTuples=\"1\" format=\"ascii\">104 105 0</DataArray>\
             </FieldData><Piece NumberOfPoints=\"1\" NumberOfCells=\"0\"><PointData>\
             <DataArray type=\"String\" Name=\"label\" format=\"ascii\">97 0</DataArray></PointData><Points>\
             <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">1 2 3</DataArray>\
             </Points></Piece></UnstructuredGrid></VTKFile>";
    let m = parse(f.as_bytes(), Path::new("s.vtu")).unwrap();
    assert_eq!(m.vertices, vec![Vec3::new(1.0, 2.0, 3.0)]);
    assert!(m.point_data.is_empty());
    let bad = f.replace("Float64", "String");
    let e = parse(bad.as_bytes(), Path::new("s.vtu")).unwrap_err();
    assert_eq!(
        e.to_string(),
        "s.vtu:1: unsupported DataArray type `String`"
    );
}

#[test]
fn information_keys_inside_a_data_array_are_not_data() {
    let f = "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>\
             <Piece NumberOfPoints=\"1\" NumberOfCells=\"0\"><Points>\
             <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\
             <InformationKey name=\"L2_NORM_RANGE\"><Value index=\"0\">7 7 7</Value></InformationKey>\
             1 2 3</DataArray></Points></Piece></UnstructuredGrid></VTKFile>";
    let m = parse(f.as_bytes(), Path::new("i.vtu")).unwrap();
    assert_eq!(m.vertices, vec![Vec3::new(1.0, 2.0, 3.0)]);
}

#[test]
fn zlib_blocks_full_partial_and_broken() {
    use std::io::Write;
    let z = |d: &[u8]| {
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
        e.write_all(d).unwrap();
        e.finish().unwrap()
    };
    let data: Vec<u8> = (0..10u8).collect();
    let header =
        |words: &[u32]| -> Vec<u8> { words.iter().flat_map(|w| w.to_le_bytes()).collect() };
    // Two full blocks of 5: last size 0 means "full".
    let (a, b) = (z(&data[..5]), z(&data[5..]));
    let mut raw = header(&[2, 5, 0, a.len() as u32, b.len() as u32]);
    raw.extend(&a);
    raw.extend(&b);
    assert_eq!(zlib::inflate(&raw, 4, false).unwrap().as_ref(), &data[..]);
    // Blocks of 4, 4 and a partial 2.
    let blocks: Vec<Vec<u8>> = data.chunks(4).map(z).collect();
    let mut raw = header(&[3, 4, 2]);
    blocks
        .iter()
        .for_each(|b| raw.extend((b.len() as u32).to_le_bytes()));
    blocks.iter().for_each(|b| raw.extend(b));
    assert_eq!(zlib::inflate(&raw, 4, false).unwrap().as_ref(), &data[..]);
    // A block that inflates to fewer bytes than announced.
    let mut raw = header(&[1, 11, 0, a.len() as u32]);
    raw.extend(&a);
    let (at, m) = zlib::inflate(&raw, 4, false).unwrap_err();
    assert_eq!(
        (at, m.as_str()),
        (16, "block 0 inflates to 5 bytes, but the header says 11")
    );
    // A truncated stream, and a last block larger than a block.
    let mut raw = header(&[1, 5, 0, a.len() as u32]);
    raw.extend(&a[..a.len() - 3]);
    let (at, m) = zlib::inflate(&raw, 4, false).unwrap_err();
    assert_eq!(at, 12);
    assert!(
        m.starts_with("block 0 is 13 compressed bytes but only 10 are left"),
        "{m}"
    );
    let (at, _) = zlib::inflate(&header(&[1, 4, 5, 0]), 4, false).unwrap_err();
    assert_eq!(at, 8);
}

#[test]
fn malformed_appended_sections_name_the_line() {
    let no_underscore =
        b"<VTKFile type=\"UnstructuredGrid\">\n<AppendedData encoding=\"raw\">\n  xyz";
    let e = parse(no_underscore, Path::new("u.vtu")).unwrap_err();
    assert_eq!(
        e.to_string(),
        "u.vtu:3: the appended data should start with `_`"
    );
    let f = appended_file("", "ascii85", b"");
    let e = parse(&f, Path::new("e.vtu")).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("e.vtu:6: AppendedData encoding `ascii85`"),
        "{e}"
    );
    // The XML before the appended data must close everything but <VTKFile>.
    let f = b"<VTKFile type=\"UnstructuredGrid\">\n<UnstructuredGrid>\n<AppendedData encoding=\"raw\">_";
    let e = parse(f, Path::new("o.vtu")).unwrap_err();
    assert_eq!(
        e.to_string(),
        "o.vtu:3: the XML before <AppendedData> ends inside <UnstructuredGrid>"
    );
    // Raw data runs to the end of the file: a header read from the closing tags announces
    // far more bytes than are left, named by the byte where the array starts.
    let f = appended_file("", "raw", &[1, 0]);
    let start = f.iter().rposition(|&b| b == b'_').unwrap() + 1;
    let e = parse(&f, Path::new("s.vtu")).unwrap_err();
    assert_eq!(e.location, Location::Byte(start as u64));
    assert!(e.message.contains("but 23 follow"), "{e}");
}

#[test]
fn points_with_two_components_say_so() {
    let f = "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>\
             <Piece NumberOfPoints=\"2\" NumberOfCells=\"0\"><Points>\
             <DataArray type=\"Float64\" NumberOfComponents=\"2\" format=\"ascii\">1 2 3 4 5 6\
             </DataArray></Points></Piece></UnstructuredGrid></VTKFile>";
    let e = parse(f.as_bytes(), Path::new("p.vtu")).unwrap_err();
    assert_eq!(
        e.to_string(),
        "p.vtu:1: Points has NumberOfComponents = 2, but points in space need 3"
    );
}

#[test]
fn polydata_reads_polygons_and_strips_and_skips_vertices_and_lines() {
    // Cells are numbered verts (1), lines (1), polys (1 quad), strips (1 strip of 5 points):
    // the tags of cells 2 and 3 belong to the quad and the strip.
    let f = "<VTKFile type=\"PolyData\"><PolyData>\
         <Piece NumberOfPoints=\"6\" NumberOfVerts=\"1\" NumberOfLines=\"1\" NumberOfPolys=\"1\" NumberOfStrips=\"1\">\
         <Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\
         0 0 0 1 0 0 0 1 0 1 1 0 0 2 0 1 2 0</DataArray></Points>\
         <CellData><DataArray type=\"Int32\" Name=\"tag\" format=\"ascii\">9 8 5 6</DataArray></CellData>\
         <Verts><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0</DataArray>\
         <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">1</DataArray></Verts>\
         <Lines><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1</DataArray>\
         <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">2</DataArray></Lines>\
         <Polys><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 3 2</DataArray>\
         <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4</DataArray></Polys>\
         <Strips><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">2 3 4 5 0</DataArray>\
         <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">5</DataArray></Strips>\
         </Piece></PolyData></VTKFile>";
    let m = parse(f.as_bytes(), Path::new("s.vtp")).unwrap();
    assert_eq!(
        m.triangles,
        vec![[0, 1, 3], [0, 3, 2], [2, 3, 4], [4, 3, 5], [4, 5, 0]]
    );
    assert_eq!(m.triangle_tags, vec![5, 5, 6, 6, 6]);
    // The strip's triangles all face the way its first one does (+z here).
    for t in &m.triangles[2..4] {
        let [a, b, c] = t.map(|i| m.vertices[i as usize]);
        assert!((b - a).cross(c - a).z > 0.0, "{t:?}");
    }
}

#[test]
fn polydata_counts_are_checked_by_section() {
    let f = "<VTKFile type=\"PolyData\"><PolyData>\n<Piece NumberOfPoints=\"3\" NumberOfPolys=\"2\">\
         <Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\
         0 0 0 1 0 0 0 1 0</DataArray></Points>\n<Polys>\
         <DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2</DataArray>\n\
         <DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">3</DataArray></Polys>\
         </Piece></PolyData></VTKFile>";
    let e = parse(f.as_bytes(), Path::new("p.vtp"))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("p.vtp:4:")
            && e.contains("Polys offsets has 1 values, but the Piece needs 2"),
        "{e}"
    );
    let e = parse(
        b"<VTKFile type=\"ImageData\"></VTKFile>",
        Path::new("i.vti"),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("only UnstructuredGrid (.vtu) and PolyData (.vtp)"),
        "{e}"
    );
}
