//! The record block file of one shard (docs/distributed.md §3): an MCAP file without chunks or
//! compression, so that it is written and read as a stream, and any MCAP reader (the `mcap` Python
//! package, Foxglove) opens it.
//!
//! ```text
//! magic, Header (profile "ribbon-records")
//! Metadata "ribbon.shard"      plan hash, shard K of N, samples first..end, nominal, sizes
//! Channel  /records            one message per record time: samples × outputs f64, little-endian
//! Channel  /nominal            (shard 0 only) per record time: outputs, then nq positions, f64 LE
//! Message …                    record r at log_time = t_r in ns, sequence = r; /records then /nominal
//! Metadata "ribbon.shard.end"  complete, failures (JSON), Newton iterations, steps, retried
//!                              (JSON, only when a sample was re-run with the adaptive step), and
//!                              fnv1a64: the FNV-1a 64 digest of every byte of the file before
//!                              this record
//! DataEnd, summary section, Footer, magic     the data section's and the summary's CRC-32
//! ```
//!
//! Written and read through the MCAP layer ([`crate::mcap_io`]); the header and trailer metadata
//! are `block_metadata.rs`'s, the digest `integrity.rs`'s. Every byte is checked each time a block
//! is read: the CRC-32s first (`mcap_io::verify_checksums`), before any record is interpreted,
//! then the structure and the digest, and the digest again while the records stream.

use super::block_metadata::{BlockHeader, BlockTrailer, HEADER_NAME, TRAILER_NAME};
use super::error::ShardError;
use super::integrity::{DigestHandle, DigestReader, DigestWriter};
use crate::mcap_io::{
    magic_bytes, verify_checksums, ByteSource, Damage, Frame, McapFileWriter, McapWriteError,
    MessageId, MESSAGE_HEADER_BYTES, MESSAGE_ID_BYTES, OP_CHANNEL, OP_DATA_END, OP_MESSAGE,
    OP_METADATA,
};
use ::mcap::records::{MessageHeader, Record};
use ::mcap::WriteOptions;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// The MCAP profile of a record block.
pub const RECORD_BLOCK_PROFILE: &str = "ribbon-records";
/// Topic of the samples' recorded outputs.
pub const RECORDS_TOPIC: &str = "/records";
/// Topic of the nominal run's outputs and configuration.
pub const NOMINAL_TOPIC: &str = "/nominal";
/// Message encoding of both topics: raw little-endian IEEE-754 doubles, no schema.
pub const RECORDS_ENCODING: &str = "ribbon.f64le";
/// The trailer entry holding the FNV-1a 64 of the file's bytes before the trailer record, 16
/// lowercase hex digits.
const DIGEST_KEY: &str = "fnv1a64";
/// Largest metadata record read (the failures list of a shard), bytes.
const MAX_METADATA_BYTES: u64 = 256 << 20;

/// Writes a record block through a temporary file beside its target, renamed into place by
/// [`RecordBlockWriter::finish`]; dropped unfinished, nothing changes at the target.
pub struct RecordBlockWriter {
    header: BlockHeader,
    file: McapFileWriter<DigestWriter<BufWriter<File>>>,
    /// The digest of the bytes written so far (the trailer records it).
    digest: DigestHandle,
    records: u16,
    nominal: Option<u16>,
    written: usize,
    row: Vec<u8>,
}

impl RecordBlockWriter {
    /// Starts the record block `path` with `header`.
    pub fn create(path: &Path, header: BlockHeader) -> Result<RecordBlockWriter, ShardError> {
        let options = WriteOptions::new()
            .use_chunks(false)
            .compression(None)
            .profile(RECORD_BLOCK_PROFILE)
            .library(format!("ribbon {}", env!("CARGO_PKG_VERSION")));
        let digest = DigestHandle::new();
        let write = |error| write_error(path, error);
        let mut file = McapFileWriter::create(path, options, |buffered| {
            DigestWriter::with_handle(buffered, &digest)
        })
        .map_err(write)?;
        file.write_metadata(HEADER_NAME, header.to_metadata())
            .map_err(write)?;
        let no_metadata = BTreeMap::new();
        let records = file
            .add_channel(0, RECORDS_TOPIC, RECORDS_ENCODING, &no_metadata)
            .map_err(write)?;
        let nominal = if header.nominal {
            let channel = file.add_channel(0, NOMINAL_TOPIC, RECORDS_ENCODING, &no_metadata);
            Some(channel.map_err(write)?)
        } else {
            None
        };
        Ok(RecordBlockWriter {
            header,
            file,
            digest,
            records,
            nominal,
            written: 0,
            row: Vec::new(),
        })
    }

