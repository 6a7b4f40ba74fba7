//! rollcal on a Cortex-M under QEMU.
//!
//! Two builds (see `firmware/run-qemu.sh`): Cortex-M4F with the estimator in
//! `f32` (feature `f32`, the default, board `mps2-an386`) and Cortex-M7 with
//! `f64` (feature `f64`, `RUSTFLAGS="-C target-cpu=cortex-m7"`, board
//! `mps2-an500`). Logging is defmt over semihosting; a panic or a HardFault
//! exits QEMU with a non-zero status through semihosting.
//!
//! The run is chosen by the semihosting command line (`qemu -append "…"`),
//! words `key=value`: see [`Args`]. QEMU's exit status is the firmware's:
//! 0 all samples accepted (and, on a stream, `Finish` answered with the
//! estimator of record), 2 some rejected (or a synthetic step failed), 3 no
//! final estimate of record (samples dropped before any `Configure`, or the
//! final answer was a single pass), 101 panic or HardFault ([`EXIT_OK`],
//! [`EXIT_REJECTS`], [`EXIT_NO_FINAL`], [`EXIT_CRASH`]).
//!
//! The sample log of the estimator of record is `rollcal`'s `FlashLog` over
//! a NOR flash device in the linker section `.log`, the `LOG` region of
//! `memory.x` ([`flash`], [`stream`]).
#![no_std]
#![no_main]

mod flash;
mod frames;
mod marks;
mod stack;
mod stream;
#[cfg(feature = "synthetic")]
mod synthetic;
/// Without the cargo feature `synthetic` (a flight image): fails.
#[cfg(not(feature = "synthetic"))]
mod synthetic {
    pub fn run(_: &crate::Args) -> bool {
        defmt::error!("source=synthetic needs the cargo feature synthetic");
        false
    }
}
mod uart;

use core::mem::size_of;

use cortex_m_rt::{entry, exception, ExceptionFrame};
use defmt_semihosting as _;
use rollcal::models::{ConfigId, ErrorModel};

/// The estimator's scalar in this build.
#[cfg(not(feature = "f64"))]
pub type Real = f32;
/// The estimator's scalar in this build.
#[cfg(feature = "f64")]
pub type Real = f64;

// The f64 build is meant for the Cortex-M7 (`-C target-cpu=cortex-m7`, double
// FPU); `target_feature = "fp64"` is not visible to cfg on this target, so
// run-qemu.sh checks the disassembly for `vmul.f64` instead.

/// Filter variant, for instruction counts.
#[derive(Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum Mode {
    /// `Options::default()`: EKF with the second-order innovation covariance.
    Default,
    /// `Options::plain()`: plain EKF.
    Plain,
    /// Linearised Kalman filter about a nominal (`Filter::set_nominal`).
    Linearised,
}

/// Where the samples come from.
#[derive(Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum Source {
    /// `source=uart`: wire frames on UART0 (default).
    Uart,
    /// `source=synthetic`: the built-in synthetic motion (no input).
    Synthetic,
    /// `source=frames`: the frame layer's self-measurement (no input;
    /// [`frames`]).
    Frames,
}

