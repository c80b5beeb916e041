//! Volume mesh formats (Gmsh, VTK legacy, VTU, ParaView collections): the liver through every
//! writer and back, hand-written files with exact expected arrays, malformed files whose errors
//! must name the file and line or byte, and random input that must never panic.

use std::path::Path;

use proptest::prelude::*;
use tissue::Vec3;
use tissue::io::{self, Format, MshVersion, WriteOptions, msh, series, vtk, vtu};
use tissue::mesh::{Field, MeshData, boundary_surface};

const LIVER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");

fn liver() -> MeshData {
    io::read(LIVER).expect("liver.msh loads")
}

/// Equality that also compares coordinates and field values bit for bit.
fn assert_identical(a: &MeshData, b: &MeshData, what: &str) {
    let bits = |m: &MeshData| {
        m.vertices
            .iter()
            .flat_map(|p| p.to_array())
            .map(f64::to_bits)
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(a), bits(b), "{what}: vertices");
    assert_eq!(a.triangles, b.triangles, "{what}: triangles");
    assert_eq!(a.tets, b.tets, "{what}: tets");
    assert_eq!(a.tets10, b.tets10, "{what}: tets10");
    assert_eq!(a.triangle_tags, b.triangle_tags, "{what}: triangle tags");
    assert_eq!(a.tet_tags, b.tet_tags, "{what}: tet tags");
    assert_eq!(a.point_data.len(), b.point_data.len(), "{what}: fields");
    for (f, g) in a.point_data.iter().zip(&b.point_data) {
        assert_eq!((&f.name, f.components), (&g.name, g.components), "{what}");
        let fb: Vec<u64> = f.values.iter().map(|v| v.to_bits()).collect();
        let gb: Vec<u64> = g.values.iter().map(|v| v.to_bits()).collect();
        assert_eq!(fb, gb, "{what}: field {}", f.name);
    }
}

#[test]
fn liver_v1_counts_volume_and_boundary() {
    let m = liver();
    assert_eq!(m.vertices.len(), 181);
    assert_eq!(m.tets.len(), 596);
    assert!(m.triangles.is_empty() && m.tets10.is_empty());
    assert_eq!(m.tet_tags, vec![1; 596]);
    let tets = m.tet_mesh("x").unwrap();
    assert!(
        (tets.volume() - 36.561).abs() < 1e-3,
        "volume {}",
        tets.volume()
    );
    let b = boundary_surface(&tets);
    assert_eq!(b.surface.triangles.len(), 276);
    assert_eq!(b.nodes.len(), 140);
    let (_, report) =
        msh::parse_with_report(&std::fs::read(LIVER).unwrap(), Path::new(LIVER)).unwrap();
    assert!(report.skipped.is_empty());
}

/// The liver with a vector and a scalar field and a few tagged triangles, so every kind of
/// data is carried.
fn liver_with_data() -> MeshData {
    let mut m = liver();
    let n = m.vertices.len();
    let u: Vec<f64> = m
        .vertices
        .iter()
        .flat_map(|p| [p.x * 1e-3, -p.y / 3.0, p.z.sin()])
        .collect();
    let s: Vec<f64> = (0..n)
        .map(|i| (i as f64).sqrt() * std::f64::consts::PI)
        .collect();
    m.point_data = vec![
        Field {
            name: "displacement".into(),
            components: 3,
            values: u,
        },
        Field {
            name: "von Mises".into(),
            components: 1,
            values: s,
        },
    ];
    m.triangles = vec![[0, 1, 2], [3, 4, 5]];
    m.triangle_tags = vec![4, 9];
    m
}

