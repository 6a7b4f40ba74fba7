//! The errors of the wire: [`EncodeError`] (a frame that cannot be
//! written) and [`FrameError`] (why a received frame was rejected).

use super::VERSION;

/// Errors of [`encode`](super::encode()).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum EncodeError {
    /// The output buffer cannot hold the frame ([`MAX_FRAME_LEN`](super::MAX_FRAME_LEN) always can).
    BufferTooSmall,
    /// The message cannot be serialised (a vector longer than its capacity
    /// cannot be built, so this is not expected).
    Serialize,
}

impl core::fmt::Display for EncodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            EncodeError::BufferTooSmall => "output buffer too small for the frame",
            EncodeError::Serialize => "message cannot be serialised",
        })
    }
}

impl core::error::Error for EncodeError {}

/// Why a frame was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FrameError {
    /// The CRC does not match (bit errors, or two frames merged by a lost
    /// delimiter).
    Corrupt,
    /// The CRC matches but the bytes are not a valid message (unknown tag,
    /// bad varint, too-long vector, trailing bytes): a sender bug.
    Malformed,
    /// The frame ended early: a COBS block runs past the delimiter, or the
    /// frame is shorter than [`MIN_DECODED_LEN`](super::MIN_DECODED_LEN) (a frame cut short, or the
    /// partial frame at the start of a stream).
    Truncated,
    /// More bytes than the decoder's capacity arrived before a delimiter.
    Oversized,
    /// A valid frame of another protocol version (the version it carries).
    WrongVersion(u8),
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::Corrupt => f.write_str("frame CRC mismatch"),
            FrameError::Malformed => f.write_str("frame is not a valid message"),
            FrameError::Truncated => f.write_str("frame truncated"),
            FrameError::Oversized => f.write_str("frame larger than the decoder buffer"),
            FrameError::WrongVersion(v) => {
                write!(f, "frame of protocol version {v} (expected {VERSION})")
            }
        }
    }
}

impl core::error::Error for FrameError {}
