//! NIfTI-1 reader: single files (`.nii`, magic `n+1`) and header/image pairs (`.hdr` +
//! `.img`, magic `ni1`), either byte order, 3-D scalar data of the common integer and float
//! types, with `scl_slope`/`scl_inter` applied.
//!
//! Geometry kept: spacing from `pixdim[1..3]` (absolute values) and the origin from the
//! translation column of the sform when `sform_code > 0`, else from the qform offsets when
//! `qform_code > 0`, else zero; that is the world position of the centre of voxel 0. The
//! rotation and axis flips of the sform/qform are NOT applied (a flipped axis, such as the
//! usual negative x of radiological images, still runs towards +x here).
//!
//! Units come from `xyzt_units`: metres, millimetres or micrometres, converted to metres.
//! A file that leaves the unit unknown (0) is read as millimetres, which is what scanners and
//! SPM/FSL write in practice.

use std::path::{Path, PathBuf};

use crate::error::{IoError, Location};
use crate::image::grid::{ByteOrder, SourceType, VoxelImage, data_size, decode};
use crate::math::Vec3;

/// The first bytes of a gzip stream (`.nii.gz`).
const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];
/// Largest image accepted after decompression, so a gzip bomb cannot exhaust memory.
const MAX_INFLATED: u64 = 4 << 30;

/// The bytes inflated when they are a gzip stream, else as they are.
fn gunzip(bytes: Vec<u8>, path: &Path) -> Result<Vec<u8>, IoError> {
    use std::io::Read;
    if !bytes.starts_with(&GZIP_MAGIC) {
        return Ok(bytes);
    }
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(bytes.as_slice())
        .take(MAX_INFLATED)
        .read_to_end(&mut out)
        .map_err(|e| {
            IoError::new(
                path,
                Location::File,
                format!(
                    "not a valid gzip stream ({e}) after {} inflated bytes",
                    out.len()
                ),
            )
        })?;
    Ok(out)
}

/// Size of the NIfTI-1 header; `sizeof_hdr` must hold it, which also reveals the byte order.
const HEADER: usize = 348;
/// Where data starts in a `.nii` whose `vox_offset` is 0 (header + 4-byte extension flag).
const MIN_NII_OFFSET: usize = 352;

/// Reads a `.nii`, `.hdr` or `.img` (the pair is found from either name).
pub fn read(path: impl AsRef<Path>) -> Result<VoxelImage, IoError> {
    let path = path.as_ref();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let header_path = if ext.as_deref() == Some("img") {
        path.with_extension("hdr")
    } else {
        path.to_path_buf()
    };
    let bytes =
        std::fs::read(&header_path).map_err(|e| IoError::os(&header_path, "read the file", e))?;
    let bytes = gunzip(bytes, &header_path)?;
    let header = Header::parse(&bytes, &header_path)?;
    if header.single_file {
        return header.image_from(&bytes, &header_path);
    }
    let image_path: PathBuf = header_path.with_extension("img");
    let data = std::fs::read(&image_path).map_err(|e| {
        IoError::new(
            &header_path,
            Location::Byte(344),
            format!(
                "the header (magic `ni1`) keeps its data in `{}`, which cannot be read: {e}",
                image_path.display()
            ),
        )
    })?;
    header.image_from(&data, &image_path)
}

/// Parses a single-file NIfTI-1 (`n+1`) already in memory; `path` only names it in errors.
/// Gzip-compressed bytes (`.nii.gz`) are inflated first.
pub fn parse(bytes: &[u8], path: &Path) -> Result<VoxelImage, IoError> {
    if bytes.starts_with(&GZIP_MAGIC) {
        let bytes = gunzip(bytes.to_vec(), path)?;
        return parse(&bytes, path);
    }
    let header = Header::parse(bytes, path)?;
    if !header.single_file {
        return Err(IoError::new(
            path,
            Location::Byte(344),
            "magic `ni1` means the data is in a separate .img file; read the .hdr from disk",
        ));
    }
    header.image_from(bytes, path)
}

