//! ParaView `.pvd` collections: one line per time step naming the file of that step, so a
//! series of `.vtu` frames opens in ParaView as an animation.

use std::fmt::Write;
use std::path::Path;

use quick_xml::Reader;
use quick_xml::events::Event;

use crate::error::{IoError, Location};

/// The text of a `.pvd` file listing `(time in s, file name relative to the .pvd)` entries.
pub fn encode_pvd(entries: &[(f64, String)]) -> String {
    let mut out = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n  <Collection>\n",
    );
    for (time, file) in entries {
        let _ = writeln!(
            out,
            "    <DataSet timestep=\"{time:?}\" group=\"\" part=\"0\" file=\"{}\"/>",
            quick_xml::escape::escape(file.as_str())
        );
    }
    out.push_str("  </Collection>\n</VTKFile>\n");
    out
}

/// Writes a `.pvd` file.
pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> Result<(), IoError> {
    std::fs::write(path, encode_pvd(entries)).map_err(|e| IoError::os(path, "write the file", e))
}

/// Reads the `(time, file)` entries of a `.pvd` file, in file order.
pub fn parse_pvd(bytes: &[u8], path: &Path) -> Result<Vec<(f64, String)>, IoError> {
    let line = |at: u64| {
        let at = usize::try_from(at).unwrap_or(usize::MAX).min(bytes.len());
        Location::Line(
            1 + bytes
                .get(..at)
                .unwrap_or(&[])
                .iter()
                .filter(|&&b| b == b'\n')
                .count(),
        )
    };
    let mut reader = Reader::from_reader(bytes);
    let mut out = Vec::new();
    let mut collection = false;
    loop {
        let at = reader.buffer_position();
        let event = reader.read_event().map_err(|e| {
            IoError::new(
                path,
                line(reader.error_position()),
                format!("XML error: {e}"),
            )
        })?;
        let e = match event {
            Event::Start(e) | Event::Empty(e) => e,
            Event::Eof => break,
            _ => continue,
        };
        match e.local_name().as_ref() {
            b"VTKFile" => {
                let ty = e.try_get_attribute("type").ok().flatten();
                if ty.as_ref().map(|a| a.value.as_ref()) != Some(b"Collection") {
                    return Err(IoError::new(
                        path,
                        line(at),
                        "not a ParaView collection: VTKFile type is not `Collection`",
                    ));
                }
                collection = true;
            }
            b"DataSet" => {
                let mut time = None;
                let mut file = None;
                for a in e.attributes() {
                    let a = a.map_err(|err| {
                        IoError::new(path, line(at), format!("bad attribute: {err}"))
                    })?;
                    let value = a.unescape_value().map_err(|err| {
                        IoError::new(path, line(at), format!("bad attribute: {err}"))
                    })?;
                    match a.key.local_name().as_ref() {
                        b"timestep" => {
                            let t: f64 = value.trim().parse().map_err(|_| {
                                IoError::new(
                                    path,
                                    line(at),
                                    format!("timestep should be a number, found `{value}`"),
                                )
                            })?;
                            time = Some(t);
                        }
                        b"file" => file = Some(value.into_owned()),
                        _ => {}
                    }
                }
                let file = file.ok_or_else(|| {
                    IoError::new(path, line(at), "DataSet without a `file` attribute")
                })?;
                out.push((time.unwrap_or(0.0), file));
            }
            _ => {}
        }
    }
    if !collection {
        return Err(IoError::new(
            path,
            Location::File,
            "not a ParaView collection: no <VTKFile type=\"Collection\">",
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_keeps_times_and_escaped_names() {
        let entries = vec![
            (0.0, "a&b/frame_0000.vtu".to_string()),
            (1e-3, "frame \"1\".vtu".to_string()),
            (0.1 + 0.2, "c.vtu".into()),
        ];
        let text = encode_pvd(&entries);
        assert!(text.contains("file=\"a&amp;b/frame_0000.vtu\""), "{text}");
        assert_eq!(
            parse_pvd(text.as_bytes(), Path::new("s.pvd")).unwrap(),
            entries
        );
    }

    #[test]
    fn bad_timestep_names_the_line() {
        let text = "<VTKFile type=\"Collection\">\n<Collection>\n<DataSet timestep=\"x\" file=\"a.vtu\"/>\n</Collection></VTKFile>";
        let e = parse_pvd(text.as_bytes(), Path::new("s.pvd")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "s.pvd:3: timestep should be a number, found `x`"
        );
    }
}
