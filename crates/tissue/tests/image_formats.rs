//! Medical image input: the shipped NIfTI and MetaImage files against numbers computed by an
//! independent parser, hand-made files in both byte orders, the errors, and fuzzed headers.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use proptest::prelude::*;
use tissue::Vec3;
use tissue::image::{
    ByteOrder, LabelRef, SourceType, VoxelImage, metaimage, nifti, nrrd, read_image,
};

fn asset(name: &str) -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/images")).join(name)
}

fn tmp(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("image_formats");
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn close(a: Vec3, b: Vec3, tol: f64) -> bool {
    (a - b).abs().max_element() <= tol
}

#[test]
fn image_anatomical_nii_matches_an_independent_parser() {
    let im = read_image(asset("anatomical.nii"), 1.0).unwrap();
    assert_eq!(im.dims, [33, 41, 25]);
    assert_eq!(im.len(), 33825);
    assert!(close(im.spacing, Vec3::splat(0.002), 1e-12));
    // sform translation (32, −40, −16) mm; its x flip is not applied.
    assert!(close(im.origin, Vec3::new(0.032, -0.040, -0.016), 1e-12));
    assert_eq!(im.source_type, SourceType::I16);
    assert_eq!(im.byte_order, ByteOrder::Big);
    let s = im.stats();
    assert_eq!((s.min, s.max), (-610.0, 30393.0));
    assert_eq!(s.negatives, 26);
    assert_eq!(s.zeros, 0);
    assert!((s.mean - 8401.066725794532).abs() < 1e-6, "{}", s.mean);
    // Samples at the corners of the x, y, z strides and the last voxel.
    assert_eq!(im.value(0, 0, 0), Some(10712.0));
    assert_eq!(im.value(1, 0, 0), Some(10463.0));
    assert_eq!(im.value(0, 1, 0), Some(6349.0));
    assert_eq!(im.value(0, 0, 1), Some(8026.0));
    assert_eq!(im.value(32, 40, 24), Some(2971.0));
    assert_eq!(im.value(33, 0, 0), None);
    let dark = im.threshold(f32::MIN, -0.5);
    assert_eq!(dark.iter().filter(|&&b| b).count(), 26);
    assert!(close(
        im.position(32, 40, 24),
        Vec3::new(0.032 + 0.064, -0.040 + 0.080, -0.016 + 0.048),
        1e-12
    ));
}

#[test]
fn image_pelvis_mhd_matches_an_independent_parser() {
    let scale = 0.01;
    let im = read_image(asset("pelvis_f.mhd"), scale).unwrap();
    assert_eq!(im.dims, [221, 271, 69]);
    assert_eq!(im.len(), 4_132_479);
    assert!(close(
        im.spacing,
        Vec3::new(0.0078125, 0.0078125, 0.0246876) * scale,
        1e-15
    ));
    assert!(close(
        im.origin,
        Vec3::new(-1.86497, -0.968755, -0.0824288) * scale,
        1e-15
    ));
    assert_eq!(im.source_type, SourceType::U8);
    assert_eq!(im.min_max(), Some((0.0, 226.0)));
    let distinct: HashSet<u32> = im.values.iter().map(|v| v.to_bits()).collect();
    assert_eq!(distinct.len(), 218);
    let s = im.stats();
    assert_eq!(s.zeros, 476_587);
    assert!((s.zeros as f64 / s.count as f64 - 0.115).abs() < 0.001);
    assert!((s.mean - 61.3163824909939).abs() < 1e-6, "{}", s.mean);
    assert_eq!(im.value(100, 135, 34), Some(37.0));
    // The header's numbers, unscaled, come back with scale 1.
    let raw = metaimage::read(asset("pelvis_f.mhd"), 1.0).unwrap();
    assert_eq!(raw.spacing, Vec3::new(0.0078125, 0.0078125, 0.0246876));
}

/// A NIfTI-1 header of 2×2×1 int16 voxels, 0.5 × 0.5 × 2 mm, the given byte order.
fn nifti_header(big: bool, magic: &[u8; 4], slope: f32, inter: f32) -> Vec<u8> {
    let mut h = vec![0u8; 352];
    let mut put = |at: usize, le: &[u8]| {
        let mut v = le.to_vec();
        if big {
            v.reverse();
        }
        h[at..at + v.len()].copy_from_slice(&v);
    };
    put(0, &348i32.to_le_bytes());
    for (k, d) in [3i16, 2, 2, 1, 1, 1, 1, 1].iter().enumerate() {
        put(40 + 2 * k, &d.to_le_bytes());
    }
    put(70, &4i16.to_le_bytes());
    put(72, &16i16.to_le_bytes());
    for (k, p) in [1.0f32, 0.5, 0.5, 2.0].iter().enumerate() {
        put(76 + 4 * k, &p.to_le_bytes());
    }
    let vox: f32 = if magic == b"n+1\0" { 352.0 } else { 0.0 };
    put(108, &vox.to_le_bytes());
    put(112, &slope.to_le_bytes());
    put(116, &inter.to_le_bytes());
    h[123] = 2;
    h[344..348].copy_from_slice(magic);
    h
}

const SHORTS: [i16; 4] = [-3, 0, 1000, 32767];

fn nifti_file(big: bool, slope: f32, inter: f32) -> Vec<u8> {
    let mut b = nifti_header(big, b"n+1\0", slope, inter);
    for v in SHORTS {
        b.extend(if big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        });
    }
    b
}