#[test]
fn liver_round_trips_through_every_writer() {
    let m = liver_with_data();
    let p = Path::new("rt");
    let geometry = MeshData {
        point_data: Vec::new(),
        ..m.clone()
    };
    let cases: Vec<(&str, Vec<u8>, Format)> = vec![
        (
            "msh v2",
            msh::encode(&m, MshVersion::V2).unwrap(),
            Format::Msh,
        ),
        (
            "msh v2 binary",
            msh::encode_v2_binary(&m).unwrap(),
            Format::Msh,
        ),
        (
            "msh v4.1",
            msh::encode(&m, MshVersion::V4).unwrap(),
            Format::Msh,
        ),
    ];
    for (what, bytes, format) in cases {
        let back = io::parse(format, &bytes, p).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_identical(&geometry, &back, what);
    }
    let ascii = WriteOptions {
        binary: false,
        ..WriteOptions::default()
    };
    let cases: Vec<(&str, Vec<u8>, Format)> = vec![
        ("vtk", vtk::encode(&m).unwrap(), Format::Vtk),
        (
            "vtu ascii",
            io::encode(Format::Vtu, &m, &ascii).unwrap(),
            Format::Vtu,
        ),
        (
            "vtu base64",
            io::encode(Format::Vtu, &m, &WriteOptions::default()).unwrap(),
            Format::Vtu,
        ),
    ];
    for (what, bytes, format) in cases {
        let back = io::parse(format, &bytes, p).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_identical(&m, &back, what);
    }
    // The original tagless v1 file through v4 keeps its tags as entity = physical tag 1.
    let v4 = String::from_utf8(msh::encode(&liver(), MshVersion::V4).unwrap()).unwrap();
    assert!(v4.contains("$Entities\n0 0 0 1\n1 "), "{}", &v4[..200]);
}

