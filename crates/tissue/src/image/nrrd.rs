//! NRRD reader: `.nrrd` (data after the header) and `.nhdr` (data in the file its `data file`
//! names), the format 3D Slicer and Teem write, including Slicer's segmentations
//! (`.seg.nrrd`), whose segments keep their names.
//!
//! Read: the types int8 to double (64-bit integers too), the encodings raw, gzip, ascii and
//! hex, either byte order, `line skip` and `byte skip` (−1 for raw: the data ends the file),
//! and the geometry from `space directions` and `space origin` (or `spacings`). Lengths are in
//! `space units` when the header gives them, else millimetres, the convention of the medical
//! tools that write NRRD. Directions along the axes, flipped or permuted (LPS files are
//! often flipped), are applied exactly: the voxels are reordered so that the grid runs along
//! +x, +y, +z of the file's space. An oblique direction keeps only its length, as the NIfTI
//! and MetaImage readers do. Refused with the reason: bzip2 data, data spread over several
//! files, more than one non-spatial axis, a non-spatial axis outside a segmentation.
//!
//! A segmentation whose segments overlap stores one layer per entry of a non-spatial axis;
//! otherwise it is a plain label volume. Its segments (`SegmentN_Name`, `SegmentN_ID`,
//! `SegmentN_LabelValue`, `SegmentN_Layer` key/values) become `VoxelImage::segments`. In a
//! single-layer file they keep the file's label values; with several layers (whose values
//! repeat from layer to layer) segment N's voxels get the value N + 1, the first segment
//! listed winning where layers overlap.

use std::io::Read;
use std::path::{Path, PathBuf};

use crate::error::{IoError, Location};
use crate::image::grid::{ByteOrder, Segment, SourceType, VoxelImage, decode};
use crate::math::Vec3;

/// Reads a `.nrrd` or `.nhdr` file (a detached header reads its data file).
pub fn read(path: impl AsRef<Path>) -> Result<VoxelImage, IoError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| IoError::os(path, "read the file", e))?;
    parse_with(&bytes, path, &|p: &Path| std::fs::read(p))
}

/// Parses a header (and its attached data) already in memory; a detached data file is read
/// through `load`, which receives the path resolved against `path`'s folder.
pub fn parse_with(
    bytes: &[u8],
    path: &Path,
    load: &dyn Fn(&Path) -> std::io::Result<Vec<u8>>,
) -> Result<VoxelImage, IoError> {
    let h = Header::parse(bytes, path)?;
    let axes = h.axes(path)?;
    let (file_bytes, data_path): (Vec<u8>, PathBuf) = match &h.data_file {
        None => (
            bytes.get(h.header_end..).unwrap_or_default().to_vec(),
            path.to_path_buf(),
        ),
        Some((name, line)) => {
            let full = path.parent().unwrap_or(Path::new("")).join(name);
            let data = load(&full).map_err(|e| {
                h.error(
                    path,
                    *line,
                    format!("cannot read the data file `{}`: {e}", full.display()),
                )
            })?;
            (data, full)
        }
    };
    let count = axes
        .sizes
        .iter()
        .try_fold(1usize, |n, &s| n.checked_mul(s))
        .filter(|n| n.checked_mul(h.ty.size()).is_some())
        .ok_or_else(|| h.error(path, h.line("sizes"), "the image size overflows memory"))?;
    let samples = h.samples(&file_bytes, &data_path, count)?;
    let image = axes.arrange(&samples, &h, path)?;
    Ok(image)
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Encoding {
    Raw,
    Gzip,
    Ascii,
    Hex,
}

/// The header's fields, as read.
struct Header {
    ty: SourceType,
    sizes: Vec<usize>,
    encoding: Encoding,
    order: Option<ByteOrder>,
    directions: Option<Vec<Option<Vec3>>>,
    origin: Option<Vec3>,
    spacings: Option<Vec<f64>>,
    kinds: Option<Vec<String>>,
    /// Metres per length unit of the space.
    unit: f64,
    data_file: Option<(String, usize)>,
    byte_skip: i64,
    line_skip: usize,
    key_values: Vec<(String, String)>,
    header_end: usize,
    /// The line of each field read, to name it in errors.
    lines: Vec<(String, usize)>,
}

/// The lines of `bytes` up to the first empty one: (line number, text, offset after it).
fn header_lines(bytes: &[u8]) -> impl Iterator<Item = (usize, &[u8], usize)> {
    let mut at = 0usize;
    let mut number = 0usize;
    std::iter::from_fn(move || {
        if at >= bytes.len() {
            return None;
        }
        let rest = &bytes[at..];
        let len = rest.iter().position(|&b| b == b'\n');
        let (line, next) = match len {
            Some(n) => (&rest[..n], at + n + 1),
            None => (rest, bytes.len()),
        };
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        at = next;
        number += 1;
        Some((number, line, next))
    })
}

fn type_of(name: &str) -> Option<SourceType> {
    Some(match name {
        "signed char" | "int8" | "int8_t" => SourceType::I8,
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => SourceType::U8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            SourceType::I16
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
            SourceType::U16
        }
        "int" | "signed int" | "int32" | "int32_t" => SourceType::I32,
        "uint" | "unsigned int" | "uint32" | "uint32_t" => SourceType::U32,
        "longlong"
        | "long long"
        | "long long int"
        | "signed long long"
        | "signed long long int"
        | "int64"
        | "int64_t" => SourceType::I64,
        "ulonglong" | "unsigned long long" | "unsigned long long int" | "uint64" | "uint64_t" => {
            SourceType::U64
        }
        "float" => SourceType::F32,
        "double" => SourceType::F64,
        _ => return None,
    })
}

