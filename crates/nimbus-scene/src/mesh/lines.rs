//! A line reader that never holds more than [`MAX_LINE_BYTES`] of one line, for the
//! text parts of mesh files (a file without newlines must not be read whole).

use std::io::{BufRead, ErrorKind};

use anyhow::{bail, Result};

/// Longest line accepted in a text mesh file (OBJ, a PLY header or ascii body).
pub const MAX_LINE_BYTES: usize = 1 << 20;

/// Reads `\n`-terminated lines (a trailing `\r` is removed) with a length limit.
pub(crate) struct LineReader<'a> {
    pub inner: &'a mut dyn BufRead,
    buf: Vec<u8>,
    /// 1-based number of the line last returned (0 before the first).
    pub line: u64,
}

impl<'a> LineReader<'a> {
    pub fn new(inner: &'a mut dyn BufRead) -> Self {
        Self {
            inner,
            buf: Vec::new(),
            line: 0,
        }
    }

    /// A reader whose first line is numbered `lines_before + 1` (the rest of a file).
    pub fn starting_after(inner: &'a mut dyn BufRead, lines_before: u64) -> Self {
        Self {
            line: lines_before,
            ..Self::new(inner)
        }
    }

    /// The next line's 1-based number and text without its terminator, or `None` at
    /// the end of the input. Errors name the line but not the file: callers add it.
    pub fn next_line(&mut self) -> Result<Option<(u64, &[u8])>> {
        self.buf.clear();
        let mut any = false;
        loop {
            let available = match self.inner.fill_buf() {
                Ok(bytes) => bytes,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => bail!("read error after line {}: {e}", self.line),
            };
            if available.is_empty() {
                break;
            }
            any = true;
            let (take, done) = match available.iter().position(|&b| b == b'\n') {
                Some(i) => (i, true),
                None => (available.len(), false),
            };
            if self.buf.len() + take > MAX_LINE_BYTES {
                bail!(
                    "line {} is longer than {MAX_LINE_BYTES} bytes",
                    self.line + 1
                );
            }
            self.buf.extend_from_slice(&available[..take]);
            self.inner.consume(if done { take + 1 } else { take });
            if done {
                break;
            }
        }
        if !any {
            return Ok(None);
        }
        self.line += 1;
        if self.buf.last() == Some(&b'\r') {
            self.buf.pop();
        }
        Ok(Some((self.line, &self.buf)))
    }

    /// The line last returned by [`Self::next_line`].
    pub fn current(&self) -> &[u8] {
        &self.buf
    }
}

/// Whitespace-separated tokens of a line.
pub(crate) fn tokens(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
}

/// A token as text for messages (lossy, shortened).
pub(crate) fn show(token: &[u8]) -> String {
    let text = String::from_utf8_lossy(token);
    if text.chars().count() > 40 {
        format!("{}...", text.chars().take(40).collect::<String>())
    } else {
        text.into_owned()
    }
}

/// Parses a token as a number of type `T`.
pub(crate) fn parse<T: std::str::FromStr>(token: &[u8]) -> Option<T> {
    std::str::from_utf8(token).ok()?.parse().ok()
}
