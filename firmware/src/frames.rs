//! `source=frames`: a self-measurement of the frame layer (`rollcal::wire`).
//!
//! Encodes and decodes three messages of the M2-ps configuration (18
//! states), `REPS` times each, every operation between the markers
//! `rollcal_mark_frame_start` and `rollcal_mark_frame_end`, in this order:
//! a `Sample`, an `Estimate` and a `Checkpoint`, each `REPS` encodes
//! (`wire::encode` into a buffer) then [`REPS`] decodes (the frame's bytes,
//! delimiter included, pushed one by one into a `FrameDecoder` with
//! `push_byte_into`, as `stream::run` does). `firmware/frames.sh` counts
//! the instructions of each region (QEMU + tools/qemu-insnmark, `out=FILE`:
//! one line per region, in that order) and gives the last repetition's
//! (QEMU counts no cache: the repetitions differ by a few instructions of
//! the loop around them).
//!
//! The values are made up but of the shapes a calibration sends: floats
//! with full mantissas, and a checkpoint's U-D factor with zeros below its
//! diagonal (COBS then closes a block at each zero byte). The decoder, the
//! frame buffer and the message slot are statics, as in `stream`.
//!
//! Only in an image built with the cargo feature `frame-bench` (so that
//! the flight images' flash is without it); without it the run fails at
//! once.

#[cfg(feature = "frame-bench")]
pub use bench::run;

/// Without the cargo feature `frame-bench`: fails.
#[cfg(not(feature = "frame-bench"))]
pub fn run() -> bool {
    defmt::error!("source=frames needs the cargo feature frame-bench");
    false
}

#[cfg(feature = "frame-bench")]
mod bench {
    use core::hint::black_box;
    use core::mem::MaybeUninit;
    use core::ptr::addr_of_mut;
    use core::sync::atomic::{AtomicBool, Ordering};

    use rollcal::models::{ConfigId, ErrorModel};
    use rollcal::wire::{
        crc32, encode, Checkpoint, Estimate, EstimateKind, FrameDecoder, Message, Progress, Sample,
        MAX_FRAME_LEN,
    };

    use crate::marks::{rollcal_mark_frame_end, rollcal_mark_frame_start};

    /// Encodes (and decodes) of each message.
    pub const REPS: usize = 3;

    /// States of the M2-ps configuration.
    const N: usize = 18;

    struct Bench {
        decoder: &'static mut FrameDecoder,
        out: &'static mut [u8; MAX_FRAME_LEN],
        slot: &'static mut Message,
    }

    // Zero-initialised or uninitialised (.bss, not flash).
    static mut DECODER: FrameDecoder = FrameDecoder::new();
    static mut OUT: [u8; MAX_FRAME_LEN] = [0; MAX_FRAME_LEN];
    static mut SLOT: MaybeUninit<Message> = MaybeUninit::uninit();
    static TAKEN: AtomicBool = AtomicBool::new(false);

    fn bench() -> Option<Bench> {
        if TAKEN.swap(true, Ordering::AcqRel) {
            return None;
        }
        // SAFETY: the flag above makes these the only references ever made to
        // the three statics; SLOT is written before its reference is formed.
        unsafe {
            Some(Bench {
                decoder: &mut *addr_of_mut!(DECODER),
                out: &mut *addr_of_mut!(OUT),
                slot: (*addr_of_mut!(SLOT)).write(Message::Reset),
            })
        }
    }

    /// A made-up value of magnitude `scale` with a full mantissa.
    fn value(i: usize, scale: f64) -> f64 {
        let x = i as f64 + 1.0;
        scale * (0.123_456_789_012_345 * x + 1.0 / (x + 0.377))
    }

    fn vector<V: FromIterator<f64>>(scale: f64) -> V {
        (0..N).map(|i| value(i, scale)).collect()
    }

    fn progress() -> Progress {
        Progress {
            last_seq: Some(4321),
            last_t_us: Some(4_321_000_000),
            last_increment: [value(1, 1e-3), value(2, -1e-7), value(3, 1e-6)],
            last_nis: 1.234_5,
            accepted: 4321,
            logged: 4321,
            since_estimate: 1,
            ..Progress::default()
        }
    }

    fn sample() -> Message {
        Message::Sample(Sample {
            seq: 4321,
            t_us: 4_321_000_000,
            dt: 1.0,
            dtheta_cmd: [-1.745_329_3e-3, 3.1e-9, 7.2e-7],
            c_cn_quat: [0.999_999_6, -8.726_6e-4, 1.5e-9, 3.6e-7],
            accel_mean: [0.001_234, 0.999_998_8, -0.003_5],
            gimbal: Some([0.003_665, -0.001_396, 0.002_269]),
        })
    }

    fn estimate() -> Message {
        Message::Estimate(Estimate {
            config: ConfigId::M2Ps,
            errors: ErrorModel::Installation,
            seq: 4321,
            updates: 4320,
            state: vector(1e-4),
            sigma: vector(1e-6),
            progress: progress(),
            frame_errors: 0,
            kind: EstimateKind::Running,
        })
    }

    fn checkpoint() -> Message {
        // A U-D factor's upper triangle row by row: D on the diagonal, U
        // to its right.
        let factor = (0..N)
            .flat_map(|r| (r..N).map(move |c| (r, c)))
            .map(|(r, c)| {
                let k = r * N + c;
                if r == c {
                    value(k, 1e-10)
                } else {
                    value(k, -1e-2)
                }
            })
            .collect();
        Message::Checkpoint(Checkpoint {
            config: ConfigId::M2Ps,
            errors: ErrorModel::Installation,
            state: vector(1e-4),
            factor,
            nominal: None,
            c_cn: [
                0.999_999_6,
                -8.726_6e-4,
                1.5e-9,
                8.726_6e-4,
                0.999_999_6,
                3.6e-7,
                -1.5e-9,
                -3.6e-7,
                1.0,
            ],
            updates: 4320,
            gated_run: 0,
            gate_open: true,
            progress: progress(),
        })
    }

    /// Runs the measurement; `false` when a frame does not round-trip.
    #[inline(never)]
    pub fn run() -> bool {
        let Some(b) = bench() else {
            defmt::panic!("the frame bench is already in use");
        };
        let mut ok = true;
        for (name, make) in [
            ("Sample", sample as fn() -> Message),
            ("Estimate", estimate),
            ("Checkpoint", checkpoint),
        ] {
            *b.slot = make();
            let mut n = 0;
            for _ in 0..REPS {
                rollcal_mark_frame_start();
                let r = encode(black_box(&*b.slot), black_box(&mut b.out[..]));
                rollcal_mark_frame_end();
                n = r.unwrap_or(0);
            }
            let frame = b.out.get(..n).unwrap_or(&[]);
            let crc = crc32(frame);
            let mut decoded = 0;
            for _ in 0..REPS {
                rollcal_mark_frame_start();
                for &byte in black_box(frame) {
                    if let Some(Ok(())) = b.decoder.push_byte_into(byte, b.slot) {
                        decoded += 1;
                    }
                }
                rollcal_mark_frame_end();
            }
            // The decoded message encodes to the same bytes.
            let again = encode(b.slot, &mut b.out[..]).unwrap_or(0);
            let same = again == n && crc32(b.out.get(..again).unwrap_or(&[])) == crc;
            defmt::info!(
                "frames: {=str}, {} bytes, decoded {} of {}, round trip {=bool}",
                name,
                n,
                decoded,
                REPS,
                same
            );
            ok &= n > 0 && decoded == REPS && same;
        }
        defmt::info!("frames: decoder {}", b.decoder.stats());
        ok
    }
}
