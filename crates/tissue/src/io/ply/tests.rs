use super::*;

fn p() -> &'static Path {
    Path::new("t.ply")
}

const HEADER_BODY: &str = "comment made by hand\nobj_info nothing\n\
element vertex 4\nproperty float32 x\nproperty double y\nproperty int16 z\nproperty uchar red\n\
element extra 2\nproperty list uint8 int32 junk\nproperty ushort more\n\
element face 2\nproperty list uchar uint vertex_indices\n\
element 3d_element 1\nproperty list int uint16 vertex_indices\n\
element boundary_condition 2\nproperty int vertex_index\n\
element material 1\nproperty double mass_density\nproperty float poisson_ratio\nproperty double young_modulus\n\
end_header\n";

fn expected() -> MeshData {
    MeshData {
        vertices: vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.5, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(0.0, 0.0, -3.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3], [3, 2, 1]],
        tets: vec![[0, 1, 2, 3]],
        fixed_vertices: vec![3, 0],
        material: Some(MaterialRecord {
            density: 1000.0,
            poisson_ratio: 0.25,
            young_modulus: 75000.0,
        }),
        ..MeshData::default()
    }
}

fn ascii() -> Vec<u8> {
    format!(
        "ply\r\nformat ascii 1.0\n{HEADER_BODY}0 0 0 255\n1.5 0 0 0\n0 2 0 1\n0 0 -3 7\n\
3 -1 2 3 9\n0 65535\n4 0 1 2 3\n3 3 2 1\n\n4 0 1 2 3\n3\n0\n1000 0.25 7.5e4\n"
    )
    .into_bytes()
}

/// The same data as `ascii()`, encoded by hand in binary.
fn binary(big: bool) -> Vec<u8> {
    let fmt = if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut out = format!("ply\nformat {fmt} 1.0\n{HEADER_BODY}").into_bytes();
    let mut put = |b: &[u8]| {
        let mut b = b.to_vec();
        if !big {
            b.reverse();
        }
        out.extend_from_slice(&b);
    };
    for (x, y, z, r) in [
        (0.0f32, 0.0f64, 0i16, 255u8),
        (1.5, 0.0, 0, 0),
        (0.0, 2.0, 0, 1),
        (0.0, 0.0, -3, 7),
    ] {
        put(&x.to_be_bytes());
        put(&y.to_be_bytes());
        put(&z.to_be_bytes());
        put(&[r]);
    }
    put(&[3]);
    for v in [-1i32, 2, 3] {
        put(&v.to_be_bytes());
    }
    put(&9u16.to_be_bytes());
    put(&[0]);
    put(&65535u16.to_be_bytes());
    for f in [&[0u32, 1, 2, 3][..], &[3, 2, 1]] {
        put(&[f.len() as u8]);
        for v in f {
            put(&v.to_be_bytes());
        }
    }
    put(&4i32.to_be_bytes());
    for v in [0u16, 1, 2, 3] {
        put(&v.to_be_bytes());
    }
    put(&3i32.to_be_bytes());
    put(&0i32.to_be_bytes());
    put(&1000f64.to_be_bytes());
    put(&0.25f32.to_be_bytes());
    put(&75000f64.to_be_bytes());
    out
}

#[test]
fn ascii_and_both_binaries_agree() {
    assert_eq!(parse(&ascii(), p()).unwrap(), expected());
    assert_eq!(parse(&binary(false), p()).unwrap(), expected());
    assert_eq!(parse(&binary(true), p()).unwrap(), expected());
}

#[test]
fn binary_too_short_names_the_byte() {
    let full = binary(false);
    let cut = &full[..full.len() - 3];
    let e = parse(cut, p()).unwrap_err();
    // The material's last double starts 8 bytes before the end of the full file.
    assert_eq!(e.location, Location::Byte((full.len() - 8) as u64), "{e}");
}

#[test]
fn huge_counts_do_not_allocate_or_spin() {
    let src = b"ply\nformat binary_little_endian 1.0\nelement nothing 1000000000000\n\
element vertex 1000000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0";
    let e = parse(src, p()).unwrap_err();
    assert!(matches!(e.location, Location::Byte(_)), "{e}");
    let src = b"ply\nformat binary_little_endian 1.0\nelement face 1\n\
property list uint uint vertex_indices\nend_header\n\xff\xff\xff\xff\0\0\0\0";
    let e = parse(src, p()).unwrap_err().to_string();
    assert!(e.contains("more than the 4 bytes left"), "{e}");
}

#[test]
fn header_and_data_errors_name_the_line() {
    let cases: [(&[u8], &str); 9] = [
        (
            b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
property float z\nend_header\n0 0 0\n\n0 nan 0\n",
            "t.ply:10: vertex 1 has a non-finite coordinate",
        ),
        (b"plx\nformat ascii 1.0\nend_header\n", "t.ply:1:"),
        (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty flot x\nend_header\n", "t.ply:4:"),
        (b"ply\nformat ascii 1.0\nelement vertex x\n", "t.ply:3:"),
        (b"ply\nformat ascii 1.0\nproperty float x\n", "t.ply:3:"),
        (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", "t.ply:4:"),
        (
            b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
property float z\nend_header\n0 0 0\n0 a 0\n",
            "t.ply:9:",
        ),
        (
            b"ply\nformat ascii 1.0\nelement 3d_element 1\nproperty list uchar int vertex_indices\n\
end_header\n3 0 1 2\n",
            "t.ply:6:",
        ),
        (
            b"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n\
end_header\n2 0 1\n",
            "t.ply:6:",
        ),
    ];
    for (src, want) in cases {
        let e = parse(src, p()).unwrap_err().to_string();
        assert!(e.starts_with(want), "{e} should start with {want}");
    }
}

#[test]
fn vertex_without_z_is_reported_at_its_header_line() {
    let src = b"ply\nformat ascii 1.0\ncomment\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n";
    let e = parse(src, p()).unwrap_err();
    assert_eq!(e.location, Location::Line(4), "{e}");
}
