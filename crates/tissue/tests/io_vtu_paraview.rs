//! The `.vtu` layouts ParaView writes by default (appended raw or base64 data, zlib
//! compression, UInt32 or UInt64 headers), built byte by byte here independently of the
//! reader, must read back exactly as the ascii file of the same mesh.

use std::io::Write;
use std::path::Path;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;
use flate2::Compression;
use flate2::write::ZlibEncoder;
use proptest::prelude::*;
use tissue::io::{self, Format, vtu};
use tissue::mesh::{Field, MeshData};

const LIVER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../assets/meshes/liver.msh");

/// The liver with a vector point field, so PointData is checked too.
fn liver() -> MeshData {
    let mut m = io::read(LIVER).unwrap();
    assert_eq!((m.vertices.len(), m.tets.len()), (181, 596));
    let values = m
        .vertices
        .iter()
        .flat_map(|p| [0.5 * p.x, p.y * p.z, -p.z])
        .collect();
    m.point_data.push(Field {
        name: "u".into(),
        components: 3,
        values,
    });
    m
}

#[derive(Clone, Copy, Debug)]
enum Store {
    Inline,
    Raw,
    Base64,
}

#[derive(Clone, Copy, Debug)]
struct Layout {
    header64: bool,
    store: Store,
    /// zlib block size, or None for uncompressed data.
    block: Option<usize>,
}

/// One data array: where, name, VTK type, components, little-endian bytes.
struct Arr(&'static str, &'static str, &'static str, usize, Vec<u8>);

fn le<T: Copy, const N: usize>(v: &[T], f: fn(T) -> [u8; N]) -> Vec<u8> {
    v.iter().flat_map(|&x| f(x)).collect()
}

fn arrays(m: &MeshData) -> Vec<Arr> {
    let pts: Vec<f64> = m.vertices.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    let conn: Vec<i64> = m.tets.iter().flatten().map(|&i| i64::from(i)).collect();
    let offs: Vec<i32> = (1..=m.tets.len() as i32).map(|k| 4 * k).collect();
    vec![
        Arr(
            "PointData",
            "u",
            "Float64",
            3,
            le(&m.point_data[0].values, f64::to_le_bytes),
        ),
        Arr(
            "CellData",
            "tag",
            "Int32",
            1,
            le(&m.tet_tags, i32::to_le_bytes),
        ),
        Arr("Points", "Points", "Float64", 3, le(&pts, f64::to_le_bytes)),
        Arr(
            "Cells",
            "connectivity",
            "Int64",
            1,
            le(&conn, i64::to_le_bytes),
        ),
        Arr("Cells", "offsets", "Int32", 1, le(&offs, i32::to_le_bytes)),
        Arr("Cells", "types", "UInt8", 1, vec![10u8; m.tets.len()]),
    ]
}

fn word(v: usize, header64: bool) -> Vec<u8> {
    if header64 {
        (v as u64).to_le_bytes().to_vec()
    } else {
        (v as u32).to_le_bytes().to_vec()
    }
}

fn zlib(data: &[u8]) -> Vec<u8> {
    let mut e = ZlibEncoder::new(Vec::new(), Compression::default());
    e.write_all(data).unwrap();
    e.finish().unwrap()
}

/// The binary form of an array as (header, body): VTK encodes them as two base64 streams.
fn binary(data: &[u8], l: Layout) -> (Vec<u8>, Vec<u8>) {
    let Some(bs) = l.block else {
        return (word(data.len(), l.header64), data.to_vec());
    };
    let blocks: Vec<Vec<u8>> = data.chunks(bs).map(zlib).collect();
    let mut header = word(blocks.len(), l.header64);
    header.extend(word(bs, l.header64));
    header.extend(word(data.len() % bs, l.header64));
    for b in &blocks {
        header.extend(word(b.len(), l.header64));
    }
    (header, blocks.concat())
}

/// Builds the file; also returns the file position of each array's data in the appended
/// section (for raw files: where its header starts).
fn build(m: &MeshData, l: Layout) -> (Vec<u8>, Vec<usize>) {
    let mut xml = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"{}\"{}>\n  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n",
        if l.header64 { "UInt64" } else { "UInt32" },
        if l.block.is_some() {
            " compressor=\"vtkZLibDataCompressor\""
        } else {
            ""
        },
        m.vertices.len(),
        m.tets.len()
    );
    let mut appended: Vec<u8> = Vec::new();
    let mut offsets = Vec::new();
    let mut section = "";
    for Arr(sec, name, ty, nc, data) in arrays(m) {
        if sec != section {
            if !section.is_empty() {
                xml += &format!("      </{section}>\n");
            }
            xml += &format!("      <{sec}>\n");
            section = sec;
        }
        let (h, b) = binary(&data, l);
        let format = match l.store {
            Store::Inline => "binary".to_string(),
            _ => format!("appended\" offset=\"{}", appended.len()),
        };
        xml += &format!(
            "        <DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{nc}\" format=\"{format}\">\n"
        );
        // ParaView adds information keys inside the Points array; their text is not data.
        if name == "Points" {
            xml += "          <InformationKey name=\"L2_NORM_RANGE\" location=\"vtkDataArray\" length=\"2\">\n            <Value index=\"0\">\n              1\n            </Value>\n          </InformationKey>\n";
        }
        offsets.push(appended.len());
        match l.store {
            Store::Inline => {
                xml += &format!("          {}{}\n", STANDARD.encode(&h), STANDARD.encode(&b));
            }
            Store::Raw => {
                appended.extend(h);
                appended.extend(b);
            }
            Store::Base64 => {
                appended.extend(STANDARD.encode(&h).into_bytes());
                appended.extend(STANDARD.encode(&b).into_bytes());
            }
        }
        xml += "        </DataArray>\n";
    }
    xml += &format!("      </{section}>\n    </Piece>\n  </UnstructuredGrid>\n");
    let mut file = xml.into_bytes();
    if !matches!(l.store, Store::Inline) {
        let enc = if matches!(l.store, Store::Raw) {
            "raw"
        } else {
            "base64"
        };
        file.extend(format!("  <AppendedData encoding=\"{enc}\">\n   _").into_bytes());
        let start = file.len();
        offsets.iter_mut().for_each(|o| *o += start);
        file.extend(appended);
        file.extend(b"\n  </AppendedData>\n");
    }
    file.extend(b"</VTKFile>\n");
    (file, offsets)
}

