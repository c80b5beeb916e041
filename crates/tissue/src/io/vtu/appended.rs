//! The `<AppendedData>` section of a `.vtu` file, located before any XML parsing.
//!
//! Raw appended data is arbitrary binary after an underscore, so the file is not well-formed
//! XML from there on: the file is split at `<AppendedData`, the part before it goes to the XML
//! parser, and arrays are later cut out of the part after the `_` by their `offset`.

use std::path::Path;

use quick_xml::Reader;
use quick_xml::events::Event;

use crate::error::{IoError, Location};

/// How the appended bytes are stored.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Encoding {
    Raw,
    Base64,
}

/// The data after the `_` of `<AppendedData>`.
pub(super) struct Appended<'a> {
    pub(super) encoding: Encoding,
    /// Raw: everything up to the end of the file (array sizes come from their headers).
    /// Base64: the text up to the next `<`.
    pub(super) data: &'a [u8],
    /// File position of `data[0]`, so errors can name absolute bytes.
    pub(super) start: usize,
}

fn line_of(bytes: &[u8], at: usize) -> usize {
    1 + bytes
        .get(..at)
        .unwrap_or(bytes)
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Splits a file into the length of its XML part and its appended data, if any.
pub(super) fn split<'a>(
    bytes: &'a [u8],
    path: &Path,
) -> Result<(usize, Option<Appended<'a>>), IoError> {
    // Everything before the first `<AppendedData` is XML written by the same writer, so the
    // first occurrence is the element itself.
    let Some(tag) = find(bytes, b"<AppendedData") else {
        return Ok((bytes.len(), None));
    };
    let err = |at: usize, m: String| IoError::new(path, Location::Line(line_of(bytes, at)), m);
    let rest = bytes.get(tag..).unwrap_or(&[]);
    let Some(gt) = rest.iter().position(|&b| b == b'>') else {
        return Err(err(tag, "unterminated <AppendedData> tag".into()));
    };
    let head = rest.get(..=gt).unwrap_or(&[]);
    let mut reader = Reader::from_reader(head);
    let (encoding, empty) = match reader.read_event() {
        Ok(Event::Start(e)) | Ok(Event::Empty(e)) => {
            let empty = head.ends_with(b"/>");
            let mut encoding = None;
            for a in e.attributes() {
                let a = a.map_err(|x| err(tag, format!("bad XML attribute: {x}")))?;
                if a.key.local_name().as_ref() == b"encoding" {
                    encoding = Some(String::from_utf8_lossy(&a.value).into_owned());
                }
            }
            let encoding = match encoding.as_deref() {
                Some("raw") => Encoding::Raw,
                Some("base64") => Encoding::Base64,
                other => {
                    return Err(err(
                        tag,
                        format!(
                            "AppendedData encoding `{}` is not supported: only raw or base64",
                            other.unwrap_or("")
                        ),
                    ));
                }
            };
            (encoding, empty)
        }
        Ok(_) => return Err(err(tag, "malformed <AppendedData> tag".into())),
        Err(x) => return Err(err(tag, format!("XML error in <AppendedData>: {x}"))),
    };
    let after = tag + gt + 1;
    if empty {
        return Ok((
            tag,
            Some(Appended {
                encoding,
                data: &[],
                start: after,
            }),
        ));
    }
    let tail = bytes.get(after..).unwrap_or(&[]);
    let skip = tail
        .iter()
        .position(|b| !b.is_ascii_whitespace())
        .unwrap_or(tail.len());
    if tail.get(skip) != Some(&b'_') {
        return Err(err(
            after + skip,
            "the appended data should start with `_`".into(),
        ));
    }
    let start = after + skip + 1;
    let mut data = bytes.get(start..).unwrap_or(&[]);
    if encoding == Encoding::Base64 {
        let end = data.iter().position(|&b| b == b'<').unwrap_or(data.len());
        data = data.get(..end).unwrap_or(&[]);
    }
    Ok((
        tag,
        Some(Appended {
            encoding,
            data,
            start,
        }),
    ))
}
