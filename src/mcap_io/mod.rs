//! The one MCAP layer (the MCAP specification, mcap.dev/spec), under both MCAP files ribbon
//! writes: the envelope log (`output::mcap`, chunked and lz4-compressed, for the viewers) and the
//! shards' record blocks (`distributed`, unchunked, read back by `merge`).
//!
//! - writing ([`McapFileWriter`], `file_writer.rs`): schemas, channels, messages, metadata and
//!   attachments through a temporary file beside the target, renamed onto it when complete; every
//!   failure a [`McapWriteError`] naming the file and the step;
//! - reading, checked ([`verify_checksums`], `checksums.rs`): the magic, the Footer, DataEnd and
//!   both CRC-32s before any record is interpreted, a failure a [`Damage`] saying what was found
//!   where;
//! - the record framing read by hand ([`Frame`], [`MessageId`], `framing.rs`), so that a reader
//!   can hash what it reads and place each record before the `mcap` crate parses it.
//!
//! What the files hold (topics, metadata keys, payload encodings) is their owners' business; this
//! layer adds no record and reorders none, so the bytes are the `mcap` crate's for the same calls.

mod checksums;
mod file_writer;
mod framing;

pub use checksums::{magic_bytes, verify_checksums, ByteSource, Damage, READ_PIECE_BYTES};
pub use file_writer::{FileStream, McapFileWriter, McapWriteError};
pub use framing::{
    Frame, MessageId, RecordStream, MESSAGE_HEADER_BYTES, MESSAGE_ID_BYTES, OP_CHANNEL,
    OP_DATA_END, OP_FOOTER, OP_MESSAGE, OP_METADATA, RECORD_FRAME_BYTES,
};
