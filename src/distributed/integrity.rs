//! Every byte of a record block checked (docs/distributed.md §3): the MCAP CRC-32s of the data
//! section (in its DataEnd record) and of the summary section (in the Footer) verified before any
//! record is interpreted ([`verify_checksums`]), and the FNV-1a 64 digest of the data before the
//! trailer, which the writer records in the trailer ([`DigestWriter`]) and the reader computes
//! again each time it reads the block ([`DigestReader`]).
//!
//! Between them every byte is covered: the data section's CRC covers the magic, the header, the
//! channels, the messages and the trailer (with its digest); the DataEnd record's opcode and length
//! are checked for their exact values and its CRC field against the bytes; the summary CRC covers
//! the summary section and the footer up to the CRC field itself; the end magic is compared.

use super::hash::Fnv1a64;
use std::io::{self, BufReader, Read, Seek, SeekFrom, Write};
use std::sync::{Arc, Mutex, PoisonError};

/// A record block's bytes: a file, or bytes in memory (tests, the fuzz target).
pub trait BlockSource: Read + Seek + Send + Sync {}

impl<T: Read + Seek + Send + Sync> BlockSource for T {}

/// MCAP opcode of the DataEnd record.
pub(super) const OP_DATA_END: u8 = 0x0F;
/// MCAP opcode of the Footer record.
const OP_FOOTER: u8 = 0x02;
/// Opcode and length of an MCAP record.
pub(super) const RECORD_FRAME_BYTES: u64 = 1 + 8;
/// The DataEnd record: opcode, length, the data section's CRC-32.
const DATA_END_BYTES: u64 = RECORD_FRAME_BYTES + 4;
/// The Footer record: opcode, length, summary start, summary offset start, summary CRC-32.
const FOOTER_BYTES: u64 = RECORD_FRAME_BYTES + 8 + 8 + 4;
/// Bytes read at a time while checksumming.
const PIECE_BYTES: usize = 1 << 16;

/// What is wrong with a block's bytes; the reader names the file and the command that rewrites it.
#[derive(Debug)]
pub enum Damage {
    /// No MCAP magic at either end: not a record block at all.
    NotMcap(String),
    /// The file ends early.
    Truncated(String),
    /// A checksum or a framing field of fixed value does not match the bytes.
    Corrupted(String),
    /// Reading failed.
    Io(io::Error),
}

impl From<io::Error> for Damage {
    fn from(error: io::Error) -> Damage {
        Damage::Io(error)
    }
}

/// The MCAP magic's length.
pub(super) fn magic_bytes() -> u64 {
    ::mcap::MAGIC.len() as u64
}

