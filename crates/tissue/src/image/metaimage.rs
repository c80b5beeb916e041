//! MetaImage (ITK / SOFA) reader: a text header of `Key = Value` lines (`.mhd`, data in the
//! file named by `ElementDataFile`, relative to the header) or a header followed by the data
//! in the same file (`.mha`, `ElementDataFile = LOCAL`).
//!
//! The header states no length unit, so spacing and offset are the file's numbers times the
//! caller's `scale` (metres per file unit). Orientation (`TransformMatrix`) is not applied.
//! Unknown keys (SOFA writes `isPerpective`) are ignored; CRLF line endings are accepted.

use std::path::{Path, PathBuf};

use crate::error::{IoError, Location};
use crate::image::grid::{ByteOrder, SourceType, VoxelImage, data_size, decode};
use crate::math::Vec3;

/// Reads a `.mhd` or `.mha` file; `scale` converts the header's numbers to metres.
pub fn read(path: impl AsRef<Path>, scale: f64) -> Result<VoxelImage, IoError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| IoError::os(path, "read the file", e))?;
    parse_with(&bytes, path, scale, &|data_path: &Path| {
        std::fs::read(data_path)
    })
}

/// Parses a header (and, for `LOCAL`, its data) already in memory. A separate data file is
/// read through `load`, which receives the path resolved against `path`'s folder.
pub fn parse_with(
    bytes: &[u8],
    path: &Path,
    scale: f64,
    load: &dyn Fn(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<VoxelImage, IoError> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(IoError::new(
            path,
            Location::File,
            format!("scale {scale} is not a finite positive number of metres per unit"),
        ));
    }
    let h = Header::parse(bytes, path)?;
    let (data, data_path): (Vec<u8>, PathBuf) = match &h.data_file {
        None => (
            bytes.get(h.header_end..).unwrap_or_default().to_vec(),
            path.to_path_buf(),
        ),
        Some(name) => {
            let full = path.parent().unwrap_or(Path::new("")).join(name);
            let data = load(&full).map_err(|e| {
                IoError::new(
                    path,
                    Location::Line(h.data_line),
                    format!("cannot read the data file `{}`: {e}", full.display()),
                )
            })?;
            (data, full)
        }
    };
    let [nx, ny, nz] = h.dims;
    let (_, need) = data_size(h.dims, h.ty).ok_or_else(|| {
        IoError::new(
            path,
            Location::Line(h.dims_line),
            "the image size overflows memory",
        )
    })?;
    // HeaderSize −1: the data is the last `need` bytes; otherwise it starts after that many.
    let start = if h.header_size < 0 {
        data.len().saturating_sub(need)
    } else {
        usize::try_from(h.header_size).unwrap_or(usize::MAX)
    };
    let have = data.len().saturating_sub(start);
    let block = data.get(start..).filter(|b| b.len() == need).ok_or_else(|| {
        IoError::new(
            &data_path,
            Location::Byte(start as u64),
            format!(
                "DimSize {nx}×{ny}×{nz} of {} needs {need} bytes of data, but the file has {have}{}",
                h.ty,
                if start > 0 {
                    format!(" after byte {start}")
                } else {
                    String::new()
                }
            ),
        )
    })?;
    Ok(VoxelImage {
        dims: h.dims,
        spacing: h.spacing * scale,
        origin: h.origin * scale,
        values: decode(block, h.ty, h.order, None),
        source_type: h.ty,
        byte_order: h.order,
        segments: Vec::new(),
    })
}

/// What the header says, in file units.
struct Header {
    dims: [usize; 3],
    dims_line: usize,
    spacing: Vec3,
    origin: Vec3,
    ty: SourceType,
    order: ByteOrder,
    header_size: i64,
    /// `None` for `LOCAL`.
    data_file: Option<String>,
    data_line: usize,
    /// Byte just after the `ElementDataFile` line (start of `LOCAL` data).
    header_end: usize,
}

