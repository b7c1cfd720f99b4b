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
//! Metadata "ribbon.shard.end"  complete, failures (JSON), Newton iterations, steps; retried
//!                              (JSON, only when a sample was re-run with the adaptive step)
//! DataEnd, summary section, Footer, magic
//! ```

use super::error::ShardError;
use crate::analysis::SampleFailure;
use crate::effects::ContactStats;
use crate::output::paths::TemporaryFile;
use ::mcap::records::{MessageHeader, Metadata, Record};
use ::mcap::{WriteOptions, Writer};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// The MCAP profile of a record block.
pub const RECORD_BLOCK_PROFILE: &str = "ribbon-records";
/// The version of the record block layout (the `format_version` metadata entry).
pub const RECORD_BLOCK_VERSION: u32 = 1;
/// Topic of the samples' recorded outputs.
pub const RECORDS_TOPIC: &str = "/records";
/// Topic of the nominal run's outputs and configuration.
pub const NOMINAL_TOPIC: &str = "/nominal";
/// Message encoding of both topics: raw little-endian IEEE-754 doubles, no schema.
pub const RECORDS_ENCODING: &str = "ribbon.f64le";
/// Name of the metadata record at the start.
const HEADER_NAME: &str = "ribbon.shard";
/// Name of the metadata record at the end.
const TRAILER_NAME: &str = "ribbon.shard.end";
/// Largest metadata record read (the failures list of a shard), bytes.
const MAX_METADATA_BYTES: u64 = 256 << 20;

const OP_CHANNEL: u8 = 0x04;
const OP_MESSAGE: u8 = 0x05;
const OP_METADATA: u8 = 0x0C;
const OP_DATA_END: u8 = 0x0F;
/// Channel id, sequence, log time, publish time.
const MESSAGE_HEADER_BYTES: u64 = 2 + 4 + 8 + 8;

/// What a record block holds, written before the data.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BlockHeader {
    /// The plan's hash.
    pub plan_hash: String,
    /// The shard's index, from 0.
    pub shard: usize,
    /// Shards in all.
    pub shards: usize,
    /// First design sample held.
    pub first_sample: usize,
    /// One past the last design sample held.
    pub end_sample: usize,
    /// Whether the block holds the nominal run (`/nominal`).
    pub nominal: bool,
    /// Outputs per record.
    pub outputs: usize,
    /// Record times.
    pub records: usize,
    /// Configuration coordinates (of the nominal run's positions).
    pub nq: usize,
}

impl BlockHeader {
    /// Design samples held.
    pub fn samples(&self) -> usize {
        self.end_sample - self.first_sample
    }

