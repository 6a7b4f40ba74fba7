//! The streaming decoder: [`Decoder`] accepts bytes in chunks of any size,
//! splits them at the `0x00` delimiters, decodes each frame and counts the
//! outcome in [`DecoderStats`]; [`FrameDecoder`] is the one whose capacity
//! accepts every message.

use serde::{Deserialize, Serialize};

use super::decode::{decode_frame, decode_frame_into};
use super::{FrameError, Message, MAX_FRAME_LEN};

/// Recommended decoder capacity: [`MAX_FRAME_LEN`].
pub type FrameDecoder = Decoder<MAX_FRAME_LEN>;

/// Frame counters of a [`Decoder`], by outcome.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DecoderStats {
    /// Frames decoded into a message.
    pub ok: u32,
    /// [`FrameError::Corrupt`] frames.
    pub corrupt: u32,
    /// [`FrameError::Malformed`] frames.
    pub malformed: u32,
    /// [`FrameError::Truncated`] frames.
    pub truncated: u32,
    /// [`FrameError::Oversized`] frames.
    pub oversized: u32,
    /// [`FrameError::WrongVersion`] frames.
    pub wrong_version: u32,
    /// Empty frames (two delimiters in a row): ignored, not an error.
    pub empty: u32,
}

impl DecoderStats {
    /// All rejected frames.
    pub fn errors(&self) -> u32 {
        [
            self.corrupt,
            self.malformed,
            self.truncated,
            self.oversized,
            self.wrong_version,
        ]
        .iter()
        .fold(0u32, |a, b| a.saturating_add(*b))
    }

    fn count<R>(&mut self, r: &Result<R, FrameError>) {
        let c = match r {
            Ok(_) => &mut self.ok,
            Err(FrameError::Corrupt) => &mut self.corrupt,
            Err(FrameError::Malformed) => &mut self.malformed,
            Err(FrameError::Truncated) => &mut self.truncated,
            Err(FrameError::Oversized) => &mut self.oversized,
            Err(FrameError::WrongVersion(_)) => &mut self.wrong_version,
        };
        *c = c.saturating_add(1);
    }
}

/// Streaming frame decoder over a fixed buffer of `CAP` bytes (use
/// [`FrameDecoder`] = `Decoder<MAX_FRAME_LEN>` to accept every message).
/// Bytes may arrive in chunks of any size; a rejected frame is counted in
/// [`Decoder::stats`] and skipped, and decoding resumes after the next
/// `0x00`. No input can make it panic.
///
/// # Examples
///
/// Bytes arrive in chunks that cut frames anywhere; a damaged frame is
/// counted and skipped:
///
/// ```
/// use rollcal::wire::{encode, FrameDecoder, Message, MAX_FRAME_LEN};
///
/// let mut stream = Vec::new();
/// for msg in [Message::Reset, Message::CheckpointRequest, Message::Finish] {
///     let mut buf = [0u8; MAX_FRAME_LEN];
///     let n = encode(&msg, &mut buf).unwrap();
///     stream.extend_from_slice(&buf[..n]);
/// }
/// let second = stream.iter().position(|&b| b == 0).unwrap() + 1;
/// stream[second + 2] ^= 0x01; // damage the second frame
///
/// let mut decoder = FrameDecoder::new();
/// let mut got = Vec::new();
/// for chunk in stream.chunks(3) {
///     decoder.feed(chunk, |m| got.push(m));
/// }
/// assert_eq!(got, [Message::Reset, Message::Finish]);
/// assert_eq!((decoder.stats().ok, decoder.stats().corrupt), (2, 1));
/// assert_eq!(decoder.stats().errors(), 1);
/// ```
#[derive(Clone, Debug)]
pub struct Decoder<const CAP: usize> {
    buf: [u8; CAP],
    len: usize,
    overflow: bool,
    stats: DecoderStats,
}

impl<const CAP: usize> Default for Decoder<CAP> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const CAP: usize> Decoder<CAP> {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            buf: [0; CAP],
            len: 0,
            overflow: false,
            stats: DecoderStats {
                ok: 0,
                corrupt: 0,
                malformed: 0,
                truncated: 0,
                oversized: 0,
                wrong_version: 0,
                empty: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> &DecoderStats {
        &self.stats
    }

    /// Bytes of an unfinished frame held in the buffer.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Drops any unfinished frame (counters are kept).
    pub fn clear(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Accepts one byte; at a delimiter returns the frame's outcome (already
    /// counted), otherwise `None`. Empty frames give `None`.
    // Not inlined: the decoder's temporaries stay out of the caller's
    // frame, which holds the message while it is handled (a firmware, whose
    // stack is small, uses `push_byte_into` and a static slot).
    #[inline(never)]
    pub fn push_byte(&mut self, byte: u8) -> Option<Result<Message, FrameError>> {
        self.push_byte_with(byte, decode_frame)
    }

    /// [`Decoder::push_byte`] with a decoded message written into `msg`
    /// (what it held is replaced; it is untouched when the frame is
    /// rejected): `Some(Ok(()))` when `msg` holds a new message. A message
    /// is a checkpoint's size whatever it holds (≈ 3 KB, ≈ 12.5 KB with the
    /// `full-model` feature): a firmware that
    /// keeps `msg` in static memory has none in its frames
    /// ([`decode_frame_into`]).
    #[inline(never)]
    pub fn push_byte_into(
        &mut self,
        byte: u8,
        msg: &mut Message,
    ) -> Option<Result<(), FrameError>> {
        self.push_byte_with(byte, |frame| decode_frame_into(frame, msg))
    }

    /// The buffer, when it holds no part of a frame that may still decode
    /// (between frames, or in a frame already too long): the integration
    /// kit encodes its replies and flash records there. What is written is
    /// overwritten by the next frame's bytes.
    pub(crate) fn spare_buffer(&mut self) -> Option<&mut [u8; CAP]> {
        (self.len == 0 || self.overflow).then_some(&mut self.buf)
    }

    /// Accepts one byte; at a delimiter decodes the frame with `decode`
    /// and counts the outcome.
    pub(crate) fn push_byte_with<R>(
        &mut self,
        byte: u8,
        decode: impl FnOnce(&mut [u8]) -> Result<R, FrameError>,
    ) -> Option<Result<R, FrameError>> {
        if byte != 0 {
            if self.overflow {
                return None;
            }
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflow = true,
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.clear();
        let result = if overflow {
            Err(FrameError::Oversized)
        } else if len == 0 {
            self.stats.empty = self.stats.empty.saturating_add(1);
            return None;
        } else {
            match self.buf.get_mut(..len) {
                Some(frame) => decode(frame),
                None => Err(FrameError::Oversized),
            }
        };
        self.stats.count(&result);
        Some(result)
    }

    /// Accepts a chunk of bytes and calls `on_frame` with the outcome of
    /// every frame it completes (rejected frames are also counted in
    /// [`Decoder::stats`]).
    pub fn feed_results(
        &mut self,
        chunk: &[u8],
        mut on_frame: impl FnMut(Result<Message, FrameError>),
    ) {
        for b in chunk {
            if let Some(r) = self.push_byte(*b) {
                on_frame(r);
            }
        }
    }

    /// Accepts a chunk of bytes and calls `on_message` with every message it
    /// completes; rejected frames are counted and skipped.
    pub fn feed(&mut self, chunk: &[u8], mut on_message: impl FnMut(Message)) {
        self.feed_results(chunk, |r| {
            if let Ok(m) = r {
                on_message(m);
            }
        });
    }
}
