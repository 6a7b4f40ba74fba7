//! Frame encoding: [`encode`] serialises a message with postcard through a
//! flavor that computes the CRC and COBS-encodes on the fly into the
//! caller's buffer (no second buffer, no heap).
//!
//! The COBS encoder is hand-written rather than the `cobs` crate's, by
//! measurement (BENCHMARKS.md §The frame layer): its `EncoderState` (which
//! postcard's `Cobs` flavor wraps) costs about 2 KB more flash and 19 to
//! 41 % more instructions per encoded frame on the Cortex-M; its slice
//! encoder `CobsEncoder` would also change the bytes (it leaves out the
//! final `0x01` after a full 254-byte block at the end of the data).

use super::crc::Crc;
use super::{EncodeError, Message, Refusal, VERSION};

/// A postcard flavor that CRCs and COBS-encodes on the fly into a slice.
struct FrameWriter<'a> {
    out: &'a mut [u8],
    /// Index of the current COBS block's code byte.
    code_idx: usize,
    /// Next write position.
    pos: usize,
    /// Current block code (1 + data bytes so far).
    code: u8,
    crc: Crc,
    overflow: bool,
}

impl<'a> FrameWriter<'a> {
    fn new(out: &'a mut [u8]) -> Self {
        let mut w = Self {
            out,
            code_idx: 0,
            pos: 1,
            code: 1,
            crc: Crc::new(),
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
        if b == 0 {
            self.put(self.code_idx, self.code);
            self.code_idx = self.pos;
            self.pos = self.pos.saturating_add(1);
            self.code = 1;
        } else {
            self.put(self.pos, b);
            self.pos = self.pos.saturating_add(1);
            self.code = self.code.saturating_add(1);
            if self.code == 0xFF {
                self.put(self.code_idx, self.code);
                self.code_idx = self.pos;
                self.pos = self.pos.saturating_add(1);
                self.code = 1;
            }
        }
    }

    fn push(&mut self, b: u8) {
        self.crc.update(b);
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
        for b in self.crc.finish().to_le_bytes() {
            self.cobs_push(b);
        }
        self.put(self.code_idx, self.code);
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
    encode_value(msg, out)
}

/// [`encode`] of `Message::Refused(*refusal)`, without a message-sized
/// value (a message is a checkpoint's size, 13.0 KB with the full model):
/// the same bytes. For the integration kit, whose one message slot then
/// keeps the session's reply ([`crate::device::Device::reply`]).
pub(crate) fn encode_refusal(refusal: &Refusal, out: &mut [u8]) -> Result<usize, EncodeError> {
    /// `Message::Refused(..)` as serde sees it (a newtype variant).
    struct AsRefused<'a>(&'a Refusal);
    impl serde::Serialize for AsRefused<'_> {
        fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            s.serialize_newtype_variant("Message", REFUSED_VARIANT, "Refused", self.0)
        }
    }
    encode_value(&AsRefused(refusal), out)
}

/// The index of `Message::Refused` among the variants of [`Message`] (its
/// tag, [`Message::tag`]): what postcard writes first.
const REFUSED_VARIANT: u32 = 8;

/// One frame of `value`'s postcard bytes.
fn encode_value<V: serde::Serialize + ?Sized>(
    value: &V,
    out: &mut [u8],
) -> Result<usize, EncodeError> {
    if out.is_empty() {
        return Err(EncodeError::BufferTooSmall);
    }
    postcard::serialize_with_flavor(value, FrameWriter::new(out)).map_err(|e| match e {
        postcard::Error::SerializeBufferFull => EncodeError::BufferTooSmall,
        _ => EncodeError::Serialize,
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::{encode, encode_refusal, REFUSED_VARIANT};
    use crate::wire::{Message, Refusal, RefusalReason, MAX_FRAME_LEN};

    /// `encode_refusal` writes the bytes of `encode(&Message::Refused(..))`.
    #[test]
    fn a_refusal_encodes_as_its_message() {
        let r = Refusal {
            message: 7,
            reason: RefusalReason::NotConfigured,
        };
        let m = Message::Refused(r);
        assert_eq!(u32::from(m.tag()), REFUSED_VARIANT);
        let (mut a, mut b) = ([0u8; MAX_FRAME_LEN], [0u8; MAX_FRAME_LEN]);
        let n = encode(&m, &mut a).unwrap();
        assert_eq!(encode_refusal(&r, &mut b).unwrap(), n);
        assert_eq!(a[..n], b[..n]);
    }
}