    /// Writes the next record (at `time_s`): the samples' values (`samples × outputs`) and, in
    /// the nominal shard, the nominal run's outputs and configuration.
    pub fn write_record(
        &mut self,
        time_s: f64,
        samples: &[f64],
        nominal: Option<(&[f64], &[f64])>,
    ) -> Result<(), ShardError> {
        let record = self.written;
        let sequence = u32::try_from(record).unwrap_or(u32::MAX);
        let header = MessageHeader {
            channel_id: self.records,
            sequence,
            log_time: (time_s * 1e9).round() as u64,
            publish_time: (time_s * 1e9).round() as u64,
        };
        encode(&mut self.row, &[samples]);
        let result = self.file.write_message(&header, &self.row);
        result.map_err(|e| write_error(self.file.path(), e))?;
        if let (Some(channel), Some((outputs, positions))) = (self.nominal, nominal) {
            encode(&mut self.row, &[outputs, positions]);
            let header = MessageHeader {
                channel_id: channel,
                ..header
            };
            let result = self.file.write_message(&header, &self.row);
            result.map_err(|e| write_error(self.file.path(), e))?;
        }
        self.written += 1;
        Ok(())
    }

    /// Writes the trailer (with the digest of every byte before it), finishes the MCAP file (its
    /// CRC-32s), syncs it and renames it into place.
    pub fn finish(mut self, trailer: &BlockTrailer) -> Result<(), ShardError> {
        let path = self.file.path().to_path_buf();
        if self.written != self.header.records && trailer.complete {
            return Err(ShardError::Malformed {
                path,
                message: format!(
                    "internal: {} of {} records written",
                    self.written, self.header.records
                ),
            });
        }
        let mut entries = trailer.to_metadata();
        entries.insert(DIGEST_KEY.to_string(), self.digest.digest().hex());
        let result = self.file.write_metadata(TRAILER_NAME, entries);
        result.map_err(|e| write_error(&path, e))?;
        self.file.finish().map_err(|e| write_error(&path, e))
    }
}

/// A failure writing the record block `path`, as every step of it is reported.
fn write_error(path: &Path, error: McapWriteError) -> ShardError {
    ShardError::Io {
        what: "write the record block",
        path: path.to_path_buf(),
        source: error.into_io_error(),
    }
}

/// `parts` as little-endian f64 bytes into `row` (cleared first).
fn encode(row: &mut Vec<u8>, parts: &[&[f64]]) {
    row.clear();
    for part in parts {
        for value in *part {
            row.extend_from_slice(&value.to_le_bytes());
        }
    }
}

/// Who is blamed for a block's faults: the file and the command that writes it again.
#[derive(Clone, Debug)]
struct Blame {
    path: PathBuf,
    rewrite: String,
}

impl Blame {
    fn malformed(&self, message: impl std::fmt::Display) -> ShardError {
        ShardError::Malformed {
            path: self.path.clone(),
            message: format!("{message}; run its shard again with `{}`", self.rewrite),
        }
    }

    fn truncated(&self, message: String) -> ShardError {
        ShardError::Truncated {
            path: self.path.clone(),
            message,
            command: self.rewrite.clone(),
        }
    }

    fn corrupted(&self, message: String) -> ShardError {
        ShardError::Corrupted {
            path: self.path.clone(),
            message,
            command: self.rewrite.clone(),
        }
    }

    fn io(&self, source: std::io::Error) -> ShardError {
        ShardError::Io {
            what: "read the record block",
            path: self.path.clone(),
            source,
        }
    }

    fn damage(&self, damage: Damage) -> ShardError {
        match damage {
            Damage::NotMcap(message) => ShardError::Malformed {
                path: self.path.clone(),
                message: format!("{message}; record blocks are written by `ribbon run`"),
            },
            Damage::Truncated(message) => self.truncated(message),
            Damage::Corrupted(message) => self.corrupted(message),
            Damage::Io(source) => self.io(source),
        }
    }
}

/// What the walk of a whole block found.
struct Walked {
    header: BlockHeader,
    trailer: BlockTrailer,
    trailer_at: u64,
    data_digest: String,
    channels: BTreeMap<u16, String>,
}

