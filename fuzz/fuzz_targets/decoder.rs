//! Fuzzes the frame decoders. The first byte of an input picks the mode:
//!
//! - `0`: the rest is a postcard payload. It is framed as the encoder frames
//!   a message (the version byte before it, its CRC-32 after it, COBS), so
//!   every input reaches the message decoders, and decoded by
//!   `decode_frame` (the derived `Deserialize`) and by `decode_frame_into`
//!   (the in-place decoder a firmware uses, into a slot that holds a stale
//!   checkpoint): both must accept the same payloads, with the same message
//!   (compared through its encoding, bit for bit), and refuse the others
//!   with the same error.
//! - otherwise it is a chunk size, and the rest bytes fed to a small and a
//!   full-size streaming decoder in chunks of that size: no panic, every
//!   delimiter counted once (`ok + errors + empty`), every message that
//!   comes out re-encodes to a frame that decodes to the same bytes; and
//!   every delimited frame decodes to the same result by both decoders.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rollcal::wire::{
    crc32, decode_frame, decode_frame_into, encode, Checkpoint, Decoder, FrameDecoder, Message,
    MAX_FRAME_LEN, VERSION,
};

/// COBS, as the encoder applies it (without the delimiter).
fn cobs(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8];
    let (mut code_idx, mut code) = (0, 1u8);
    for &b in data {
        if b == 0 {
            out[code_idx] = code;
            code_idx = out.len();
            out.push(0);
            code = 1;
        } else {
            out.push(b);
            code += 1;
            if code == 0xFF {
                out[code_idx] = code;
                code_idx = out.len();
                out.push(0);
                code = 1;
            }
        }
    }
    out[code_idx] = code;
    out
}

/// A message's encoding (its frame), for a bitwise (NaN-safe) comparison.
fn encoded(m: &Message) -> Vec<u8> {
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    let n = encode(m, &mut buf).expect("a decoded message re-encodes");
    buf.truncate(n);
    buf
}

/// Both decoders on one frame (without its delimiter): the same outcome.
fn both_decoders_agree(frame: &[u8]) {
    let derived = decode_frame(&mut frame.to_vec());
    let mut slot = Message::Checkpoint(Checkpoint::empty());
    let in_place = decode_frame_into(&mut frame.to_vec(), &mut slot);
    match (derived, in_place) {
        (Ok(m), Ok(())) => assert_eq!(encoded(&m), encoded(&slot)),
        (Err(a), Err(b)) => assert_eq!(a, b),
        (a, b) => panic!("decode_frame {a:?}, decode_frame_into {b:?}"),
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&split, bytes)) = data.split_first() else {
        return;
    };
    if split == 0 {
        let mut body = vec![VERSION];
        body.extend_from_slice(bytes);
        body.extend_from_slice(&crc32(&body).to_le_bytes());
        both_decoders_agree(&cobs(&body));
        return;
    }
    let chunk = usize::from(split);
    // A small decoder (oversize path) and a full-size one.
    let mut small = Decoder::<96>::new();
    let mut full = FrameDecoder::new();
    let mut messages = Vec::new();
    for c in bytes.chunks(chunk) {
        small.feed(c, |_| {});
        full.feed(c, |m| messages.push(m));
    }
    let delimiters = bytes.iter().filter(|b| **b == 0).count() as u32;
    for d in [*small.stats(), *full.stats()] {
        assert_eq!(d.ok + d.errors() + d.empty, delimiters);
    }
    for m in messages {
        let first = encoded(&m);
        let mut again = FrameDecoder::new();
        let mut out = Vec::new();
        again.feed(&first, |x| out.push(x));
        assert_eq!(out.len(), 1);
        assert_eq!(first, encoded(&out[0]));
    }
    // Every delimited frame (not the partial one at the end).
    let mut frames: Vec<&[u8]> = bytes.split(|b| *b == 0).collect();
    frames.pop();
    for f in frames
        .into_iter()
        .filter(|f| !f.is_empty() && f.len() <= MAX_FRAME_LEN)
    {
        both_decoders_agree(f);
    }
});