/// `(a,b,c)` vectors and `none` words, in order.
fn vectors(text: &str) -> Result<Vec<Option<Vec<f64>>>, String> {
    let mut out = Vec::new();
    let mut rest = text.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("none") {
            out.push(None);
            rest = r.trim_start();
        } else if let Some(r) = rest.strip_prefix('(') {
            let end = r
                .find(')')
                .ok_or_else(|| format!("`({r}` has no closing parenthesis"))?;
            let v = r[..end]
                .split(',')
                .map(|x| {
                    x.trim()
                        .parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| format!("`{}` is not a finite number", x.trim()))
                })
                .collect::<Result<Vec<_>, _>>()?;
            out.push(Some(v));
            rest = r[end + 1..].trim_start();
        } else {
            return Err(format!("expected `(x,y,z)` or `none`, found `{rest}`"));
        }
    }
    Ok(out)
}

fn vec3(v: &[f64]) -> Option<Vec3> {
    match v {
        [x, y, z] => Some(Vec3::new(*x, *y, *z)),
        _ => None,
    }
}

/// Metres per unit of a `space units` entry.
fn metres_per(unit: &str) -> Option<f64> {
    Some(match unit {
        "m" | "meter" | "meters" | "metre" | "metres" => 1.0,
        "cm" => 1e-2,
        "mm" | "millimeter" | "millimeters" | "millimetre" | "millimetres" | "" => 1e-3,
        "um" | "µm" | "micron" | "microns" | "micrometer" | "micrometers" => 1e-6,
        _ => return None,
    })
}