/// Verifies the MCAP framing and checksums of the `length` bytes of `source`: the magic at both
/// ends, the Footer and the DataEnd record where they must be, the summary section's CRC-32 and
/// the data section's CRC-32. Returns the offset of the DataEnd record (where the data section
/// ends).
pub fn verify_checksums(source: &mut dyn BlockSource, length: u64) -> Result<u64, Damage> {
    let magic = ::mcap::MAGIC;
    let magic_len = magic_bytes();
    if length < magic_len {
        return Err(Damage::Truncated(format!(
            "{length} bytes, shorter than the MCAP magic"
        )));
    }
    let start = read_at(source, 0, magic.len())?;
    let end = read_at(source, length - magic_len, magic.len())?;
    match (start == magic, end == magic) {
        (false, false) => {
            return Err(Damage::NotMcap(
                "not an MCAP file (no MCAP magic at either end); record blocks are written by `ribbon run`"
                    .to_string(),
            ))
        }
        (true, false) => {
            return Err(Damage::Truncated(format!(
                "{length} bytes and no MCAP magic at the end"
            )))
        }
        (false, true) => {
            return Err(Damage::Corrupted(
                "the MCAP magic at the start is damaged".to_string(),
            ))
        }
        (true, true) => {}
    }
    let smallest = 2 * magic_len + DATA_END_BYTES + FOOTER_BYTES;
    if length < smallest {
        return Err(Damage::Truncated(format!(
            "{length} bytes, fewer than the {smallest} of an empty MCAP file"
        )));
    }
    let footer_at = length - magic_len - FOOTER_BYTES;
    let footer = read_at(source, footer_at, FOOTER_BYTES as usize)?;
    let (op, len) = frame(&footer);
    if op != OP_FOOTER || len != FOOTER_BYTES - RECORD_FRAME_BYTES {
        return Err(Damage::Corrupted(format!(
            "no Footer record at byte {footer_at}, before the end magic (opcode {op:#04x}, length {len})"
        )));
    }
    let summary_start = le_u64(&footer[9..17]);
    let summary_offset_start = le_u64(&footer[17..25]);
    let summary_crc = le_u32(&footer[25..29]);
    if summary_start < magic_len + DATA_END_BYTES || summary_start > footer_at {
        return Err(Damage::Corrupted(format!(
            "the Footer's summary start {summary_start} lies outside the file's summary section (bytes {}..{footer_at})",
            magic_len + DATA_END_BYTES
        )));
    }
    if summary_offset_start < summary_start || summary_offset_start > footer_at {
        return Err(Damage::Corrupted(format!(
            "the Footer's summary offset start {summary_offset_start} lies outside its summary section (bytes {summary_start}..{footer_at})"
        )));
    }
    let data_end_at = summary_start - DATA_END_BYTES;
    let data_end = read_at(source, data_end_at, DATA_END_BYTES as usize)?;
    let (op, len) = frame(&data_end);
    if op != OP_DATA_END || len != DATA_END_BYTES - RECORD_FRAME_BYTES {
        return Err(Damage::Corrupted(format!(
            "no DataEnd record at byte {data_end_at}, before the summary section the Footer names (opcode {op:#04x}, length {len})"
        )));
    }
    let recorded = le_u32(&data_end[9..13]);
    let found = crc32_of(source, 0, data_end_at)?;
    if found != recorded {
        return Err(Damage::Corrupted(format!(
            "the data section (bytes 0..{data_end_at}) has CRC-32 {found:08x}, its DataEnd record says {recorded:08x}"
        )));
    }
    let covered_end = footer_at + FOOTER_BYTES - 4;
    let found = crc32_of(source, summary_start, covered_end)?;
    if found != summary_crc {
        return Err(Damage::Corrupted(format!(
            "the summary section (bytes {summary_start}..{covered_end}) has CRC-32 {found:08x}, the Footer says {summary_crc:08x}"
        )));
    }
    Ok(data_end_at)
}

/// `len` bytes of `source` from `offset`.
fn read_at(source: &mut dyn BlockSource, offset: u64, len: usize) -> io::Result<Vec<u8>> {
    let mut bytes = vec![0u8; len];
    source.seek(SeekFrom::Start(offset))?;
    source.read_exact(&mut bytes)?;
    Ok(bytes)
}

/// The CRC-32 (MCAP's, IEEE) of bytes `start..end` of `source`.
fn crc32_of(source: &mut dyn BlockSource, start: u64, end: u64) -> io::Result<u32> {
    source.seek(SeekFrom::Start(start))?;
    let mut hasher = crc32fast::Hasher::new();
    let mut buffer = vec![0u8; PIECE_BYTES];
    let mut left = end - start;
    while left > 0 {
        let piece = left.min(PIECE_BYTES as u64) as usize;
        source.read_exact(&mut buffer[..piece])?;
        hasher.update(&buffer[..piece]);
        left -= piece as u64;
    }
    Ok(hasher.finalize())
}

/// The opcode and length at the start of an MCAP record's bytes (at least 9).
pub(super) fn frame(bytes: &[u8]) -> (u8, u64) {
    (bytes[0], le_u64(&bytes[1..9]))
}

fn le_u64(bytes: &[u8]) -> u64 {
    let mut word = [0u8; 8];
    word.copy_from_slice(&bytes[..8]);
    u64::from_le_bytes(word)
}

