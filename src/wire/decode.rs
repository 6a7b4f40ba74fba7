//! Decoding one frame given without its delimiter: COBS decoded in place,
//! the length, CRC and version checked, and the postcard payload read as
//! one [`Message`] with nothing left over.

use super::crc::crc32;
use super::in_place::MessageInto;
use super::{FrameError, Message, CRC_LEN, MIN_DECODED_LEN, VERSION};

/// Decodes COBS in place; returns the decoded length, or `None` when a block
/// runs past the end (or holds a zero, which a split at delimiters excludes).
///
/// Hand-written rather than `cobs::decode_in_place`, by measurement
/// (BENCHMARKS.md §The frame layer): that one (which first scans the frame
/// for a zero) costs 1.3 KB more flash and 3 to 10 % more instructions per
/// decoded frame on the Cortex-M; the crate's streaming `DecoderState`, fed
/// as the bytes arrive, 1.7 KB and 7 to 19 %.
fn cobs_decode_in_place(buf: &mut [u8]) -> Option<usize> {
    let n = buf.len();
    let (mut read, mut write) = (0usize, 0usize);
    while read < n {
        let code = *buf.get(read)?;
        read += 1;
        if code == 0 {
            return None;
        }
        let run = usize::from(code - 1);
        if read.checked_add(run)? > n {
            return None;
        }
        for _ in 0..run {
            let b = *buf.get(read)?;
            if b == 0 {
                return None;
            }
            *buf.get_mut(write)? = b;
            read += 1;
            write += 1;
        }
        if code != 0xFF && read < n {
            *buf.get_mut(write)? = 0;
            write += 1;
        }
    }
    Some(write)
}

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

/// [`decode_frame`] with the message written into `msg` (what it held is
/// replaced). A message is a checkpoint's size whatever it holds (≈ 1.8 KB
/// for the installation model's 18 states, ≈ 12.8 KB for the full model's
/// 54: [`crate::wire::MAX_STATES`]): a firmware that keeps `msg` in
/// static memory has no copy of it on its stack, as a checkpoint is
/// decoded into `msg`'s own vectors (the `in_place` module). On an error of
/// the frame (COBS, length, CRC, version) `msg` is untouched; on a
/// malformed payload it holds some valid message, not necessarily the one
/// it held.
pub fn decode_frame_into(frame: &mut [u8], msg: &mut Message) -> Result<(), FrameError> {
    message_into(frame_payload(frame)?, msg)
}

/// The postcard payload of a frame (COBS decoded in place; length, CRC and
/// version checked).
fn frame_payload(frame: &mut [u8]) -> Result<&[u8], FrameError> {
    let n = cobs_decode_in_place(frame).ok_or(FrameError::Truncated)?;
    let raw = frame.get(..n).ok_or(FrameError::Truncated)?;
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

/// [`message_of`] written into `msg`, a checkpoint into its own vectors
/// ([`MessageInto`]): the same messages and errors, no message-sized
/// temporary. Out of line: the small messages' values are in this frame
/// only, not in its callers'.
#[inline(never)]
fn message_into(payload: &[u8], msg: &mut Message) -> Result<(), FrameError> {
    use serde::de::DeserializeSeed;
    let mut d = postcard::Deserializer::from_bytes(payload);
    match MessageInto(msg)
        .deserialize(&mut d)
        .and_then(|()| d.finalize())
    {
        Ok([]) => Ok(()),
        _ => Err(FrameError::Malformed),
    }
}
