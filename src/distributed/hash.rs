//! FNV-1a, 64 bit: a fast, dependency-free fingerprint of the plan, its input files and the record
//! blocks. It detects a changed, damaged or foreign file (accidents: every change of a single byte
//! changes it, since each step is a bijection of the state), not an adversary; docs/distributed.md
//! §2 and §3.

use std::io::Read;
use std::path::Path;

/// FNV-1a 64-bit offset basis.
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
/// FNV-1a 64-bit prime.
const FNV_PRIME: u64 = 0x0100_0000_01b3;

/// FNV-1a 64 over bytes fed in pieces: the same value as [`fnv1a64`] of their concatenation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fnv1a64 {
    state: u64,
}

impl Default for Fnv1a64 {
    fn default() -> Self {
        Fnv1a64::new()
    }
}

impl Fnv1a64 {
    /// The hash of no bytes.
    pub fn new() -> Fnv1a64 {
        Fnv1a64 { state: FNV_OFFSET }
    }

    /// The hash of the bytes so far followed by `bytes`.
    pub fn update(&mut self, bytes: &[u8]) {
        self.state = bytes.iter().fold(self.state, |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(FNV_PRIME)
        });
    }

    /// The hash of the bytes so far.
    pub fn value(&self) -> u64 {
        self.state
    }

    /// The hash of the bytes so far as the files write it: 16 lowercase hex digits.
    pub fn hex(&self) -> String {
        format!("{:016x}", self.state)
    }
}

/// The FNV-1a 64 hash of `bytes`.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut hash = Fnv1a64::new();
    hash.update(bytes);
    hash.value()
}

/// The FNV-1a 64 hash of the file at `path`, read in pieces.
pub fn fnv1a64_file(path: &Path) -> std::io::Result<u64> {
    let mut file = std::fs::File::open(path)?;
    let mut buffer = vec![0u8; 1 << 16];
    let mut hash = Fnv1a64::new();
    loop {
        let n = file.read(&mut buffer)?;
        if n == 0 {
            return Ok(hash.value());
        }
        hash.update(&buffer[..n]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_values() {
        // Published FNV-1a 64 test vectors.
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn pieces_hash_as_their_concatenation() {
        let mut hash = Fnv1a64::new();
        hash.update(b"foo");
        hash.update(b"");
        hash.update(b"bar");
        assert_eq!(hash.value(), fnv1a64(b"foobar"));
        assert_eq!(hash.hex(), "85944171f73967e8");
    }

    #[test]
    fn every_single_bit_flip_changes_the_hash() {
        let bytes: Vec<u8> = (0..64u8).map(|b| b.wrapping_mul(37)).collect();
        let clean = fnv1a64(&bytes);
        for i in 0..bytes.len() {
            for bit in 0..8 {
                let mut flipped = bytes.clone();
                flipped[i] ^= 1 << bit;
                assert_ne!(fnv1a64(&flipped), clean, "byte {i} bit {bit}");
            }
        }
    }
}