impl Header {
    fn parse(bytes: &[u8], path: &Path) -> Result<Self, IoError> {
        let mut line_no = 0usize;
        let mut pos = 0usize;
        let mut dims: Option<([usize; 3], usize)> = None;
        let mut ndims_seen = false;
        let mut spacing: Option<Vec3> = None;
        let mut size: Option<Vec3> = None;
        let mut origin = Vec3::ZERO;
        let mut ty: Option<SourceType> = None;
        let mut order = ByteOrder::Little;
        let mut header_size = 0i64;
        loop {
            let rest = bytes.get(pos..).unwrap_or_default();
            if rest.is_empty() {
                return Err(IoError::new(
                    path,
                    Location::Line(line_no.max(1)),
                    "the header ends without `ElementDataFile`",
                ));
            }
            let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
            let raw = rest.get(..len).unwrap_or_default();
            pos += (len + 1).min(rest.len());
            line_no += 1;
            let err = |msg: String| IoError::new(path, Location::Line(line_no), msg);
            let text = std::str::from_utf8(raw)
                .map_err(|_| err("header line is not text (missing `ElementDataFile`?)".into()))?
                .trim();
            if text.is_empty() || text.starts_with('#') {
                continue;
            }
            let (key, value) = text
                .split_once('=')
                .map(|(k, v)| (k.trim(), v.trim()))
                .ok_or_else(|| err(format!("expected `Key = Value`, found `{text}`")))?;
            let reals = |n: usize| -> Result<Vec3, IoError> {
                let v: Vec<f64> = value
                    .split_whitespace()
                    .map(|t| t.parse::<f64>().ok().filter(|x| x.is_finite()))
                    .collect::<Option<_>>()
                    .ok_or_else(|| err(format!("{key}: expected numbers, found `{value}`")))?;
                if v.len() != n {
                    return Err(err(format!(
                        "{key}: expected {n} numbers, found {}",
                        v.len()
                    )));
                }
                Ok(Vec3::new(v[0], v[1], v[2]))
            };
            let boolean = || match value.to_ascii_lowercase().as_str() {
                "true" | "1" => Ok(true),
                "false" | "0" => Ok(false),
                _ => Err(err(format!(
                    "{key}: expected True or False, found `{value}`"
                ))),
            };
            match key.to_ascii_lowercase().as_str() {
                "objecttype" if !value.eq_ignore_ascii_case("image") => {
                    return Err(err(format!("ObjectType `{value}` is not an Image")));
                }
                "ndims" => {
                    if value != "3" {
                        return Err(err(format!(
                            "NDims = {value}: only 3-D images are supported"
                        )));
                    }
                    ndims_seen = true;
                }
                "dimsize" => {
                    let d: Vec<usize> = value
                        .split_whitespace()
                        .map(|t| t.parse::<usize>().ok().filter(|&n| n > 0))
                        .collect::<Option<_>>()
                        .filter(|d: &Vec<usize>| d.len() == 3)
                        .ok_or_else(|| {
                            err(format!(
                                "DimSize: expected 3 positive integers, found `{value}`"
                            ))
                        })?;
                    dims = Some(([d[0], d[1], d[2]], line_no));
                }
                "elementspacing" | "elementsize" => {
                    let s = reals(3)?;
                    if s.min_element() <= 0.0 {
                        return Err(err(format!(
                            "{key}: spacing must be positive, found `{value}`"
                        )));
                    }
                    if key.eq_ignore_ascii_case("elementspacing") {
                        spacing = Some(s);
                    } else {
                        size = Some(s);
                    }
                }
                "offset" | "position" | "origin" => origin = reals(3)?,
                "elementtype" => {
                    ty = Some(match value {
                        "MET_UCHAR" => SourceType::U8,
                        "MET_CHAR" => SourceType::I8,
                        "MET_SHORT" => SourceType::I16,
                        "MET_USHORT" => SourceType::U16,
                        "MET_INT" => SourceType::I32,
                        "MET_UINT" => SourceType::U32,
                        "MET_FLOAT" => SourceType::F32,
                        "MET_DOUBLE" => SourceType::F64,
                        _ => {
                            return Err(err(format!(
                                "unsupported ElementType `{value}`; supported: MET_UCHAR MET_CHAR \
                                 MET_SHORT MET_USHORT MET_INT MET_UINT MET_FLOAT MET_DOUBLE"
                            )));
                        }
                    });
                }
                "elementbyteordermsb" | "binarydatabyteordermsb" => {
                    order = if boolean()? {
                        ByteOrder::Big
                    } else {
                        ByteOrder::Little
                    };
                }
                "headersize" => {
                    header_size =
                        value
                            .parse::<i64>()
                            .ok()
                            .filter(|&n| n >= -1)
                            .ok_or_else(|| {
                                err(format!(
                                    "HeaderSize: expected −1 or a byte count, found `{value}`"
                                ))
                            })?;
                }
                "compresseddata" if boolean()? => {
                    return Err(err(
                        "compressed MetaImage data (CompressedData = True) is not supported".into(),
                    ));
                }
                "binarydata" if !boolean()? => {
                    return Err(err(
                        "text MetaImage data (BinaryData = False) is not supported".into(),
                    ));
                }
                "elementnumberofchannels" if value != "1" => {
                    return Err(err(format!(
                        "ElementNumberOfChannels = {value}: only scalar images are supported"
                    )));
                }
                "elementdatafile" => {
                    let data_file = if value.eq_ignore_ascii_case("local") {
                        None
                    } else if value.eq_ignore_ascii_case("list") || value.contains('%') {
                        return Err(err(format!(
                            "ElementDataFile = {value}: data split over several files is not supported"
                        )));
                    } else if value.is_empty() {
                        return Err(err("ElementDataFile is empty".into()));
                    } else {
                        Some(value.to_string())
                    };
                    let missing = |what: &str| err(format!("the header has no {what}"));
                    if !ndims_seen {
                        return Err(missing("NDims"));
                    }
                    let (dims, dims_line) = dims.ok_or_else(|| missing("DimSize"))?;
                    return Ok(Header {
                        dims,
                        dims_line,
                        spacing: spacing.or(size).unwrap_or(Vec3::ONE),
                        origin,
                        ty: ty.ok_or_else(|| missing("ElementType"))?,
                        order,
                        header_size,
                        data_file,
                        data_line: line_no,
                        header_end: pos,
                    });
                }
                _ => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn no_file(_: &Path) -> std::io::Result<Vec<u8>> {
        Err(std::io::Error::from(std::io::ErrorKind::NotFound))
    }

    #[test]
    fn local_big_endian_shorts_with_crlf() {
        let mut b = b"ObjectType = Image\r\nNDims = 3\r\nDimSize = 2 1 1\r\n\
            ElementSpacing = 1 2 3\r\nOffset = 4 5 6\r\nElementType = MET_SHORT\r\n\
            BinaryDataByteOrderMSB = True\r\nElementDataFile = LOCAL\r\n"
            .to_vec();
        b.extend([0x01, 0x00, 0xff, 0xff]);
        let im = parse_with(&b, Path::new("x.mha"), 0.5, &no_file).unwrap();
        assert_eq!(im.values, vec![256.0, -1.0]);
        assert_eq!(im.spacing, Vec3::new(0.5, 1.0, 1.5));
        assert_eq!(im.origin, Vec3::new(2.0, 2.5, 3.0));
        assert_eq!(im.byte_order, ByteOrder::Big);
    }

    #[test]
    fn header_size_minus_one_takes_the_tail_of_the_raw_file() {
        let h = b"NDims = 3\nDimSize = 1 1 2\nElementType = MET_UCHAR\nHeaderSize = -1\n\
            ElementDataFile = d.raw\n";
        let load = |p: &Path| {
            assert_eq!(p, Path::new("dir/d.raw"));
            Ok(vec![7, 7, 7, 3, 4])
        };
        let im = parse_with(h, Path::new("dir/h.mhd"), 1.0, &load).unwrap();
        assert_eq!(im.values, vec![3.0, 4.0]);
        assert_eq!(im.spacing, Vec3::ONE);
    }

    #[test]
    fn errors_name_the_line() {
        let h = b"ObjectType = Image\nNDims = 2\nElementDataFile = LOCAL\n";
        let e = parse_with(h, Path::new("x.mha"), 1.0, &no_file).unwrap_err();
        assert_eq!(
            e.to_string(),
            "x.mha:2: NDims = 2: only 3-D images are supported"
        );
        let h = b"NDims = 3\nDimSize = 1 1 1\nElementType = MET_UCHAR\nCompressedData = True\n";
        let e = parse_with(h, Path::new("x.mha"), 1.0, &no_file).unwrap_err();
        assert!(e.to_string().starts_with("x.mha:4: compressed"), "{e}");
        let h = b"NDims = 3\nDimSize = 1 1 1\nElementType = MET_LONG\n";
        let e = parse_with(h, Path::new("x.mha"), 1.0, &no_file).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("x.mha:3: unsupported ElementType"),
            "{e}"
        );
    }
}