/// Run arguments from the semihosting command line.
#[derive(Clone, Copy, defmt::Format)]
pub struct Args {
    /// `source=uart|synthetic|frames`.
    pub source: Source,
    /// `exit=request`: end the run after answering a `Finish` (default
    /// `exit=never`, as on a device).
    pub exit_on_request: bool,
    /// `reply=uart1`: send replies on UART1 instead of UART0 (under QEMU,
    /// UART0 then reads stdin while the replies go to a file).
    pub reply_uart1: bool,
    /// `config=M2-ps|M1-pa|…` (synthetic runs; any of the seven).
    pub config: ConfigId,
    /// `errors=installation|full` (synthetic runs): the error model.
    pub errors: ErrorModel,
    /// `mode=default|plain|linearised` (`plain` overrides the options of a
    /// `Configure` message; `linearised` is synthetic only).
    pub mode: Mode,
    /// `periods=N` of synthetic motion.
    pub periods: u32,
    /// `wander=none|realistic` (synthetic runs of the full model): the
    /// errors that wander, none (default) or the realistic scenario's
    /// data-sheet figures ([`synthetic::realistic_wander`]).
    pub realistic_wander: bool,
    /// `noise_scale=K`: multiply the synthetic run's accelerometer and
    /// gimbal noise by K (f32 needs K ≈ 1000 to keep S positive definite
    /// at every step, so that the counts are of complete periods).
    pub noise_scale: u32,
    /// `selftest=checkpoint-at=N` (stream runs): after the N-th `Sample`
    /// frame, take a checkpoint (encoded as a wire frame, as a device would
    /// store it), handle a `Reset`, and restore from the decoded frame, as
    /// if the host had sent `CheckpointRequest`, `Reset`, `Checkpoint`. The
    /// log stays in RAM. 0: off.
    pub checkpoint_at: u32,
    /// `selftest=reset-at=N` (stream runs): after the N-th `Sample` frame
    /// (and its idle moment), start the device again on the flash alone,
    /// as a board does after a reset ([`stream`]). 0: off.
    pub reset_at: u32,
}

impl Args {
    fn parse(line: &[u8]) -> Self {
        let mut a = Args {
            source: Source::Uart,
            exit_on_request: false,
            reply_uart1: false,
            config: if ConfigId::M2Ps.is_built() {
                ConfigId::M2Ps
            } else {
                ConfigId::first_built()
            },
            errors: ErrorModel::Installation,
            mode: Mode::Default,
            periods: 200,
            realistic_wander: false,
            noise_scale: 1,
            checkpoint_at: 0,
            reset_at: 0,
        };
        for word in line.split(|&b| b == b' ') {
            let mut kv = word.splitn(2, |&b| b == b'=');
            let (Some(k), Some(v)) = (kv.next(), kv.next()) else {
                continue;
            };
            match (k, v) {
                (b"source", b"uart") => a.source = Source::Uart,
                (b"source", b"synthetic") => a.source = Source::Synthetic,
                (b"source", b"frames") => a.source = Source::Frames,
                (b"exit", b"request") => a.exit_on_request = true,
                (b"exit", b"never") => a.exit_on_request = false,
                (b"reply", b"uart0") => a.reply_uart1 = false,
                (b"reply", b"uart1") => a.reply_uart1 = true,
                (b"config", id) => match core::str::from_utf8(id).ok().and_then(ConfigId::parse) {
                    Some(id) => a.config = id,
                    None => defmt::warn!("ignored argument {=[u8]:a}", word),
                },
                (b"errors", e) => match core::str::from_utf8(e).ok().and_then(ErrorModel::parse) {
                    Some(e) => a.errors = e,
                    None => defmt::warn!("ignored argument {=[u8]:a}", word),
                },
                (b"wander", b"none") => a.realistic_wander = false,
                (b"wander", b"realistic") => a.realistic_wander = true,
                (b"mode", b"default") => a.mode = Mode::Default,
                (b"mode", b"plain") => a.mode = Mode::Plain,
                (b"mode", b"linearised") => a.mode = Mode::Linearised,
                (b"noise_scale", n) => {
                    if let Some(n) = parse_u32(n) {
                        a.noise_scale = n.max(1);
                    }
                }
                (b"selftest", t) if t.starts_with(b"checkpoint-at=") => {
                    match parse_u32(t.get(14..).unwrap_or(&[])) {
                        Some(n) if n > 0 => a.checkpoint_at = n,
                        _ => defmt::warn!("ignored argument {=[u8]:a}", word),
                    }
                }
                (b"selftest", t) if t.starts_with(b"reset-at=") => {
                    match parse_u32(t.get(9..).unwrap_or(&[])) {
                        Some(n) if n > 0 => a.reset_at = n,
                        _ => defmt::warn!("ignored argument {=[u8]:a}", word),
                    }
                }
                (b"periods", n) => {
                    if let Some(n) = parse_u32(n) {
                        a.periods = n;
                    }
                }
                _ => defmt::warn!("ignored argument {=[u8]:a}", word),
            }
        }
        a
    }
}