    fn to_metadata(&self) -> BTreeMap<String, String> {
        [
            ("format_version", RECORD_BLOCK_VERSION.to_string()),
            ("plan_hash", self.plan_hash.clone()),
            ("shard", self.shard.to_string()),
            ("shards", self.shards.to_string()),
            ("first_sample", self.first_sample.to_string()),
            ("end_sample", self.end_sample.to_string()),
            ("nominal", self.nominal.to_string()),
            ("outputs", self.outputs.to_string()),
            ("records", self.records.to_string()),
            ("nq", self.nq.to_string()),
            (
                "layout",
                "/records: samples first_sample..end_sample × outputs; /nominal: outputs then nq positions; f64 little-endian, one message per record time".to_string(),
            ),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }

    fn from_metadata(map: &BTreeMap<String, String>) -> Result<BlockHeader, String> {
        let text = |key: &str| {
            map.get(key)
                .cloned()
                .ok_or_else(|| format!("the ribbon.shard metadata has no '{key}'"))
        };
        let number = |key: &str| -> Result<usize, String> {
            text(key)?
                .parse()
                .map_err(|_| format!("ribbon.shard '{key}' is not a count"))
        };
        let version = number("format_version")?;
        if version != RECORD_BLOCK_VERSION as usize {
            return Err(format!(
                "record block version {version}, this ribbon reads version {RECORD_BLOCK_VERSION}; run the shard again with this ribbon"
            ));
        }
        let header = BlockHeader {
            plan_hash: text("plan_hash")?,
            shard: number("shard")?,
            shards: number("shards")?,
            first_sample: number("first_sample")?,
            end_sample: number("end_sample")?,
            nominal: text("nominal")? == "true",
            outputs: number("outputs")?,
            records: number("records")?,
            nq: number("nq")?,
        };
        if header.end_sample < header.first_sample {
            return Err("end_sample before first_sample".to_string());
        }
        Ok(header)
    }
}

/// What a record block says after the data.
#[derive(Clone, Debug)]
pub struct BlockTrailer {
    /// Whether every record time was written.
    pub complete: bool,
    /// Samples left out under `--keep-going` (indices in the whole design).
    pub failures: Vec<SampleFailure>,
    /// Samples re-run with the adaptive step, each with its fixed step's failure (indices in the
    /// whole design; the `retried` entry, absent when there are none).
    pub retried: Vec<SampleFailure>,
    /// Newton iterations of the shard's runs.
    pub newton_iterations: u64,
    /// Steps of the shard's runs.
    pub steps: u64,
    /// Contact counters of the shard's runs, summed (the `contacts` entry, absent when the scene
    /// declares no contacts), so that a merge reports what `analyze` reports.
    pub contacts: Option<ContactStats>,
}

impl BlockTrailer {
    fn to_metadata(&self) -> BTreeMap<String, String> {
        let mut map: BTreeMap<String, String> = [
            ("complete", self.complete.to_string()),
            ("newton_iterations", self.newton_iterations.to_string()),
            ("steps", self.steps.to_string()),
            ("failures", failures_json(&self.failures)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        if !self.retried.is_empty() {
            map.insert("retried".to_string(), failures_json(&self.retried));
        }
        if let Some(contacts) = &self.contacts {
            // Counts as integers; the depth's shortest round-trip text reads back to the same f64.
            let entry = serde_json::json!({
                "pair_tests": contacts.pair_tests,
                "narrow_queries": contacts.narrow_queries,
                "made": contacts.made,
                "broken": contacts.broken,
                "max_depth_m": contacts.max_depth_m,
            });
            map.insert("contacts".to_string(), entry.to_string());
        }
        map
    }

    fn from_metadata(map: &BTreeMap<String, String>) -> Result<BlockTrailer, String> {
        let text = |key: &str| {
            map.get(key)
                .ok_or_else(|| format!("the ribbon.shard.end metadata has no '{key}'"))
        };
        let count = |key: &str| -> Result<u64, String> {
            text(key)?
                .parse()
                .map_err(|_| format!("ribbon.shard.end '{key}' is not a count"))
        };
        let failures = failures_from_json(text("failures")?, "failures")?;
        let retried = match map.get("retried") {
            Some(entry) => failures_from_json(entry, "retried")?,
            None => Vec::new(),
        };
        let contacts = match map.get("contacts") {
            None => None,
            Some(entry) => {
                let value: serde_json::Value = serde_json::from_str(entry)
                    .map_err(|e| format!("ribbon.shard.end 'contacts' is not JSON: {e}"))?;
                let count = |key: &str| {
                    value
                        .get(key)
                        .and_then(serde_json::Value::as_u64)
                        .ok_or_else(|| {
                            format!("ribbon.shard.end 'contacts' lacks the count '{key}'")
                        })
                };
                Some(ContactStats {
                    pair_tests: count("pair_tests")?,
                    narrow_queries: count("narrow_queries")?,
                    made: count("made")?,
                    broken: count("broken")?,
                    max_depth_m: value
                        .get("max_depth_m")
                        .and_then(serde_json::Value::as_f64)
                        .ok_or("ribbon.shard.end 'contacts' lacks 'max_depth_m'")?,
                })
            }
        };
        Ok(BlockTrailer {
            complete: text("complete")? == "true",
            failures,
            retried,
            newton_iterations: count("newton_iterations")?,
            steps: count("steps")?,
            contacts,
        })
    }
}

/// A list of sample failures as the trailer's JSON (`failures`, `retried`).
fn failures_json(failures: &[SampleFailure]) -> String {
    let entries: Vec<serde_json::Value> = failures
        .iter()
        .map(|f| {
            serde_json::json!({
                "index": f.index, "xi": f.xi, "values": f.values, "time_s": f.time_s,
                "record": f.record, "message": f.message,
            })
        })
        .collect();
    serde_json::Value::Array(entries).to_string()
}

/// The trailer's list `key` of sample failures, read back from its JSON `text`.
fn failures_from_json(text: &str, key: &str) -> Result<Vec<SampleFailure>, String> {
    let entries: Vec<serde_json::Value> = serde_json::from_str(text)
        .map_err(|e| format!("ribbon.shard.end '{key}' is not a JSON list: {e}"))?;
    entries
        .iter()
        .map(|f| {
            let floats = |key: &str| -> Option<Vec<f64>> {
                f.get(key)?.as_array()?.iter().map(|x| x.as_f64()).collect()
            };
            Some(SampleFailure {
                index: usize::try_from(f.get("index")?.as_u64()?).ok()?,
                xi: floats("xi")?,
                values: floats("values")?,
                time_s: f.get("time_s")?.as_f64()?,
                record: usize::try_from(f.get("record")?.as_u64()?).ok()?,
                message: f.get("message")?.as_str()?.to_string(),
            })
        })
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| format!("an entry of '{key}' in ribbon.shard.end lacks a field"))
}

/// Writes a record block through a temporary file beside its target, renamed into place by
/// [`RecordBlockWriter::finish`]; dropped unfinished, nothing changes at the target.
pub struct RecordBlockWriter {
    path: PathBuf,
    header: BlockHeader,
    writer: Writer<BufWriter<File>>,
    temporary: TemporaryFile,
    records: u16,
    nominal: Option<u16>,
    written: usize,
    row: Vec<u8>,
}

impl RecordBlockWriter {
    /// Starts the record block `path` with `header`.
    pub fn create(path: &Path, header: BlockHeader) -> Result<RecordBlockWriter, ShardError> {
        let io = |source| ShardError::Io {
            what: "write the record block",
            path: path.to_path_buf(),
            source,
        };
        let (file, temporary) = TemporaryFile::create_beside(path).map_err(io)?;
        let options = WriteOptions::new()
            .use_chunks(false)
            .compression(None)
            .profile(RECORD_BLOCK_PROFILE)
            .library(format!("ribbon {}", env!("CARGO_PKG_VERSION")));
        let mcap = |e: ::mcap::McapError| io(std::io::Error::other(e.to_string()));
        let mut writer = Writer::with_options(BufWriter::new(file), options).map_err(mcap)?;
        writer
            .write_metadata(&Metadata {
                name: HEADER_NAME.to_string(),
                metadata: header.to_metadata(),
            })
            .map_err(mcap)?;
        let records = writer
            .add_channel(0, RECORDS_TOPIC, RECORDS_ENCODING, &BTreeMap::new())
            .map_err(mcap)?;
        let nominal = if header.nominal {
            Some(
                writer
                    .add_channel(0, NOMINAL_TOPIC, RECORDS_ENCODING, &BTreeMap::new())
                    .map_err(mcap)?,
            )
        } else {
            None
        };
        Ok(RecordBlockWriter {
            path: path.to_path_buf(),
            header,
            writer,
            temporary,
            records,
            nominal,
            written: 0,
            row: Vec::new(),
        })
    }

