//! The MCAP record framing read by hand (the MCAP specification, "Records"): every record is an
//! opcode byte, a little-endian `u64` length and that many bytes. The record block reader walks a
//! file record by record through it, so that it can hash every byte it reads and check each
//! record's place before the `mcap` crate parses one ([`::mcap::parse_record`]).

use std::io;

/// Opcode of the Footer record.
pub const OP_FOOTER: u8 = 0x02;
/// Opcode of the Channel record.
pub const OP_CHANNEL: u8 = 0x04;
/// Opcode of the Message record.
pub const OP_MESSAGE: u8 = 0x05;
/// Opcode of the Metadata record.
pub const OP_METADATA: u8 = 0x0C;
/// Opcode of the DataEnd record.
pub const OP_DATA_END: u8 = 0x0F;
/// Opcode and length of a record.
pub const RECORD_FRAME_BYTES: u64 = 1 + 8;
/// A Message record's fixed fields: channel id, sequence, log time, publish time.
pub const MESSAGE_HEADER_BYTES: u64 = 2 + 4 + 8 + 8;
/// A Message record's channel id and sequence, the fields a reader checks first.
pub const MESSAGE_ID_BYTES: usize = 2 + 4;

/// Bytes read front to back with their position: what a record walk reads through.
pub trait RecordStream {
    /// Fills `bytes` from the stream.
    fn read_exact(&mut self, bytes: &mut [u8]) -> io::Result<()>;
    /// Bytes read since the start.
    fn position(&self) -> u64;
}

/// The start of one record: where it is, its opcode and the length of its body.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame {
    /// The byte offset of the opcode.
    pub at: u64,
    /// The opcode.
    pub op: u8,
    /// The body's length, bytes (as the file claims it: the caller checks it against what is
    /// left).
    pub len: u64,
}

impl Frame {
    /// Reads the next record's opcode and length from `stream`.
    pub fn read(stream: &mut impl RecordStream) -> io::Result<Frame> {
        let at = stream.position();
        let mut bytes = [0u8; RECORD_FRAME_BYTES as usize];
        stream.read_exact(&mut bytes)?;
        let (op, len) = frame(&bytes);
        Ok(Frame { at, op, len })
    }
}

/// A Message record's channel id and sequence number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MessageId {
    /// The channel id.
    pub channel: u16,
    /// The sequence number.
    pub sequence: u32,
}

impl MessageId {
    /// The id at the start of a Message record's body (at least [`MESSAGE_ID_BYTES`] long).
    pub fn parse(body: &[u8]) -> MessageId {
        MessageId {
            channel: u16::from_le_bytes([body[0], body[1]]),
            sequence: u32::from_le_bytes([body[2], body[3], body[4], body[5]]),
        }
    }
}

/// The opcode and length at the start of a record's bytes (at least [`RECORD_FRAME_BYTES`]).
pub fn frame(bytes: &[u8]) -> (u8, u64) {
    (bytes[0], le_u64(&bytes[1..9]))
}

/// The little-endian `u64` at the start of `bytes`.
pub fn le_u64(bytes: &[u8]) -> u64 {
    let mut word = [0u8; 8];
    word.copy_from_slice(&bytes[..8]);
    u64::from_le_bytes(word)
}

/// The little-endian `u32` at the start of `bytes`.
pub fn le_u32(bytes: &[u8]) -> u32 {
    let mut word = [0u8; 4];
    word.copy_from_slice(&bytes[..4]);
    u32::from_le_bytes(word)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_and_a_message_id_read_back() {
        let mut bytes = vec![OP_MESSAGE];
        bytes.extend_from_slice(&300u64.to_le_bytes());
        assert_eq!(frame(&bytes), (OP_MESSAGE, 300));
        let mut body = 7u16.to_le_bytes().to_vec();
        body.extend_from_slice(&0x0102_0304u32.to_le_bytes());
        let id = MessageId::parse(&body);
        assert_eq!((id.channel, id.sequence), (7, 0x0102_0304));
    }
}