fn read(bytes: &[u8], name: &str) -> Result<MeshData, String> {
    io::parse(Format::Vtu, bytes, Path::new(name)).map_err(|e| e.to_string())
}

const LAYOUTS: [Layout; 8] = [
    Layout {
        header64: false,
        store: Store::Raw,
        block: None,
    },
    Layout {
        header64: true,
        store: Store::Raw,
        block: None,
    },
    Layout {
        header64: false,
        store: Store::Base64,
        block: None,
    },
    Layout {
        header64: true,
        store: Store::Inline,
        block: Some(1 << 20),
    },
    Layout {
        header64: false,
        store: Store::Inline,
        block: Some(64),
    },
    Layout {
        header64: true,
        store: Store::Raw,
        block: Some(4096),
    },
    Layout {
        header64: false,
        store: Store::Raw,
        block: Some(1000),
    },
    Layout {
        header64: true,
        store: Store::Base64,
        block: Some(500),
    },
];

#[test]
fn vtu_paraview_layouts_read_as_the_ascii_file() {
    let m = liver();
    let ascii = read(&vtu::encode(&m, false).unwrap(), "a.vtu").unwrap();
    assert_eq!(ascii.vertices, m.vertices);
    assert_eq!(ascii.tets, m.tets);
    assert_eq!(ascii.tet_tags, vec![1; 596]);
    assert_eq!(ascii.point_data, m.point_data);
    for l in LAYOUTS {
        let (file, _) = build(&m, l);
        let got = read(&file, "p.vtu").unwrap_or_else(|e| panic!("{l:?}: {e}"));
        assert_eq!(got, ascii, "{l:?}");
        assert_eq!((got.vertices.len(), got.tets.len()), (181, 596), "{l:?}");
        assert_eq!(got.point_data[0].values.len(), 543, "{l:?}");
    }
}