#[test]
fn image_nifti_both_byte_orders_apply_slope_and_intercept() {
    let mut images: Vec<VoxelImage> = Vec::new();
    for big in [false, true] {
        let path = tmp(if big { "be.nii" } else { "le.nii" });
        std::fs::write(&path, nifti_file(big, 0.5, 10.0)).unwrap();
        let im = read_image(&path, 123.0).unwrap();
        assert_eq!(im.values, vec![8.5, 10.0, 510.0, 16393.5]);
        assert_eq!(im.dims, [2, 2, 1]);
        assert!(close(im.spacing, Vec3::new(0.0005, 0.0005, 0.002), 1e-15));
        let order = if big {
            ByteOrder::Big
        } else {
            ByteOrder::Little
        };
        assert_eq!(im.byte_order, order);
        images.push(im);
    }
    assert_eq!(images[0].values, images[1].values);
    // NaN slope means "no scaling"; a NaN intercept with a real slope counts as 0.
    let im = nifti::parse(&nifti_file(true, f32::NAN, 5.0), Path::new("n.nii")).unwrap();
    assert_eq!(im.values, vec![-3.0, 0.0, 1000.0, 32767.0]);
    let im = nifti::parse(&nifti_file(false, 2.0, f32::NAN), Path::new("n.nii")).unwrap();
    assert_eq!(im.values, vec![-6.0, 0.0, 2000.0, 65534.0]);
}

#[test]
fn image_nifti_pair_reads_data_from_the_img() {
    let hdr = tmp("pair.hdr");
    std::fs::write(&hdr, &nifti_header(true, b"ni1\0", 1.0, 0.0)[..348]).unwrap();
    let data: Vec<u8> = SHORTS.iter().flat_map(|v| v.to_be_bytes()).collect();
    std::fs::write(tmp("pair.img"), data).unwrap();
    let a = read_image(&hdr, 1.0).unwrap();
    let b = read_image(tmp("pair.img"), 1.0).unwrap();
    assert_eq!(a.values, vec![-3.0, 0.0, 1000.0, 32767.0]);
    assert_eq!(a, b);
    let e = read_image(tmp("lonely.hdr"), 1.0).unwrap_err().to_string();
    assert!(e.contains("lonely.hdr"), "{e}");
}

#[test]
fn image_mha_local_little_endian_floats() {
    let mut b = b"ObjectType = Image\nNDims = 3\nBinaryData = True\nDimSize = 2 2 1\n\
        ElementSize = 2 4 8\nPosition = 10 -20 30\nElementType = MET_FLOAT\n\
        ElementByteOrderMSB = False\nAnatomicalOrientation = RAI\nElementDataFile = LOCAL\n"
        .to_vec();
    for v in [1.5f32, -2.0, 0.0, 1e6] {
        b.extend(v.to_le_bytes());
    }
    let path = tmp("local.mha");
    std::fs::write(&path, &b).unwrap();
    let im = read_image(&path, 0.001).unwrap();
    assert_eq!(im.dims, [2, 2, 1]);
    assert_eq!(im.values, vec![1.5, -2.0, 0.0, 1e6]);
    assert!(close(im.spacing, Vec3::new(0.002, 0.004, 0.008), 1e-15));
    assert!(close(im.origin, Vec3::new(0.01, -0.02, 0.03), 1e-15));
    assert_eq!(
        (im.source_type, im.byte_order),
        (SourceType::F32, ByteOrder::Little)
    );
    assert!(close(
        im.position(1, 1, 0),
        Vec3::new(0.012, -0.016, 0.03),
        1e-15
    ));
}

