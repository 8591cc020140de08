//! A bounds-checked little-endian reader over a seekable file: every read says how
//! many bytes it needs, and a read past the end is a "truncated" error naming the
//! offset, never a short read or an allocation larger than what the file still holds.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};

use anyhow::{bail, Result};

pub struct Input<R> {
    inner: R,
    pos: u64,
    len: u64,
}

impl Input<BufReader<File>> {
    pub fn open(file: File) -> Result<Self> {
        let len = file.metadata()?.len();
        Ok(Self::new(BufReader::with_capacity(1 << 16, file), len))
    }
}

impl<R: Read + Seek> Input<R> {
    pub fn new(inner: R, len: u64) -> Self {
        Self { inner, pos: 0, len }
    }

    pub fn pos(&self) -> u64 {
        self.pos
    }

    pub fn len(&self) -> u64 {
        self.len
    }

    pub fn remaining(&self) -> u64 {
        self.len.saturating_sub(self.pos)
    }

    fn need(&self, n: u64, what: &str) -> Result<()> {
        if n > self.remaining() {
            bail!(
                "truncated file: {what} needs {n} bytes at byte {}, but the file ends at {}",
                self.pos,
                self.len
            );
        }
        Ok(())
    }

    pub fn seek(&mut self, pos: u64) -> Result<()> {
        if pos > self.len {
            bail!(
                "truncated file: offset {pos} is past the end ({} bytes)",
                self.len
            );
        }
        self.inner.seek(SeekFrom::Start(pos))?;
        self.pos = pos;
        Ok(())
    }

    pub fn skip(&mut self, n: u64, what: &str) -> Result<()> {
        self.need(n, what)?;
        self.inner.seek_relative(n as i64)?;
        self.pos += n;
        Ok(())
    }

    pub fn fill(&mut self, buf: &mut [u8], what: &str) -> Result<()> {
        self.need(buf.len() as u64, what)?;
        self.inner.read_exact(buf)?;
        self.pos += buf.len() as u64;
        Ok(())
    }

    /// Reads `n` bytes into a new buffer; `n` is checked against the file first.
    pub fn bytes(&mut self, n: u64, what: &str) -> Result<Vec<u8>> {
        self.need(n, what)?;
        let mut buf = vec![0u8; n as usize];
        self.fill(&mut buf, what)?;
        Ok(buf)
    }

    pub fn array<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        let mut buf = [0u8; N];
        self.fill(&mut buf, what)?;
        Ok(buf)
    }

    pub fn u8(&mut self, what: &str) -> Result<u8> {
        Ok(self.array::<1>(what)?[0])
    }

    pub fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.array(what)?))
    }

    pub fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.array(what)?))
    }

    pub fn i64(&mut self, what: &str) -> Result<i64> {
        Ok(i64::from_le_bytes(self.array(what)?))
    }

    pub fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.array(what)?))
    }

    /// An OpenVDB string: a u32 byte count, then the bytes (not NUL-terminated).
    /// Names longer than 64 KiB are treated as corruption.
    pub fn string(&mut self, what: &str) -> Result<String> {
        let n = self.u32(what)?;
        if n > 1 << 16 {
            bail!(
                "corrupt file: {what} at byte {} claims {n} bytes",
                self.pos - 4
            );
        }
        let bytes = self.bytes(u64::from(n), what)?;
        Ok(String::from_utf8_lossy(&bytes).into_owned())
    }
}
