//! An MCAP file's checksums verified before any record is read ([`verify_checksums`]): the magic
//! at both ends, the Footer and the DataEnd record where they must be, the summary section's
//! CRC-32 (in the Footer) and the data section's CRC-32 (in DataEnd). A file that fails is
//! [`Damage`]: not MCAP, truncated, or corrupted, each with what was found where.
//!
//! Between them every byte of an unchunked file is covered: the data section's CRC covers the
//! magic and every record before DataEnd; the DataEnd record's opcode and length are checked for
//! their exact values and its CRC field against the bytes; the summary CRC covers the summary
//! section and the footer up to the CRC field itself; the end magic is compared.

use super::framing::{frame, le_u32, le_u64, OP_DATA_END, OP_FOOTER, RECORD_FRAME_BYTES};
use std::io::{self, Read, Seek, SeekFrom};

/// An MCAP file's bytes: a file, or bytes in memory (tests, the fuzz target).
pub trait ByteSource: Read + Seek + Send + Sync {}

impl<T: Read + Seek + Send + Sync> ByteSource for T {}

/// The DataEnd record: opcode, length, the data section's CRC-32.
const DATA_END_BYTES: u64 = RECORD_FRAME_BYTES + 4;
/// The Footer record: opcode, length, summary start, summary offset start, summary CRC-32.
const FOOTER_BYTES: u64 = RECORD_FRAME_BYTES + 8 + 8 + 4;
/// Bytes read at a time while checksumming (and by the record blocks' digest reader).
pub const READ_PIECE_BYTES: usize = 1 << 16;

/// What is wrong with an MCAP file's bytes; the caller names the file (and what to do).
#[derive(Debug)]
pub enum Damage {
    /// No MCAP magic at either end: not an MCAP file at all.
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
pub fn magic_bytes() -> u64 {
    ::mcap::MAGIC.len() as u64
}

/// Verifies the MCAP framing and checksums of the `length` bytes of `source`: the magic at both
/// ends, the Footer and the DataEnd record where they must be, the summary section's CRC-32 and
/// the data section's CRC-32. Returns the offset of the DataEnd record (where the data section
/// ends).
pub fn verify_checksums(source: &mut dyn ByteSource, length: u64) -> Result<u64, Damage> {
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
                "not an MCAP file (no MCAP magic at either end)".to_string(),
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
fn read_at(source: &mut dyn ByteSource, offset: u64, len: usize) -> io::Result<Vec<u8>> {
    let mut bytes = vec![0u8; len];
    source.seek(SeekFrom::Start(offset))?;
    source.read_exact(&mut bytes)?;
    Ok(bytes)
}

/// The CRC-32 (MCAP's, IEEE) of bytes `start..end` of `source`.
fn crc32_of(source: &mut dyn ByteSource, start: u64, end: u64) -> io::Result<u32> {
    source.seek(SeekFrom::Start(start))?;
    let mut hasher = crc32fast::Hasher::new();
    let mut buffer = vec![0u8; READ_PIECE_BYTES];
    let mut left = end - start;
    while left > 0 {
        let piece = left.min(READ_PIECE_BYTES as u64) as usize;
        source.read_exact(&mut buffer[..piece])?;
        hasher.update(&buffer[..piece]);
        left -= piece as u64;
    }
    Ok(hasher.finalize())
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
}
