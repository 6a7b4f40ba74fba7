//! The calibrator on a frame stream: bytes in from the UART, through the
//! wire decoder, into a `Calibrator`; `Estimate` (and `Checkpoint`) frames
//! out over the same UART.
//!
//! Messages handled (docs/wire.md): `Configure` (re)creates the calibrator
//! for M2-ps or M1-pa (other configurations are logged and ignored);
//! `Sample` runs one period; `EstimateRequest` replies with an `Estimate`
//! (and, with `exit=request`, ends the run: the QEMU script appends one to
//! the recorded stream, as a UART has no end of file); `CheckpointRequest`
//! replies with a `Checkpoint`; `Checkpoint` restores; `Reset` restarts.

use rollcal::calibrator::{M1PaCalibrator, M2PsCalibrator, RejectReason};
use rollcal::models::ConfigId;
use rollcal::wire::{encode, CalibratorConfig, FrameDecoder, Message, MAX_FRAME_LEN};
use rollcal::Options;

use crate::marks::{rollcal_mark_period_end, rollcal_mark_period_start};
use crate::uart::Uart;
use crate::{Args, Mode, Real};

/// The running calibrator, if a `Configure` message has chosen one.
// One of them lives on the stack of `run`, for the whole run.
#[allow(clippy::large_enum_variant)]
enum Cal {
    None,
    M2Ps(M2PsCalibrator<Real>),
    M1Pa(M1PaCalibrator<Real>),
}

/// Totals of a run, for the closing log line.
#[derive(Default, defmt::Format)]
pub struct Totals {
    /// Samples pushed into the calibrator.
    pub samples: u32,
    /// Of those, rejected.
    pub rejected: u32,
    /// Estimate frames sent.
    pub estimates: u32,
}

struct Link {
    uart: Uart,
    tx: Option<Uart>,
    out: [u8; MAX_FRAME_LEN],
}

impl Link {
    fn send(&mut self, msg: &Message) {
        match encode(msg, &mut self.out) {
            Ok(n) => {
                let bytes = self.out.get(..n).unwrap_or(&[]);
                match &mut self.tx {
                    Some(tx) => tx.write_all(bytes),
                    None => self.uart.write_all(bytes),
                }
            }
            Err(e) => defmt::error!("cannot encode a reply: {}", e),
        }
    }
}

fn configure(mut c: CalibratorConfig, args: &Args) -> Cal {
    if args.mode == Mode::Plain {
        c.options = Options::plain();
    }
    let made = match c.config {
        ConfigId::M2Ps => M2PsCalibrator::<Real>::new(c).map(Cal::M2Ps),
        ConfigId::M1Pa => M1PaCalibrator::<Real>::new(c).map(Cal::M1Pa),
        other => {
            defmt::error!("configuration {} is not built into this firmware", other);
            return Cal::None;
        }
    };
    match made {
        Ok(cal) => {
            defmt::info!(
                "configured {}, estimate every {} samples, second-order S {}",
                c.config,
                c.estimate_every,
                c.options.second_order_covariance
            );
            cal
        }
        Err(e) => {
            defmt::error!("Configure rejected: {}", e);
            Cal::None
        }
    }
}

macro_rules! with_cal {
    ($cal:expr, $c:ident => $body:expr) => {
        match $cal {
            Cal::M2Ps($c) => Some($body),
            Cal::M1Pa($c) => Some($body),
            Cal::None => None,
        }
    };
}

