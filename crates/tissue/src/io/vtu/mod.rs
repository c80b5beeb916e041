//! VTK XML unstructured grids (`.vtu`) and polygon data (`.vtp`, a surface: its polygons
//! and triangle strips; vertices and lines are not a surface and are skipped): read data
//! arrays of any numeric type, either byte
//! order and header size, stored as ascii, inline base64 (`format="binary"`) or in
//! `<AppendedData>` (raw or base64), each binary form plain or zlib-compressed; that covers
//! what ParaView writes by default. Write ascii or base64 files that ParaView opens.
//!
//! Cells kept are those of the legacy reader (see `vtk`): triangles, quads and polygons
//! (split), tetrahedra and quadratic tetrahedra. PointData arrays become fields; an integer
//! CellData array named like a tag becomes the element tags. LZ4 or LZMA compression is
//! refused with an error naming the compressor, the file and the line.

mod appended;
mod data;
mod parser;
#[cfg(test)]
mod tests;
mod write;
mod zlib;

pub use write::{encode, encode_appended, encode_poly};

use std::path::Path;

use quick_xml::Reader;
use quick_xml::events::Event;

use crate::error::{IoError, Location};
use crate::mesh::MeshData;
use parser::{Array, Head, Parser};

/// Reads a `.vtu` file.
pub fn parse(bytes: &[u8], path: &Path) -> Result<MeshData, IoError> {
    let (xml_len, appended) = appended::split(bytes, path)?;
    let has_appended = appended.is_some();
    let mut p = Parser {
        path,
        bytes,
        big_endian: false,
        header64: false,
        compressed: false,
        appended,
        offsets: Vec::new(),
        poly: false,
        piece: None,
        arrays: Vec::new(),
    };
    let mut reader = Reader::from_reader(bytes.get(..xml_len).unwrap_or(bytes));
    let mut stack: Vec<String> = Vec::new();
    let mut current: Option<Head> = None;
    // Elements nested in the current DataArray (ParaView's <InformationKey>): their text
    // is not data.
    let mut inner = 0usize;
    let mut text: Vec<u8> = Vec::new();
    let mut seen_root = false;
    loop {
        let before = reader.buffer_position() as usize;
        let event = reader
            .read_event()
            .map_err(|e| p.error(reader.error_position() as usize, format!("XML error: {e}")))?;
        match event {
            Event::Start(e) if current.is_some() => {
                inner += 1;
                stack.push(String::from_utf8_lossy(e.local_name().as_ref()).into_owned());
            }
            Event::Empty(_) if current.is_some() => {}
            Event::Start(e) => {
                if !seen_root && e.local_name().as_ref() != b"VTKFile" {
                    return Err(p.error(
                        before,
                        "not a VTK XML file: the root element is not <VTKFile>",
                    ));
                }
                seen_root = true;
                current = p.open(&e, before, stack.last().map(String::as_str))?;
                text.clear();
                stack.push(String::from_utf8_lossy(e.local_name().as_ref()).into_owned());
            }
            Event::Empty(e) => {
                if let Some(head) = p.open(&e, before, stack.last().map(String::as_str))? {
                    let values = p.decode_inline(&head, &[])?;
                    p.arrays.push(Array { head, values });
                }
            }
            Event::Text(t) if current.is_some() && inner == 0 => text.extend_from_slice(&t),
            Event::CData(t) if current.is_some() && inner == 0 => text.extend_from_slice(&t),
            Event::GeneralRef(_) if current.is_some() && inner == 0 => {
                return Err(p.error(before, "unexpected entity reference inside a DataArray"));
            }
            Event::End(_) if inner > 0 => {
                inner -= 1;
                stack.pop();
            }
            Event::End(_) => {
                stack.pop();
                if let Some(head) = current.take() {
                    let values = p.decode_inline(&head, &text)?;
                    p.arrays.push(Array { head, values });
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if !seen_root {
        return Err(IoError::new(
            path,
            Location::File,
            "not a VTK XML file: no <VTKFile> element",
        ));
    }
    // The XML part of a file with appended data stops inside <VTKFile>.
    let complete = if has_appended {
        stack.len() == 1
    } else {
        stack.is_empty()
    };
    if let Some(open) = stack.last().filter(|_| !complete) {
        let what = if has_appended {
            "the XML before <AppendedData> ends"
        } else {
            "unexpected end of file"
        };
        return Err(p.error(xml_len, format!("{what} inside <{open}>")));
    }
    // Appended arrays are cut out now that every offset is known.
    let mut arrays = std::mem::take(&mut p.arrays);
    for a in &mut arrays {
        if let parser::Format::Appended(_) = a.head.format {
            a.values = p.decode(&a.head, &[])?;
        }
    }
    p.arrays = arrays;
    p.finish()
}

pub(crate) fn type_size(ty: &str) -> Option<usize> {
    Some(match ty {
        "Int8" | "UInt8" => 1,
        "Int16" | "UInt16" => 2,
        "Int32" | "UInt32" | "Float32" => 4,
        "Int64" | "UInt64" | "Float64" => 8,
        _ => return None,
    })
}

pub(crate) fn decode_uint(b: &[u8], big: bool) -> u64 {
    let mut a = [0u8; 8];
    let n = b.len().min(8);
    if big {
        a[8 - n..].copy_from_slice(&b[..n]);
        u64::from_be_bytes(a)
    } else {
        a[..n].copy_from_slice(&b[..n]);
        u64::from_le_bytes(a)
    }
}

pub(crate) fn decode_value(b: &[u8], ty: &str, big: bool) -> f64 {
    let u = decode_uint(b, big);
    match ty {
        "Int8" => f64::from(u as u8 as i8),
        "Int16" => f64::from(u as u16 as i16),
        "Int32" => f64::from(u as u32 as i32),
        "Int64" => u as i64 as f64,
        "Float32" => f64::from(f32::from_bits(u as u32)),
        "Float64" => f64::from_bits(u),
        _ => u as f64,
    }
}
