//! The calibrator on a frame stream, through the integration kit
//! (`rollcal::device`): every byte from UART0 goes to the `Device`, every
//! reply it hands back goes out on UART0 (or UART1), and the device is
//! given an idle moment after every frame (`Device::idle`: the sample log's
//! next sector erased ahead, the periodic checkpoint written). What this
//! module adds to the kit is the board's (the UART, the flash stand-in),
//! the instruction marks (the kit's `Hooks`), logging, the run's totals
//! and two self-tests.
//!
//! The device runs the protocol (`rollcal::session`, the one `host-sim
//! calibrate` drives): `Configure` (re)creates the calibrator for any of
//! the configurations the image holds; `Sample` runs one period and logs
//! it; `EstimateRequest` replies with the running `Estimate`; `Finish` runs
//! the estimator of record over the log (at most 4 passes) and replies
//! with the final `Estimate` (with `exit=request` the run then ends: the
//! QEMU script appends `EstimateRequest`, `Finish` to the recorded stream,
//! as a UART has no end of file); `CheckpointRequest` replies with a
//! `Checkpoint`; `Checkpoint` restores; `Reset` restarts from the prior; a
//! message it cannot act on is answered with `Refused`.
//!
//! # The flash
//!
//! The kit keeps, in the 512 KiB `LOG` region of `memory.x` behind
//! `embedded-storage`'s `NorFlash` traits ([`Ssram`]: a serial NOR chip's
//! semantics over the boards' SSRAM), the configuration and the last
//! checkpoint (two 16 KiB banks) and the sample log (`FlashLog`). At boot
//! it resumes from them (nothing under QEMU, whose SSRAM starts zeroed).
//!
//! # Self-tests
//!
//! - `selftest=checkpoint-at=N`: after the N-th `Sample`, what a host
//!   does over the wire: `CheckpointRequest` (the reply kept), `Reset`,
//!   the kept `Checkpoint` frame back (feature `selftest`).
//! - `selftest=reset-at=N`: after the N-th `Sample` (and its idle
//!   moment), the device started again on the flash alone
//!   (`Device::start`: what a board does after a reset): it resumes from
//!   the stored configuration, checkpoint and the records after it
//!   (feature `selftest`).

use rollcal::device::{DeviceCell, Hooks, Idle};
use rollcal::session::{Reply, SessionError};
use rollcal::wire::{CalibratorConfig, EstimateKind, Message};
use rollcal::Options;

use crate::flash::{Ssram, LOG_BYTES};
use crate::marks::{
    rollcal_mark_finish_end, rollcal_mark_finish_start, rollcal_mark_period_end,
    rollcal_mark_period_start,
};
use crate::uart::Uart;
use crate::{Args, Mode, Real};

/// The device: built in place by `take` (no device-sized value on the
/// stack), zero bytes in the image.
static DEVICE: DeviceCell<Ssram, Real> = DeviceCell::new();

/// The flash region the kit owns: the whole `LOG` region.
const REGION: core::ops::Range<u32> = 0..LOG_BYTES as u32;

/// Totals of a run, for the closing log line (and the exit status).
#[derive(Default, defmt::Format)]
pub struct Totals {
    /// `Sample` frames received.
    pub samples: u32,
    /// Of those, rejected by the calibrator.
    pub rejected: u32,
    /// Of those, dropped because no `Configure` had come before them.
    pub dropped: u32,
    /// Frames sent (estimates, checkpoints, refusals).
    pub sent: u32,
    /// Final estimates of record sent (`EstimateKind::Final`).
    pub finals: u32,
    /// Records in the sample log at the end.
    pub logged: u32,
}

/// The instruction marks around a period and around `Finish`
/// (`tools/qemu-insnmark`), through the kit's hooks.
fn period_start() {
    rollcal_mark_period_start();
}
fn period_end() {
    rollcal_mark_period_end();
}
fn finish_start() {
    rollcal_mark_finish_start();
}
fn finish_end() {
    rollcal_mark_finish_end();
}

/// `mode=plain`: every `Configure` runs the plain EKF.
fn plain(c: &mut CalibratorConfig) {
    c.options = Options::plain();
}

/// What the loop does after a frame.
#[derive(PartialEq, Eq)]
enum Flow {
    Continue,
    /// `Finish` answered with `exit=request`: end the run.
    Exit,
}