fn parse_u32(s: &[u8]) -> Option<u32> {
    let mut n: u32 = 0;
    for &c in s {
        if !c.is_ascii_digit() {
            return None;
        }
        n = n.checked_mul(10)?.checked_add(u32::from(c - b'0'))?;
    }
    Some(n)
}

/// The semihosting command line (SYS_GET_CMDLINE), NUL-terminated in `buf`.
fn cmdline(buf: &mut [u8; 256]) -> &[u8] {
    let block = [buf.as_mut_ptr() as usize, buf.len() - 1];
    // SAFETY: SYS_GET_CMDLINE (0x15) writes at most `len` bytes into `buf`.
    let r = unsafe {
        cortex_m_semihosting::syscall1(
            cortex_m_semihosting::nr::GET_CMDLINE,
            block.as_ptr() as usize,
        )
    };
    if r != 0 {
        return &[];
    }
    let n = buf.iter().position(|&b| b == 0).unwrap_or(0);
    &buf[..n]
}

/// Exit status of the run: all samples accepted.
pub const EXIT_OK: u32 = 0;
/// Exit status: the run completed but samples were rejected (or a
/// synthetic step failed).
pub const EXIT_REJECTS: u32 = 2;
/// Exit status: no final estimate of record (samples arrived before any
/// `Configure` and were dropped, or `Finish` was answered with a single pass
/// or not at all).
pub const EXIT_NO_FINAL: u32 = 3;
/// Exit status after a panic or a HardFault.
pub const EXIT_CRASH: u32 = 101;

/// Ends the QEMU process with exit status `code` (semihosting
/// SYS_EXIT_EXTENDED, reason ADP_Stopped_ApplicationExit).
pub fn exit(code: u32) -> ! {
    let block = [0x2_0026u32, code];
    // SAFETY: SYS_EXIT_EXTENDED (0x20) reads the two-word block.
    unsafe {
        cortex_m_semihosting::syscall1(0x20, block.as_ptr() as usize);
    }
    loop {
        cortex_m::asm::bkpt();
    }
}

#[entry]
fn main() -> ! {
    stack::paint();
    let mut line = [0u8; 256];
    let args = Args::parse(cmdline(&mut line));
    defmt::info!(
        "rollcal firmware: {=str}, {} bytes per M2-ps filter, {} per M1-pa filter; {}",
        if size_of::<Real>() == 8 { "f64" } else { "f32" },
        size_of::<rollcal::ekf::M2PsFilter<Real>>(),
        size_of::<rollcal::ekf::M1PaFilter<Real>>(),
        args
    );
    let code = match args.source {
        Source::Synthetic => {
            if synthetic::run(&args) {
                EXIT_OK
            } else {
                EXIT_REJECTS
            }
        }
        Source::Frames => {
            if frames::run() {
                EXIT_OK
            } else {
                EXIT_REJECTS
            }
        }
        Source::Uart => {
            let t = stream::run(&args);
            defmt::info!("stream done: {}", t);
            if t.rejected > 0 {
                EXIT_REJECTS
            } else if t.samples == 0 || t.dropped > 0 || t.finals == 0 {
                EXIT_NO_FINAL
            } else {
                EXIT_OK
            }
        }
    };
    let (peak, region) = stack::peak();
    defmt::info!("peak stack {} bytes of {}", peak, region);
    exit(code)
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    defmt::error!("HardFault at pc={=u32:#x}", ef.pc());
    exit(EXIT_CRASH)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    if let Some(l) = info.location() {
        defmt::error!("panic at {=str}:{=u32}", l.file(), l.line());
    } else {
        defmt::error!("panic");
    }
    exit(EXIT_CRASH)
}