/// Reads a record block: [`RecordBlockReader::open`] checks every byte of the file (its MCAP
/// checksums, its digest) and its structure without holding its data, then
/// [`RecordBlockReader::read_record`] streams the records in order, computing the digest again as
/// it reads.
pub struct RecordBlockReader {
    blame: Blame,
    header: BlockHeader,
    trailer: BlockTrailer,
    /// The trailer's digest of the bytes before it (16 hex digits).
    data_digest: String,
    /// Where the trailer record starts.
    trailer_at: u64,
    /// FNV-1a 64 of the whole file (16 hex digits).
    file_digest: String,
    reader: DigestReader,
    records: u16,
    nominal: Option<u16>,
    next: usize,
    bytes: Vec<u8>,
}

impl RecordBlockReader {
    /// Opens `path` and checks it: the MCAP framing and both CRC-32s (data and summary sections),
    /// then the records — the header and trailer metadata, one `/records` (and `/nominal`) message
    /// of the right size per record time, in order, the trailer last — and the trailer's digest of
    /// the bytes before it. `rewrite` is the `ribbon run` command that writes this block again,
    /// named by every refusal. A file that ends early is [`ShardError::Truncated`]; one whose bytes
    /// do not match a checksum or the digest is [`ShardError::Corrupted`].
    pub fn open(path: &Path, rewrite: &str) -> Result<RecordBlockReader, ShardError> {
        let blame = Blame {
            path: path.to_path_buf(),
            rewrite: rewrite.to_string(),
        };
        let file = File::open(path).map_err(|e| blame.io(e))?;
        let length = file.metadata().map_err(|e| blame.io(e))?.len();
        RecordBlockReader::from_source(blame, Box::new(file), length)
    }

    /// [`RecordBlockReader::open`] for a block held in memory (tests, the fuzz target), named
    /// `name` in messages.
    pub fn from_bytes(
        name: &Path,
        rewrite: &str,
        bytes: Vec<u8>,
    ) -> Result<RecordBlockReader, ShardError> {
        let blame = Blame {
            path: name.to_path_buf(),
            rewrite: rewrite.to_string(),
        };
        let length = bytes.len() as u64;
        RecordBlockReader::from_source(blame, Box::new(std::io::Cursor::new(bytes)), length)
    }