impl Header {
    fn parse(bytes: &[u8], path: &Path) -> Result<Self, IoError> {
        let err = |line: usize, m: String| IoError::new(path, Location::Line(line), m);
        let mut lines = header_lines(bytes);
        match lines.next() {
            Some((_, first, _)) if first.starts_with(b"NRRD000") => {}
            _ => {
                return Err(err(
                    1,
                    "not a NRRD file: the first line is not the magic `NRRD000X`".into(),
                ));
            }
        }
        let mut ty = None;
        let mut dimension = None;
        let mut h = Header {
            ty: SourceType::U8,
            sizes: Vec::new(),
            encoding: Encoding::Raw,
            order: None,
            directions: None,
            origin: None,
            spacings: None,
            kinds: None,
            unit: 1e-3,
            data_file: None,
            byte_skip: 0,
            line_skip: 0,
            key_values: Vec::new(),
            header_end: bytes.len(),
            lines: Vec::new(),
        };
        let mut encoding = None;
        for (number, raw, next) in lines {
            if raw.is_empty() {
                h.header_end = next;
                break;
            }
            let Ok(line) = std::str::from_utf8(raw) else {
                return Err(err(number, "the header line is not text".into()));
            };
            if line.starts_with('#') {
                continue;
            }
            if let Some((k, v)) = line.split_once(":=") {
                h.key_values.push((k.to_string(), v.to_string()));
                continue;
            }
            let Some((field, value)) = line.split_once(':') else {
                return Err(err(
                    number,
                    format!("`{line}` is neither `field: value` nor `key:=value`"),
                ));
            };
            let field = field.trim().to_ascii_lowercase();
            let value = value.trim();
            let bad = |what: &str| err(number, format!("{field}: {what}, found `{value}`"));
            h.lines.push((field.clone(), number));
            match field.as_str() {
                "type" => {
                    ty = Some(
                        type_of(&value.to_ascii_lowercase())
                            .ok_or_else(|| bad("unknown type (int8 … double expected)"))?,
                    );
                }
                "dimension" => {
                    dimension = Some(
                        value
                            .parse::<usize>()
                            .ok()
                            .filter(|d| (1..=16).contains(d))
                            .ok_or_else(|| bad("expected a count from 1 to 16"))?,
                    );
                }
                "sizes" => {
                    h.sizes = value
                        .split_whitespace()
                        .map(|s| s.parse::<usize>().ok().filter(|&n| n > 0))
                        .collect::<Option<Vec<_>>>()
                        .ok_or_else(|| bad("expected positive counts"))?;
                }
                "encoding" => {
                    encoding = Some(match value.to_ascii_lowercase().as_str() {
                        "raw" => Encoding::Raw,
                        "gz" | "gzip" => Encoding::Gzip,
                        "txt" | "text" | "ascii" => Encoding::Ascii,
                        "hex" => Encoding::Hex,
                        "bz2" | "bzip2" => {
                            return Err(bad(
                                "bzip2 is not supported (save the image with gzip or raw encoding)",
                            ));
                        }
                        _ => return Err(bad("unknown encoding (raw, gzip, ascii, hex)")),
                    });
                }
                "endian" => {
                    h.order = Some(match value.to_ascii_lowercase().as_str() {
                        "little" => ByteOrder::Little,
                        "big" => ByteOrder::Big,
                        _ => return Err(bad("expected little or big")),
                    });
                }
                "space directions" => {
                    let v = vectors(value).map_err(|m| err(number, format!("{field}: {m}")))?;
                    h.directions = Some(
                        v.iter()
                            .map(|d| match d {
                                None => Ok(None),
                                Some(d) => vec3(d)
                                    .map(Some)
                                    .ok_or_else(|| bad("each direction needs 3 numbers")),
                            })
                            .collect::<Result<_, _>>()?,
                    );
                }
                "space origin" => {
                    let v = vectors(value).map_err(|m| err(number, format!("{field}: {m}")))?;
                    h.origin = Some(match v.as_slice() {
                        [Some(o)] => vec3(o).ok_or_else(|| bad("the origin needs 3 numbers"))?,
                        _ => return Err(bad("expected one `(x,y,z)`")),
                    });
                }
                "spacings" => {
                    h.spacings = Some(
                        value
                            .split_whitespace()
                            .map(|s| s.parse::<f64>().ok())
                            .collect::<Option<Vec<_>>>()
                            .ok_or_else(|| bad("expected numbers (nan for a non-spatial axis)"))?,
                    );
                }
                "kinds" => {
                    h.kinds = Some(
                        value
                            .split_whitespace()
                            .map(str::to_ascii_lowercase)
                            .collect(),
                    );
                }
                "space units" => {
                    let units: Vec<&str> = value.split_whitespace().collect();
                    let m: Vec<f64> = units
                        .iter()
                        .map(|u| metres_per(u.trim_matches('"')))
                        .collect::<Option<_>>()
                        .ok_or_else(|| bad("a length unit (m, cm, mm, um) for each axis"))?;
                    if m.windows(2).any(|w| w[0] != w[1]) {
                        return Err(bad("different units on different axes are not supported"));
                    }
                    h.unit = m.first().copied().unwrap_or(1e-3);
                }
                "space dimension" if value != "3" => {
                    return Err(bad("only 3-D space is supported"));
                }
                "space" => {
                    let three = [
                        "right-anterior-superior",
                        "ras",
                        "left-anterior-superior",
                        "las",
                        "left-posterior-superior",
                        "lps",
                        "scanner-xyz",
                        "3d-right-handed",
                        "3d-left-handed",
                    ];
                    if !three.contains(&value.to_ascii_lowercase().as_str()) {
                        return Err(bad("only 3-D spaces are supported"));
                    }
                }
                "data file" | "datafile" => {
                    if value.starts_with("LIST") || value.split_whitespace().count() > 1 {
                        return Err(bad(
                            "data spread over several files is not supported: write one data file",
                        ));
                    }
                    h.data_file = Some((value.to_string(), number));
                }
                "byte skip" | "byteskip" => {
                    h.byte_skip = value
                        .parse::<i64>()
                        .ok()
                        .filter(|&b| b >= -1)
                        .ok_or_else(|| bad("expected a count, or -1"))?;
                }
                "line skip" | "lineskip" => {
                    h.line_skip = value.parse().map_err(|_| bad("expected a count"))?;
                }
                _ => {}
            }
        }
        h.ty = ty.ok_or_else(|| err(1, "the header has no `type` field".into()))?;
        h.encoding = encoding.ok_or_else(|| err(1, "the header has no `encoding` field".into()))?;
        let dimension =
            dimension.ok_or_else(|| err(1, "the header has no `dimension` field".into()))?;
        if h.sizes.len() != dimension {
            return Err(err(
                h.line("sizes"),
                format!(
                    "sizes gives {} counts, but the dimension is {dimension}",
                    h.sizes.len()
                ),
            ));
        }
        if h.order.is_none()
            && h.ty.size() > 1
            && matches!(h.encoding, Encoding::Raw | Encoding::Gzip | Encoding::Hex)
        {
            return Err(err(
                h.line("encoding"),
                format!(
                    "{} samples in binary need an `endian: little` or `endian: big` field",
                    h.ty
                ),
            ));
        }
        if h.byte_skip == -1 && h.encoding != Encoding::Raw {
            return Err(err(
                h.line("byte skip"),
                "byte skip -1 (data at the end of the file) needs raw encoding".into(),
            ));
        }
        Ok(h)
    }

