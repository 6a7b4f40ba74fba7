//! The serial wire protocol (docs/wire.md): messages, framing, and a streaming
//! decoder. The byte layout is specified in `docs/wire.md`.
//!
//! A **frame** on the wire is
//!
//! ```text
//! COBS( version:u8 | postcard(Message) | crc32:u32 little-endian ) | 0x00
//! ```
//!
//! - `version` is [`VERSION`]; a frame of another version is counted and
//!   skipped (its CRC is checked first, so a corrupt frame is never counted
//!   as a wrong version);
//! - the message is serialised with `postcard` (varint integers, `f32`/`f64`
//!   little-endian IEEE 754, enum tags as varints in declaration order);
//! - the CRC is CRC-32/ISO-HDLC (the zlib/Ethernet CRC; check value
//!   `0xCBF43926` over `"123456789"`) over the version byte and the postcard
//!   bytes;
//! - COBS removes every `0x00` from the frame, so `0x00` is the delimiter
//!   and a receiver resynchronises at the next one.
//!
//! [`encode`] writes a frame into a caller's buffer; [`Decoder`] accepts
//! bytes in chunks of any size, yields messages and counts rejected frames
//! by reason ([`DecoderStats`]). Neither allocates nor panics.
//!
//! Units and frames of every field are those of the crate (docs/model.md §Notation):
//! radians, seconds, specific force in g, navigation frame North–Up–East.

//! The module by concern: `messages` (the schema: [`Message`] and what it
//! carries), `crc` ([`crc32`]), `encode` ([`encode`], COBS on the fly),
//! `field` (the data-sheet figures of a `Configure` and their bounds:
//! [`ConfigField`]), `decode` (one frame: [`decode_frame`]), `decoder` (the stream:
//! [`Decoder`], [`DecoderStats`]) and `error` ([`EncodeError`],
//! [`FrameError`]).
//!
//! # Examples
//!
//! A message round-trips through a frame:
//!
//! ```
//! use rollcal::wire::{encode, FrameDecoder, Message, MAX_FRAME_LEN};
//!
//! let mut buf = [0u8; MAX_FRAME_LEN];
//! let n = encode(&Message::EstimateRequest, &mut buf).unwrap();
//! assert_eq!(buf[n - 1], 0x00); // the delimiter
//!
//! let mut decoder = FrameDecoder::new();
//! let mut got = Vec::new();
//! decoder.feed(&buf[..n], |m| got.push(m));
//! assert_eq!(got, [Message::EstimateRequest]);
//! ```

mod crc;
mod decode;
mod decoder;
mod encode;
mod error;
mod field;
mod in_place;
mod messages;

pub use crc::crc32;
pub use decode::{decode_frame, decode_frame_into};
pub use decoder::{Decoder, DecoderStats, FrameDecoder};
pub use encode::encode;
pub(crate) use encode::encode_refusal;
pub use error::{EncodeError, FrameError};
pub use field::{ConfigField, FieldBounds};
pub use messages::{
    factor_index, factor_len, CalibratorConfig, Checkpoint, Estimate, EstimateKind,
    InstrumentPrior, Limits, Message, Progress, Refusal, RefusalReason, RejectCounts, Sample,
    SinglePassReason, INSTRUMENT_STATES, MAX_COVARIANCE, MAX_FACTOR, MAX_STATES,
};

/// Protocol version carried in the first byte of every frame (8: a
/// [`Checkpoint`] of the full model carries its factor in the factor's
/// order, [`Filter::FACTOR_ORDER`](crate::ekf::Filter::FACTOR_ORDER); 7: a
/// checkpoint carries its factor's upper triangle only; docs/wire.md
/// §Version policy).
pub const VERSION: u8 = 8;

/// Length of the CRC trailer (bytes).
pub const CRC_LEN: usize = 4;

/// Smallest valid decoded frame: version, one tag byte, CRC (bytes).
pub const MIN_DECODED_LEN: usize = 1 + 1 + CRC_LEN;

/// Upper bound of an encoded frame of any [`Message`] of this build,
/// delimiter included (bytes): [`max_frame_len`] of [`MAX_STATES`], so an
/// image pays for its own models' largest message, not the crate's. 13 382
/// with the default features (a [`Checkpoint`] of the full model's 54
/// states, 12 839 to 13 179 bytes encoded; docs/wire.md §Limits and sizes),
/// 2 250 in an image of the installation M2-ps model. A [`Decoder`] with
/// this capacity accepts every message of the build; a larger frame is for
/// a model the build does not hold.
pub const MAX_FRAME_LEN: usize = max_frame_len(MAX_STATES);

/// Upper bound of the encoded frame of any [`Message`] of a model of `n`
/// states, delimiter included (bytes). The largest is a [`Checkpoint`]: `n`
/// states, `n` nominal states, the factor's [`factor_len`]`(n)` values and
/// the 3×3 `C_cn`, each an 8-byte `f64`, and fields of bounded size
/// (version, tags, vector lengths, counters, bookkeeping, CRC: 191 bytes in
/// the largest frame of docs/wire.md §Limits and sizes, bounded here by
/// 512); COBS adds a byte per 254 and the delimiter one.
///
/// # Examples
///
/// ```
/// use rollcal::wire::{max_frame_len, MAX_FRAME_LEN, MAX_STATES};
/// assert_eq!(max_frame_len(54), 13_382);
/// assert_eq!(MAX_FRAME_LEN, max_frame_len(MAX_STATES));
/// ```
pub const fn max_frame_len(n: usize) -> usize {
    let payload = 8 * (factor_len(n) + 2 * n + 9) + 512;
    payload + payload.div_ceil(254) + 1
}
