//! Fuzzes the streaming frame decoder: arbitrary bytes, fed in chunks whose
//! sizes come from the input, must never panic; every message that comes
//! out must re-encode to a frame that decodes to the same message; and the
//! counters must add up to the number of delimiters seen.
#![no_main]

use libfuzzer_sys::fuzz_target;
use rollcal::wire::{encode, Decoder, FrameDecoder, MAX_FRAME_LEN};

fuzz_target!(|data: &[u8]| {
    let Some((&split, bytes)) = data.split_first() else {
        return;
    };
    let chunk = usize::from(split).max(1);
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
    let mut buf = vec![0u8; MAX_FRAME_LEN];
    for m in messages {
        let n = encode(&m, &mut buf).expect("a decoded message re-encodes");
        let mut again = FrameDecoder::new();
        let mut out = Vec::new();
        again.feed(&buf[..n], |x| out.push(x));
        assert_eq!(out.len(), 1);
        // Bitwise comparison (NaN-safe) through a second encoding.
        let mut buf2 = vec![0u8; MAX_FRAME_LEN];
        let n2 = encode(&out[0], &mut buf2).expect("re-encodes");
        assert_eq!(&buf[..n], &buf2[..n2]);
    }
});