/// Runs the calibrator on the UART stream. Returns when a `Finish` arrives
/// and `args.exit_on_request` is set; otherwise never.
#[inline(never)]
pub fn run(args: &Args) -> Totals {
    // SAFETY: UART0 is used by nothing else in this program.
    let mut uart = unsafe { Uart::new(crate::uart::UART0_BASE) };
    // SAFETY: likewise UART1.
    let mut tx = args
        .reply_uart1
        .then(|| unsafe { Uart::new(crate::uart::UART1_BASE) });
    let Some(flash) = Ssram::take() else {
        defmt::panic!("the flash device is already in use");
    };
    let Some(device) = DEVICE.take() else {
        defmt::panic!("the device is already in use");
    };
    device.set_hooks(Hooks {
        before_sample: period_start,
        after_sample: period_end,
        before_finish: finish_start,
        after_finish: finish_end,
        configure: if args.mode == Mode::Plain {
            plain
        } else {
            Hooks::NONE.configure
        },
    });
    start(device, flash);
    let mut totals = Totals::default();
    let mut handled = 0;
    defmt::info!("waiting for frames on UART0");
    loop {
        let byte = loop {
            if let Some(b) = uart.try_read() {
                break b;
            }
        };
        let reply = device.push_byte(byte);
        if !reply.is_empty() {
            match &mut tx {
                Some(tx) => tx.write_all(reply),
                None => uart.write_all(reply),
            }
        }
        if byte != 0 {
            continue;
        }
        // A frame ended: what it did, then the idle moment.
        if device.stats().messages != handled {
            handled = device.stats().messages;
            if observe(device, args, &mut totals) == Flow::Exit {
                report(device, &mut totals);
                return totals;
            }
        } else {
            let n = device.decoder().stats().errors();
            if n <= 5 {
                defmt::warn!("frame rejected ({} so far)", n);
            }
        }
        if device.idle() == Idle::Failed {
            defmt::warn!("flash: {}", device.stats().last_flash_error);
        }
        if device.last_tag() == Some(0) && totals.samples == args.checkpoint_at {
            selftest::checkpoint(device);
        }
        if device.last_tag() == Some(0) && totals.samples == args.reset_at {
            selftest::reset(device);
        }
    }
}

/// `Device::start` on `flash`, logged.
fn start(device: &mut rollcal::device::Device<Ssram, Real>, flash: Ssram) {
    match device.start(flash, REGION) {
        Ok(r) => defmt::info!(
            "flash: resumed a checkpoint of {} samples, {} replayed, last seq {}",
            r.checkpoint,
            r.replayed,
            r.last_seq
        ),
        Err((_, e)) => defmt::error!("the flash cannot be used: {}", e),
    }
}

/// Logs and counts what the last message did.
fn observe(device: &rollcal::device::Device<Ssram, Real>, args: &Args, t: &mut Totals) -> Flow {
    let tag = device.last_tag();
    let is_sample = tag == Some(0);
    if is_sample {
        t.samples += 1;
    }
    match device.reply() {
        Reply::Error(SessionError::NotConfigured) if is_sample => {
            t.dropped += 1;
            if t.dropped == 1 {
                defmt::warn!(
                    "sample {} before any Configure message: dropped (and every one after it until a Configure)",
                    t.samples
                );
            }
        }
        Reply::Rejected(reason) => {
            t.rejected += 1;
            if t.rejected <= 5 {
                defmt::warn!("sample {} rejected: {}", t.samples, reason);
            }
        }
        Reply::Send(Message::Estimate(est)) => match est.kind {
            EstimateKind::Running => {
                if est.seq % 600 == 0 {
                    defmt::info!(
                        "seq {}: {} updates, last NIS {}, {} logged",
                        est.seq,
                        est.updates,
                        est.progress.last_nis,
                        est.progress.logged
                    );
                }
            }
            EstimateKind::Final { passes, converged } => {
                t.finals += 1;
                defmt::info!(
                    "Finish: estimator of record over {} records: {} passes, converged {}",
                    est.progress.logged,
                    passes,
                    converged
                );
            }
            EstimateKind::SinglePass { reason, logged } => {
                defmt::warn!(
                    "Finish: single pass only ({}); {} records logged",
                    reason,
                    logged
                )
            }
        },
        Reply::Error(e) => defmt::warn!("message {} refused: {}", tag, e),
        _ => {}
    }
    if tag == Some(3) {
        if let Some(c) = device.session().calibrator() {
            let s = c.settings();
            defmt::info!(
                "configured {} ({} model), estimate every {} samples, second-order S {}",
                s.config,
                s.errors,
                s.estimate_every,
                s.options.second_order_covariance
            );
        }
    }
    if tag == Some(7) && args.exit_on_request {
        return Flow::Exit;
    }
    Flow::Continue
}

