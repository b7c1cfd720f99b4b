//! The record block reader on arbitrary bytes: `RecordBlockReader::from_bytes` (the MCAP framing,
//! both CRC-32s, the records' structure, the trailer's digest), then every record streamed as a
//! merge reads them.
//!
//! The first byte chooses the mode. Even: the bytes as they are, so the checksums face them (a
//! random change almost never gets past them). Odd: the bytes "resealed" first — the trailer's
//! digest, the DataEnd record's CRC and the Footer's CRC recomputed wherever the framing lets
//! them be found — so that the structure checks behind the checksums face arbitrary records too.
#![no_main]

use libfuzzer_sys::fuzz_target;
use ribbon::distributed::{fnv1a64, RecordBlockReader};
use std::path::Path;

/// MCAP magic.
const MAGIC_BYTES: usize = 8;
/// DataEnd: opcode, length, CRC-32.
const DATA_END_BYTES: usize = 13;
/// Footer: opcode, length, summary start, summary offset start, CRC-32.
const FOOTER_BYTES: usize = 29;
/// The trailer's digest entry as MCAP writes a map entry: key length, key, value length.
const DIGEST_ENTRY: &[u8] = b"\x07\x00\x00\x00fnv1a64\x10\x00\x00\x00";

fuzz_target!(|data: &[u8]| {
    let Some((&mode, block)) = data.split_first() else {
        return;
    };
    let mut bytes = block.to_vec();
    if mode % 2 == 1 {
        reseal(&mut bytes);
    }
    let name = Path::new("shard-0-of-1.records.mcap");
    let Ok(mut reader) = RecordBlockReader::from_bytes(name, "ribbon run PLAN --shard 0/1 --into DIR", bytes) else {
        return;
    };
    let header = reader.header().clone();
    let _ = reader.block_digest();
    let _ = reader.trailer().failures.len();
    if header.records == 0 {
        return;
    }
    // Sizes the walk proved to fit in the file (one message of each per record time).
    let mut values = vec![0.0; header.samples() * header.outputs];
    let nominal_values = if header.nominal { header.outputs + header.nq } else { 0 };
    let mut nominal = vec![0.0; nominal_values];
    for record in 0..header.records {
        let target = header.nominal.then_some(nominal.as_mut_slice());
        if reader.read_record(&mut values, target).is_err() {
            return;
        }
        assert!(record < header.records);
    }
});

fn le_u64(bytes: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?))
}

/// Makes the checksums of `bytes` match them where the framing allows: the trailer's digest (in
/// the last metadata record holding one), then the data section's CRC-32 in DataEnd, then the
/// summary's CRC-32 in the Footer.
fn reseal(bytes: &mut [u8]) {
    let length = bytes.len();
    if length < 2 * MAGIC_BYTES + DATA_END_BYTES + FOOTER_BYTES {
        return;
    }
    let footer = length - MAGIC_BYTES - FOOTER_BYTES;
    let Some(summary_start) = le_u64(bytes, footer + 9).and_then(|s| usize::try_from(s).ok()) else {
        return;
    };
    if summary_start < MAGIC_BYTES + DATA_END_BYTES || summary_start > footer {
        return;
    }
    let data_end = summary_start - DATA_END_BYTES;
    // The trailer's digest: the FNV-1a 64 of the bytes before its record.
    let mut at = MAGIC_BYTES;
    let mut trailer: Option<(usize, usize)> = None;
    while at + 9 <= data_end {
        let Some(len) = le_u64(bytes, at + 1).and_then(|l| usize::try_from(l).ok()) else {
            break;
        };
        let Some(end) = (at + 9).checked_add(len).filter(|&e| e <= data_end) else {
            break;
        };
        if bytes[at] == 0x0C {
            if let Some(offset) = bytes[at..end]
                .windows(DIGEST_ENTRY.len())
                .position(|w| w == DIGEST_ENTRY)
            {
                let value = at + offset + DIGEST_ENTRY.len();
                if value + 16 <= end {
                    trailer = Some((at, value));
                }
            }
        }
        at = end;
    }
    if let Some((record, value)) = trailer {
        let digest = format!("{:016x}", fnv1a64(&bytes[..record]));
        bytes[value..value + 16].copy_from_slice(digest.as_bytes());
    }
    let crc = crc32fast::hash(&bytes[..data_end]);
    bytes[data_end + 9..data_end + 13].copy_from_slice(&crc.to_le_bytes());
    let crc = crc32fast::hash(&bytes[summary_start..footer + FOOTER_BYTES - 4]);
    bytes[footer + 25..footer + 29].copy_from_slice(&crc.to_le_bytes());
}