    fn from_source(
        blame: Blame,
        mut source: Box<dyn ByteSource>,
        length: u64,
    ) -> Result<RecordBlockReader, ShardError> {
        let data_end = verify_checksums(source.as_mut(), length).map_err(|d| blame.damage(d))?;
        let mut reader = DigestReader::new(source).map_err(|e| blame.io(e))?;
        let walked = walk(&mut reader, data_end, &blame)?;
        reader.skip(length - data_end).map_err(|e| blame.io(e))?;
        let file_digest = reader.digest().hex();
        let Walked {
            header,
            trailer,
            trailer_at,
            data_digest,
            channels,
        } = walked;
        let find = |topic: &str| {
            channels
                .iter()
                .find(|(_, t)| *t == topic)
                .map(|(id, _)| *id)
        };
        let records = find(RECORDS_TOPIC).ok_or_else(|| blame.malformed("no /records channel"))?;
        let nominal = find(NOMINAL_TOPIC);
        // Streaming reads the file again from its start (the first record skips the magic),
        // hashing it again.
        reader.rewind().map_err(|e| blame.io(e))?;
        Ok(RecordBlockReader {
            blame,
            header,
            trailer,
            data_digest,
            trailer_at,
            file_digest,
            reader,
            records,
            nominal,
            next: 0,
            bytes: Vec::new(),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.blame.path
    }

    /// The header.
    pub fn header(&self) -> &BlockHeader {
        &self.header
    }

    /// The trailer.
    pub fn trailer(&self) -> &BlockTrailer {
        &self.trailer
    }

    /// The FNV-1a 64 of the whole file, 16 lowercase hex digits: the block's identity, which a
    /// later stage's plan names (docs/distributed.md §7).
    pub fn block_digest(&self) -> &str {
        &self.file_digest
    }

    /// Reads the next record time: the samples' values into `samples` (`samples × outputs`) and,
    /// in the nominal shard, the nominal run's outputs then positions into `nominal` (read and
    /// checked, but not kept, when `nominal` is `None`). After the last record, the digest of the
    /// bytes read must be the trailer's: a block that changed since it was opened is
    /// [`ShardError::Corrupted`].
    pub fn read_record(
        &mut self,
        samples: &mut [f64],
        mut nominal: Option<&mut [f64]>,
    ) -> Result<(), ShardError> {
        let record = self.next;
        if record >= self.header.records {
            return Err(self.blame.malformed(format!(
                "internal: record {record} asked of {} records",
                self.header.records
            )));
        }
        let changed = |blame: &Blame, what: String| {
            blame.corrupted(format!(
                "its bytes changed after they were checked when it was opened ({what})"
            ))
        };
        if self.reader.position() == 0 {
            let skipped = self.reader.skip(magic_bytes());
            skipped.map_err(|e| self.blame.io(e))?;
        }
        let nominal_values = self.header.outputs + self.header.nq;
        let mut want_records = true;
        let mut want_nominal = self.nominal.is_some();
        while want_records || want_nominal {
            let read = Frame::read(&mut self.reader);
            let Frame { at, op, len } = read.map_err(|e| self.blame.io(e))?;
            if len > self.trailer_at.saturating_sub(self.reader.position()) {
                let what = format!("a record at byte {at} runs past the trailer");
                return Err(changed(&self.blame, what));
            }
            if op != OP_MESSAGE {
                let skipped = self.reader.skip(len);
                skipped.map_err(|e| self.blame.io(e))?;
                continue;
            }
            if len < MESSAGE_HEADER_BYTES {
                let what = format!("a message of {len} bytes at byte {at}");
                return Err(changed(&self.blame, what));
            }
            self.bytes.resize(len as usize, 0);
            let mut bytes = std::mem::take(&mut self.bytes);
            let read = self.reader.read_exact(&mut bytes);
            read.map_err(|e| self.blame.io(e))?;
            let MessageId { channel, sequence } = MessageId::parse(&bytes);
            let sequence = sequence as usize;
            let data = &bytes[MESSAGE_HEADER_BYTES as usize..];
            let (target, expected): (Option<&mut [f64]>, usize) = if channel == self.records {
                want_records = false;
                let len = samples.len();
                (Some(&mut *samples), len)
            } else if Some(channel) == self.nominal {
                want_nominal = false;
                (nominal.as_deref_mut(), nominal_values)
            } else {
                self.bytes = bytes;
                let what = format!("a message on unknown channel {channel} at byte {at}");
                return Err(changed(&self.blame, what));
            };
            if sequence != record || data.len() != 8 * expected {
                self.bytes = bytes;
                return Err(self.blame.malformed(format!(
                    "record {record}: found message {sequence} of another size or order"
                )));
            }
            if let Some(target) = target {
                for (value, chunk) in target.iter_mut().zip(data.chunks_exact(8)) {
                    let mut word = [0u8; 8];
                    word.copy_from_slice(chunk);
                    *value = f64::from_le_bytes(word);
                }
            }
            self.bytes = bytes;
        }
        self.next += 1;
        if self.next == self.header.records {
            let digest = self.reader.digest().hex();
            if self.reader.position() != self.trailer_at || digest != self.data_digest {
                let what = format!(
                    "the {} bytes before the trailer hash to {digest}, the trailer records {}",
                    self.reader.position(),
                    self.data_digest
                );
                return Err(changed(&self.blame, what));
            }
        }
        Ok(())
    }
}

/// Walks the data section of a block whose checksums passed (`data_end`: the DataEnd record's
/// offset), from the start: the records' framing, the header and trailer metadata, the channels,
/// one message of the right size per record time and topic, in order, the trailer last, and the
/// trailer's digest against the bytes before it.
fn walk(reader: &mut DigestReader, data_end: u64, blame: &Blame) -> Result<Walked, ShardError> {
    reader.skip(magic_bytes()).map_err(|e| blame.io(e))?;
    let mut header: Option<BlockHeader> = None;
    let mut trailer: Option<(BlockTrailer, u64, String, Option<String>)> = None;
    let mut channels: BTreeMap<u16, String> = BTreeMap::new();
    let mut counts = (0usize, 0usize);
    // Message sizes of /records and /nominal, in bytes, once the header is read.
    let mut sizes = (0u64, 0u64);
    while reader.position() < data_end {
        let before = reader.digest();
        let Frame { at, op, len } = Frame::read(reader).map_err(|e| blame.io(e))?;
        if len > data_end - reader.position() {
            return Err(blame.malformed(format!(
                "a record at byte {at} claims {len} bytes, past the end of the data section at byte {data_end}"
            )));
        }
        if trailer.is_some() {
            return Err(blame.malformed(format!(
                "a record (opcode {op:#04x}) at byte {at} after the ribbon.shard.end metadata"
            )));
        }
        match op {
            OP_DATA_END => {
                return Err(blame.malformed(format!(
                    "a DataEnd record at byte {at}, before the end of the data section at byte {data_end}"
                )))
            }
            OP_MESSAGE => {
                if header.is_none() {
                    return Err(blame.malformed("a message before the ribbon.shard metadata"));
                }
                if len < MESSAGE_ID_BYTES as u64 {
                    return Err(blame.malformed(format!("a message of {len} bytes at byte {at}")));
                }
                let mut id = [0u8; MESSAGE_ID_BYTES];
                reader.read_exact(&mut id).map_err(|e| blame.io(e))?;
                let MessageId { channel, sequence } = MessageId::parse(&id);
                let sequence = sequence as usize;
                let topic = channels.get(&channel).map(String::as_str);
                let (count, size) = match topic {
                    Some(RECORDS_TOPIC) => (&mut counts.0, sizes.0),
                    Some(NOMINAL_TOPIC) => (&mut counts.1, sizes.1),
                    _ => return Err(blame.malformed(format!("a message on unknown channel {channel}"))),
                };
                if sequence != *count || len != size {
                    return Err(blame.malformed(format!(
                        "message {sequence} of {} is out of order or of the wrong size ({len} bytes)",
                        topic.unwrap_or("")
                    )));
                }
                *count += 1;
                reader.skip(len - MESSAGE_ID_BYTES as u64).map_err(|e| blame.io(e))?;
            }
            OP_METADATA | OP_CHANNEL => {
                if len > MAX_METADATA_BYTES {
                    return Err(blame.malformed(format!("a metadata record of {len} bytes")));
                }
                let mut body = vec![0u8; len as usize];
                reader.read_exact(&mut body).map_err(|e| blame.io(e))?;
                match ::mcap::parse_record(op, &body) {
                    Ok(Record::Metadata(m)) if m.name == HEADER_NAME => {
                        if header.is_some() {
                            return Err(blame.malformed("a second ribbon.shard metadata"));
                        }
                        let read = BlockHeader::from_metadata(&m.metadata).map_err(|message| {
                            blame.malformed(message)
                        })?;
                        sizes = message_sizes(&read).ok_or_else(|| {
                            blame.malformed("its sizes (samples × outputs, outputs + nq) overflow")
                        })?;
                        header = Some(read);
                    }
                    Ok(Record::Metadata(m)) if m.name == TRAILER_NAME => {
                        let read = BlockTrailer::from_metadata(&m.metadata)
                            .map_err(|message| blame.malformed(message))?;
                        let digest = m.metadata.get(DIGEST_KEY).cloned();
                        trailer = Some((read, at, before.hex(), digest));
                    }
                    Ok(Record::Channel(c)) => {
                        channels.insert(c.id, c.topic);
                    }
                    Ok(_) => {}
                    Err(e) => {
                        return Err(blame.malformed(format!("a record cannot be parsed: {e}")))
                    }
                }
            }
            _ => reader.skip(len).map_err(|e| blame.io(e))?,
        }
    }
    let header = header.ok_or_else(|| {
        blame.malformed("no ribbon.shard metadata: not a record block of `ribbon run`")
    })?;
    let (trailer, trailer_at, computed, recorded) = trailer.ok_or_else(|| {
        blame.truncated("the data section has no ribbon.shard.end metadata".to_string())
    })?;
    let recorded = recorded.ok_or_else(|| {
        blame.malformed(format!(
            "the ribbon.shard.end metadata has no '{DIGEST_KEY}'"
        ))
    })?;
    if recorded != computed {
        return Err(blame.corrupted(format!(
            "its {trailer_at} bytes before the trailer hash to {computed} (FNV-1a 64), the trailer records {recorded}"
        )));
    }
    let expected_nominal = if header.nominal { header.records } else { 0 };
    if !trailer.complete || counts.0 != header.records || counts.1 != expected_nominal {
        return Err(blame.truncated(format!(
            "{} of {} record times written{}",
            counts.0,
            header.records,
            if trailer.complete {
                ""
            } else {
                " (its run was interrupted)"
            }
        )));
    }
    Ok(Walked {
        header,
        trailer,
        trailer_at,
        data_digest: recorded,
        channels,
    })
}

/// The sizes in bytes of a `/records` and a `/nominal` message of a block with `header`, or
/// `None` when they overflow.
fn message_sizes(header: &BlockHeader) -> Option<(u64, u64)> {
    let bytes = |values: usize| {
        u64::try_from(values)
            .ok()?
            .checked_mul(8)?
            .checked_add(MESSAGE_HEADER_BYTES)
    };
    let records = bytes(header.samples().checked_mul(header.outputs)?)?;
    let nominal = bytes(header.outputs.checked_add(header.nq)?)?;
    Some((records, nominal))
}

#[cfg(test)]
mod tests {
    use super::super::block_metadata::tests::trailer;
    use super::*;

    /// A small block (2 samples, 2 outputs, 3 record times, the nominal run with nq = 1) written
    /// to `dir`, and its bytes.
    fn small_block(dir: &Path) -> (PathBuf, Vec<u8>) {
        std::fs::create_dir_all(dir).expect("mkdir");
        let path = dir.join("shard-0-of-1.records.mcap");
        let header = BlockHeader {
            plan_hash: "0123456789abcdef".to_string(),
            shard: 0,
            shards: 1,
            first_sample: 0,
            end_sample: 2,
            nominal: true,
            outputs: 2,
            records: 3,
            nq: 1,
        };
        let mut writer = RecordBlockWriter::create(&path, header).expect("create");
        for r in 0..3 {
            let x = r as f64;
            let samples = [x, x + 0.5, -x, 1e-300 * x];
            writer
                .write_record(0.1 * x, &samples, Some((&[x * 3.0, 7.0], &[x])))
                .expect("record");
        }
        writer.finish(&trailer(None)).expect("finish");
        let bytes = std::fs::read(&path).expect("read");
        (path, bytes)
    }

    fn scratch(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("ribbon-record-block-{name}-{}", std::process::id()))
    }

    #[test]
    fn a_block_reads_back_and_every_flipped_bit_is_refused() {
        let dir = scratch("flips");
        let (path, bytes) = small_block(&dir);
        let mut reader = RecordBlockReader::open(&path, "REWRITE").expect("clean block");
        let (mut samples, mut nominal) = ([0.0; 4], [0.0; 3]);
        for r in 0..3 {
            reader
                .read_record(&mut samples, Some(&mut nominal))
                .expect("record");
            let x = r as f64;
            assert_eq!(samples, [x, x + 0.5, -x, 1e-300 * x]);
            assert_eq!(nominal, [x * 3.0, 7.0, x]);
        }
        let digest = format!("{:016x}", crate::distributed::fnv1a64(&bytes));
        assert_eq!(reader.block_digest(), digest);
        for i in 0..bytes.len() {
            for bit in 0..8 {
                let mut flipped = bytes.clone();
                flipped[i] ^= 1 << bit;
                match RecordBlockReader::from_bytes(&path, "REWRITE", flipped) {
                    Ok(_) => panic!("byte {i} of {} bit {bit} passed", bytes.len()),
                    Err(
                        ShardError::Corrupted { command, .. }
                        | ShardError::Truncated { command, .. },
                    ) => assert_eq!(command, "REWRITE"),
                    Err(ShardError::Malformed { message, .. }) => {
                        assert!(message.contains("MCAP"), "byte {i} bit {bit}: {message}")
                    }
                    Err(other) => panic!("byte {i} bit {bit}: {other}"),
                }
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_block_that_changes_while_it_is_read_is_refused() {
        let dir = scratch("changed");
        let (path, bytes) = small_block(&dir);
        // Opened (and checked), then a bit of the last record flips on disk before the records
        // are read.
        let mut reader = RecordBlockReader::open(&path, "REWRITE").expect("clean block");
        let mut flipped = bytes.clone();
        let last_message = reader.trailer_at as usize - 3;
        flipped[last_message] ^= 1;
        std::fs::write(&path, &flipped).expect("flip");
        let (mut samples, mut nominal) = ([0.0; 4], [0.0; 3]);
        for _ in 0..2 {
            reader
                .read_record(&mut samples, Some(&mut nominal))
                .expect("record");
        }
        let error = reader
            .read_record(&mut samples, None)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            error.contains("changed after they were checked") && error.contains("REWRITE"),
            "{error}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