/// The parts of the header this reader uses.
#[derive(Debug)]
struct Header {
    order: ByteOrder,
    single_file: bool,
    dims: [usize; 3],
    spacing: Vec3,
    origin: Vec3,
    ty: SourceType,
    offset: usize,
    scaling: Option<(f64, f64)>,
}

/// Fixed-offset field access into the 348 header bytes in the file's byte order.
struct Fields<'a> {
    b: &'a [u8],
    order: ByteOrder,
}

impl Fields<'_> {
    fn raw<const N: usize>(&self, at: usize) -> [u8; N] {
        let mut a = [0u8; N];
        if let Some(src) = self.b.get(at..at + N) {
            a.copy_from_slice(src);
        }
        if self.order == ByteOrder::Big {
            a.reverse();
        }
        a
    }
    fn i16(&self, at: usize) -> i16 {
        i16::from_le_bytes(self.raw(at))
    }
    fn i32(&self, at: usize) -> i32 {
        i32::from_le_bytes(self.raw(at))
    }
    fn f32(&self, at: usize) -> f64 {
        f64::from(f32::from_le_bytes(self.raw(at)))
    }
}

impl Header {
    fn parse(bytes: &[u8], path: &Path) -> Result<Self, IoError> {
        let err = |at: u64, msg: String| IoError::new(path, Location::Byte(at), msg);
        if bytes.len() < HEADER {
            return Err(err(
                bytes.len() as u64,
                format!(
                    "the file has {} bytes, too short for a {HEADER}-byte NIfTI-1 header",
                    bytes.len()
                ),
            ));
        }
        let mut f = Fields {
            b: bytes,
            order: ByteOrder::Little,
        };
        let le = f.i32(0);
        if le != HEADER as i32 {
            f.order = ByteOrder::Big;
            let be = f.i32(0);
            if be != HEADER as i32 {
                let hint = if le == 540 || be == 540 {
                    " (this is NIfTI-2, which is not supported)"
                } else {
                    ""
                };
                return Err(err(
                    0,
                    format!("not a NIfTI-1 header: sizeof_hdr is {le} (expected 348){hint}"),
                ));
            }
        }
        let single_file = match bytes.get(344..348) {
            Some(b"n+1\0") => true,
            Some(b"ni1\0") => false,
            other => {
                return Err(err(
                    344,
                    format!(
                        "bad NIfTI-1 magic {:?} (expected \"n+1\" or \"ni1\")",
                        String::from_utf8_lossy(other.unwrap_or_default())
                    ),
                ));
            }
        };

        let dim: Vec<i16> = (0..8).map(|k| f.i16(40 + 2 * k)).collect();
        let ndim = dim.first().copied().unwrap_or(0);
        let fourth = dim.get(4).copied().unwrap_or(0);
        if !(ndim == 3 || (ndim == 4 && fourth == 1)) {
            return Err(err(
                40,
                format!(
                    "only 3-D images are supported: dim[0] = {ndim}{}",
                    if ndim == 4 {
                        format!(" with dim[4] = {fourth} time points")
                    } else {
                        String::new()
                    }
                ),
            ));
        }
        let mut dims = [0usize; 3];
        for (a, d) in dims.iter_mut().enumerate() {
            let v = dim.get(a + 1).copied().unwrap_or(0);
            *d = usize::try_from(v).ok().filter(|&n| n > 0).ok_or_else(|| {
                err(
                    42 + 2 * a as u64,
                    format!("dim[{}] = {v} is not positive", a + 1),
                )
            })?;
        }

        let code = f.i16(70);
        let ty = match code {
            2 => SourceType::U8,
            4 => SourceType::I16,
            8 => SourceType::I32,
            16 => SourceType::F32,
            64 => SourceType::F64,
            256 => SourceType::I8,
            512 => SourceType::U16,
            768 => SourceType::U32,
            other => {
                return Err(err(
                    70,
                    format!(
                        "unsupported NIfTI datatype {other}; supported: 2 uint8, 4 int16, 8 int32, \
                         16 float32, 64 float64, 256 int8, 512 uint16, 768 uint32"
                    ),
                ));
            }
        };

        let unit = match bytes.get(123).copied().unwrap_or(0) & 0x07 {
            1 => 1.0,
            3 => 1e-6,
            // 2 = mm; 0 = unknown, read as mm (see the module doc).
            0 | 2 => 1e-3,
            other => {
                return Err(err(
                    123,
                    format!("xyzt_units has spatial unit code {other}, which is not a length"),
                ));
            }
        };
        let mut sp = [0.0f64; 3];
        for (a, s) in sp.iter_mut().enumerate() {
            let v = f.f32(80 + 4 * a);
            if !(v.is_finite() && v != 0.0) {
                return Err(err(
                    80 + 4 * a as u64,
                    format!("pixdim[{}] = {v} is not a finite non-zero spacing", a + 1),
                ));
            }
            *s = v.abs() * unit;
        }

        let origin_mm = if f.i16(254) > 0 {
            [f.f32(292), f.f32(308), f.f32(324)]
        } else if f.i16(252) > 0 {
            [f.f32(268), f.f32(272), f.f32(276)]
        } else {
            [0.0; 3]
        };
        if let Some(bad) = origin_mm.iter().find(|v| !v.is_finite()) {
            return Err(err(
                if f.i16(254) > 0 { 280 } else { 268 },
                format!("the origin has a non-finite coordinate {bad}"),
            ));
        }

        let vox = f.f32(108);
        if !(vox.is_finite() && vox >= 0.0 && vox.fract() == 0.0 && vox < 1e15) {
            return Err(err(108, format!("vox_offset = {vox} is not a byte offset")));
        }
        let mut offset = vox as usize;
        if single_file {
            // Some writers leave vox_offset at 0 in a .nii; the data then follows the header
            // and its 4-byte extension flag, as in nibabel.
            if offset == 0 {
                offset = MIN_NII_OFFSET;
            } else if offset < MIN_NII_OFFSET {
                return Err(err(
                    108,
                    format!("vox_offset = {offset} lies inside the {MIN_NII_OFFSET}-byte header"),
                ));
            }
        }

        let slope = f.f32(112);
        let inter = f.f32(116);
        let scaling = (slope.is_finite() && slope != 0.0)
            .then_some((slope, if inter.is_finite() { inter } else { 0.0 }));

        Ok(Header {
            order: f.order,
            single_file,
            dims,
            spacing: Vec3::from_array(sp),
            origin: Vec3::from_array(origin_mm) * unit,
            ty,
            offset,
            scaling,
        })
    }

