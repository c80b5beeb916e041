//! Surface formats (OBJ, STL, PLY, MEDIT) against the shipped organ meshes: exact counts,
//! enclosed volumes, round trips through every writer, malformed inputs that must fail at
//! a named line or byte, and random bytes that must never panic.

use std::path::Path;
use std::sync::OnceLock;

use proptest::prelude::*;
use tissue::Vec3;
use tissue::io::{self, Format, WriteOptions};
use tissue::mesh::MeshData;

fn asset(name: &str) -> String {
    format!("{}/../../assets/meshes/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn load(name: &str) -> MeshData {
    io::read(asset(name)).unwrap_or_else(|e| panic!("{e}"))
}

fn volume(m: &MeshData) -> f64 {
    m.surface_mesh().unwrap().signed_volume()
}

#[test]
fn io_liver_obj_counts_and_volume() {
    let m = load("liver.obj");
    assert_eq!((m.vertices.len(), m.triangles.len()), (181, 274));
    assert!(m.tets.is_empty() && m.triangle_tags.is_empty());
    assert!((volume(&m) - 36.569).abs() < 1e-3, "{}", volume(&m));
    // 42 vertices are never used by a face.
    let mut used = vec![false; m.vertices.len()];
    m.triangles
        .iter()
        .flatten()
        .for_each(|&i| used[i as usize] = true);
    assert_eq!(used.iter().filter(|u| !**u).count(), 42);
}

#[test]
fn io_liver_smooth_obj_counts_and_volume() {
    let m = load("liver-smooth.obj");
    assert_eq!((m.vertices.len(), m.triangles.len()), (2194, 4384));
    assert!((volume(&m) - 39.267).abs() < 1e-3, "{}", volume(&m));
}

#[test]
fn io_wound_ply_counts_material_and_tet_boundary() {
    let m = load("wound_deformable.ply");
    assert_eq!(m.vertices.len(), 391);
    assert_eq!(m.tets.len(), 1476);
    assert_eq!(m.triangles.len(), 407);
    assert_eq!(m.fixed_vertices.len(), 79);
    let mat = m.material.expect("material element");
    assert_eq!(mat.density, 1000.0);
    assert_eq!(mat.poisson_ratio, 0.45);
    assert_eq!(mat.young_modulus, 75000.0);
    // The first vertex and the first tet as written in the file.
    assert_eq!(m.vertices[0], Vec3::new(-0.017638, 0.001427, -0.012363));
    let tets = m.tet_mesh("wound").unwrap();
    assert!(
        (tets.volume() - 9.28e-5).abs() < 0.01e-5,
        "{}",
        tets.volume()
    );
    assert_eq!(m.surface_mesh().unwrap().triangles.len(), 540);
}

fn round_trip(m: &MeshData, format: Format, binary: bool) -> MeshData {
    let opts = WriteOptions {
        binary,
        ..WriteOptions::default()
    };
    let bytes = io::encode(format, m, &opts).unwrap();
    io::parse(format, &bytes, Path::new("rt")).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn io_round_trips_of_real_meshes() {
    let smooth = load("liver-smooth.obj");
    assert_eq!(round_trip(&smooth, Format::Obj, false), smooth);
    // MEDIT keeps tets and tags exactly.
    let mut wound = load("wound_deformable.ply");
    wound.fixed_vertices.clear();
    wound.material = None;
    wound.tet_tags = (0..wound.tets.len() as i32).map(|t| t % 5 - 2).collect();
    wound.triangle_tags = vec![7; wound.triangles.len()];
    assert_eq!(round_trip(&wound, Format::Medit, false), wound);
}

#[test]
fn io_vtp_round_trips_a_surface_and_writes_a_volume_as_its_surface() {
    let mut smooth = load("liver-smooth.obj");
    smooth.triangle_tags = (0..smooth.triangles.len() as i32).map(|t| t % 3).collect();
    for binary in [false, true] {
        let back = round_trip(&smooth, Format::Vtp, binary);
        assert_eq!(back.triangles, smooth.triangles);
        assert_eq!(back.triangle_tags, smooth.triangle_tags);
        let err = back
            .vertices
            .iter()
            .zip(&smooth.vertices)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        // Ascii writes shortest round-trip decimals, binary the bits.
        assert!(err == 0.0, "binary {binary}: {err}");
    }
    let wound = load("wound_deformable.ply");
    let back = round_trip(&wound, Format::Vtp, true);
    assert!(back.tets.is_empty());
    assert_eq!(back.triangles.len(), 540);
    assert!(
        (volume(&back) - 9.28e-5).abs() < 0.01e-5,
        "{}",
        volume(&back)
    );
}

#[test]
fn io_stl_round_trips_ascii_and_binary() {
    // STL welds by position and orders vertices by first use; f32 for binary. Build the
    // expected mesh accordingly from liver-smooth (closed, every vertex used).
    let smooth = load("liver-smooth.obj");
    let f32ed: Vec<Vec3> = smooth
        .vertices
        .iter()
        .map(|v| v.as_vec3().as_dvec3())
        .collect();
    let mut order = vec![u32::MAX; f32ed.len()];
    let mut vertices = Vec::new();
    let triangles: Vec<[u32; 3]> = smooth
        .triangles
        .iter()
        .map(|t| {
            t.map(|i| {
                if order[i as usize] == u32::MAX {
                    order[i as usize] = vertices.len() as u32;
                    vertices.push(f32ed[i as usize]);
                }
                order[i as usize]
            })
        })
        .collect();
    let expected = MeshData {
        vertices,
        triangles,
        ..MeshData::default()
    };
    assert_eq!(expected.vertices.len(), 2194);
    assert_eq!(round_trip(&expected, Format::Stl, true), expected);
    assert_eq!(round_trip(&expected, Format::Stl, false), expected);
    // Ascii keeps f64 exactly; the welded liver keeps its volume.
    let back = round_trip(&smooth, Format::Stl, false);
    assert_eq!(back.triangles.len(), 4384);
    assert!((volume(&back) - 39.267).abs() < 1e-3);
}

fn err(format: Format, name: &str, bytes: &[u8]) -> String {
    match io::parse(format, bytes, Path::new(name)) {
        Ok(m) => panic!("{name} parsed: {} vertices", m.vertices.len()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn io_malformed_inputs_name_file_and_place() {
    let mut stl = io::encode(Format::Stl, &load("liver.obj"), &WriteOptions::default()).unwrap();
    stl.truncate(stl.len() - 7);
    let cases: Vec<(Format, &str, Vec<u8>, &str)> = vec![
        (Format::Stl, "a.stl", stl, "a.stl: byte 80: binary STL header says 274 triangles"),
        (Format::Stl, "b.stl", vec![1; 40], "b.stl: byte 40:"),
        (
            Format::Stl,
            "c.stl",
            b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\n".to_vec(),
            "c.stl:6: expected `vertex x y z`",
        ),
        (Format::Ply, "a.ply", b"ply\nformat ascii 1.0\nelement vertex 3 2\n".to_vec(), "a.ply:3:"),
        (
            Format::Ply,
            "b.ply",
            b"ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty double x\n\
property double y\nproperty double z\nend_header\n0123456789abcdef01234567abc"
                .to_vec(),
            "b.ply: byte 139:",
        ),
        (
            Format::Ply,
            "c.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n\n3 0 0 -1\n"
                .to_vec(),
            "c.ply:12:",
        ),
        (Format::Obj, "a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n".to_vec(), "a.obj:4: face refers to vertex 4"),
        (Format::Obj, "b.obj", b"v 0 0 0\r\nv 1 0 0\r\n# c\r\nf 1 0 2\r\n".to_vec(), "b.obj:4:"),
        (Format::Obj, "c.obj", b"v 0 0 0\nv 1 0 nan\n".to_vec(), "c.obj:2:"),
        (Format::Obj, "d.obj", b"v 0 0 0\nv 1 0 zero\n".to_vec(), "d.obj:2:"),
        (
            Format::Medit,
            "a.mesh",
            b"MeshVersionFormatted 2\nDimension 3\nVertices\n\nEnd\n".to_vec(),
            "a.mesh:5:",
        ),
        (
            Format::Medit,
            "b.mesh",
            b"MeshVersionFormatted 2\nDimension 3\nVertices 1\n0 0 0 0\nTetrahedra\n1\n1 1 2 1 0\n".to_vec(),
            "b.mesh: element 0: tetrahedron 0 refers to vertex 1",
        ),
        (
            Format::Medit,
            "c.mesh",
            b"MeshVersionFormatted 2\nDimension 3\nVertices 1\n0 0 0 0\nTetrahedra\n2\n1 1 1 1 0\n".to_vec(),
            "c.mesh:7: unexpected end of file",
        ),
    ];
    for (format, name, bytes, want) in cases {
        let e = err(format, name, &bytes);
        assert!(e.starts_with(want), "`{e}` should start with `{want}`");
    }
}

/// Every reader over arbitrary bytes: `Ok` or `Err`, never a panic.
fn no_panic(bytes: &[u8]) {
    for f in [
        Format::Obj,
        Format::Stl,
        Format::Ply,
        Format::Medit,
        Format::Vtp,
    ] {
        let _ = io::parse(f, bytes, Path::new("fuzz"));
    }
}

fn seeds() -> &'static [Vec<u8>] {
    static SEEDS: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    SEEDS.get_or_init(make_seeds)
}

fn make_seeds() -> Vec<Vec<u8>> {
    let mut v: Vec<Vec<u8>> = ["liver.obj", "wound_deformable.ply"]
        .iter()
        .map(|n| std::fs::read(asset(n)).unwrap())
        .collect();
    let liver = load("liver.obj");
    for (f, b) in [
        (Format::Stl, true),
        (Format::Stl, false),
        (Format::Medit, false),
        (Format::Vtp, false),
        (Format::Vtp, true),
    ] {
        let o = WriteOptions {
            binary: b,
            ..WriteOptions::default()
        };
        v.push(io::encode(f, &liver, &o).unwrap());
    }
    // A binary PLY: the ascii wound with a binary header over its leading bytes.
    let mut ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
element other 2\nproperty list int double a\nend_header\n"
        .to_vec();
    ply.extend_from_slice(&[0u8; 36]);
    ply.extend_from_slice(&[3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0]);
    ply.extend_from_slice(&[1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    v.push(ply);
    v
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn io_random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        no_panic(&bytes);
        // Random bytes behind each format's magic start reach the deeper code.
        for magic in [&b"solid "[..], b"ply\nformat ascii 1.0\n", b"ply\nformat binary_big_endian 1.0\n",
            b"MeshVersionFormatted 1\nDimension 3\n", b"v 1 2 3\nf "] {
            let mut b = magic.to_vec();
            b.extend_from_slice(&bytes);
            no_panic(&b);
        }
    }

    #[test]
    fn io_mutated_real_files_never_panic(
        seed in 0usize..7,
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..8),
        cut in any::<prop::sample::Index>(),
    ) {
        let seeds = seeds();
        let mut b = seeds[seed % seeds.len()].clone();
        for (at, byte, op) in edits {
            if b.is_empty() { break; }
            let i = at.index(b.len());
            match op {
                0 => b[i] = byte,
                1 => { b.remove(i); }
                _ => b.insert(i, byte),
            }
        }
        no_panic(&b);
        let keep = cut.index(b.len() + 1);
        no_panic(&b[..keep]);
    }
}