#[test]
fn image_truncated_data_names_both_sizes() {
    let mut b = nifti_file(false, 1.0, 0.0);
    b.truncate(b.len() - 2);
    let e = nifti::parse(&b, Path::new("cut.nii"))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "cut.nii: byte 352: truncated data: 2×2×1 voxels of int16 need 8 bytes from byte 352, \
         but the file has 6"
    );

    let hdr = tmp("short.mhd");
    std::fs::write(
        &hdr,
        "NDims = 3\r\nDimSize = 3 2 2\r\nElementType = MET_USHORT\r\nElementDataFile = short.raw\r\n",
    )
    .unwrap();
    std::fs::write(tmp("short.raw"), [0u8; 23]).unwrap();
    let e = read_image(&hdr, 1.0).unwrap_err().to_string();
    assert!(
        e.contains("short.raw") && e.contains("24 bytes") && e.contains("has 23"),
        "{e}"
    );
    // Too much data is as wrong as too little for MetaImage (no HeaderSize to explain it).
    std::fs::write(tmp("short.raw"), [0u8; 25]).unwrap();
    let e = read_image(&hdr, 1.0).unwrap_err().to_string();
    assert!(e.contains("24 bytes") && e.contains("has 25"), "{e}");
}

#[test]
fn image_header_errors_name_the_place() {
    let mut b = nifti_file(false, 1.0, 0.0);
    b[344..348].copy_from_slice(b"n+2\0");
    let e = nifti::parse(&b, Path::new("m.nii"))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("m.nii: byte 344: bad NIfTI-1 magic"), "{e}");

    let mut b = nifti_file(true, 1.0, 0.0);
    b[70..72].copy_from_slice(&128i16.to_be_bytes());
    let e = nifti::parse(&b, Path::new("rgb.nii"))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("rgb.nii: byte 70: unsupported NIfTI datatype 128"),
        "{e}"
    );

    let mut b = nifti_file(false, 1.0, 0.0);
    b[0..4].copy_from_slice(&540i32.to_le_bytes());
    let e = nifti::parse(&b, Path::new("two.nii"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("byte 0") && e.contains("NIfTI-2"), "{e}");

    let hdr = tmp("ndims.mhd");
    std::fs::write(
        &hdr,
        "ObjectType = Image\r\n\r\nNDims = 4\r\nDimSize = 1 1 1 1\r\n",
    )
    .unwrap();
    let e = read_image(&hdr, 1.0).unwrap_err().to_string();
    assert!(
        e.ends_with("ndims.mhd:3: NDims = 4: only 3-D images are supported"),
        "{e}"
    );

    let hdr = tmp("noraw.mhd");
    std::fs::write(
        &hdr,
        "NDims = 3\nDimSize = 1 1 1\nElementType = MET_UCHAR\nisPerpective = 0\n\
         ElementDataFile = missing.raw\n",
    )
    .unwrap();
    let e = read_image(&hdr, 1.0).unwrap_err().to_string();
    assert!(
        e.contains("noraw.mhd:5: cannot read the data file") && e.contains("missing.raw"),
        "{e}"
    );

    // A missing .nii.gz is named like any missing file (gzip is read since issue 25).
    let e = read_image(tmp("x.nii.gz"), 1.0).unwrap_err().to_string();
    assert!(e.contains("x.nii.gz"), "{e}");
    let e = read_image(asset("pelvis_f.mhd"), 0.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("scale 0"), "{e}");
}

fn mha_local() -> Vec<u8> {
    let mut b = b"ObjectType = Image\r\nNDims = 3\r\nDimSize = 2 2 2\r\n\
        ElementSpacing = 1 1 1\r\nOffset = 0 0 0\r\nElementType = MET_SHORT\r\n\
        BinaryDataByteOrderMSB = True\r\nHeaderSize = 0\r\nElementDataFile = LOCAL\r\n"
        .to_vec();
    b.extend((0..16u8).collect::<Vec<_>>());
    b
}