/// Runs the calibrator on the UART stream. Returns when an
/// `EstimateRequest` arrives and `args.exit_on_request` is set; otherwise
/// never.
pub fn run(args: &Args) -> Totals {
    // SAFETY: UART0 is used by nothing else in this program.
    let uart = unsafe { Uart::new(crate::uart::UART0_BASE) };
    // SAFETY: likewise UART1.
    let tx = args
        .reply_uart1
        .then(|| unsafe { Uart::new(crate::uart::UART1_BASE) });
    let mut link = Link {
        uart,
        tx,
        out: [0; MAX_FRAME_LEN],
    };
    let mut decoder = FrameDecoder::new();
    let mut cal = Cal::None;
    let mut totals = Totals::default();
    defmt::info!("waiting for frames on UART0");
    loop {
        let byte = loop {
            if let Some(b) = link.uart.try_read() {
                break b;
            }
        };
        let Some(frame) = decoder.push_byte(byte) else {
            continue;
        };
        let msg = match frame {
            Ok(m) => m,
            Err(e) => {
                let n = decoder.stats().errors();
                if n <= 5 {
                    defmt::warn!("frame rejected: {}", e);
                }
                with_cal!(&mut cal, c => c.set_frame_errors(n));
                continue;
            }
        };
        match msg {
            Message::Configure(c) => cal = configure(c, args),
            Message::Sample(s) => {
                totals.samples += 1;
                rollcal_mark_period_start();
                let r = with_cal!(&mut cal, c => c.push(&s));
                rollcal_mark_period_end();
                match r {
                    None => {
                        if totals.samples == 1 {
                            defmt::warn!("samples before a Configure message are dropped");
                        }
                    }
                    Some(Ok(Some(est))) => {
                        totals.estimates += 1;
                        if est.seq % 600 == 0 || totals.estimates == 1 {
                            defmt::info!(
                                "seq {}: {} updates, last NIS {}",
                                est.seq,
                                est.updates,
                                est.progress.last_nis
                            );
                        }
                        link.send(&Message::Estimate(est));
                    }
                    Some(Ok(None)) => {}
                    Some(Err(reason)) => {
                        totals.rejected += 1;
                        if totals.rejected <= 5 || matches!(reason, RejectReason::Filter(_)) {
                            defmt::warn!("sample {} rejected: {}", s.seq, reason);
                        }
                    }
                }
            }
            Message::EstimateRequest => {
                if let Some(est) = with_cal!(&cal, c => c.estimate()) {
                    totals.estimates += 1;
                    link.send(&Message::Estimate(est));
                }
                if args.exit_on_request {
                    defmt::info!(
                        "EstimateRequest: final estimate sent; decoder {}",
                        decoder.stats()
                    );
                    return totals;
                }
            }
            Message::CheckpointRequest => {
                if let Some(cp) = with_cal!(&cal, c => c.checkpoint()) {
                    link.send(&Message::Checkpoint(cp));
                }
            }
            Message::Checkpoint(cp) => {
                let restored = match (&cal, cp.config) {
                    (Cal::M2Ps(c), ConfigId::M2Ps) => {
                        M2PsCalibrator::<Real>::restore(*c.settings(), &cp).map(Cal::M2Ps)
                    }
                    (Cal::M1Pa(c), ConfigId::M1Pa) => {
                        M1PaCalibrator::<Real>::restore(*c.settings(), &cp).map(Cal::M1Pa)
                    }
                    _ => {
                        defmt::warn!("Checkpoint for another configuration ignored");
                        continue;
                    }
                };
                match restored {
                    Ok(c) => {
                        cal = c;
                        defmt::info!("restored from a checkpoint");
                    }
                    Err(e) => defmt::warn!("checkpoint rejected: {}", e),
                }
            }
            Message::Reset => {
                if let Some(Err(e)) = with_cal!(&mut cal, c => c.reset()) {
                    defmt::error!("reset failed: {}", e);
                }
            }
            Message::Finish => {
                // No sample log in this firmware yet: the final answer is
                // the running estimate, marked as pass 1 only.
                if let Some(est) = with_cal!(&cal, c => c.estimate()) {
                    let logged = est.progress.logged;
                    link.send(&Message::Estimate(rollcal::wire::Estimate {
                        kind: rollcal::wire::EstimateKind::SinglePass {
                            reason: rollcal::wire::SinglePassReason::NoLog,
                            logged,
                        },
                        ..est
                    }));
                }
            }
            Message::Estimate(_) => {}
        }
    }
}
