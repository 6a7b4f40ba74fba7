//! The calibrator on a frame stream: bytes in from the UART, through the
//! wire decoder, into a `Calibrator` that logs every period into the sample
//! log; `Estimate` (and `Checkpoint`) frames out over the same UART (or
//! UART1).
//!
//! Messages handled (docs/wire.md): `Configure` (re)creates the calibrator
//! for M2-ps or M1-pa (other configurations are logged and ignored) and
//! clears the log; `Sample` runs one period (`Calibrator::push_logged`);
//! `EstimateRequest` replies with the running `Estimate`; `Finish` runs the
//! estimator of record over the log (`Calibrator::finish`, default
//! `EstimatorOptions`: at most 4 passes) and replies with the final
//! `Estimate` (and, with `exit=request`, ends the run: the QEMU script
//! appends `EstimateRequest`, `Finish` to the recorded stream, as a UART has
//! no end of file); `CheckpointRequest` replies with a `Checkpoint`;
//! `Checkpoint` restores; `Reset` restarts and clears the log.
//!
//! # The sample log
//!
//! [`LOG_CAPACITY`] records in the static [`LOG`], linker section `.log`:
//! the `LOG` region of `memory.x` (SSRAM2&3 from 0x2010_0000, outside the
//! 128 KiB of `RAM`). The section is NOLOAD, so the start-up code neither
//! copies nor zeroes it; [`log_storage`] writes every record in place once,
//! and the stream loop keeps a `SliceLog` over it for the whole run.
//!
//! The log stands for storage that survives a reset (FRAM): a `Checkpoint`
//! restore keeps its records and takes its length back to the checkpoint's
//! `progress.logged` (`SliceLog::set_len`), so that the restored calibrator
//! and its log agree and `Finish` still runs the estimator of record. (A
//! device whose log is not the run's since that checkpoint must not do
//! this: `Finish` then answers a single pass, `LogMismatch`.)

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicBool, Ordering};

use nalgebra::Vector3;
use rollcal::calibrator::{M1PaCalibrator, M2PsCalibrator, RejectReason};
use rollcal::estimator::{EstimatorOptions, LogRecord, SampleLog, SliceLog};
use rollcal::models::ConfigId;
use rollcal::wire::{
    decode_frame, encode, CalibratorConfig, EstimateKind, FrameDecoder, Message, MAX_FRAME_LEN,
};
use rollcal::Options;

use crate::marks::{
    rollcal_mark_finish_end, rollcal_mark_finish_start, rollcal_mark_period_end,
    rollcal_mark_period_start,
};
use crate::uart::Uart;
use crate::{Args, Mode, Real};

/// Records in the sample log: the 5400 periods of the paper's run plus 13 %
/// (bridged periods are logged too, one record each).
pub const LOG_CAPACITY: usize = 6144;

/// The sample log's storage, in the `LOG` region (NOLOAD: uninitialised at
/// reset). Only [`log_storage`] touches it.
#[link_section = ".log"]
static mut LOG: MaybeUninit<[LogRecord<Real>; LOG_CAPACITY]> = MaybeUninit::uninit();

/// Set once [`log_storage`] has handed out [`LOG`].
static LOG_TAKEN: AtomicBool = AtomicBool::new(false);

/// The log's storage, every record initialised in place (one record at a
/// time: no copy of the whole array on the stack). `None` on a second call.
fn log_storage() -> Option<&'static mut [LogRecord<Real>]> {
    if LOG_TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // SAFETY: the flag above makes this the only reference ever made to
    // LOG; every element is written before the slice is formed.
    unsafe {
        let base = addr_of_mut!(LOG).cast::<LogRecord<Real>>();
        for k in 0..LOG_CAPACITY {
            base.add(k)
                .write(LogRecord::predicted(0.0, Vector3::zeros()));
        }
        Some(core::slice::from_raw_parts_mut(base, LOG_CAPACITY))
    }
}

/// The running calibrator, if a `Configure` message has chosen one.
// One of them lives on the stack of `run`, for the whole run.
#[allow(clippy::large_enum_variant)]
enum Cal {
    None,
    M2Ps(M2PsCalibrator<Real>),
    M1Pa(M1PaCalibrator<Real>),
}

/// Totals of a run, for the closing log line (and the exit status).
#[derive(Default, defmt::Format)]
pub struct Totals {
    /// `Sample` frames received.
    pub samples: u32,
    /// Of those, rejected by the calibrator.
    pub rejected: u32,
    /// Of those, dropped because no `Configure` had come before them.
    pub dropped: u32,
    /// Estimate frames sent (running and final).
    pub estimates: u32,
    /// Final estimates of record sent (`EstimateKind::Final`).
    pub finals: u32,
    /// Records in the sample log at the end.
    pub logged: u32,
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

/// What the loop does after a message.
#[derive(PartialEq, Eq)]
enum Flow {
    Continue,
    /// `Finish` answered with `exit=request`: end the run.
    Exit,
}

/// The stream's state: the calibrator, its log, the reply link.
struct Stream<'a> {
    args: &'a Args,
    link: Link,
    cal: Cal,
    log: SliceLog<'static, Real>,
    totals: Totals,
    /// The decoder's count of rejected frames, told to every calibrator.
    frame_errors: u32,
}