/// The shipped NIfTI written as a gzip NRRD in LPS with its x axis flipped (as Slicer writes
/// it), millimetres, big-endian shorts.
fn anatomical_as_nrrd(im: &VoxelImage) -> Vec<u8> {
    use std::io::Write;
    let [nx, ny, nz] = im.dims;
    let mm = im.spacing * 1000.0;
    // File axis 0 runs along −x: its first sample is the image's last column.
    let start = (im.origin + Vec3::X * im.spacing.x * (nx - 1) as f64) * 1000.0;
    let mut data = Vec::with_capacity(2 * im.len());
    for k in 0..nz {
        for j in 0..ny {
            for i in (0..nx).rev() {
                let v = im.value(i, j, k).unwrap() as i16;
                data.extend(v.to_be_bytes());
            }
        }
    }
    let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    z.write_all(&data).unwrap();
    let mut out = format!(
        "NRRD0004\n# Complete NRRD file format specification at:\n\
         type: short\ndimension: 3\nspace: left-posterior-superior\nsizes: {nx} {ny} {nz}\n\
         space directions: ({},0,0) (0,{},0) (0,0,{})\nkinds: domain domain domain\n\
         endian: big\nencoding: gzip\nspace origin: ({},{},{})\n\n",
        -mm.x, mm.y, mm.z, start.x, start.y, start.z
    )
    .into_bytes();
    out.extend(z.finish().unwrap());
    out
}

#[test]
fn image_nrrd_of_the_anatomical_nii_reads_the_same_voxels_at_the_same_places() {
    let nii = read_image(asset("anatomical.nii"), 1.0).unwrap();
    let path = tmp("anatomical.nrrd");
    std::fs::write(&path, anatomical_as_nrrd(&nii)).unwrap();
    let im = read_image(&path, 1.0).unwrap();
    assert_eq!(im.dims, nii.dims);
    assert!(close(im.spacing, nii.spacing, 1e-15));
    assert!(
        close(im.origin, nii.origin, 1e-15),
        "{} {}",
        im.origin,
        nii.origin
    );
    assert_eq!(im.values, nii.values);
    assert_eq!(im.source_type, SourceType::I16);
    assert_eq!(im.byte_order, ByteOrder::Big);
}

#[test]
fn image_seg_nrrd_segments_select_by_name() {
    // A 4×1×1 label volume, one layer: background, liver (3), tumour (5), liver.
    let head = "NRRD0004\ntype: unsigned char\ndimension: 3\nsizes: 4 1 1\nencoding: raw\n\
                space directions: (1,0,0) (0,1,0) (0,0,1)\nSegment0_ID:=Segment_1\n\
                Segment0_Name:=liver\nSegment0_LabelValue:=3\nSegment1_ID:=Segment_2\n\
                Segment1_Name:=tumour\nSegment1_LabelValue:=5\n\n";
    let mut bytes = head.as_bytes().to_vec();
    bytes.extend([0u8, 3, 5, 3]);
    let path = tmp("two.seg.nrrd");
    std::fs::write(&path, &bytes).unwrap();
    let im = read_image(&path, 1.0).unwrap();
    let names = ["tumour", "liver"].map(|n| LabelRef::Name(n.into()));
    assert_eq!(im.label_values(&names), Ok(vec![5.0, 3.0]));
    assert_eq!(
        im.label_values(&[LabelRef::Name("Segment_2".into())]),
        Ok(vec![5.0])
    );
}

/// A small layered segmentation with every field the reader knows.
fn nrrd_seed() -> &'static [u8] {
    b"NRRD0004\ntype: short\ndimension: 4\nspace: left-posterior-superior\n\
sizes: 2 2 2 1\nspace directions: none (-1.5,0,0) (0,2,0) (0,0,1)\n\
kinds: list domain domain domain\nendian: little\nencoding: raw\n\
space origin: (1,2,3)\nspace units: \"mm\" \"mm\" \"mm\"\nbyte skip: 0\nline skip: 0\n\
Segment0_Name:=a\nSegment0_LabelValue:=1\nSegment0_Layer:=0\n\
Segment1_Name:=b\nSegment1_LabelValue:=1\nSegment1_Layer:=1\n\n\
\x01\x00\x00\x00\x00\x00\x01\x00\x01\x00\x01\x00\x00\x00\x00\x00"
}