fn le_u32(bytes: &[u8]) -> u32 {
    let mut word = [0u8; 4];
    word.copy_from_slice(&bytes[..4]);
    u32::from_le_bytes(word)
}

/// Reads a block front to back, keeping its position and the FNV-1a 64 of every byte read.
pub struct DigestReader {
    inner: BufReader<Box<dyn BlockSource>>,
    digest: Fnv1a64,
    position: u64,
    scratch: Vec<u8>,
}

impl DigestReader {
    /// Reads `source` from its start.
    pub fn new(mut source: Box<dyn BlockSource>) -> io::Result<DigestReader> {
        source.seek(SeekFrom::Start(0))?;
        Ok(DigestReader {
            inner: BufReader::with_capacity(PIECE_BYTES, source),
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
        scratch.resize(PIECE_BYTES, 0);
        let mut left = count;
        let mut result = Ok(());
        while left > 0 && result.is_ok() {
            let piece = left.min(PIECE_BYTES as u64) as usize;
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

impl DigestHandle {
    /// The digest of every byte written so far.
    pub fn digest(&self) -> Fnv1a64 {
        *self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl<W: Write> DigestWriter<W> {
    /// Writes to `inner` from its start, and the handle that reads the digest.
    pub fn new(inner: W) -> (DigestWriter<W>, DigestHandle) {
        let digest = Arc::new(Mutex::new(Fnv1a64::new()));
        let handle = DigestHandle(Arc::clone(&digest));
        let writer = DigestWriter {
            inner,
            digest,
            position: 0,
        };
        (writer, handle)
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

    /// A small MCAP file as the `mcap` crate writes it, unchunked like a record block.
    fn small_mcap() -> Vec<u8> {
        let mut bytes = Vec::new();
        {
            let options = ::mcap::WriteOptions::new()
                .use_chunks(false)
                .compression(None)
                .profile("test");
            let mut writer = options.create(Cursor::new(&mut bytes)).expect("writer");
            let channel = writer
                .add_channel(0, "/x", "raw", &Default::default())
                .expect("channel");
            for sequence in 0..3u32 {
                let header = ::mcap::records::MessageHeader {
                    channel_id: channel,
                    sequence,
                    log_time: u64::from(sequence),
                    publish_time: u64::from(sequence),
                };
                writer
                    .write_to_known_channel(&header, &[sequence as u8; 24])
                    .expect("message");
            }
            writer.finish().expect("finish");
        }
        bytes
    }

    fn verify(bytes: &[u8]) -> Result<u64, Damage> {
        let length = bytes.len() as u64;
        verify_checksums(&mut Cursor::new(bytes.to_vec()), length)
    }

    #[test]
    fn a_clean_file_passes_and_every_flipped_bit_is_caught() {
        let bytes = small_mcap();
        let data_end = verify(&bytes).expect("clean");
        assert_eq!(bytes[data_end as usize], OP_DATA_END);
        for i in 0..bytes.len() {
            for bit in [0, 3, 7] {
                let mut flipped = bytes.clone();
                flipped[i] ^= 1 << bit;
                assert!(
                    verify(&flipped).is_err(),
                    "byte {i} of {} bit {bit} passed",
                    bytes.len()
                );
            }
        }
    }

    #[test]
    fn truncations_and_other_files_are_told_apart() {
        let bytes = small_mcap();
        assert!(matches!(verify(&bytes[..5]), Err(Damage::Truncated(_))));
        assert!(matches!(
            verify(&bytes[..bytes.len() - 3]),
            Err(Damage::Truncated(_))
        ));
        assert!(matches!(
            verify(b"<robot name='x'/> not a block at all"),
            Err(Damage::NotMcap(_))
        ));
    }

    #[test]
    fn the_digest_writer_hashes_what_it_writes() {
        let (mut writer, handle) = DigestWriter::new(Vec::new());
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
