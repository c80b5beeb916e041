//! A reader over a file's bytes that mixes text lines and binary blocks (Gmsh binary, PLY
//! binary, STL) and always knows where it is, so every error names the file and the line or
//! byte offset.

use std::path::Path;
use std::str::FromStr;

use crate::error::{IoError, Location};

pub(crate) struct Cursor<'a> {
    path: &'a Path,
    data: &'a [u8],
    pos: usize,
    /// 1-based number of the line most recently returned (0 before the first).
    line: usize,
}

impl<'a> Cursor<'a> {
    pub fn new(path: &'a Path, data: &'a [u8]) -> Self {
        Self {
            path,
            data,
            pos: 0,
            line: 0,
        }
    }

    pub fn path(&self) -> &'a Path {
        self.path
    }

    /// The line most recently returned (1-based).
    pub fn line(&self) -> usize {
        self.line
    }

    pub fn position(&self) -> usize {
        self.pos
    }

    pub fn at_end(&self) -> bool {
        self.pos >= self.data.len()
    }

    /// The next line without its `\n` or `\r\n`; `None` at the end of the data.
    pub fn next_line(&mut self) -> Result<Option<&'a str>, IoError> {
        if self.at_end() {
            return Ok(None);
        }
        let rest = &self.data[self.pos..];
        let len = rest.iter().position(|&b| b == b'\n').unwrap_or(rest.len());
        let mut raw = &rest[..len];
        self.pos += (len + 1).min(rest.len());
        self.line += 1;
        if raw.last() == Some(&b'\r') {
            raw = &raw[..raw.len() - 1];
        }
        match std::str::from_utf8(raw) {
            Ok(s) => Ok(Some(s)),
            Err(_) => Err(self.error("the line is not valid UTF-8 text")),
        }
    }

    /// The next line that is not blank (after trimming), trimmed.
    pub fn next_nonblank(&mut self) -> Result<Option<&'a str>, IoError> {
        while let Some(l) = self.next_line()? {
            let t = l.trim();
            if !t.is_empty() {
                return Ok(Some(t));
            }
        }
        Ok(None)
    }

    /// The next non-blank line, or an error saying what was expected instead of the end.
    pub fn expect_line(&mut self, what: &str) -> Result<&'a str, IoError> {
        self.next_nonblank()?
            .ok_or_else(|| self.error(format!("unexpected end of file, expected {what}")))
    }

    /// The next `n` raw bytes (binary sections).
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], IoError> {
        if self.data.len() - self.pos < n {
            return Err(IoError::new(
                self.path,
                Location::Byte(self.pos as u64),
                format!(
                    "unexpected end of file: {n} bytes of binary data needed, {} left",
                    self.data.len() - self.pos
                ),
            ));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }

    /// Skips one line ending (`\n` or `\r\n`) if the cursor stands on one.
    pub fn skip_newline(&mut self) {
        if self.data.get(self.pos) == Some(&b'\r') {
            self.pos += 1;
        }
        if self.data.get(self.pos) == Some(&b'\n') {
            self.pos += 1;
        }
    }

    /// An error at the current line.
    pub fn error(&self, message: impl Into<String>) -> IoError {
        IoError::new(self.path, Location::Line(self.line.max(1)), message)
    }

    /// An error at the current byte offset (binary sections).
    pub fn byte_error(&self, message: impl Into<String>) -> IoError {
        IoError::new(self.path, Location::Byte(self.pos as u64), message)
    }

    /// Parses one token, naming what it should have been on failure.
    pub fn parse<T: FromStr>(&self, token: &str, what: &str) -> Result<T, IoError> {
        token
            .parse::<T>()
            .map_err(|_| self.error(format!("expected {what}, found `{token}`")))
    }

    /// Parses a finite real number.
    pub fn parse_real(&self, token: &str, what: &str) -> Result<f64, IoError> {
        let v: f64 = self.parse(token, what)?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.error(format!("{what} is not finite: `{token}`")))
        }
    }

    /// Parses exactly `N` whitespace-separated tokens from `tokens`, naming what was short.
    pub fn parse_n<T: FromStr + Copy + Default, const N: usize>(
        &self,
        tokens: &mut dyn Iterator<Item = &'a str>,
        what: &str,
    ) -> Result<[T; N], IoError> {
        let mut out = [T::default(); N];
        for (k, slot) in out.iter_mut().enumerate() {
            let tok = tokens
                .next()
                .ok_or_else(|| self.error(format!("expected {N} values for {what}, found {k}")))?;
            *slot = self.parse(tok, what)?;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_strip_crlf_and_count() {
        let p = Path::new("t.txt");
        let mut c = Cursor::new(p, b"a\r\n\r\nb c\nlast");
        assert_eq!(c.next_line().unwrap(), Some("a"));
        assert_eq!(c.next_nonblank().unwrap(), Some("b c"));
        assert_eq!(c.line(), 3);
        assert_eq!(c.expect_line("x").unwrap(), "last");
        let e = c.expect_line("the node count").unwrap_err();
        assert_eq!(
            e.to_string(),
            "t.txt:4: unexpected end of file, expected the node count"
        );
    }

    #[test]
    fn short_binary_block_names_the_offset() {
        let p = Path::new("b.stl");
        let mut c = Cursor::new(p, &[0u8; 10]);
        c.take(4).unwrap();
        let e = c.take(8).unwrap_err();
        assert!(e.to_string().contains("byte 4"), "{e}");
    }
}
