//! Decoding one data array: ascii text, inline base64, or appended raw / base64 bytes, each
//! binary form optionally zlib-compressed in VTK's block layout.

use std::borrow::Cow;

use base64::Engine;
use base64::alphabet;
use base64::engine::{DecodePaddingMode, GeneralPurpose, GeneralPurposeConfig};

use super::appended::Encoding;
use super::parser::{Format, Head, Parser};
use super::{decode_uint, decode_value, type_size, zlib};
use crate::error::{IoError, Location};

/// Decodes base64 made of one or several padded streams glued together: VTK encodes a
/// binary header and its data as two streams, so padding may sit in the middle.
pub(super) fn decode_base64(clean: &[u8]) -> Result<Vec<u8>, base64::DecodeError> {
    let engine = GeneralPurpose::new(
        &alphabet::STANDARD,
        GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent),
    );
    let mut out = Vec::with_capacity(clean.len() / 4 * 3 + 3);
    let mut start = 0;
    let mut at = 0;
    for quantum in clean.chunks(4) {
        at += quantum.len();
        if quantum.contains(&b'=') {
            engine.decode_vec(clean.get(start..at).unwrap_or(&[]), &mut out)?;
            start = at;
        }
    }
    if start < clean.len() {
        engine.decode_vec(clean.get(start..).unwrap_or(&[]), &mut out)?;
    }
    Ok(out)
}

/// Where the bytes handed to [`Parser::payload`] come from, for error locations.
#[derive(Clone, Copy)]
pub(super) enum Origin {
    /// Decoded from base64 text: name the line of the DataArray.
    Line(usize),
    /// Decoded from appended base64 starting at this file byte.
    Encoded(usize),
    /// Raw appended bytes: byte `k` of the slice is file byte `base + k`.
    Raw(usize),
}

impl Origin {
    pub(super) fn at(self, k: usize) -> Location {
        match self {
            Origin::Line(l) => Location::Line(l),
            Origin::Encoded(b) => Location::Byte(b as u64),
            Origin::Raw(b) => Location::Byte(b.saturating_add(k) as u64),
        }
    }
}

impl Parser<'_> {
    /// Decodes an array as its element closes; appended arrays wait for [`Parser::decode`].
    pub(super) fn decode_inline(&self, head: &Head, text: &[u8]) -> Result<Vec<f64>, IoError> {
        match head.format {
            Format::Appended(_) => Ok(Vec::new()),
            _ => self.decode(head, text),
        }
    }

    pub(super) fn decode(&self, head: &Head, text: &[u8]) -> Result<Vec<f64>, IoError> {
        match head.format {
            Format::Ascii => self.decode_ascii(head, text),
            Format::Binary => {
                let clean: Vec<u8> = text
                    .iter()
                    .copied()
                    .filter(|b| !b.is_ascii_whitespace())
                    .collect();
                let raw = decode_base64(&clean).map_err(|e| {
                    self.error(
                        head.at,
                        format!("DataArray `{}`: bad base64 data: {e}", head.name),
                    )
                })?;
                let origin = Origin::Line(self.line_of(head.at));
                self.values(head, &raw, origin)
            }
            Format::Appended(offset) => self.decode_appended(head, offset),
        }
    }

    fn decode_ascii(&self, head: &Head, text: &[u8]) -> Result<Vec<f64>, IoError> {
        let text = std::str::from_utf8(text)
            .map_err(|_| self.error(head.at, "the data is not UTF-8 text"))?;
        text.split_ascii_whitespace()
            .map(|t| {
                t.parse::<f64>().map_err(|_| {
                    self.error(
                        head.at,
                        format!("DataArray `{}`: expected a number, found `{t}`", head.name),
                    )
                })
            })
            .collect()
    }

    fn decode_appended(&self, head: &Head, offset: usize) -> Result<Vec<f64>, IoError> {
        let Some(app) = &self.appended else {
            return Err(self.error(
                head.at,
                format!(
                    "DataArray `{}` has format=\"appended\" but the file has no <AppendedData>",
                    head.name
                ),
            ));
        };
        let Some(chunk) = app.data.get(offset..) else {
            return Err(self.error(
                head.at,
                format!(
                    "DataArray `{}`: offset {offset} is past the end of the appended data ({} bytes)",
                    head.name,
                    app.data.len()
                ),
            ));
        };
        let base = app.start.saturating_add(offset);
        match app.encoding {
            Encoding::Raw => self.values(head, chunk, Origin::Raw(base)),
            Encoding::Base64 => {
                // An array's text ends where the next array's begins.
                let end = self
                    .offsets
                    .iter()
                    .copied()
                    .filter(|&o| o > offset)
                    .min()
                    .map_or(chunk.len(), |o| o - offset);
                let clean: Vec<u8> = chunk
                    .get(..end)
                    .unwrap_or(chunk)
                    .iter()
                    .copied()
                    .filter(|b| !b.is_ascii_whitespace())
                    .collect();
                let raw = decode_base64(&clean).map_err(|e| {
                    IoError::new(
                        self.path,
                        Location::Byte(base as u64),
                        format!("DataArray `{}`: bad base64 data: {e}", head.name),
                    )
                })?;
                self.values(head, &raw, Origin::Encoded(base))
            }
        }
    }

    /// Reads the header and data of one binary array (`raw` may hold more bytes after it)
    /// and converts them to numbers.
    fn values(&self, head: &Head, raw: &[u8], origin: Origin) -> Result<Vec<f64>, IoError> {
        let fail = |k: usize, m: String| {
            IoError::new(
                self.path,
                origin.at(k),
                format!("DataArray `{}`: {m}", head.name),
            )
        };
        let hsize: usize = if self.header64 { 8 } else { 4 };
        let data: Cow<'_, [u8]> = if self.compressed {
            zlib::inflate(raw, hsize, self.big_endian).map_err(|(k, m)| fail(k, m))?
        } else {
            let Some(header) = raw.get(..hsize) else {
                return Err(fail(0, "the binary data is shorter than its header".into()));
            };
            let nbytes = decode_uint(header, self.big_endian);
            let data = usize::try_from(nbytes)
                .ok()
                .and_then(|n| raw.get(hsize..hsize.checked_add(n)?));
            let Some(data) = data else {
                return Err(fail(
                    0,
                    format!(
                        "the header announces {nbytes} bytes of {} but {} follow",
                        head.ty,
                        raw.len() - hsize
                    ),
                ));
            };
            Cow::Borrowed(data)
        };
        let size = type_size(&head.ty).unwrap_or(8);
        if !data.len().is_multiple_of(size) {
            return Err(fail(
                0,
                format!(
                    "{} bytes of data are not a whole number of {} values",
                    data.len(),
                    head.ty
                ),
            ));
        }
        Ok(data
            .chunks_exact(size)
            .map(|b| decode_value(b, &head.ty, self.big_endian))
            .collect())
    }
}
