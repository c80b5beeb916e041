//! The PLY header: format, elements and their typed properties.

use super::Cursor;
use crate::error::IoError;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    pub(super) fn from_name(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// Decodes one value from exactly `self.size()` bytes.
    pub(super) fn decode(self, b: &[u8], big: bool) -> f64 {
        let mut a = [0u8; 8];
        let n = self.size().min(b.len());
        a[..n].copy_from_slice(&b[..n]);
        if big {
            a[..n].reverse();
        }
        match self {
            Scalar::I8 => f64::from(a[0] as i8),
            Scalar::U8 => f64::from(a[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([a[0], a[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([a[0], a[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([a[0], a[1], a[2], a[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([a[0], a[1], a[2], a[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([a[0], a[1], a[2], a[3]])),
            Scalar::F64 => f64::from_le_bytes(a),
        }
    }

    pub(super) fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Clone, Copy, Debug)]
pub(super) enum Kind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
pub(super) struct Property {
    pub(super) name: String,
    pub(super) kind: Kind,
}

#[derive(Debug)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: u64,
    pub(super) props: Vec<Property>,
    /// Header line declaring the element, for errors about its layout.
    pub(super) line: usize,
}

impl Element {
    pub(super) fn find(&self, name: &str) -> Option<usize> {
        self.props.iter().position(|p| p.name == name)
    }

    /// Smallest number of bytes one record can take, to bound reservations.
    pub(super) fn min_record_bytes(&self, binary: bool) -> usize {
        let per = |k: &Kind| match (k, binary) {
            (_, false) => 2,
            (Kind::Scalar(s), true) => s.size(),
            (Kind::List { count, .. }, true) => count.size(),
        };
        self.props
            .iter()
            .map(|p| per(&p.kind))
            .sum::<usize>()
            .max(1)
    }
}

#[derive(Clone, Copy, PartialEq)]
pub(super) enum Encoding {
    Ascii,
    Binary { big: bool },
}

pub(super) fn parse_header(c: &mut Cursor<'_>) -> Result<(Encoding, Vec<Element>), IoError> {
    if c.next_line()?.map(str::trim) != Some("ply") {
        return Err(c.error("not a PLY file: the first line must be `ply`"));
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let line = c
            .next_line()?
            .ok_or_else(|| c.error("unexpected end of file, expected `end_header`"))?;
        let mut t = line.split_whitespace();
        let Some(key) = t.next() else { continue };
        match key {
            "format" => {
                encoding = Some(match (t.next(), t.next()) {
                    (Some("ascii"), Some(_)) => Encoding::Ascii,
                    (Some("binary_little_endian"), Some(_)) => Encoding::Binary { big: false },
                    (Some("binary_big_endian"), Some(_)) => Encoding::Binary { big: true },
                    _ => {
                        return Err(c.error(format!(
                            "expected `format ascii|binary_little_endian|binary_big_endian 1.0`, found `{line}`"
                        )));
                    }
                });
            }
            "comment" | "obj_info" => {}
            "element" => {
                let (Some(name), Some(count), None) = (t.next(), t.next(), t.next()) else {
                    return Err(
                        c.error(format!("expected `element <name> <count>`, found `{line}`"))
                    );
                };
                let count = c.parse::<u64>(count, "an element count")?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                    line: c.line(),
                });
            }
            "property" => {
                let kind = match t.next() {
                    Some("list") => {
                        let count = scalar_type(c, t.next())?;
                        let item = scalar_type(c, t.next())?;
                        if count.is_float() {
                            return Err(c.error("a list count must have an integer type"));
                        }
                        Kind::List { count, item }
                    }
                    ty => Kind::Scalar(scalar_type(c, ty)?),
                };
                let (Some(name), None) = (t.next(), t.next()) else {
                    return Err(
                        c.error(format!("expected `property <type> <name>`, found `{line}`"))
                    );
                };
                let e = elements
                    .last_mut()
                    .ok_or_else(|| c.error("a property before any element"))?;
                e.props.push(Property {
                    name: name.to_string(),
                    kind,
                });
            }
            "end_header" => break,
            other => return Err(c.error(format!("unknown PLY header keyword `{other}`"))),
        }
    }
    let encoding = encoding.ok_or_else(|| c.error("the header has no `format` line"))?;
    Ok((encoding, elements))
}

fn scalar_type(c: &Cursor<'_>, tok: Option<&str>) -> Result<Scalar, IoError> {
    let tok = tok.unwrap_or("");
    Scalar::from_name(tok).ok_or_else(|| c.error(format!("unknown PLY property type `{tok}`")))
}