#[test]
fn vtu_appended_writer_round_trips() {
    let m = liver();
    let ascii = read(&vtu::encode(&m, false).unwrap(), "a.vtu").unwrap();
    let raw = vtu::encode_appended(&m, false).unwrap();
    let zip = vtu::encode_appended(&m, true).unwrap();
    assert_eq!(read(&raw, "r.vtu").unwrap(), ascii);
    assert_eq!(read(&zip, "z.vtu").unwrap(), ascii);
    // Raw: 6 arrays of 8-byte header + data (u and points 4344 each, tags 2384,
    // connectivity 19072, offsets 4768, types 596).
    let data = 6 * 8 + 4344 * 2 + 2384 + 19072 + 4768 + 596;
    let start = raw.windows(2).position(|w| w == b" _").unwrap() + 2;
    assert_eq!(
        raw.len() - start,
        data + "\n  </AppendedData>\n</VTKFile>\n".len()
    );
    let has = |f: &[u8], s: &str| f.windows(s.len()).any(|w| w == s.as_bytes());
    assert!(has(&zip, "compressor=\"vtkZLibDataCompressor\"") && !has(&raw, "compressor"));
    assert!(zip.len() < raw.len(), "{} vs {}", zip.len(), raw.len());
}

#[test]
fn vtu_compressed_layouts_have_the_blocks_they_claim() {
    // Points: 181 * 24 = 4344 bytes; block 64 gives 68 blocks, the last 56 bytes long;
    // connectivity: 596 * 4 * 8 = 19072 bytes, exactly 298 full blocks (last size 0).
    let m = liver();
    let a = arrays(&m);
    assert_eq!((a[2].4.len(), a[3].4.len()), (4344, 19072));
    let l = LAYOUTS[4];
    let (h, _) = binary(&a[2].4, l);
    assert_eq!((w_of(&h, 0), w_of(&h, 1), w_of(&h, 2)), (68, 64, 56));
    let (h, _) = binary(&a[3].4, l);
    assert_eq!((w_of(&h, 0), w_of(&h, 1), w_of(&h, 2)), (298, 64, 0));
    let (file, _) = build(&m, l);
    assert_eq!(read(&file, "c.vtu").unwrap().tets, m.tets);
}

fn w_of(h: &[u8], k: usize) -> u32 {
    u32::from_le_bytes(h[4 * k..4 * k + 4].try_into().unwrap())
}

fn line_of(file: &[u8], needle: &str) -> usize {
    let s = String::from_utf8_lossy(file);
    let at = s.find(needle).unwrap();
    1 + s[..at].matches('\n').count()
}

#[test]
fn vtu_an_offset_past_the_end_names_the_line() {
    let (file, _) = build(&liver(), LAYOUTS[1]);
    let s = String::from_utf8_lossy(&file).into_owned();
    let old = "Name=\"Points\" NumberOfComponents=\"3\" format=\"appended\" offset=\"";
    let at = s.find(old).unwrap() + old.len();
    let end = at + s[at..].find('"').unwrap();
    let mut bad = file[..at].to_vec();
    bad.extend(b"99999999");
    bad.extend(&file[end..]);
    let e = read(&bad, "o.vtu").unwrap_err();
    let line = line_of(&bad, "Name=\"Points\"");
    assert_eq!(line, 14);
    assert!(
        e.starts_with(&format!(
            "o.vtu:{line}: DataArray `Points`: offset 99999999 is past the end"
        )),
        "{e}"
    );
}

#[test]
fn vtu_a_block_that_is_not_zlib_names_its_byte() {
    // Raw, UInt64 headers, one 4096-byte block per small array: Points (index 2) has a
    // header of 3 + 2 words and its first block right after.
    let l = LAYOUTS[5];
    let (mut file, at) = build(&liver(), l);
    let block = at[2] + 5 * 8;
    file[block] = 0xFF;
    file[block + 1] = 0xFF;
    let e = read(&file, "z.vtu").unwrap_err();
    assert!(
        e.starts_with(&format!(
            "z.vtu: byte {block}: DataArray `Points`: block 0 is not valid zlib data"
        )),
        "{e}"
    );
    // The same damage in an inline base64 file names the DataArray's line.
    let m = liver();
    let a = arrays(&m);
    let (h, mut b) = binary(&a[2].4, LAYOUTS[3]);
    b[0] = 0xFF;
    let (file, _) = build(&m, LAYOUTS[3]);
    let s = String::from_utf8(file).unwrap();
    let (good_h, good_b) = binary(&a[2].4, LAYOUTS[3]);
    let good = format!("{}{}", STANDARD.encode(&good_h), STANDARD.encode(&good_b));
    let bad = s.replace(
        &good,
        &format!("{}{}", STANDARD.encode(&h), STANDARD.encode(&b)),
    );
    assert_ne!(bad, s);
    let e = read(bad.as_bytes(), "y.vtu").unwrap_err();
    let line = line_of(bad.as_bytes(), "Name=\"Points\"");
    assert!(
        e.starts_with(&format!(
            "y.vtu:{line}: DataArray `Points`: block 0 is not valid zlib"
        )),
        "{e}"
    );
}

