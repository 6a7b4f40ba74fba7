//! CRC-32/ISO-HDLC (the zlib/Ethernet CRC) of the frame trailer, by the
//! `crc` crate: the algorithm of its catalogue, a 256-entry table built at
//! compile time (`Table<1>`: one lookup a byte, 1 KiB of flash; the
//! variant chosen by measurement, BENCHMARKS.md §The frame layer), the
//! running digest the encoder feeds byte by byte, and [`crc32`] of a slice.

use crc::{Crc, Digest, Table, CRC_32_ISO_HDLC};

/// The table variant.
type Impl = Table<1>;

/// CRC-32/ISO-HDLC (init and final XOR `0xFFFFFFFF`, reflected,
/// polynomial `0x04C11DB7`) with its table: one copy, in flash.
static CRC: Crc<u32, Impl> = Crc::<u32, Impl>::new(&CRC_32_ISO_HDLC);

/// Running CRC register of a frame being encoded.
pub(super) type Running = Digest<'static, u32, Impl>;

/// A running CRC at its initial value.
pub(super) fn running() -> Running {
    CRC.digest()
}

/// CRC-32/ISO-HDLC of `data` (check value `crc32(b"123456789") ==
/// 0xCBF43926`), as used in the frame trailer.
///
/// # Examples
///
/// ```
/// use rollcal::wire::crc32;
///
/// assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
/// assert_eq!(crc32(b""), 0);
/// ```
pub fn crc32(data: &[u8]) -> u32 {
    CRC.checksum(data)
}