#[test]
fn files_on_disk_and_pvd_series() {
    let dir = std::env::temp_dir().join(format!("tissue-io-volume-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let m = liver_with_data();
    let mut entries = Vec::new();
    for (k, ext) in ["vtu", "vtk", "msh"].iter().enumerate() {
        let name = format!("frame_{k:04}.{ext}");
        io::write(dir.join(&name), &m).unwrap();
        let back = io::read(dir.join(&name)).unwrap();
        assert_eq!(back.tets, m.tets, "{ext}");
        entries.push((k as f64 * 0.01, name));
    }
    let pvd = dir.join("series.pvd");
    series::write_pvd(&pvd, &entries).unwrap();
    let back = series::parse_pvd(&std::fs::read(&pvd).unwrap(), &pvd).unwrap();
    assert_eq!(back, entries);
    std::fs::remove_dir_all(&dir).unwrap();
}

const V41: &str = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n2\n2 5 \"skin\"\n3 7 \"body\"\n$EndPhysicalNames\n\
$Entities\n1 1 1 1\n1 0 0 0 0\n1 0 0 0 1 0 0 0 2 1 -1\n1 0 0 0 1 1 1 1 5 0\n1 0 0 0 1 1 1 1 7 0\n$EndEntities\n\
$Nodes\n2 11 3 100\n0 1 0 1\n10\n0 0 0\n3 1 0 10\n3\n7\n100\n4\n50\n51\n52\n53\n54\n55\n\
1 0 0\n0 1 0\n0 0 1\n1 1 1\n0.5 0 0\n0.5 0.5 0\n0 0.5 0\n0 0 0.5\n0 0.5 0.5\n0.5 0 0.5\n$EndNodes\n\
$Elements\n5 7 1 7\n0 1 15 1\n1 10\n1 1 1 2\n2 10 3\n3 7 3\n2 1 2 2\n4 10 3 7\n5 3 4 7\n\
3 1 4 1\n6 10 3 7 100\n3 1 11 1\n7 10 3 7 100 50 51 52 53 54 55\n$EndElements\n";

#[test]
fn hand_written_v41_sparse_ids_mixed_elements_two_groups() {
    let (m, report) = msh::parse_with_report(V41.as_bytes(), Path::new("h.msh")).unwrap();
    let v = |x, y, z| Vec3::new(x, y, z);
    assert_eq!(
        m.vertices,
        vec![
            v(0., 0., 0.),
            v(1., 0., 0.),
            v(0., 1., 0.),
            v(0., 0., 1.),
            v(1., 1., 1.),
            v(0.5, 0., 0.),
            v(0.5, 0.5, 0.),
            v(0., 0.5, 0.),
            v(0., 0., 0.5),
            v(0., 0.5, 0.5),
            v(0.5, 0., 0.5),
        ]
    );
    assert_eq!(m.triangles, vec![[0, 1, 2], [1, 4, 2]]);
    assert_eq!(m.triangle_tags, vec![5, 5]);
    assert_eq!(m.tets, vec![[0, 1, 2, 3]]);
    assert_eq!(m.tet_tags, vec![7]);
    assert_eq!(m.tets10, vec![[0, 1, 2, 3, 5, 6, 7, 8, 10, 9]]);
    assert_eq!(
        report.skipped.into_iter().collect::<Vec<_>>(),
        vec![(1, 2), (15, 1)]
    );
}

/// Every mid-edge node of a VTK-ordered quadratic tet lies at the middle of its edge.
fn check_vtk_tet10(m: &MeshData, what: &str) {
    const EDGES: [[usize; 2]; 6] = [[0, 1], [1, 2], [0, 2], [0, 3], [1, 3], [2, 3]];
    let t = m.tets10[0];
    for (k, [a, b]) in EDGES.iter().enumerate() {
        let mid = (m.vertices[t[*a] as usize] + m.vertices[t[*b] as usize]) * 0.5;
        assert_eq!(
            m.vertices[t[4 + k] as usize],
            mid,
            "{what}: node {} on edge {a}-{b}",
            4 + k
        );
    }
}

#[test]
fn tet10_keeps_vtk_order_through_every_format() {
    let m = msh::parse(V41.as_bytes(), Path::new("h.msh")).unwrap();
    check_vtk_tet10(&m, "v4.1 read");
    // Node 8 in VTK order is edge (1,3): (1,0,0)-(0,0,1).
    assert_eq!(
        m.vertices[m.tets10[0][8] as usize],
        Vec3::new(0.5, 0.0, 0.5)
    );
    let only = MeshData {
        vertices: m.vertices.clone(),
        tets10: m.tets10.clone(),
        ..MeshData::default()
    };
    let v2 = msh::encode(&only, MshVersion::V2).unwrap();
    // Written back in Gmsh order: ..., edge (2,3) = node 10 (1-based), edge (1,3) = node 11.
    assert!(String::from_utf8_lossy(&v2).contains("1 11 2 0 1 1 2 3 4 6 7 8 9 10 11\n"));
    let files = [
        ("msh v2", v2, Format::Msh),
        (
            "msh v4",
            msh::encode(&only, MshVersion::V4).unwrap(),
            Format::Msh,
        ),
        (
            "msh v2 binary",
            msh::encode_v2_binary(&only).unwrap(),
            Format::Msh,
        ),
        ("vtk", vtk::encode(&only).unwrap(), Format::Vtk),
        ("vtu", vtu::encode(&only, true).unwrap(), Format::Vtu),
        ("vtu ascii", vtu::encode(&only, false).unwrap(), Format::Vtu),
    ];
    for (what, bytes, format) in files {
        let back = io::parse(format, &bytes, Path::new("q")).unwrap();
        assert_eq!(back.tets10, only.tets10, "{what}");
        check_vtk_tet10(&back, what);
    }
}

fn v2_text(nodes: &str, elements: &str) -> String {
    format!(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n{nodes}$EndNodes\n$Elements\n{elements}$EndElements\n"
    )
}

fn err(format: Format, bytes: &[u8], name: &str) -> String {
    io::parse(format, bytes, Path::new(name))
        .expect_err("must be rejected")
        .to_string()
}

fn assert_starts(e: &str, prefix: &str) {
    assert!(
        e.starts_with(prefix),
        "error `{e}` should start with `{prefix}`"
    );
}

#[test]
fn malformed_gmsh_files_name_the_line_or_byte() {
    let nodes = "3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n";
    // Truncated $Nodes: the file ends after the second node (line 7).
    let e = err(
        Format::Msh,
        b"$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n",
        "a.msh",
    );
    assert_starts(&e, "a.msh:7: unexpected end of file, expected a node line");
    // $EndNodes too early, on line 8.
    let e = err(
        Format::Msh,
        v2_text("3\n1 0 0 0\n2 1 0 0\n", "0\n").as_bytes(),
        "b.msh",
    );
    assert_starts(
        &e,
        "b.msh:8: the section declares 3 nodes but `$EndNodes` follows node 2",
    );
    // Missing $EndElements: the file ends on line 12.
    let f = format!(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n{nodes}$EndNodes\n$Elements\n1\n1 2 2 1 1 1 2 3\n"
    );
    assert_starts(
        &err(Format::Msh, f.as_bytes(), "c.msh"),
        "c.msh:12: unexpected end of file, expected `$EndElements`",
    );
    // An element naming an undefined node, on line 13.
    let e = err(
        Format::Msh,
        v2_text(nodes, "2\n1 2 2 1 1 1 2 3\n2 2 2 1 1 1 2 44\n").as_bytes(),
        "d.msh",
    );
    assert_starts(
        &e,
        "d.msh:13: element refers to node id 44, which is not defined",
    );
    // A bad number on line 7.
    let e = err(
        Format::Msh,
        v2_text("3\n1 0 0 0\n2 1 0x 0\n3 0 1 0\n", "0\n").as_bytes(),
        "e.msh",
    );
    assert_starts(&e, "e.msh:7: expected a coordinate, found `0x`");
    // A triangle with 4 nodes, line 12.
    let e = err(
        Format::Msh,
        v2_text(nodes, "1\n1 2 0 1 2 3 1\n").as_bytes(),
        "f.msh",
    );
    assert_starts(&e, "f.msh:12: element of type 2 needs 3 nodes, found 4");
    // v1: a node count that disagrees with the list, line 7.
    let e = err(
        Format::Msh,
        b"$NOD\n1\n1 0 0 0\n$ENDNOD\n$ELM\n1\n1 4 1 1 4 1 1 1\n$ENDELM\n",
        "g.msh",
    );
    assert_starts(&e, "g.msh:7: the element declares 4 nodes but lists 3");
    // v4.1: the blocks hold fewer nodes than the header declares.
    let bad = V41.replace("$Nodes\n2 11 3 100", "$Nodes\n2 12 3 100");
    assert_starts(
        &err(Format::Msh, bad.as_bytes(), "h.msh"),
        "h.msh:17: the header declares 12 nodes but the blocks hold 11",
    );
    // Binary v2 truncated inside the third node record: caught before reading the nodes.
    let tri = MeshData {
        vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        triangles: vec![[0, 1, 2]],
        ..MeshData::default()
    };
    let full = msh::encode_v2_binary(&tri).unwrap();
    let start = full.windows(9).position(|w| w == b"$Nodes\n3\n").unwrap() + 9;
    let e = err(Format::Msh, &full[..start + 2 * 28 + 10], "i.msh");
    assert_eq!(
        e,
        format!(
            "i.msh: byte {start}: the section declares 3 binary nodes (84 bytes) but only 66 bytes are left"
        )
    );
    // Binary v2 truncated inside the element record, after its 12-byte block header.
    let start = full
        .windows(12)
        .position(|w| w == b"$Elements\n1\n")
        .unwrap()
        + 12;
    let e = err(Format::Msh, &full[..start + 12 + 10], "k.msh");
    assert_eq!(
        e,
        format!(
            "k.msh: byte {}: unexpected end of file: 24 bytes of binary data needed, 10 left",
            start + 12
        )
    );
    // Binary v2 whose endianness check is not 1.
    let mut bad = full.clone();
    bad[20] = 7;
    assert_starts(
        &err(Format::Msh, &bad, "j.msh"),
        "j.msh: byte 20: the binary endianness check",
    );
}

const VTK_OK: &str = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n\
CELLS 2 9\n3 0 1 2\n4 0 1 2 3\nCELL_TYPES 2\n5\n10\n";

#[test]
fn malformed_vtk_files_name_the_line() {
    assert!(io::parse(Format::Vtk, VTK_OK.as_bytes(), Path::new("ok.vtk")).is_ok());
    // CELLS declares a size of 10 but the cells use 9: the values run into CELL_TYPES.
    let bad = VTK_OK.replace("CELLS 2 9", "CELLS 2 10");
    let e = err(Format::Vtk, bad.as_bytes(), "a.vtk");
    assert_starts(
        &e,
        "a.vtk:13: expected a number for CELLS (value 10 of 10), found `CELL_TYPES`",
    );
    let bad = VTK_OK.replace("CELLS 2 9", "CELLS 3 9");
    assert_starts(
        &err(Format::Vtk, bad.as_bytes(), "b.vtk"),
        "b.vtk:10: CELLS declares 3 cells in 9 values, but the values end after 2 cells",
    );
    let bad = VTK_OK.replace("1 0 0\n0 1", "1 zero 0\n0 1");
    assert_starts(
        &err(Format::Vtk, bad.as_bytes(), "c.vtk"),
        "c.vtk:7: expected a number for POINTS (value 5 of 12), found `zero`",
    );
    let bad = VTK_OK.replace("CELL_TYPES 2\n5\n10\n", "CELL_TYPES 1\n5\n");
    assert_starts(
        &err(Format::Vtk, bad.as_bytes(), "d.vtk"),
        "d.vtk:13: CELL_TYPES lists 1 types but CELLS has 2 cells",
    );
    let bad = VTK_OK.replace("4 0 1 2 3", "4 0 1 2 9");
    assert_starts(
        &err(Format::Vtk, bad.as_bytes(), "e.vtk"),
        "e.vtk:10: CELLS refers to point 9, but the file has 4 points",
    );
    let bad = format!("{VTK_OK}POINT_DATA 5\n");
    assert_starts(
        &err(Format::Vtk, bad.as_bytes(), "f.vtk"),
        "f.vtk:16: POINT_DATA declares 5 tuples but the file has 4 points",
    );
}

#[test]
fn malformed_vtu_files_name_the_line() {
    let tri = MeshData {
        vertices: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        triangles: vec![[0, 1, 2]],
        ..MeshData::default()
    };
    let good = String::from_utf8(vtu::encode(&tri, true).unwrap()).unwrap();
    let line_of =
        |text: &str, needle: &str| 1 + text[..text.find(needle).unwrap()].matches('\n').count();
    let points = line_of(&good, "Name=\"Points\"");
    // Base64 broken inside the points array.
    let at = good.find("Name=\"Points\"").unwrap();
    let data = at + good[at..].find('\n').unwrap() + 12;
    let mut bad = good.clone();
    bad.replace_range(data..data + 1, "*");
    let e = err(Format::Vtu, bad.as_bytes(), "a.vtu");
    assert_starts(
        &e,
        &format!("a.vtu:{points}: DataArray `Points`: bad base64 data"),
    );
    // A Piece announcing 4 points for 3.
    let bad = good.replace("NumberOfPoints=\"3\"", "NumberOfPoints=\"4\"");
    let e = err(Format::Vtu, bad.as_bytes(), "b.vtu");
    assert_starts(
        &e,
        &format!("b.vtu:{points}: Points has 9 values, but the Piece needs 12"),
    );
    // Ascii connectivity naming a missing point.
    let ascii = String::from_utf8(vtu::encode(&tri, false).unwrap()).unwrap();
    let bad = ascii.replace("          0 1 2\n", "          0 1 3\n");
    let conn = line_of(&bad, "Name=\"connectivity\"");
    assert_starts(
        &err(Format::Vtu, bad.as_bytes(), "c.vtu"),
        &format!("c.vtu:{conn}: connectivity refers to point 3"),
    );
    // An appended array in a file without <AppendedData> is refused by line.
    let bad = ascii.replacen("format=\"ascii\"", "format=\"appended\" offset=\"0\"", 1);
    let e = err(Format::Vtu, bad.as_bytes(), "d.vtu");
    assert_starts(
        &e,
        &format!("d.vtu:{}: DataArray", line_of(&bad, "appended")),
    );
    assert!(e.contains("the file has no <AppendedData>"), "{e}");
    // Broken XML: an unclosed element.
    let e = err(
        Format::Vtu,
        ascii.replace("</Points>", "").as_bytes(),
        "e.vtu",
    );
    assert!(e.starts_with("e.vtu:") && e.contains("XML error"), "{e}");
    // The binary header announces more bytes than follow.
    let short = {
        let mut raw = 100u64.to_le_bytes().to_vec();
        raw.extend([0u8; 72]);
        use base64::Engine;
        base64::engine::general_purpose::STANDARD.encode(raw)
    };
    let start = good[at..].find('\n').unwrap() + at + 1;
    let end = start + good[start..].find('\n').unwrap();
    let mut bad = good.clone();
    bad.replace_range(start..end, &short);
    assert_starts(
        &err(Format::Vtu, bad.as_bytes(), "f.vtu"),
        &format!("f.vtu:{points}: DataArray `Points`: the header announces 100 bytes"),
    );
}

/// The liver in every format, for mutation.
fn seeds() -> Vec<(Format, Vec<u8>)> {
    let m = liver_with_data();
    let small = MeshData {
        point_data: Vec::new(),
        ..m.clone()
    };
    vec![
        (Format::Msh, std::fs::read(LIVER).unwrap()),
        (Format::Msh, msh::encode(&small, MshVersion::V2).unwrap()),
        (Format::Msh, msh::encode_v2_binary(&small).unwrap()),
        (Format::Msh, msh::encode(&small, MshVersion::V4).unwrap()),
        (Format::Msh, V41.as_bytes().to_vec()),
        (Format::Vtk, vtk::encode(&m).unwrap()),
        (Format::Vtk, VTK_OK.as_bytes().to_vec()),
        (Format::Vtu, vtu::encode(&m, false).unwrap()),
        (Format::Vtu, vtu::encode(&m, true).unwrap()),
    ]
}

fn all_parsers(bytes: &[u8]) {
    for f in [Format::Msh, Format::Vtk, Format::Vtu] {
        let _ = io::parse(f, bytes, Path::new("fuzz"));
    }
    let _ = series::parse_pvd(bytes, Path::new("fuzz.pvd"));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..600), prefix in 0usize..6) {
        let heads: [&[u8]; 6] = [b"", b"$MeshFormat\n2.2 1 8\n", b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n",
            b"$NOD\n", b"# vtk DataFile Version 5.1\nx\nBINARY\nDATASET UNSTRUCTURED_GRID\n",
            b"<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece NumberOfPoints=\"1\" NumberOfCells=\"1\">"];
        let mut data = heads[prefix].to_vec();
        data.extend(bytes);
        all_parsers(&data);
    }

    #[test]
    fn mutated_files_never_panic(
        seed in 0usize..9,
        edits in prop::collection::vec((any::<u32>(), 0u8..4, any::<u8>()), 1..6),
    ) {
        let seeds = seeds();
        let (format, mut data) = seeds[seed % seeds.len()].clone();
        for (at, kind, byte) in edits {
            if data.is_empty() {
                break;
            }
            let i = at as usize % data.len();
            match kind {
                0 => data[i] = byte,
                1 => data.insert(i, byte),
                2 => { data.remove(i); }
                _ => data.truncate(i),
            }
        }
        let _ = io::parse(format, &data, Path::new("mutated"));
        all_parsers(&data);
    }
}