#[test]
fn vtu_a_header_claiming_more_blocks_than_bytes_names_its_byte() {
    let l = LAYOUTS[6];
    let (mut file, at) = build(&liver(), l);
    // types (the last array): nblocks becomes 10^9, far more than the bytes left.
    let h = at[5];
    file[h..h + 4].copy_from_slice(&1_000_000_000u32.to_le_bytes());
    let e = read(&file, "n.vtu").unwrap_err();
    assert!(
        e.starts_with(&format!(
            "n.vtu: byte {h}: DataArray `types`: the compression header claims 1000000000 blocks"
        )),
        "{e}"
    );
    // A raw uncompressed header announcing more bytes than the file holds.
    let (mut file, at) = build(&liver(), LAYOUTS[0]);
    let h = at[5];
    file[h..h + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = read(&file, "r.vtu").unwrap_err();
    assert!(
        e.starts_with(&format!(
            "r.vtu: byte {h}: DataArray `types`: the header announces 4294967295 bytes"
        )),
        "{e}"
    );
}

#[test]
fn vtu_a_block_claiming_an_impossible_ratio_is_refused() {
    // One block declared as 2^40 bytes from a handful of compressed bytes.
    let l = LAYOUTS[1];
    let (file, at) = build(&liver(), l);
    let s = String::from_utf8_lossy(&file).into_owned();
    let head = s.find("header_type").unwrap();
    let insert = b"compressor=\"vtkZLibDataCompressor\" ";
    let mut bad = file[..head].to_vec();
    bad.extend(insert);
    bad.extend(&file[head..]);
    let start = at[0] + insert.len();
    let z = zlib(&[0u8; 8]);
    let mut block = Vec::new();
    for w in [1u64, 1 << 40, 0, z.len() as u64] {
        block.extend(w.to_le_bytes());
    }
    block.extend(&z);
    // The first array (u) at offset 0 gets the lying header.
    bad.splice(start..start + block.len(), block);
    let e = read(&bad, "q.vtu").unwrap_err();
    assert!(
        e.starts_with(&format!(
            "q.vtu: byte {}: DataArray `u`: block 0 claims 1099511627776 bytes",
            start + 32
        )),
        "{e}"
    );
}

#[test]
fn vtu_unknown_compressors_are_named() {
    let (file, _) = build(&liver(), LAYOUTS[3]);
    let s = String::from_utf8(file).unwrap();
    for c in [
        "vtkLZ4DataCompressor",
        "vtkLZMADataCompressor",
        "MyCompressor",
    ] {
        let bad = s.replace("vtkZLibDataCompressor", c);
        let e = read(bad.as_bytes(), "u.vtu").unwrap_err();
        assert!(
            e.starts_with(&format!("u.vtu:2: compressor `{c}` is not supported")),
            "{e}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn vtu_mutated_files_never_panic(
        layout in 0usize..LAYOUTS.len(),
        edits in prop::collection::vec((any::<u32>(), any::<u8>(), any::<bool>()), 1..8),
        cut in prop::option::of(any::<u32>()),
    ) {
        let (mut file, at) = build(&liver(), LAYOUTS[layout]);
        for (pos, byte, near_header) in edits {
            // Half of the edits land in the first bytes of an array, where headers are.
            let pos = if near_header {
                at[pos as usize % at.len()] + (pos as usize >> 8) % 48
            } else {
                pos as usize
            } % file.len();
            file[pos] = byte;
        }
        if let Some(c) = cut {
            file.truncate(c as usize % (file.len() + 1));
        }
        let _ = read(&file, "m.vtu");
    }
}