    /// The line a field was read from (1 when absent: the header as a whole).
    fn line(&self, field: &str) -> usize {
        self.lines
            .iter()
            .find(|(f, _)| f == field || f.replace(' ', "") == field.replace(' ', ""))
            .map_or(1, |(_, l)| *l)
    }

    fn error(&self, path: &Path, line: usize, m: impl Into<String>) -> IoError {
        IoError::new(path, Location::Line(line), m)
    }

    /// Splits the axes into the three spatial ones and at most one other.
    fn axes(&self, path: &Path) -> Result<Axes, IoError> {
        let d = self.sizes.len();
        let count_check = |field: &str, n: usize| {
            if n != d {
                Err(self.error(
                    path,
                    self.line(field),
                    format!("{field} gives {n} entries, but the dimension is {d}"),
                ))
            } else {
                Ok(())
            }
        };
        if let Some(v) = &self.directions {
            count_check("space directions", v.len())?;
        }
        if let Some(v) = &self.spacings {
            count_check("spacings", v.len())?;
        }
        if let Some(v) = &self.kinds {
            count_check("kinds", v.len())?;
        }
        let spatial: Vec<bool> = (0..d)
            .map(|a| {
                if let Some(dirs) = &self.directions {
                    dirs[a].is_some()
                } else if let Some(kinds) = &self.kinds {
                    matches!(kinds[a].as_str(), "domain" | "space")
                } else if let Some(s) = &self.spacings {
                    s[a].is_finite()
                } else {
                    true
                }
            })
            .collect();
        let space: Vec<usize> = (0..d).filter(|&a| spatial[a]).collect();
        let other: Vec<usize> = (0..d).filter(|&a| !spatial[a]).collect();
        if space.len() != 3 || other.len() > 1 {
            return Err(self.error(
                path,
                self.line("sizes"),
                format!(
                    "{} spatial and {} other axes: a volume needs 3 spatial axes and at most \
                     one other (the layers of a segmentation)",
                    space.len(),
                    other.len()
                ),
            ));
        }
        let unit = self.unit;
        let steps: Vec<Vec3> = space
            .iter()
            .enumerate()
            .map(|(i, &a)| match (&self.directions, &self.spacings) {
                (Some(dirs), _) => dirs[a].unwrap_or(Vec3::ZERO) * unit,
                (None, Some(s)) => {
                    let mut v = Vec3::ZERO;
                    v[i] = s[a] * unit;
                    v
                }
                (None, None) => {
                    let mut v = Vec3::ZERO;
                    v[i] = unit;
                    v
                }
            })
            .collect();
        for (i, s) in steps.iter().enumerate() {
            if !(s.length() > 0.0 && s.length().is_finite()) {
                return Err(self.error(
                    path,
                    self.line("space directions").max(self.line("spacings")),
                    format!(
                        "spatial axis {} has no positive finite step",
                        space.get(i).copied().unwrap_or(i)
                    ),
                ));
            }
        }
        Ok(Axes {
            sizes: self.sizes.clone(),
            space: [space[0], space[1], space[2]],
            layers: other.first().copied(),
            steps: [steps[0], steps[1], steps[2]],
            origin: self.origin.unwrap_or(Vec3::ZERO) * unit,
        })
    }