impl Stream<'_> {
    // Every handler is its own function (not inlined): the stack of the
    // sample path must not carry the frames of `Finish` or a restore (the
    // M7 build's filter step alone takes ~70 KB of the 128 KB RAM).
    fn handle(&mut self, msg: &Message) -> Flow {
        match msg {
            Message::Configure(c) => self.configure(c),
            Message::Sample(s) => self.sample(s),
            Message::EstimateRequest => self.estimate_request(),
            Message::Finish => return self.finish(),
            Message::CheckpointRequest => self.checkpoint_request(),
            Message::Checkpoint(cp) => self.restore(cp),
            Message::Reset => self.reset(),
            Message::Estimate(_) => {}
        }
        Flow::Continue
    }

    /// `Configure`: a new calibrator, an empty log.
    #[inline(never)]
    fn configure(&mut self, c: &CalibratorConfig) {
        self.cal = configure(*c, self.args);
        self.log.clear();
        let n = self.frame_errors;
        with_cal!(&mut self.cal, c => c.set_frame_errors(n));
    }

    /// `Reset`: the calibrator from the prior, an empty log.
    #[inline(never)]
    fn reset(&mut self) {
        if let Some(Err(e)) = with_cal!(&mut self.cal, c => c.reset()) {
            defmt::error!("reset failed: {}", e);
        }
        self.log.clear();
    }

    #[inline(never)]
    fn estimate_request(&mut self) {
        if let Some(est) = with_cal!(&self.cal, c => c.estimate()) {
            self.totals.estimates += 1;
            self.link.send(&Message::Estimate(est));
        }
    }

    #[inline(never)]
    fn checkpoint_request(&mut self) {
        if let Some(cp) = with_cal!(&self.cal, c => c.checkpoint()) {
            self.link.send(&Message::Checkpoint(cp));
        }
    }

    #[inline(never)]
    fn sample(&mut self, s: &rollcal::wire::Sample) {
        let t = &mut self.totals;
        t.samples += 1;
        rollcal_mark_period_start();
        let r = with_cal!(&mut self.cal, c => c.push_logged(s, &mut self.log));
        rollcal_mark_period_end();
        match r {
            None => {
                t.dropped += 1;
                if t.dropped == 1 {
                    defmt::warn!(
                        "sample {} before any Configure message: dropped (and every one after it until a Configure)",
                        s.seq
                    );
                }
            }
            Some(Ok(Some(est))) => {
                t.estimates += 1;
                if est.seq % 600 == 0 || t.estimates == 1 {
                    defmt::info!(
                        "seq {}: {} updates, last NIS {}, {} logged",
                        est.seq,
                        est.updates,
                        est.progress.last_nis,
                        est.progress.logged
                    );
                }
                self.link.send(&Message::Estimate(est));
            }
            Some(Ok(None)) => {}
            Some(Err(reason)) => {
                t.rejected += 1;
                if t.rejected <= 5 || matches!(reason, RejectReason::Filter(_)) {
                    defmt::warn!("sample {} rejected: {}", s.seq, reason);
                }
            }
        }
        if self.args.checkpoint_at != 0 && self.totals.samples == self.args.checkpoint_at {
            self.selftest_checkpoint();
        }
    }

    /// `Finish`: the estimator of record over the log, the final estimate.
    #[inline(never)]
    fn finish(&mut self) -> Flow {
        let opts = EstimatorOptions::default();
        let log = &mut self.log;
        rollcal_mark_finish_start();
        let answer = with_cal!(&self.cal, c => c.finish(log, &opts, |_| {}).0);
        rollcal_mark_finish_end();
        match answer {
            Some(est) => {
                match est.kind {
                    EstimateKind::Final { passes, converged } => {
                        self.totals.finals += 1;
                        defmt::info!(
                            "Finish: estimator of record over {} records: {} passes, converged {}",
                            self.log.len(),
                            passes,
                            converged
                        );
                    }
                    EstimateKind::SinglePass { reason, logged } => defmt::warn!(
                        "Finish: single pass only ({}); {} records logged, {} in the log",
                        reason,
                        logged,
                        self.log.len()
                    ),
                    EstimateKind::Running => {}
                }
                self.totals.estimates += 1;
                self.link.send(&Message::Estimate(est));
            }
            None => defmt::error!("Finish before any Configure message: no estimate"),
        }
        if self.args.exit_on_request {
            self.totals.logged = u32::try_from(self.log.len()).unwrap_or(u32::MAX);
            return Flow::Exit;
        }
        Flow::Continue
    }

    /// `Checkpoint`: restore the calibrator; the log keeps its records and
    /// takes the checkpoint's length.
    #[inline(never)]
    fn restore(&mut self, cp: &rollcal::wire::Checkpoint) {
        let restored = match (&self.cal, cp.config) {
            (Cal::M2Ps(c), ConfigId::M2Ps) => {
                M2PsCalibrator::<Real>::restore(*c.settings(), cp).map(Cal::M2Ps)
            }
            (Cal::M1Pa(c), ConfigId::M1Pa) => {
                M1PaCalibrator::<Real>::restore(*c.settings(), cp).map(Cal::M1Pa)
            }
            _ => {
                defmt::warn!("Checkpoint for another configuration ignored");
                return;
            }
        };
        match restored {
            Ok(c) => {
                self.cal = c;
                let n = self.frame_errors;
                with_cal!(&mut self.cal, c => c.set_frame_errors(n));
                let logged = cp.progress.logged as usize;
                match self.log.set_len(logged) {
                    Ok(()) => defmt::info!(
                        "restored from a checkpoint at seq {}: {} records in the log",
                        cp.progress.last_seq,
                        logged
                    ),
                    Err(e) => defmt::warn!(
                        "restored from a checkpoint, but its {} logged records do not fit the log: {}",
                        logged,
                        e
                    ),
                }
            }
            Err(e) => defmt::warn!("checkpoint rejected: {}", e),
        }
    }

    /// `selftest=checkpoint-at=N`: checkpoint → (wire frame) → `Reset` →
    /// restore from the decoded frame, by the handlers of those messages.
    #[inline(never)]
    fn selftest_checkpoint(&mut self) {
        let Some(cp) = with_cal!(&self.cal, c => c.checkpoint()) else {
            defmt::error!("selftest: no calibrator to checkpoint");
            return;
        };
        let mut frame = [0u8; MAX_FRAME_LEN];
        let n = match encode(&Message::Checkpoint(cp), &mut frame) {
            Ok(n) => n,
            Err(e) => {
                defmt::error!("selftest: cannot encode the checkpoint: {}", e);
                return;
            }
        };
        let logged = self.log.len();
        defmt::info!(
            "selftest: checkpoint after sample {} ({} bytes framed, {} records logged); Reset; restore",
            self.totals.samples,
            n,
            logged
        );
        self.reset();
        // The frame without its delimiter.
        let body = frame.get_mut(..n.saturating_sub(1)).unwrap_or(&mut []);
        match decode_frame(body) {
            Ok(Message::Checkpoint(cp)) => self.restore(&cp),
            Ok(_) => defmt::error!("selftest: the checkpoint frame decoded to another message"),
            Err(e) => defmt::error!("selftest: the checkpoint frame does not decode: {}", e),
        }
        if self.log.len() != logged {
            defmt::error!(
                "selftest: {} records in the log after the restore, {} before the checkpoint",
                self.log.len(),
                logged
            );
        }
    }
}

