//! The FNV-1a 64 digest of a record block (docs/distributed.md §3): the writer hashes every byte
//! on its way to the file ([`DigestWriter`]) and records the digest of the bytes before the
//! trailer in it; the reader computes it again each time it reads the block ([`DigestReader`]),
//! once while the block is opened and again while its records stream.
//!
//! Together with the MCAP CRC-32s ([`crate::mcap_io::verify_checksums`], checked before any record
//! is interpreted) every byte of a block is covered: the data section's CRC covers the magic, the
//! header, the channels, the messages and the trailer (with its digest), the summary CRC the
//! summary section and the footer; the digest ties the trailer to the bytes before it.

use super::hash::Fnv1a64;
use crate::mcap_io::{ByteSource, FileStream, RecordStream, READ_PIECE_BYTES};
use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::sync::{Arc, Mutex, PoisonError};

/// Reads a block front to back, keeping its position and the FNV-1a 64 of every byte read.
pub struct DigestReader {
    inner: BufReader<Box<dyn ByteSource>>,
    digest: Fnv1a64,
    position: u64,
    scratch: Vec<u8>,
}

impl DigestReader {
    /// Reads `source` from its start.
    pub fn new(mut source: Box<dyn ByteSource>) -> io::Result<DigestReader> {
        source.seek(SeekFrom::Start(0))?;
        Ok(DigestReader {
            inner: BufReader::with_capacity(READ_PIECE_BYTES, source),
            digest: Fnv1a64::new(),
            position: 0,
            scratch: Vec::new(),
        })
    }

    /// Back to the start, with the digest of no bytes.
    pub fn rewind(&mut self) -> io::Result<()> {
        self.inner.seek(SeekFrom::Start(0))?;
        self.digest = Fnv1a64::new();
        self.position = 0;
        Ok(())
    }

    /// Fills `bytes` from the block.
    pub fn read_exact(&mut self, bytes: &mut [u8]) -> io::Result<()> {
        self.inner.read_exact(bytes)?;
        self.digest.update(bytes);
        self.position += bytes.len() as u64;
        Ok(())
    }

    /// Reads past the next `count` bytes (hashing them).
    pub fn skip(&mut self, count: u64) -> io::Result<()> {
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.resize(READ_PIECE_BYTES, 0);
        let mut left = count;
        let mut result = Ok(());
        while left > 0 && result.is_ok() {
            let piece = left.min(READ_PIECE_BYTES as u64) as usize;
            result = self.read_exact(&mut scratch[..piece]);
            left -= piece as u64;
        }
        self.scratch = scratch;
        result
    }

    /// The digest of the bytes read since the start.
    pub fn digest(&self) -> Fnv1a64 {
        self.digest
    }

    /// Bytes read since the start.
    pub fn position(&self) -> u64 {
        self.position
    }
}

impl RecordStream for DigestReader {
    fn read_exact(&mut self, bytes: &mut [u8]) -> io::Result<()> {
        DigestReader::read_exact(self, bytes)
    }

    fn position(&self) -> u64 {
        DigestReader::position(self)
    }
}

/// A writer that keeps the FNV-1a 64 of every byte written through it, readable through a
/// [`DigestHandle`] while the MCAP writer owns it.
pub struct DigestWriter<W> {
    inner: W,
    digest: Arc<Mutex<Fnv1a64>>,
    position: u64,
}

/// The digest of the bytes written so far through a [`DigestWriter`].
#[derive(Clone)]
pub struct DigestHandle(Arc<Mutex<Fnv1a64>>);

impl Default for DigestHandle {
    fn default() -> DigestHandle {
        DigestHandle::new()
    }
}

impl DigestHandle {
    /// A handle holding the digest of no bytes, for [`DigestWriter::with_handle`].
    pub fn new() -> DigestHandle {
        DigestHandle(Arc::new(Mutex::new(Fnv1a64::new())))
    }

    /// The digest of every byte written so far.
    pub fn digest(&self) -> Fnv1a64 {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl<W: Write> DigestWriter<W> {
    /// Writes to `inner` from its start, hashing into `handle` (a new one: the digest of no
    /// bytes).
    pub fn with_handle(inner: W, handle: &DigestHandle) -> DigestWriter<W> {
        DigestWriter {
            inner,
            digest: Arc::clone(&handle.0),
            position: 0,
        }
    }

    /// The writer underneath.
    pub fn into_inner(self) -> W {
        self.inner
    }
}

impl<W: Write> Write for DigestWriter<W> {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        let written = self.inner.write(bytes)?;
        self.digest
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .update(&bytes[..written]);
        self.position += written as u64;
        Ok(written)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl FileStream for DigestWriter<BufWriter<File>> {
    fn into_buffered_file(self) -> BufWriter<File> {
        self.into_inner()
    }
}

/// Only the position is asked for (the MCAP writer records offsets; unchunked, it never moves).
impl<W: Write> Seek for DigestWriter<W> {
    fn seek(&mut self, to: SeekFrom) -> io::Result<u64> {
        match to {
            SeekFrom::Current(0) => Ok(self.position),
            SeekFrom::Start(offset) if offset == self.position => Ok(self.position),
            _ => Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "a record block is written front to back",
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    #[test]
    fn the_digest_writer_hashes_what_it_writes() {
        let handle = DigestHandle::new();
        let mut writer = DigestWriter::with_handle(Vec::new(), &handle);
        writer.write_all(b"foo").expect("write");
        assert_eq!(writer.stream_position().expect("position"), 3);
        writer.write_all(b"bar").expect("write");
        assert_eq!(
            handle.digest().value(),
            super::super::hash::fnv1a64(b"foobar")
        );
        assert!(writer.seek(SeekFrom::Start(0)).is_err());
        let mut reader =
            DigestReader::new(Box::new(Cursor::new(writer.into_inner()))).expect("reader");
        let mut three = [0u8; 3];
        reader.read_exact(&mut three).expect("read");
        reader.skip(3).expect("skip");
        assert_eq!(reader.digest(), handle.digest());
        assert_eq!(reader.position(), 6);
        reader.rewind().expect("rewind");
        assert_eq!(reader.position(), 0);
    }
}