    /// The samples in file order, decoded from the bytes after the header (or of the data
    /// file).
    fn samples(&self, file: &[u8], data_path: &Path, count: usize) -> Result<Vec<f32>, IoError> {
        let at = |b: usize, m: String| IoError::new(data_path, Location::Byte(b as u64), m);
        // Line skip counts lines of the file itself, before any decoding.
        let mut start = 0usize;
        for _ in 0..self.line_skip {
            match file[start..].iter().position(|&b| b == b'\n') {
                Some(n) => start += n + 1,
                None => {
                    return Err(at(
                        start,
                        format!("line skip {} passes the end of the data", self.line_skip),
                    ));
                }
            }
        }
        let body = &file[start..];
        let need = count * self.ty.size();
        let order = self.order.unwrap_or(ByteOrder::Little);
        let skip = usize::try_from(self.byte_skip).unwrap_or(0);
        let exact = |data: &[u8], from: usize| -> Result<Vec<f32>, IoError> {
            let have = data.len().saturating_sub(from);
            match from.checked_add(need).and_then(|end| data.get(from..end)) {
                Some(block) if have == need => Ok(decode(block, self.ty, order, None)),
                _ => Err(at(
                    start + from,
                    format!(
                        "sizes {:?} of {} need {need} bytes of data, but {have} follow{}",
                        self.sizes,
                        self.ty,
                        if from > 0 {
                            format!(" byte skip {from}")
                        } else {
                            String::new()
                        }
                    ),
                )),
            }
        };
        match self.encoding {
            Encoding::Raw if self.byte_skip == -1 => exact(body, body.len().saturating_sub(need)),
            Encoding::Raw => exact(body, skip),
            Encoding::Gzip => {
                // At most one byte more than needed is inflated, so a small file cannot
                // expand into gigabytes before the size check.
                let limit = need.saturating_add(skip).saturating_add(1) as u64;
                let mut out = Vec::new();
                flate2::read::MultiGzDecoder::new(body)
                    .take(limit)
                    .read_to_end(&mut out)
                    .map_err(|e| at(start, format!("not a valid gzip stream: {e}")))?;
                exact(&out, skip)
            }
            Encoding::Hex => {
                let digits: Vec<u8> = body
                    .iter()
                    .copied()
                    .filter(|b| !b.is_ascii_whitespace())
                    .collect();
                let mut out = Vec::with_capacity(digits.len() / 2);
                for (k, pair) in digits.chunks(2).enumerate() {
                    let text = std::str::from_utf8(pair).unwrap_or("?");
                    let byte = u8::from_str_radix(text, 16)
                        .ok()
                        .filter(|_| pair.len() == 2)
                        .ok_or_else(|| {
                            at(
                                start,
                                format!("hex byte {k} `{text}` is not two hex digits"),
                            )
                        })?;
                    out.push(byte);
                }
                exact(&out, skip)
            }
            Encoding::Ascii => {
                let text = std::str::from_utf8(body)
                    .map_err(|e| at(start, format!("ascii data is not text: {e}")))?;
                // The header's count is not trusted for the allocation: the text bounds it.
                let mut values = Vec::with_capacity(count.min(text.len() / 2 + 1));
                for (k, word) in text
                    .split(|c: char| c.is_whitespace() || c == ',')
                    .filter(|w| !w.is_empty())
                    .enumerate()
                {
                    let v: f64 = word.parse().map_err(|_| {
                        at(start, format!("ascii value {k} `{word}` is not a number"))
                    })?;
                    values.push(v as f32);
                }
                if values.len() != count {
                    return Err(at(
                        start,
                        format!(
                            "sizes {:?} need {count} values, but the ascii data has {}",
                            self.sizes,
                            values.len()
                        ),
                    ));
                }
                Ok(values)
            }
        }
    }

    /// The segments the key/values describe, in order (none for an ordinary image).
    fn segments(&self) -> Vec<RawSegment> {
        let mut out: Vec<RawSegment> = Vec::new();
        for (k, v) in &self.key_values {
            let Some(rest) = k.strip_prefix("Segment") else {
                continue;
            };
            let Some((n, what)) = rest.split_once('_') else {
                continue;
            };
            let Ok(n) = n.parse::<usize>() else {
                continue;
            };
            if out.len() <= n {
                if n > 100_000 {
                    continue;
                }
                out.resize_with(n + 1, RawSegment::default);
            }
            let s = &mut out[n];
            match what {
                "Name" => s.name = Some(v.clone()),
                "ID" => s.id = Some(v.clone()),
                "LabelValue" => s.label = v.trim().parse().ok(),
                "Layer" => s.layer = v.trim().parse().ok(),
                _ => {}
            }
        }
        out.retain(|s| s.name.is_some() || s.id.is_some());
        out
    }
}

#[derive(Clone, Debug, Default)]
struct RawSegment {
    name: Option<String>,
    id: Option<String>,
    label: Option<f64>,
    layer: Option<usize>,
}

/// The file's axes: which three are space, which one (if any) holds layers.
struct Axes {
    sizes: Vec<usize>,
    space: [usize; 3],
    layers: Option<usize>,
    /// World step (m) along each spatial axis.
    steps: [Vec3; 3],
    origin: Vec3,
}