#[test]
fn image_nrrd_fuzz_seed_is_a_valid_file() {
    // Layers (a, b) per voxel in file order: (1,0) (0,1) (1,1) (0,0); file axis 0 runs along
    // −x, so each row comes out reversed; where both layers hold, the first segment wins.
    let im = nrrd::parse_with(nrrd_seed(), Path::new("seed.nrrd"), &no_file).unwrap();
    assert_eq!(im.dims, [2, 2, 1]);
    assert_eq!(im.values, vec![2.0, 1.0, 0.0, 1.0]);
    assert!(
        close(im.origin, Vec3::new(-0.0005, 0.002, 0.003), 1e-15),
        "{}",
        im.origin
    );
}

fn no_file(_: &Path) -> std::io::Result<Vec<u8>> {
    Ok(vec![0; 16])
}

/// A successful read must be internally consistent, whatever the header said.
fn consistent(im: &VoxelImage) -> bool {
    im.values.len() == im.dims.iter().product::<usize>()
        && im.spacing.min_element() > 0.0
        && im.spacing.is_finite()
        && im.origin.is_finite()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn image_mutated_nrrd_files_never_panic(
        edits in proptest::collection::vec((0usize..400, any::<u8>()), 1..12),
    ) {
        let mut b = nrrd_seed().to_vec();
        for (at, byte) in edits {
            if let Some(slot) = b.get_mut(at) {
                *slot = byte;
            }
        }
        if let Ok(im) = nrrd::parse_with(&b, Path::new("fuzz.nrrd"), &no_file) {
            prop_assert!(consistent(&im));
        }
    }

    #[test]
    fn image_mutated_nifti_headers_never_panic(
        big in any::<bool>(),
        edits in proptest::collection::vec((0usize..360, any::<u8>()), 1..12),
    ) {
        let mut b = nifti_file(big, 0.5, 1.0);
        for (at, byte) in edits {
            if let Some(slot) = b.get_mut(at) {
                *slot = byte;
            }
        }
        if let Ok(im) = nifti::parse(&b, Path::new("fuzz.nii")) {
            prop_assert!(consistent(&im));
        }
    }

    #[test]
    fn image_absurd_nifti_sizes_are_refused_before_allocating(
        dims in proptest::array::uniform3(any::<i16>()),
        vox in any::<f32>(),
        datatype in prop::sample::select(vec![2i16, 4, 8, 16, 64, 256, 512, 768, 1024, 0]),
    ) {
        let mut b = nifti_file(false, 1.0, 0.0);
        for (k, d) in dims.iter().enumerate() {
            b[42 + 2 * k..44 + 2 * k].copy_from_slice(&d.to_le_bytes());
        }
        b[70..72].copy_from_slice(&datatype.to_le_bytes());
        b[108..112].copy_from_slice(&vox.to_le_bytes());
        if let Ok(im) = nifti::parse(&b, Path::new("fuzz.nii")) {
            prop_assert!(consistent(&im));
            prop_assert!(im.len() <= 8);
        }
    }

    #[test]
    fn image_mutated_metaimage_headers_never_panic(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..8),
        dims in proptest::array::uniform3(prop_oneof![0u64..4, any::<u64>()]),
        header_size in prop_oneof![-3i64..20, any::<i64>()],
    ) {
        let mut b = mha_local();
        let head = format!(
            "NDims = 3\nDimSize = {} {} {}\nElementType = MET_UCHAR\nHeaderSize = {header_size}\n\
             ElementDataFile = LOCAL\n",
            dims[0], dims[1], dims[2]
        );
        let mut sized = head.into_bytes();
        sized.extend([1u8; 8]);
        if let Ok(im) = metaimage::parse_with(&sized, Path::new("s.mha"), 1.0, &no_file) {
            prop_assert!(consistent(&im));
            prop_assert!(im.len() <= 8);
        }
        for (at, byte, op) in edits {
            let i = at.index(b.len() + 1);
            match op {
                0 if i < b.len() => b[i] = byte,
                1 => b.insert(i, byte),
                _ if i < b.len() => { b.remove(i); }
                _ => {}
            }
        }
        for path in ["fuzz.mha", "fuzz.mhd"] {
            if let Ok(im) = metaimage::parse_with(&b, Path::new(path), 0.5, &no_file) {
                prop_assert!(consistent(&im));
            }
        }
    }
}
