//! A [`Message`] decoded into the caller's slot ([`decode_frame_into`]):
//! the same postcard encoding the derived `Deserialize` reads, but a
//! [`Checkpoint`] is written field by field into the slot's own vectors.
//!
//! The derived decoder builds the message by value and moves it: a
//! checkpoint passes through the decoder's frames as two or three copies
//! (the heapless vectors are returned by value, then the struct, then the
//! enum): three times the checkpoint's size (≈ 12.8 KB for the full
//! model's 54 states) of stack. Here the slot is made a checkpoint of no states first (a few
//! hundred bytes written, [`Checkpoint::empty`]) and its vectors are then
//! cleared and filled element by element, so the frames hold no vector.
//! Every other message is small and decoded by its derived `Deserialize`.
//!
//! What is accepted and what is refused is the derived decoder's: the same
//! variant indices, field order, lengths, capacities and errors (the
//! `in_place_equals_the_derived_decoder` tests below; the decoder fuzz
//! target compares the two on every input).
//!
//! [`decode_frame_into`]: super::decode_frame_into

use core::fmt;

use heapless::Vec;
use serde::de::{
    self, DeserializeSeed, Deserializer, EnumAccess, SeqAccess, VariantAccess, Visitor,
};

use super::{Checkpoint, Message};

/// The variant indices of [`Message`] (its postcard tags, docs/wire.md).
const SAMPLE: u32 = 0;
const ESTIMATE: u32 = 1;
const CHECKPOINT: u32 = 2;
const CONFIGURE: u32 = 3;
const RESET: u32 = 4;
const CHECKPOINT_REQUEST: u32 = 5;
const ESTIMATE_REQUEST: u32 = 6;
const FINISH: u32 = 7;
const REFUSED: u32 = 8;

/// The names serde's `deserialize_enum` and `deserialize_struct` take
/// (postcard reads neither: they are for self-describing formats).
const MESSAGE_VARIANTS: &[&str] = &[
    "Sample",
    "Estimate",
    "Checkpoint",
    "Configure",
    "Reset",
    "CheckpointRequest",
    "EstimateRequest",
    "Finish",
    "Refused",
];
const CHECKPOINT_FIELDS: &[&str] = &[
    "config",
    "errors",
    "state",
    "factor",
    "nominal",
    "c_cn",
    "updates",
    "gated_run",
    "gate_open",
    "progress",
];

/// Deserialises a [`Message`] into `self.0` (what it held is replaced; on
/// error it holds some valid message, not necessarily the old one).
pub(super) struct MessageInto<'a>(pub(super) &'a mut Message);

impl<'de> DeserializeSeed<'de> for MessageInto<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_enum("Message", MESSAGE_VARIANTS, self)
    }
}

impl<'de> Visitor<'de> for MessageInto<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("enum Message")
    }

    fn visit_enum<A: EnumAccess<'de>>(self, data: A) -> Result<(), A::Error> {
        let (index, variant) = data.variant::<u32>()?;
        let msg = self.0;
        *msg = match index {
            SAMPLE => Message::Sample(variant.newtype_variant()?),
            ESTIMATE => Message::Estimate(variant.newtype_variant()?),
            CHECKPOINT => {
                if !matches!(msg, Message::Checkpoint(_)) {
                    *msg = Message::Checkpoint(Checkpoint::empty());
                }
                if let Message::Checkpoint(cp) = msg {
                    variant.newtype_variant_seed(CheckpointInto(cp))?;
                }
                return Ok(());
            }
            CONFIGURE => Message::Configure(variant.newtype_variant()?),
            RESET => {
                variant.unit_variant()?;
                Message::Reset
            }
            CHECKPOINT_REQUEST => {
                variant.unit_variant()?;
                Message::CheckpointRequest
            }
            ESTIMATE_REQUEST => {
                variant.unit_variant()?;
                Message::EstimateRequest
            }
            FINISH => {
                variant.unit_variant()?;
                Message::Finish
            }
            REFUSED => Message::Refused(variant.newtype_variant()?),
            other => {
                return Err(de::Error::invalid_value(
                    de::Unexpected::Unsigned(u64::from(other)),
                    &"variant index 0 <= i < 9",
                ))
            }
        };
        Ok(())
    }
}

