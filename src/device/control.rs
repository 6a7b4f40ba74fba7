//! The device's control records: the configuration and the last
//! checkpoint, kept in two banks at the start of the flash region beside
//! the sample log, so that a reset resumes from them
//! ([`super::Device::start`]).
//!
//! A bank is whole erase sectors, enough for the header and both frames:
//!
//! | bytes | field |
//! |---|---|
//! | 0–31 | header, written last: magic `RCL` and the format version [`FORMAT`], generation, lengths, the log's epoch and count at the checkpoint, CRC-32 of bytes 0–27 |
//! | 32 … | the `Configure` frame (wire encoding, ≤ [`CONFIG_FRAME_MAX`] bytes) |
//! | 32 + [`CONFIG_FRAME_MAX`] … | the `Checkpoint` frame, if any |
//!
//! A record is written into the bank that does not hold the newest one,
//! erased beforehand, its header last: a cut before the header leaves the
//! previous record the newest. The newest is the valid header with the
//! greatest generation.

use crate::wire::{crc32, MAX_FRAME_LEN};

/// Bytes of the header.
pub(crate) const HEADER: usize = 32;
/// The largest `Configure` frame a record holds (bytes; a `Configure` frame
/// is 274 bytes).
pub const CONFIG_FRAME_MAX: usize = 512;
/// The largest write or read size (bytes) of a device the kit accepts; it
/// must divide 32.
pub const MAX_ALIGN: usize = 32;
/// Version of the control records' format.
pub const FORMAT: u8 = 1;
/// The header's first three bytes.
const MAGIC: [u8; 3] = *b"RCL";

/// Bytes of a bank before rounding up to sectors.
const RAW_BANK: usize = HEADER + CONFIG_FRAME_MAX + MAX_FRAME_LEN + MAX_ALIGN;

/// Bytes of one bank: whole sectors of `erase` bytes (0 if `erase` is 0 or
/// the size overflows).
pub(crate) const fn bank_len(erase: usize) -> usize {
    if erase == 0 {
        return 0;
    }
    match RAW_BANK.div_ceil(erase).checked_mul(erase) {
        Some(n) => n,
        None => 0,
    }
}

/// A control record's header.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Header {
    /// Greater in a newer record.
    pub generation: u32,
    /// Bytes of the `Configure` frame (its delimiter included).
    pub config_len: u32,
    /// Bytes of the `Checkpoint` frame, 0 when there is none.
    pub checkpoint_len: u32,
    /// The sample log's epoch when the checkpoint was taken.
    pub epoch: u32,
    /// The records the checkpoint counts (`Progress::logged`).
    pub logged: u32,
}

/// What a bank's first 32 bytes say.
pub(crate) enum Read {
    /// No record (erased, torn, or not a header).
    Empty,
    /// A record of another format version.
    OtherFormat(u8),
    /// A record.
    Valid(Header),
}

impl Header {
    /// The 32 bytes written.
    pub(crate) fn to_bytes(self) -> [u8; HEADER] {
        let words = [
            u32::from_le_bytes([MAGIC[0], MAGIC[1], MAGIC[2], FORMAT]),
            self.generation,
            self.config_len,
            self.checkpoint_len,
            self.epoch,
            self.logged,
            0,
        ];
        let mut b = [0u8; HEADER];
        for (chunk, w) in b.chunks_exact_mut(4).zip(words) {
            chunk.copy_from_slice(&w.to_le_bytes());
        }
        let crc = crc32(&b[..HEADER - 4]);
        b[HEADER - 4..].copy_from_slice(&crc.to_le_bytes());
        b
    }

    /// The header `b` holds.
    pub(crate) fn parse(b: &[u8; HEADER]) -> Read {
        let mut w = [0u32; HEADER / 4];
        for (word, chunk) in w.iter_mut().zip(b.chunks_exact(4)) {
            *word = chunk.try_into().map_or(0, u32::from_le_bytes);
        }
        if crc32(&b[..HEADER - 4]) != w[7] || b[..3] != MAGIC {
            return Read::Empty;
        }
        if b[3] != FORMAT {
            return Read::OtherFormat(b[3]);
        }
        Read::Valid(Header {
            generation: w[1],
            config_len: w[2],
            checkpoint_len: w[3],
            epoch: w[4],
            logged: w[5],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_header_reads_back_and_a_flipped_bit_is_no_header() {
        let h = Header {
            generation: 7,
            config_len: 274,
            checkpoint_len: 13_001,
            epoch: 3,
            logged: 1200,
        };
        let mut b = h.to_bytes();
        assert!(matches!(Header::parse(&b), Read::Valid(r) if r == h));
        b[9] ^= 1;
        assert!(matches!(Header::parse(&b), Read::Empty));
        assert!(matches!(Header::parse(&[0xFF; HEADER]), Read::Empty));
        let mut other = h.to_bytes();
        other[3] = FORMAT + 1;
        let crc = crc32(&other[..28]);
        other[28..].copy_from_slice(&crc.to_le_bytes());
        assert!(matches!(Header::parse(&other), Read::OtherFormat(v) if v == FORMAT + 1));
    }

    #[test]
    fn a_bank_is_whole_sectors_holding_both_frames() {
        for erase in [256, 1024, 4096, 65_536] {
            let n = bank_len(erase);
            assert_eq!(n % erase, 0);
            assert!(n >= HEADER + CONFIG_FRAME_MAX + MAX_FRAME_LEN);
            assert!(n < HEADER + CONFIG_FRAME_MAX + MAX_FRAME_LEN + MAX_ALIGN + erase);
        }
        assert_eq!(bank_len(0), 0);
    }
}