impl Axes {
    /// The world axis and direction (+1 or −1) of each spatial axis, when all three lie along
    /// distinct world axes.
    fn aligned(&self) -> Option<[(usize, bool); 3]> {
        let mut out = [(0usize, true); 3];
        let mut used = [false; 3];
        for (i, s) in self.steps.iter().enumerate() {
            let a = s.abs();
            let w = if a.x >= a.y && a.x >= a.z {
                0
            } else if a.y >= a.z {
                1
            } else {
                2
            };
            let off = a.length_squared() - a[w] * a[w];
            if off > 1e-12 * a.length_squared() || used[w] {
                return None;
            }
            used[w] = true;
            out[i] = (w, s[w] > 0.0);
        }
        Some(out)
    }

    /// Builds the image: spatial axes reordered along +x, +y, +z, layers merged into labels.
    fn arrange(&self, samples: &[f32], h: &Header, path: &Path) -> Result<VoxelImage, IoError> {
        let raw = h.segments();
        let layers = self.layers.map_or(1, |a| self.sizes[a]);
        if layers > 1 && raw.is_empty() {
            return Err(h.error(
                path,
                h.line("sizes"),
                format!(
                    "axis {} holds {layers} values per voxel: only a segmentation (.seg.nrrd, \
                     with segment names) may have a non-spatial axis",
                    self.layers.unwrap_or(0)
                ),
            ));
        }
        // Strides of the file's axes (axis 0 fastest).
        let mut stride = vec![1usize; self.sizes.len()];
        for a in 1..self.sizes.len() {
            stride[a] = stride[a - 1] * self.sizes[a - 1];
        }
        let n = self.space.map(|a| self.sizes[a]);
        let (map, oblique) = match self.aligned() {
            Some(m) => (m, false),
            None => ([(0, true), (1, true), (2, true)], true),
        };
        let mut dims = [1usize; 3];
        let mut spacing = Vec3::ZERO;
        let mut origin = self.origin;
        for i in 0..3 {
            let (w, positive) = map[i];
            dims[w] = n[i];
            spacing[w] = self.steps[i].length();
            if !positive && !oblique {
                // The grid starts at the file's last sample along this axis.
                origin += self.steps[i] * (n[i] - 1) as f64;
            }
        }
        // File offset of output voxel (x, y, z).
        let file_index = |out: [usize; 3]| -> usize {
            (0..3)
                .map(|i| {
                    let (w, positive) = map[i];
                    let k = if positive || oblique {
                        out[w]
                    } else {
                        n[i] - 1 - out[w]
                    };
                    k * stride[self.space[i]]
                })
                .sum()
        };
        let total = dims[0] * dims[1] * dims[2];
        let mut values = vec![0f32; total];
        let mut segments = Vec::new();
        if layers > 1 {
            let layer_stride = self.layers.map_or(0, |a| stride[a]);
            let wanted: Vec<(usize, f32, f32)> = raw
                .iter()
                .enumerate()
                .map(|(k, s)| {
                    (
                        s.layer.unwrap_or(k),
                        s.label.unwrap_or(1.0) as f32,
                        (k + 1) as f32,
                    )
                })
                .collect();
            for (k, (s, &(layer, _, value))) in raw.iter().zip(&wanted).enumerate() {
                if layer >= layers {
                    return Err(h.error(
                        path,
                        1,
                        format!("Segment{k}_Layer is {layer}, but the file has {layers} layers"),
                    ));
                }
                segments.push(segment(s, k, value));
            }
            let mut v = 0usize;
            for z in 0..dims[2] {
                for y in 0..dims[1] {
                    for x in 0..dims[0] {
                        let base = file_index([x, y, z]);
                        values[v] = wanted
                            .iter()
                            .find(|(layer, label, _)| {
                                samples.get(base + layer * layer_stride) == Some(label)
                            })
                            .map_or(0.0, |w| w.2);
                        v += 1;
                    }
                }
            }
        } else {
            for (k, s) in raw.iter().enumerate() {
                segments.push(segment(s, k, s.label.unwrap_or(1.0) as f32));
            }
            let mut v = 0usize;
            for z in 0..dims[2] {
                for y in 0..dims[1] {
                    for x in 0..dims[0] {
                        values[v] = samples.get(file_index([x, y, z])).copied().unwrap_or(0.0);
                        v += 1;
                    }
                }
            }
        }
        Ok(VoxelImage {
            dims,
            spacing,
            origin,
            values,
            source_type: h.ty,
            byte_order: h.order.unwrap_or(ByteOrder::Little),
            segments,
        })
    }
}