    /// Decodes the voxels from `data` (the .nii itself or the .img); extra bytes after them
    /// are ignored, as NIfTI readers do.
    fn image_from(&self, data: &[u8], path: &Path) -> Result<VoxelImage, IoError> {
        let [nx, ny, nz] = self.dims;
        let (_, need) = data_size(self.dims, self.ty).ok_or_else(|| {
            IoError::new(path, Location::Byte(40), "the image size overflows memory")
        })?;
        let have = data.len().saturating_sub(self.offset);
        let end = self.offset.checked_add(need).filter(|&e| e <= data.len());
        let Some(block) = end.and_then(|e| data.get(self.offset..e)) else {
            return Err(IoError::new(
                path,
                Location::Byte(self.offset as u64),
                format!(
                    "truncated data: {nx}×{ny}×{nz} voxels of {} need {need} bytes from byte {}, \
                     but the file has {have}",
                    self.ty, self.offset
                ),
            ));
        };
        Ok(VoxelImage {
            dims: self.dims,
            spacing: self.spacing,
            origin: self.origin,
            values: decode(block, self.ty, self.order, self.scaling),
            source_type: self.ty,
            byte_order: self.order,
            segments: Vec::new(),
        })
    }
}

/// Builds a NIfTI-1 header for tests (`n+1` or `ni1`, the given byte order).
#[cfg(test)]
pub(crate) fn test_header(
    order: ByteOrder,
    magic: &[u8; 4],
    dims: [i16; 3],
    datatype: i16,
    slope_inter: (f32, f32),
) -> Vec<u8> {
    let mut h = vec![0u8; MIN_NII_OFFSET];
    let mut put = |at: usize, le: &[u8]| {
        let mut v = le.to_vec();
        if order == ByteOrder::Big {
            v.reverse();
        }
        h[at..at + v.len()].copy_from_slice(&v);
    };
    put(0, &348i32.to_le_bytes());
    for (k, d) in [3, dims[0], dims[1], dims[2], 1, 1, 1, 1]
        .iter()
        .enumerate()
    {
        put(40 + 2 * k, &d.to_le_bytes());
    }
    put(70, &datatype.to_le_bytes());
    for (k, p) in [1.0f32, 1.5, 2.0, 3.0].iter().enumerate() {
        put(76 + 4 * k, &p.to_le_bytes());
    }
    put(112, &slope_inter.0.to_le_bytes());
    put(116, &slope_inter.1.to_le_bytes());
    put(252, &1i16.to_le_bytes());
    put(268, &10.0f32.to_le_bytes());
    put(272, &(-20.0f32).to_le_bytes());
    put(276, &5.0f32.to_le_bytes());
    h[123] = 2;
    h[344..348].copy_from_slice(magic);
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn little_endian_float_with_qform_origin() {
        let mut b = test_header(ByteOrder::Little, b"n+1\0", [2, 1, 1], 16, (f32::NAN, 0.0));
        b.extend(0.25f32.to_le_bytes());
        b.extend((-4.0f32).to_le_bytes());
        let im = parse(&b, Path::new("t.nii")).unwrap();
        assert_eq!(im.values, vec![0.25, -4.0]);
        assert_eq!(im.byte_order, ByteOrder::Little);
        assert!((im.spacing - Vec3::new(0.0015, 0.002, 0.003)).length() < 1e-12);
        assert!((im.origin - Vec3::new(0.01, -0.02, 0.005)).length() < 1e-12);
    }

    #[test]
    fn sform_wins_over_qform_and_units_convert() {
        let mut b = test_header(ByteOrder::Big, b"n+1\0", [1, 1, 1], 2, (0.0, 0.0));
        b[254..256].copy_from_slice(&1i16.to_be_bytes());
        b[292..296].copy_from_slice(&7.0f32.to_be_bytes());
        b[123] = 3; // micrometres
        b.push(9);
        let im = parse(&b, Path::new("t.nii")).unwrap();
        assert_eq!(im.values, vec![9.0]);
        assert!((im.origin - Vec3::new(7e-6, 0.0, 0.0)).length() < 1e-15);
        assert!((im.spacing.x - 1.5e-6).abs() < 1e-15);
    }

    #[test]
    fn zero_vox_offset_means_352_and_short_offsets_fail() {
        let mut b = test_header(ByteOrder::Little, b"n+1\0", [1, 1, 1], 256, (1.0, 0.0));
        b.push(0xff);
        assert_eq!(parse(&b, Path::new("t.nii")).unwrap().values, vec![-1.0]);
        b[108..112].copy_from_slice(&348.0f32.to_le_bytes());
        let e = parse(&b, Path::new("t.nii")).unwrap_err().to_string();
        assert!(e.contains("t.nii: byte 108") && e.contains("348"), "{e}");
    }

    #[test]
    fn gzip_and_four_d_are_refused_clearly() {
        let e = parse(&[0x1f, 0x8b, 8, 0], Path::new("a.nii.gz")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("a.nii.gz: not a valid gzip stream"),
            "{e}"
        );
        let mut b = test_header(ByteOrder::Little, b"n+1\0", [1, 1, 1], 2, (1.0, 0.0));
        b[40..42].copy_from_slice(&4i16.to_le_bytes());
        b[48..50].copy_from_slice(&5i16.to_le_bytes());
        let e = parse(&b, Path::new("t.nii")).unwrap_err().to_string();
        assert!(e.contains("byte 40") && e.contains("dim[4] = 5"), "{e}");
    }
}
