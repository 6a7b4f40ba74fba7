//! Frame encoding: [`encode`] serialises a message with postcard through a
//! flavor that computes the CRC (the `crc` crate's digest) and COBS-encodes
//! on the fly (the `cobs` crate's encoder state machine) into the caller's
//! buffer (no second buffer, no heap).

use cobs::{EncoderState, PushResult};

use super::crc::{running, Running};
use super::{EncodeError, Message, VERSION};

/// A postcard flavor that CRCs and COBS-encodes on the fly into a slice.
///
/// The `cobs` crate's [`EncoderState`] says where each byte goes (the
/// code bytes are placeholders filled in when their block closes); its
/// slice encoder (`cobs::CobsEncoder`) is not used: it leaves out the
/// final `0x01` after a full 254-byte block at the end of the data, which
/// this protocol's encoder has always sent (docs/wire.md §Frame, 4).
struct FrameWriter<'a> {
    out: &'a mut [u8],
    /// Next write position.
    pos: usize,
    cobs: EncoderState,
    crc: Running,
    overflow: bool,
}

impl<'a> FrameWriter<'a> {
    fn new(out: &'a mut [u8]) -> Self {
        // Position 0 is the first block's code byte (EncoderState's
        // placeholder).
        let mut w = Self {
            out,
            pos: 1,
            cobs: EncoderState::default(),
            crc: running(),
            overflow: false,
        };
        w.push(VERSION);
        w
    }

    fn put(&mut self, idx: usize, b: u8) {
        match self.out.get_mut(idx) {
            Some(slot) => *slot = b,
            None => self.overflow = true,
        }
    }

    fn cobs_push(&mut self, b: u8) {
        match self.cobs.push(b) {
            PushResult::AddSingle(b) => {
                self.put(self.pos, b);
                self.pos = self.pos.saturating_add(1);
            }
            // A block closed at a zero: its code, and the next block's
            // placeholder.
            PushResult::ModifyFromStartAndSkip((idx, code)) => {
                self.put(idx, code);
                self.pos = self.pos.saturating_add(1);
            }
            // A full block (254 bytes) closed: its code, its last byte and
            // the next block's placeholder.
            PushResult::ModifyFromStartAndPushAndSkip((idx, code, b)) => {
                self.put(idx, code);
                self.put(self.pos, b);
                self.pos = self.pos.saturating_add(2);
            }
        }
    }

    fn push(&mut self, b: u8) {
        self.crc.update(&[b]);
        self.cobs_push(b);
    }
}

impl postcard::ser_flavors::Flavor for FrameWriter<'_> {
    type Output = usize;

    fn try_push(&mut self, data: u8) -> postcard::Result<()> {
        self.push(data);
        if self.overflow {
            Err(postcard::Error::SerializeBufferFull)
        } else {
            Ok(())
        }
    }

    fn finalize(mut self) -> postcard::Result<usize> {
        for b in self.crc.clone().finalize().to_le_bytes() {
            self.cobs_push(b);
        }
        let (idx, code) = self.cobs.clone().finalize();
        self.put(idx, code);
        self.put(self.pos, 0);
        if self.overflow {
            return Err(postcard::Error::SerializeBufferFull);
        }
        Ok(self.pos.saturating_add(1))
    }
}

/// Encodes `msg` as one frame (delimiter included) into `out`; returns the
/// number of bytes written. A buffer of [`MAX_FRAME_LEN`](super::MAX_FRAME_LEN) bytes always
/// suffices.
///
/// # Examples
///
/// ```
/// use rollcal::wire::{crc32, encode, EncodeError, Message, MAX_FRAME_LEN, VERSION};
///
/// let mut buf = [0u8; MAX_FRAME_LEN];
/// let n = encode(&Message::Reset, &mut buf).unwrap();
/// // COBS(version, tag 4, CRC-32 little-endian), then the delimiter.
/// let crc = crc32(&[VERSION, 4]).to_le_bytes();
/// assert_eq!(buf[..n], [7, VERSION, 4, crc[0], crc[1], crc[2], crc[3], 0]);
///
/// // A buffer too small is an error, not a panic.
/// assert_eq!(encode(&Message::Reset, &mut buf[..4]), Err(EncodeError::BufferTooSmall));
/// ```
pub fn encode(msg: &Message, out: &mut [u8]) -> Result<usize, EncodeError> {
    if out.is_empty() {
        return Err(EncodeError::BufferTooSmall);
    }
    postcard::serialize_with_flavor(msg, FrameWriter::new(out)).map_err(|e| match e {
        postcard::Error::SerializeBufferFull => EncodeError::BufferTooSmall,
        _ => EncodeError::Serialize,
    })
}