fn segment(s: &RawSegment, k: usize, label: f32) -> Segment {
    let id = s.id.clone().unwrap_or_else(|| format!("Segment_{k}"));
    Segment {
        name: s.name.clone().unwrap_or_else(|| id.clone()),
        id,
        label,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::LabelRef;

    fn parse(bytes: &[u8]) -> Result<VoxelImage, IoError> {
        parse_with(bytes, Path::new("a.nrrd"), &|_| {
            Err(std::io::Error::other("no file"))
        })
    }

    fn file(header: &str, data: &[u8]) -> Vec<u8> {
        let mut b = header.as_bytes().to_vec();
        b.extend_from_slice(data);
        b
    }

    #[test]
    fn raw_big_endian_shorts_with_spacing_in_millimetres() {
        let data: Vec<u8> = (0..24i16).flat_map(|v| v.to_be_bytes()).collect();
        let im = parse(&file(
            "NRRD0004\n# a comment\ntype: short\ndimension: 3\nsizes: 2 3 4\nencoding: raw\n\
             endian: big\nspace: left-posterior-superior\n\
             space directions: (0.5,0,0) (0,1,0) (0,0,2)\nspace origin: (10,20,30)\n\n",
            &data,
        ))
        .unwrap();
        assert_eq!(im.dims, [2, 3, 4]);
        assert!((im.spacing - Vec3::new(5e-4, 1e-3, 2e-3)).length() < 1e-15);
        assert!((im.origin - Vec3::new(0.01, 0.02, 0.03)).length() < 1e-15);
        assert_eq!(im.values, (0..24).map(|v| v as f32).collect::<Vec<_>>());
        assert_eq!(im.source_type, SourceType::I16);
    }

    #[test]
    fn flipped_and_permuted_axes_put_every_voxel_at_its_world_place() {
        // File axis 0 runs along −y, axis 1 along +x, axis 2 along −z (sizes 2, 3, 4).
        let sizes = [2usize, 3, 4];
        let steps = [
            Vec3::new(0.0, -2.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -3.0),
        ];
        let origin = Vec3::new(5.0, 6.0, 7.0);
        let data: Vec<u8> = (0..24u8).collect();
        let im = parse(&file(
            "NRRD0005\ntype: uint8\ndimension: 3\nsizes: 2 3 4\nencoding: raw\n\
             space directions: (0,-2,0) (1,0,0) (0,0,-3)\nspace origin: (5,6,7)\n\
             space units: \"mm\" \"mm\" \"mm\"\n\n",
            &data,
        ))
        .unwrap();
        assert_eq!(im.dims, [3, 2, 4]);
        assert!((im.spacing - Vec3::new(1e-3, 2e-3, 3e-3)).length() < 1e-15);
        // Every file sample lands on the output voxel whose centre is its world position.
        for k in 0..sizes[2] {
            for j in 0..sizes[1] {
                for i in 0..sizes[0] {
                    let world =
                        (origin + steps[0] * i as f64 + steps[1] * j as f64 + steps[2] * k as f64)
                            * 1e-3;
                    let rel = (world - im.origin) / im.spacing;
                    let (x, y, z) = (
                        rel.x.round() as usize,
                        rel.y.round() as usize,
                        rel.z.round() as usize,
                    );
                    assert!((im.position(x, y, z) - world).length() < 1e-12);
                    let v = (i + 2 * j + 6 * k) as f32;
                    assert_eq!(im.value(x, y, z), Some(v), "sample ({i},{j},{k})");
                }
            }
        }
    }

    #[test]
    fn gzip_ascii_and_hex_give_the_raw_values() {
        use std::io::Write;
        let values: Vec<f32> = (0..8).map(|v| v as f32 * 1.5 - 2.0).collect();
        let raw: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let head = |enc: &str| {
            format!(
                "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\n\
                 encoding: {enc}\nspacings: 1 1 1\n\n"
            )
        };
        let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&raw).unwrap();
        let gz = z.finish().unwrap();
        let ascii: String = values.iter().map(|v| format!("{v}\n")).collect();
        let hex: String = raw.iter().map(|b| format!("{b:02x} ")).collect();
        for (enc, data) in [
            ("raw", raw.clone()),
            ("gzip", gz),
            ("ascii", ascii.into_bytes()),
            ("hex", hex.into_bytes()),
        ] {
            let im = parse(&file(&head(enc), &data)).unwrap();
            assert_eq!(im.values, values, "{enc}");
        }
    }

    #[test]
    fn detached_header_reads_its_data_file_after_the_skips() {
        let header = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 1 1\nencoding: raw\n\
                      data file: a.raw\nline skip: 1\nbyte skip: 2\n";
        let im = parse_with(header.as_bytes(), Path::new("dir/a.nhdr"), &|p: &Path| {
            assert_eq!(p, Path::new("dir/a.raw"));
            Ok(b"junk line\nXY\x07\x09".to_vec())
        })
        .unwrap();
        assert_eq!(im.values, vec![7.0, 9.0]);
        let e = parse_with(header.as_bytes(), Path::new("dir/a.nhdr"), &|_| {
            Err(std::io::Error::other("gone"))
        })
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("dir/a.nhdr:6:") && e.contains("a.raw"), "{e}");
    }

    #[test]
    fn errors_name_the_line_and_the_reason() {
        let cases = [
            ("PNG\n", "a.nrrd:1:", "magic"),
            ("NRRD0004\ntype: quaternion\n", "a.nrrd:2:", "unknown type"),
            (
                "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nencoding: bzip2\n\n",
                "a.nrrd:5:",
                "bzip2",
            ),
            (
                "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n",
                "a.nrrd:5:",
                "endian",
            ),
            (
                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2\nencoding: raw\n\n",
                "a.nrrd:4:",
                "dimension is 3",
            ),
            (
                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\
                 data file: a%03d.raw 1 3 1\n\n",
                "a.nrrd:6:",
                "several files",
            ),
            (
                "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 3 2 2 2\nencoding: raw\n\
                 kinds: vector domain domain domain\n\n",
                "a.nrrd:4:",
                "segmentation",
            ),
            (
                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\nabc",
                "a.nrrd: byte",
                "need 8 bytes",
            ),
        ];
        for (text, place, why) in cases {
            let mut bytes = text.as_bytes().to_vec();
            if why == "segmentation" {
                bytes.extend([0u8; 24]);
            }
            let e = parse(&bytes).unwrap_err().to_string();
            assert!(e.starts_with(place) && e.contains(why), "{text:?}: {e}");
        }
    }

    #[test]
    fn a_gzip_bomb_inflates_no_further_than_the_image_needs() {
        use std::io::Write;
        let mut z = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        z.write_all(&vec![0u8; 50_000_000]).unwrap();
        let gz = z.finish().unwrap();
        let e = parse(&file(
            "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\n",
            &gz,
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("need 8 bytes") && e.contains("9 follow"), "{e}");
    }

    const SEGMENTS: &str = "Segment0_ID:=Segment_1\nSegment0_Name:=liver\nSegment0_LabelValue:=1\n\
         Segment0_Layer:=0\nSegment1_ID:=Segment_2\nSegment1_Name:=tumor\n\
         Segment1_LabelValue:=1\nSegment1_Layer:=1\n";

    #[test]
    fn a_layered_segmentation_gives_each_segment_its_own_value_by_name() {
        // Two layers of a 2×1×1 grid: liver in both voxels, the tumour in the second.
        let header = format!(
            "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 2 2 1 1\nencoding: raw\n\
             space: right-anterior-superior\n\
             space directions: none (1,0,0) (0,1,0) (0,0,1)\n\
             kinds: list domain domain domain\nspace origin: (0,0,0)\n{SEGMENTS}\n"
        );
        // Layer axis fastest: voxel 0 = (liver 1, tumour 0), voxel 1 = (1, 1).
        let im = parse(&file(&header, &[1, 0, 1, 1])).unwrap();
        assert_eq!(im.dims, [2, 1, 1]);
        // The first segment listed wins where layers overlap.
        assert_eq!(im.values, vec![1.0, 1.0]);
        let names: Vec<&str> = im.segments.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["liver", "tumor"]);
        assert_eq!(
            im.label_values(&[LabelRef::Name("tumor".into()), LabelRef::Value(7.0)]),
            Ok(vec![2.0, 7.0])
        );
        let e = im
            .label_values(&[LabelRef::Name("spleen".into())])
            .unwrap_err();
        assert!(e.contains("spleen") && e.contains("liver, tumor"), "{e}");
        // Reversed order: the tumour wins its voxel.
        let header = header
            .replace("Segment0_", "SegmentX_")
            .replace("Segment1_", "Segment0_")
            .replace("SegmentX_", "Segment1_");
        let im = parse(&file(&header, &[1, 0, 1, 1])).unwrap();
        assert_eq!(im.values, vec![2.0, 1.0]);
    }

    #[test]
    fn a_single_layer_segmentation_keeps_its_label_values() {
        let header = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 3 1 1\nencoding: raw\n\
             space directions: (1,0,0) (0,1,0) (0,0,1)\n\
             Segment0_Name:=liver\nSegment0_LabelValue:=4\nSegment1_Name:=tumor\n\
             Segment1_LabelValue:=9\n\n";
        let im = parse(&file(header, &[0, 4, 9])).unwrap();
        assert_eq!(im.values, vec![0.0, 4.0, 9.0]);
        assert_eq!(
            im.label_values(&[
                LabelRef::Name("liver".into()),
                LabelRef::Name("tumor".into())
            ]),
            Ok(vec![4.0, 9.0])
        );
    }
}
