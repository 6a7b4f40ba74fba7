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
pub use error::{EncodeError, FrameError};
pub use field::{ConfigField, FieldBounds};
pub use messages::{
    CalibratorConfig, Checkpoint, Estimate, EstimateKind, InstrumentPrior, Limits, Message,
    Progress, Refusal, RefusalReason, RejectCounts, Sample, SinglePassReason, INSTRUMENT_STATES,
    MAX_COVARIANCE, MAX_STATES,
};

/// Protocol version carried in the first byte of every frame (6: the full
/// model with the errors that wander, and the `Refused` reply; docs/wire.md
/// §Version policy).
pub const VERSION: u8 = 6;

/// Length of the CRC trailer (bytes).
pub const CRC_LEN: usize = 4;

/// Smallest valid decoded frame: version, one tag byte, CRC (bytes).
pub const MIN_DECODED_LEN: usize = 1 + 1 + CRC_LEN;

/// Upper bound of an encoded frame of any [`Message`], delimiter included
/// (bytes). The largest message is a [`Checkpoint`] of [`MAX_STATES`]
/// states: 2 881 to 3 157 bytes encoded for 18 states, about 25 KB for the
/// full model's 54 (`full-model` feature; docs/wire.md §Limits and sizes);
/// a [`Decoder`] with this capacity accepts every message.
#[cfg(not(feature = "full-model"))]
pub const MAX_FRAME_LEN: usize = 4096;
/// Upper bound of an encoded frame of any [`Message`], delimiter included
/// (bytes). The largest message is a [`Checkpoint`] of [`MAX_STATES`]
/// states: 2 881 to 3 157 bytes encoded for 18 states, about 25 KB for the
/// full model's 54 (`full-model` feature; docs/wire.md §Limits and sizes);
/// a [`Decoder`] with this capacity accepts every message.
#[cfg(feature = "full-model")]
pub const MAX_FRAME_LEN: usize = 32768;
