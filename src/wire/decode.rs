//! Decoding one frame given without its delimiter: COBS decoded in place
//! (the `cobs` crate), the length, CRC and version checked, and the
//! postcard payload read as one [`Message`] with nothing left over.

use super::crc::crc32;
use super::{FrameError, Message, CRC_LEN, MIN_DECODED_LEN, VERSION};

/// Decodes one frame given without its delimiter, in place (the buffer is
/// overwritten).
///
/// # Examples
///
/// ```
/// use rollcal::wire::{decode_frame, encode, FrameError, Message, MAX_FRAME_LEN};
///
/// let mut buf = [0u8; MAX_FRAME_LEN];
/// let n = encode(&Message::Finish, &mut buf).unwrap();
/// let mut frame = buf[..n - 1].to_vec(); // without the delimiter
/// let mut corrupt = frame.clone();
/// assert_eq!(decode_frame(&mut frame), Ok(Message::Finish));
///
/// corrupt[2] ^= 0x10; // a bit error
/// assert_eq!(decode_frame(&mut corrupt), Err(FrameError::Corrupt));
/// ```
pub fn decode_frame(frame: &mut [u8]) -> Result<Message, FrameError> {
    message_of(frame_payload(frame)?)
}

/// [`decode_frame`] of a frame already COBS-decoded (the streaming
/// decoder's).
pub(super) fn decode_raw(raw: &[u8]) -> Result<Message, FrameError> {
    message_of(raw_payload(raw)?)
}

/// [`decode_frame_into`] of a frame already COBS-decoded.
pub(super) fn decode_raw_into(raw: &[u8], msg: &mut Message) -> Result<(), FrameError> {
    message_into(raw_payload(raw)?, msg)
}

/// [`decode_frame`] with the message written into `msg` (what it held is
/// replaced; untouched on error). A message is a checkpoint's size whatever it
/// holds (≈ 3 KB, ≈ 12.5 KB with the `full-model` feature): a firmware that keeps `msg` in static memory has no
/// second copy of it on its stack.
pub fn decode_frame_into(frame: &mut [u8], msg: &mut Message) -> Result<(), FrameError> {
    message_into(frame_payload(frame)?, msg)
}

/// The postcard payload of a frame (COBS decoded in place; length, CRC and
/// version checked).
fn frame_payload(frame: &mut [u8]) -> Result<&[u8], FrameError> {
    // A frame split at its delimiter holds no zero; `decode_in_place`
    // fails only when a code points past its end (or on an empty frame,
    // which the decoder counts as `empty` before this).
    let n = cobs::decode_in_place(frame).map_err(|_| FrameError::Truncated)?;
    raw_payload(frame.get(..n).ok_or(FrameError::Truncated)?)
}

/// The postcard payload of a COBS-decoded frame (length, CRC and version
/// checked).
fn raw_payload(raw: &[u8]) -> Result<&[u8], FrameError> {
    let n = raw.len();
    if n < MIN_DECODED_LEN {
        return Err(FrameError::Truncated);
    }
    let (body, crc) = raw.split_at(n - CRC_LEN);
    let mut crc_bytes = [0u8; CRC_LEN];
    crc_bytes.copy_from_slice(crc);
    if crc32(body) != u32::from_le_bytes(crc_bytes) {
        return Err(FrameError::Corrupt);
    }
    let (&version, payload) = body.split_first().ok_or(FrameError::Truncated)?;
    if version != VERSION {
        return Err(FrameError::WrongVersion(version));
    }
    Ok(payload)
}

/// The message of a frame's payload: all of it, nothing left over.
fn message_of(payload: &[u8]) -> Result<Message, FrameError> {
    match postcard::take_from_bytes::<Message>(payload) {
        Ok((msg, [])) => Ok(msg),
        _ => Err(FrameError::Malformed),
    }
}

/// [`message_of`] written into `msg` (untouched on error). Out of line:
/// the decoding's copies of the message are in this frame only, not in
/// its callers'.
#[inline(never)]
fn message_into(payload: &[u8], msg: &mut Message) -> Result<(), FrameError> {
    match postcard::take_from_bytes::<Message>(payload) {
        Ok((m, [])) => {
            *msg = m;
            Ok(())
        }
        _ => Err(FrameError::Malformed),
    }
}