/// Deserialises a [`Checkpoint`] into `self.0`, its vectors in place.
struct CheckpointInto<'a>(&'a mut Checkpoint);

impl<'de> DeserializeSeed<'de> for CheckpointInto<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_struct("Checkpoint", CHECKPOINT_FIELDS, self)
    }
}

/// The next field of a struct read as a sequence; missing is an error at
/// field index `i` (as the derived decoder reports it).
fn field<'de, A: SeqAccess<'de>, S: DeserializeSeed<'de>>(
    seq: &mut A,
    seed: S,
    i: usize,
) -> Result<S::Value, A::Error> {
    seq.next_element_seed(seed)?
        .ok_or_else(|| de::Error::invalid_length(i, &"struct Checkpoint with 10 elements"))
}

/// The next field of a struct, by its own `Deserialize`.
fn value<'de, A: SeqAccess<'de>, V: de::Deserialize<'de>>(
    seq: &mut A,
    i: usize,
) -> Result<V, A::Error> {
    field(seq, core::marker::PhantomData::<V>, i)
}

impl<'de> Visitor<'de> for CheckpointInto<'_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("struct Checkpoint")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let cp = self.0;
        cp.config = value(&mut seq, 0)?;
        cp.errors = value(&mut seq, 1)?;
        field(&mut seq, VecInto(&mut cp.state), 2)?;
        field(&mut seq, VecInto(&mut cp.factor), 3)?;
        field(&mut seq, OptionVecInto(&mut cp.nominal), 4)?;
        cp.c_cn = value(&mut seq, 5)?;
        cp.updates = value(&mut seq, 6)?;
        cp.gated_run = value(&mut seq, 7)?;
        cp.gate_open = value(&mut seq, 8)?;
        cp.progress = value(&mut seq, 9)?;
        Ok(())
    }
}

/// Deserialises a sequence of `f64` into `self.0` (cleared first), as
/// heapless's `Vec` does by value: more elements than its capacity is an
/// invalid length.
struct VecInto<'a, const CAP: usize>(&'a mut Vec<f64, CAP>);

impl<'de, const CAP: usize> DeserializeSeed<'de> for VecInto<'_, CAP> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de, const CAP: usize> Visitor<'de> for VecInto<'_, CAP> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a sequence")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let v = self.0;
        v.clear();
        while let Some(x) = seq.next_element::<f64>()? {
            if v.push(x).is_err() {
                return Err(de::Error::invalid_length(CAP + 1, &"a sequence"));
            }
        }
        Ok(())
    }
}

/// Deserialises an optional sequence of `f64` into `self.0`, its vector in
/// place when it already holds one.
struct OptionVecInto<'a, const CAP: usize>(&'a mut Option<Vec<f64, CAP>>);

impl<'de, const CAP: usize> DeserializeSeed<'de> for OptionVecInto<'_, CAP> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_option(self)
    }
}

impl<'de, const CAP: usize> Visitor<'de> for OptionVecInto<'_, CAP> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("option")
    }

    fn visit_none<E: de::Error>(self) -> Result<(), E> {
        *self.0 = None;
        Ok(())
    }

    fn visit_some<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        let v = self.0.get_or_insert_with(Vec::new);
        VecInto(v).deserialize(d)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]
mod tests {
    extern crate std;
    use std::vec;
    use std::vec::Vec as StdVec;

    use super::*;
    use crate::models::{ConfigId, ErrorModel};
    use crate::wire::{CalibratorConfig, Progress, MAX_STATES};

    fn in_place(bytes: &[u8], slot: &mut Message) -> Result<usize, postcard::Error> {
        let mut d = postcard::Deserializer::from_bytes(bytes);
        MessageInto(slot).deserialize(&mut d)?;
        Ok(d.finalize()?.len())
    }