    fn mcap_error(&self, e: ::mcap::McapError) -> ShardError {
        ShardError::Io {
            what: "write the record block",
            path: self.path.clone(),
            source: std::io::Error::other(e.to_string()),
        }
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
        let result = self.writer.write_to_known_channel(&header, &self.row);
        result.map_err(|e| self.mcap_error(e))?;
        if let (Some(channel), Some((outputs, positions))) = (self.nominal, nominal) {
            encode(&mut self.row, &[outputs, positions]);
            let header = MessageHeader {
                channel_id: channel,
                ..header
            };
            let result = self.writer.write_to_known_channel(&header, &self.row);
            result.map_err(|e| self.mcap_error(e))?;
        }
        self.written += 1;
        Ok(())
    }

    /// Writes the trailer, finishes the MCAP file, syncs it and renames it into place.
    pub fn finish(mut self, trailer: &BlockTrailer) -> Result<(), ShardError> {
        if self.written != self.header.records && trailer.complete {
            return Err(ShardError::Malformed {
                path: self.path.clone(),
                message: format!(
                    "internal: {} of {} records written",
                    self.written, self.header.records
                ),
            });
        }
        let metadata = Metadata {
            name: TRAILER_NAME.to_string(),
            metadata: trailer.to_metadata(),
        };
        let result = self.writer.write_metadata(&metadata);
        result.map_err(|e| self.mcap_error(e))?;
        let result = self.writer.finish();
        result.map_err(|e| self.mcap_error(e))?;
        let io = |source| ShardError::Io {
            what: "write the record block",
            path: self.path.clone(),
            source,
        };
        let file = self
            .writer
            .into_inner()
            .into_inner()
            .map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        drop(file);
        self.temporary.commit().map_err(io)
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

/// Reads a record block: [`RecordBlockReader::open`] checks the whole file's structure (without
/// holding its data), then [`RecordBlockReader::read_record`] streams the records in order.
pub struct RecordBlockReader {
    path: PathBuf,
    header: BlockHeader,
    trailer: BlockTrailer,
    reader: BufReader<File>,
    records: u16,
    nominal: Option<u16>,
    next: usize,
    bytes: Vec<u8>,
}

impl RecordBlockReader {
    /// Opens `path` and walks its records: the MCAP magic at both ends, the header and trailer
    /// metadata, one `/records` (and `/nominal`) message of the right size per record time, in
    /// order, and the end of the data section. A file that ends early is
    /// [`ShardError::Truncated`].
    pub fn open(path: &Path) -> Result<RecordBlockReader, ShardError> {
        let malformed = |message: String| ShardError::Malformed {
            path: path.to_path_buf(),
            message,
        };
        let truncated = |message: String| ShardError::Truncated {
            path: path.to_path_buf(),
            message,
        };
        let io = |source| ShardError::Io {
            what: "read the record block",
            path: path.to_path_buf(),
            source,
        };
        let mut file = File::open(path).map_err(io)?;
        let length = file.metadata().map_err(io)?.len();
        let magic = ::mcap::MAGIC;
        let magic_len = magic.len() as u64;
        let mut start = vec![0u8; magic.len()];
        if length < magic_len || file.read_exact(&mut start).is_err() || start != magic {
            return Err(if length < magic_len {
                truncated(format!("{length} bytes, shorter than the MCAP magic"))
            } else {
                malformed(
                    "not an MCAP file (no MCAP magic at the start); record blocks are written by `ribbon run`"
                        .to_string(),
                )
            });
        }
        let mut end = vec![0u8; magic.len()];
        file.seek(SeekFrom::Start(length - magic_len))
            .and_then(|_| file.read_exact(&mut end))
            .map_err(io)?;
        if end != magic || length < 2 * magic_len {
            return Err(truncated(format!(
                "{length} bytes and no MCAP magic at the end"
            )));
        }
        let mut reader = BufReader::new(file);
        reader.seek(SeekFrom::Start(magic_len)).map_err(io)?;
        let mut position = magic_len;
        let mut header: Option<BlockHeader> = None;
        let mut trailer: Option<BlockTrailer> = None;
        let mut channels: BTreeMap<u16, String> = BTreeMap::new();
        let mut counts = (0usize, 0usize);
        loop {
            let mut op_len = [0u8; 9];
            reader
                .read_exact(&mut op_len)
                .map_err(|_| truncated(format!("the data section ends at byte {position}")))?;
            let op = op_len[0];
            let len = u64::from_le_bytes(op_len[1..9].try_into().unwrap_or([0; 8]));
            position += 9;
            if len > length.saturating_sub(position) {
                return Err(truncated(format!(
                    "a record at byte {} claims {len} bytes, past the end of the file",
                    position - 9
                )));
            }
            match op {
                OP_DATA_END => break,
                OP_MESSAGE => {
                    let Some(header) = &header else {
                        return Err(malformed(
                            "a message before the ribbon.shard metadata".into(),
                        ));
                    };
                    let mut id = [0u8; 6];
                    reader.read_exact(&mut id).map_err(io)?;
                    let channel = u16::from_le_bytes([id[0], id[1]]);
                    let sequence = u32::from_le_bytes([id[2], id[3], id[4], id[5]]) as usize;
                    let topic = channels.get(&channel).map(String::as_str);
                    let (count, values) = match topic {
                        Some(RECORDS_TOPIC) => (&mut counts.0, header.samples() * header.outputs),
                        Some(NOMINAL_TOPIC) => (&mut counts.1, header.outputs + header.nq),
                        _ => {
                            return Err(malformed(format!(
                                "a message on unknown channel {channel}"
                            )))
                        }
                    };
                    if sequence != *count || len != MESSAGE_HEADER_BYTES + 8 * values as u64 {
                        return Err(malformed(format!(
                            "message {sequence} of {} is out of order or of the wrong size ({len} bytes)",
                            topic.unwrap_or("")
                        )));
                    }
                    *count += 1;
                    reader.seek_relative(len as i64 - 6).map_err(io)?;
                }
                OP_METADATA | OP_CHANNEL => {
                    if len > MAX_METADATA_BYTES {
                        return Err(malformed(format!("a metadata record of {len} bytes")));
                    }
                    let mut body = vec![0u8; len as usize];
                    reader.read_exact(&mut body).map_err(io)?;
                    match ::mcap::parse_record(op, &body) {
                        Ok(Record::Metadata(m)) if m.name == HEADER_NAME => {
                            header =
                                Some(BlockHeader::from_metadata(&m.metadata).map_err(malformed)?);
                        }
                        Ok(Record::Metadata(m)) if m.name == TRAILER_NAME => {
                            trailer =
                                Some(BlockTrailer::from_metadata(&m.metadata).map_err(malformed)?);
                        }
                        Ok(Record::Channel(c)) => {
                            channels.insert(c.id, c.topic);
                        }
                        Ok(_) => {}
                        Err(e) => return Err(malformed(format!("a record cannot be parsed: {e}"))),
                    }
                }
                _ => reader.seek_relative(len as i64).map_err(io)?,
            }
            position += len;
        }
        let header = header.ok_or_else(|| {
            malformed("no ribbon.shard metadata: not a record block of `ribbon run`".to_string())
        })?;
        let trailer = trailer.ok_or_else(|| {
            truncated("the data section has no ribbon.shard.end metadata".to_string())
        })?;
        let expected_nominal = if header.nominal { header.records } else { 0 };
        if !trailer.complete || counts.0 != header.records || counts.1 != expected_nominal {
            return Err(truncated(format!(
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
        let find = |topic: &str| {
            channels
                .iter()
                .find(|(_, t)| *t == topic)
                .map(|(id, _)| *id)
        };
        let records =
            find(RECORDS_TOPIC).ok_or_else(|| malformed("no /records channel".to_string()))?;
        let nominal = find(NOMINAL_TOPIC);
        reader.seek(SeekFrom::Start(magic_len)).map_err(io)?;
        Ok(RecordBlockReader {
            path: path.to_path_buf(),
            header,
            trailer,
            reader,
            records,
            nominal,
            next: 0,
            bytes: Vec::new(),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The header.
    pub fn header(&self) -> &BlockHeader {
        &self.header
    }

    /// The trailer.
    pub fn trailer(&self) -> &BlockTrailer {
        &self.trailer
    }

    /// Reads the next record time: the samples' values into `samples` (`samples × outputs`) and,
    /// in the nominal shard, the nominal run's outputs then positions into `nominal`.
    pub fn read_record(
        &mut self,
        samples: &mut [f64],
        mut nominal: Option<&mut [f64]>,
    ) -> Result<(), ShardError> {
        let record = self.next;
        let mut want_records = true;
        let mut want_nominal = self.nominal.is_some() && nominal.is_some();
        while want_records || want_nominal {
            let mut op_len = [0u8; 9];
            self.reader
                .read_exact(&mut op_len)
                .map_err(|source| self.io(source))?;
            let op = op_len[0];
            let len = u64::from_le_bytes(op_len[1..9].try_into().unwrap_or([0; 8]));
            if op != OP_MESSAGE {
                if op == OP_DATA_END {
                    return Err(ShardError::Truncated {
                        path: self.path.clone(),
                        message: format!("record {record} is missing"),
                    });
                }
                self.reader
                    .seek_relative(len as i64)
                    .map_err(|source| self.io(source))?;
                continue;
            }
            self.bytes.resize(len as usize, 0);
            let mut bytes = std::mem::take(&mut self.bytes);
            let read = self.reader.read_exact(&mut bytes);
            read.map_err(|source| self.io(source))?;
            let channel = u16::from_le_bytes([bytes[0], bytes[1]]);
            let sequence = u32::from_le_bytes([bytes[2], bytes[3], bytes[4], bytes[5]]) as usize;
            let data = &bytes[MESSAGE_HEADER_BYTES as usize..];
            let target: Option<&mut [f64]> = if channel == self.records {
                want_records = false;
                Some(&mut *samples)
            } else if Some(channel) == self.nominal {
                want_nominal = false;
                nominal.as_deref_mut()
            } else {
                None
            };
            if let Some(target) = target {
                if sequence != record || data.len() != 8 * target.len() {
                    self.bytes = bytes;
                    return Err(ShardError::Malformed {
                        path: self.path.clone(),
                        message: format!(
                            "record {record}: found message {sequence} of another size or order"
                        ),
                    });
                }
                for (value, chunk) in target.iter_mut().zip(data.chunks_exact(8)) {
                    *value = f64::from_le_bytes(chunk.try_into().unwrap_or([0; 8]));
                }
            }
            self.bytes = bytes;
        }
        self.next += 1;
        Ok(())
    }

    fn io(&self, source: std::io::Error) -> ShardError {
        ShardError::Io {
            what: "read the record block",
            path: self.path.clone(),
            source,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trailer(contacts: Option<ContactStats>) -> BlockTrailer {
        BlockTrailer {
            complete: true,
            failures: Vec::new(),
            retried: Vec::new(),
            newton_iterations: 7,
            steps: 5,
            contacts,
        }
    }

    #[test]
    fn contact_counters_round_trip_through_the_trailer() {
        let counters = ContactStats {
            pair_tests: 956_864,
            narrow_queries: 606_088,
            made: 910,
            broken: 546,
            max_depth_m: 0.004_642_133_472_520_491,
        };
        let map = trailer(Some(counters)).to_metadata();
        let read = BlockTrailer::from_metadata(&map).unwrap();
        assert_eq!(read.contacts, Some(counters));
        // Without contacts the entry is absent, and reads back as none.
        let map = trailer(None).to_metadata();
        assert!(!map.contains_key("contacts"));
        assert_eq!(BlockTrailer::from_metadata(&map).unwrap().contacts, None);
    }

    #[test]
    fn a_malformed_contacts_entry_is_named() {
        let mut map = trailer(None).to_metadata();
        map.insert("contacts".to_string(), "{not json".to_string());
        let message = BlockTrailer::from_metadata(&map).unwrap_err();
        assert!(message.contains("'contacts' is not JSON"), "{message}");
        map.insert(
            "contacts".to_string(),
            r#"{"pair_tests": 1, "narrow_queries": 1, "made": 1, "max_depth_m": 0.0}"#.to_string(),
        );
        let message = BlockTrailer::from_metadata(&map).unwrap_err();
        assert!(message.contains("lacks the count 'broken'"), "{message}");
    }
}