/// The run's closing figures: the totals and what the log asked of the
/// device.
fn report(device: &rollcal::device::Device<Ssram, Real>, t: &mut Totals) {
    let d = device.stats();
    t.sent = d.sent;
    defmt::info!(
        "Finish answered; decoder {}; device {}",
        device.decoder().stats(),
        d
    );
    if let Some(log) = device.log() {
        use rollcal::estimator::SampleLog;
        t.logged = u32::try_from(log.len()).unwrap_or(u32::MAX);
        let s = log.flash().stats();
        defmt::info!(
            "flash: {} records in {} segments, {} bytes a slot; {} writes ({} bytes), {} sector erases, {} reads; last error {}",
            log.len(),
            log.segments(),
            log.slot_len(),
            s.writes,
            s.bytes_written,
            s.erases,
            s.reads,
            log.last_error()
        );
    }
}

/// `selftest=checkpoint-at=N` and `selftest=reset-at=N`.
#[cfg(feature = "selftest")]
mod selftest {
    use core::mem::MaybeUninit;
    use core::ptr::addr_of_mut;
    use core::sync::atomic::{AtomicBool, Ordering};

    use rollcal::device::Device;
    use rollcal::wire::{encode, Message, MAX_FRAME_LEN};

    use super::{Real, Ssram};

    static mut FRAME: MaybeUninit<[u8; MAX_FRAME_LEN]> = MaybeUninit::uninit();
    static TAKEN: AtomicBool = AtomicBool::new(false);

    /// The checkpoint frame's buffer (zeroed in place). `None` after the
    /// first call.
    fn frame() -> Option<&'static mut [u8; MAX_FRAME_LEN]> {
        if TAKEN.swap(true, Ordering::AcqRel) {
            return None;
        }
        // SAFETY: the flag makes this the only reference ever made to
        // FRAME, zeroed before it is formed.
        unsafe {
            let p = addr_of_mut!(FRAME).cast::<[u8; MAX_FRAME_LEN]>();
            p.write_bytes(0, 1);
            Some(&mut *p)
        }
    }

    /// `selftest=reset-at=N`: the device started again on the flash alone.
    #[inline(never)]
    pub fn reset(device: &mut Device<Ssram, Real>) {
        defmt::info!("selftest: reset");
        match device.release() {
            Some(flash) => super::start(device, flash),
            None => defmt::error!("selftest: the device has no flash"),
        }
    }

    /// The frame of a message without payload into `buf`; its length.
    fn request(m: &Message, buf: &mut [u8; 16]) -> usize {
        encode(m, buf).unwrap_or(0)
    }

    /// `CheckpointRequest` (its reply kept), `Reset`, the checkpoint back:
    /// the bytes a host sends, through the device. Nothing is sent back.
    #[inline(never)]
    pub fn checkpoint(device: &mut Device<Ssram, Real>) {
        let Some(kept) = frame() else {
            defmt::error!("selftest: the checkpoint buffer is in use");
            return;
        };
        let mut small = [0u8; 16];
        let n = request(&Message::CheckpointRequest, &mut small);
        let mut len = 0;
        for &b in small.get(..n).unwrap_or(&[]) {
            let reply = device.push_byte(b);
            if let Some(dst) = kept.get_mut(..reply.len()) {
                dst.copy_from_slice(reply);
                len = reply.len();
            }
        }
        defmt::info!(
            "selftest: checkpoint ({} bytes framed); Reset; restore",
            len
        );
        let n = request(&Message::Reset, &mut small);
        for &b in small.get(..n).unwrap_or(&[]) {
            let _ = device.push_byte(b);
        }
        for &b in kept.get(..len).unwrap_or(&[]) {
            let _ = device.push_byte(b);
        }
        match device.reply() {
            rollcal::session::Reply::Error(e) => defmt::error!("selftest: restore refused: {}", e),
            _ => defmt::info!("selftest: restored"),
        }
    }
}

/// Without the feature `selftest`: the self-tests are refused.
#[cfg(not(feature = "selftest"))]
mod selftest {
    use rollcal::device::Device;

    use super::{Real, Ssram};

    pub fn checkpoint(_: &mut Device<Ssram, Real>) {
        defmt::error!("selftest: checkpoint-at needs the feature `selftest`");
    }

    pub fn reset(_: &mut Device<Ssram, Real>) {
        defmt::error!("selftest: reset-at needs the feature `selftest`");
    }
}