    fn checkpoint(n: usize, nominal: bool) -> Checkpoint {
        let mut cp = Checkpoint::empty();
        cp.config = ConfigId::M2Ps;
        cp.errors = ErrorModel::Full;
        for i in 0..n {
            cp.state.push(i as f64 * 0.25 - 1.0).unwrap();
        }
        for i in 0..crate::wire::factor_len(n) {
            cp.factor.push(1.0 / (i as f64 + 1.0)).unwrap();
        }
        cp.nominal = nominal.then(|| cp.state.clone());
        cp.c_cn = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        cp.updates = 5400;
        cp.gated_run = 2;
        cp.gate_open = true;
        cp.progress = Progress {
            logged: 5400,
            ..Progress::default()
        };
        cp
    }

    /// Every message kind, and every prefix and one-byte change of its
    /// encoding, decodes in place as the derived decoder decodes it (the
    /// same message, or an error for both), whatever the slot held.
    #[test]
    fn in_place_equals_the_derived_decoder() {
        let messages = [
            Message::Configure(CalibratorConfig::paper(ConfigId::M2Ps)),
            Message::Checkpoint(checkpoint(MAX_STATES, true)),
            Message::Checkpoint(checkpoint(12, false)),
            Message::Reset,
            Message::CheckpointRequest,
            Message::EstimateRequest,
            Message::Finish,
        ];
        let slots = [
            Message::Finish,
            Message::Checkpoint(checkpoint(3, true)),
            Message::Configure(CalibratorConfig::paper(ConfigId::M1Pa)),
        ];
        let mut buf = [0u8; crate::wire::MAX_FRAME_LEN];
        for m in &messages {
            let bytes = postcard::to_slice(m, &mut buf).unwrap().to_vec();
            let mut variants: StdVec<StdVec<u8>> = vec![bytes.clone()];
            for cut in 0..bytes.len() {
                variants.push(bytes[..cut].to_vec());
            }
            for at in (0..bytes.len()).step_by(1 + bytes.len() / 64) {
                for flip in [0x01u8, 0x80, 0xFF] {
                    let mut b = bytes.clone();
                    b[at] ^= flip;
                    variants.push(b);
                }
            }
            for b in &variants {
                let derived = postcard::take_from_bytes::<Message>(b);
                for slot in &slots {
                    let mut s = slot.clone();
                    let got = in_place(b, &mut s);
                    match (&derived, got) {
                        // Compared by their encodings: a NaN (the last
                        // NIS before any update) is not equal to itself.
                        (Ok((want, rest)), Ok(left)) => {
                            let mut x = [0u8; crate::wire::MAX_FRAME_LEN];
                            let mut y = [0u8; crate::wire::MAX_FRAME_LEN];
                            let got = postcard::to_slice(&s, &mut x).unwrap();
                            let want = postcard::to_slice(want, &mut y).unwrap();
                            assert!(got == want, "decoded in place differs on {} bytes", b.len());
                            assert_eq!(rest.len(), left);
                        }
                        (Err(_), Err(_)) => {}
                        (d, g) => {
                            panic!("derived {}, in place {g:?} on {} bytes", d.is_ok(), b.len())
                        }
                    }
                }
            }
        }
    }

    /// A checkpoint with more states than the vectors hold is refused, as
    /// the derived decoder refuses it.
    #[test]
    fn an_oversized_checkpoint_is_refused_by_both() {
        // state: MAX_STATES + 1 elements (a varint length, then f64s).
        let mut bytes: StdVec<u8> = vec![2u8, 0, 1, (MAX_STATES + 1) as u8];
        bytes.extend(core::iter::repeat_n(0u8, 8 * (MAX_STATES + 1)));
        assert!(postcard::take_from_bytes::<Message>(&bytes).is_err());
        assert!(in_place(&bytes, &mut Message::Finish).is_err());
    }
}