/// Runs the calibrator on the UART stream. Returns when a `Finish` arrives
/// and `args.exit_on_request` is set; otherwise never.
pub fn run(args: &Args) -> Totals {
    // SAFETY: UART0 is used by nothing else in this program.
    let uart = unsafe { Uart::new(crate::uart::UART0_BASE) };
    // SAFETY: likewise UART1.
    let tx = args
        .reply_uart1
        .then(|| unsafe { Uart::new(crate::uart::UART1_BASE) });
    let Some(storage) = log_storage() else {
        defmt::panic!("the sample log is already in use");
    };
    defmt::info!(
        "sample log: {} records of {} bytes ({} bytes) at {=usize:#x}",
        storage.len(),
        core::mem::size_of::<LogRecord<Real>>(),
        core::mem::size_of_val(storage),
        storage.as_ptr() as usize
    );
    let mut stream = Stream {
        args,
        link: Link {
            uart,
            tx,
            out: [0; MAX_FRAME_LEN],
        },
        cal: Cal::None,
        log: SliceLog::new(storage),
        totals: Totals::default(),
        frame_errors: 0,
    };
    let mut decoder = FrameDecoder::new();
    defmt::info!("waiting for frames on UART0");
    loop {
        let byte = loop {
            if let Some(b) = stream.link.uart.try_read() {
                break b;
            }
        };
        let Some(frame) = decoder.push_byte(byte) else {
            continue;
        };
        match frame {
            Ok(msg) => {
                if stream.handle(&msg) == Flow::Exit {
                    defmt::info!("Finish answered; decoder {}", decoder.stats());
                    return stream.totals;
                }
            }
            Err(e) => {
                let n = decoder.stats().errors();
                if n <= 5 {
                    defmt::warn!("frame rejected: {}", e);
                }
                stream.frame_errors = n;
                with_cal!(&mut stream.cal, c => c.set_frame_errors(n));
            }
        }
    }
}
