//! The calibrator on a frame stream: bytes in from the UART, through the
//! wire decoder, into a `Calibrator` that logs every period into the sample
//! log; `Estimate` (and `Checkpoint`) frames out over the same UART (or
//! UART1).
//!
//! Every message goes through `rollcal::session::Session`, the protocol
//! implementation `host-sim calibrate` drives too (docs/wire.md): `Configure`
//! (re)creates the calibrator for any of the seven configurations; `Sample`
//! runs one period and logs it (`Calibrator::push_logged`); `EstimateRequest`
//! replies with the running `Estimate`; `Finish` runs the estimator of
//! record over the log (`Calibrator::finish`, default `EstimatorOptions`: at
//! most 4 passes) and replies with the final `Estimate` (and, with
//! `exit=request`, ends the run: the QEMU script appends `EstimateRequest`,
//! `Finish` to the recorded stream, as a UART has no end of file);
//! `CheckpointRequest` replies with a `Checkpoint`; `Checkpoint` restores;
//! `Reset` restarts from the prior. This module adds the UART, the sample
//! log's storage, the instruction marks, logging and the run's totals.
//!
//! # The sample log
//!
//! `rollcal::estimator::FlashLog`, the log in NOR flash, over [`Ssram`]
//! (`crate::flash`: the `LOG` region of `memory.x` behind
//! `embedded-storage`'s `NorFlash` traits, as a flight computer's HAL
//! implements them for its flash): packed records in write-aligned slots,
//! each with its run's epoch, its index and a CRC, sectors erased as the
//! log enters them. It is opened at start-up from what the device holds
//! (`FlashLog::open`: the newest run's complete records) and in the layout
//! of each `Configure`'s configuration (with the gimbal angles for M2-ps).
//! It stands for storage that survives a reset: a `Checkpoint` restore
//! keeps its records, and the restored calibrator takes the log back to the
//! checkpoint's `progress.logged` at its next sample, so that calibrator
//! and log agree and `Finish` still runs the estimator of record (the
//! checkpoint self-test reopens the log from the device between the
//! `Reset` and the restore, as a device that lost its RAM would). After a
//! `Configure` or `Reset` the first sample empties it (a new epoch). A log
//! shorter than the calibrator's count is not the run's: `Finish` then
//! answers a single pass, `LogMismatch`.

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicBool, Ordering};

use rollcal::calibrator::RejectReason;
use rollcal::estimator::{
    EstimatorOptions, FlashLog, LogError, LogRecord, PackedLayout, SampleLog,
};
use rollcal::session::{Reply, Request, Session, SessionError};
use rollcal::wire::{
    decode_frame_into, encode, CalibratorConfig, Decoder, EstimateKind, Message, MAX_FRAME_LEN,
};
use rollcal::Options;

use crate::flash::{Ssram, LOG_BYTES};
use crate::marks::{
    rollcal_mark_finish_end, rollcal_mark_finish_start, rollcal_mark_period_end,
    rollcal_mark_period_start,
};
use crate::uart::Uart;
use crate::{Args, Mode, Real};

/// The sample log (see the module docs): a `FlashLog` over the SSRAM
/// device, or none when the device could not be opened (every append then
/// fails, and `Finish` answers a single pass).
struct Log {
    inner: Option<FlashLog<Ssram, Real>>,
}

impl Log {
    /// The log the device holds, read in `layout`.
    fn open(flash: Ssram, layout: PackedLayout) -> Self {
        match FlashLog::open(flash, 0..LOG_BYTES as u32, layout) {
            Ok(log) => {
                defmt::info!(
                    "sample log: FlashLog of {} slots of {} bytes ({} KiB NOR over SSRAM, {}-byte sectors, {}-byte words), {} records found, layout {}",
                    log.capacity(),
                    log.slot_len(),
                    LOG_BYTES / 1024,
                    crate::flash::ERASE_SIZE,
                    crate::flash::WRITE_SIZE,
                    log.len(),
                    layout
                );
                Self { inner: Some(log) }
            }
            Err(e) => {
                defmt::error!("the sample log cannot be opened: {}", e);
                Self { inner: None }
            }
        }
    }

    /// Reopened from the device, in `layout`: what a device that lost its
    /// RAM finds.
    fn reopen(&mut self, layout: PackedLayout) {
        if let Some(log) = self.inner.take() {
            *self = Self::open(log.into_inner(), layout);
        }
    }

    /// Reopened in `layout` if it is read in another one.
    fn use_layout(&mut self, layout: PackedLayout) {
        if self.inner.as_ref().is_some_and(|l| l.layout() != layout) {
            self.reopen(layout);
        }
    }

    fn layout(&self) -> PackedLayout {
        self.inner
            .as_ref()
            .map_or(PackedLayout::AccelGimbal, |l| l.layout())
    }

    /// What the log asked of the device, and its last error.
    fn report(&self) {
        if let Some(log) = &self.inner {
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
}

impl SampleLog<Real> for Log {
    fn append(&mut self, record: &LogRecord<Real>) -> Result<(), LogError> {
        match &mut self.inner {
            Some(log) => log.append(record),
            None => Err(LogError::Storage),
        }
    }

    fn len(&self) -> usize {
        self.inner.as_ref().map_or(0, |l| l.len())
    }

    fn get(&mut self, k: usize) -> Option<LogRecord<Real>> {
        self.inner.as_mut()?.get(k)
    }

    fn truncate(&mut self, len: usize) {
        if let Some(log) = &mut self.inner {
            log.truncate(len);
        }
    }
}

/// The stream's large state: the session (its calibrator and the filter
/// `Finish` runs the estimator of record in: ≈ 8 KB each for M2-ps on the
/// M7, ≈ 58 KB with the full model's 54 states), the frame decoder's buffer
/// and the reply buffer ([`MAX_FRAME_LEN`] each, sized by the crate for
/// the models this image holds: 2.2 KB for the installation model's 18
/// states, 13.1 KB for the full model's 54), the last decoded message and
/// the session's reply to it (each the size of a checkpoint of those
/// models: ≈ 1.8 KB, 12.8 KB with the full model's 54 states). A static, not `run`'s locals:
/// `main`'s frame, which every path of the firmware pays, would otherwise
/// hold them, and the message and the reply would be in the frames below
/// which the estimator of record runs. Only [`state`] touches it.
struct State {
    session: Session<Real>,
    decoder: Decoder<MAX_FRAME_LEN>,
    out: [u8; MAX_FRAME_LEN],
    message: Message,
    reply: Reply,
}

static mut STATE: MaybeUninit<State> = MaybeUninit::uninit();

/// Set once [`state`] has handed out [`STATE`].
static STATE_TAKEN: AtomicBool = AtomicBool::new(false);

/// The stream's state, initialised in place. `None` on a second call.
/// Out of line: its frame (where the compiler may build the session before
/// writing it) is gone before the stream runs.
#[inline(never)]
fn state() -> Option<&'static mut State> {
    if STATE_TAKEN.swap(true, Ordering::AcqRel) {
        return None;
    }
    // SAFETY: the flag above makes this the only reference ever made to
    // STATE; every field is written before the reference is formed.
    unsafe {
        let base = addr_of_mut!(STATE).cast::<State>();
        addr_of_mut!((*base).session).write(Session::new(None, EstimatorOptions::default()));
        addr_of_mut!((*base).decoder).write(Decoder::new());
        addr_of_mut!((*base).out).write([0; MAX_FRAME_LEN]);
        addr_of_mut!((*base).message).write(Message::Reset);
        addr_of_mut!((*base).reply).write(Reply::Nothing);
        Some(&mut *base)
    }
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
    out: &'static mut [u8; MAX_FRAME_LEN],
}

impl Link {
    fn send(&mut self, msg: &Message) {
        match encode(msg, self.out) {
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

/// What the loop does after a message.
#[derive(PartialEq, Eq)]
enum Flow {
    Continue,
    /// `Finish` answered with `exit=request`: end the run.
    Exit,
}

/// The stream's state: the protocol session (`rollcal::session`, the same
/// one `host-sim calibrate` drives), its log, its reply, the reply link.
struct Stream<'a> {
    args: &'a Args,
    link: Link,
    session: &'static mut Session<Real>,
    /// What the session answered to the last message
    /// (`Session::handle_into`).
    reply: &'static mut Reply,
    log: Log,
    totals: Totals,
    /// The decoder's count of rejected frames, told to every calibrator.
    frame_errors: u32,
}

impl Stream<'_> {
    // Every message goes through `Session::handle`; what the firmware adds
    // is logging, the instruction marks, the counts and the link. The
    // handlers that need large frames (`Finish`, a restore) are their own
    // functions, not inlined into the sample path: their frames must not
    // add up with a filter step's (BENCHMARKS.md, "Stack").
    fn handle(&mut self, msg: &Message) -> Flow {
        match msg {
            Message::Configure(c) => self.configure(c),
            Message::Sample(s) => self.sample(msg, s.seq),
            Message::Finish => return self.finish(),
            Message::Checkpoint(_) => self.restore(msg),
            other => self.other(other),
        }
        Flow::Continue
    }

    /// Any other message: what the session answers. Out of line, like the
    /// handlers above: the reply (a message, up to 3 KB) is not in the
    /// receive loop's frame.
    #[inline(never)]
    fn other(&mut self, msg: &Message) {
        self.session.handle_into(msg, &mut self.log, self.reply);
        self.send_reply();
    }

    /// Sends what the session answered (`self.reply`), or logs why it could
    /// not act.
    fn send_reply(&mut self) {
        match &*self.reply {
            Reply::Send(m) => {
                if let Message::Estimate(_) = m {
                    self.totals.estimates += 1;
                }
                self.link.send(m);
            }
            Reply::Error(e) => defmt::warn!("message refused: {}", e),
            Reply::Nothing | Reply::Rejected(_) => {}
        }
    }

    /// Tells the (new or restored) calibrator how many frames the decoder
    /// has rejected so far.
    fn tell_frame_errors(&mut self) {
        let n = self.frame_errors;
        if let Some(c) = self.session.calibrator_mut() {
            c.set_frame_errors(n);
        }
    }

    /// `Configure`: a new calibrator from the prior (`mode=plain` overrides
    /// its filter options).
    #[inline(never)]
    fn configure(&mut self, c: &CalibratorConfig) {
        let mut c = *c;
        if self.args.mode == Mode::Plain {
            c.options = Options::plain();
        }
        // `Session::configure`, what `handle` does with a `Configure`
        // (without a message-sized `Message::Configure` and reply here).
        match self.session.configure(c) {
            Err(e) => defmt::error!("Configure refused: {}", e),
            Ok(()) => {
                defmt::info!(
                    "configured {} ({} model), estimate every {} samples, second-order S {}",
                    c.config,
                    c.errors,
                    c.estimate_every,
                    c.options.second_order_covariance
                );
                let z = c.config.layout_with(c.errors).z();
                self.log.use_layout(PackedLayout::for_measurements(z));
            }
        }
        self.tell_frame_errors();
    }

    #[inline(never)]
    fn sample(&mut self, msg: &Message, seq: u32) {
        self.totals.samples += 1;
        rollcal_mark_period_start();
        self.session.handle_into(msg, &mut self.log, self.reply);
        rollcal_mark_period_end();
        let t = &mut self.totals;
        match &*self.reply {
            Reply::Error(SessionError::NotConfigured) => {
                t.dropped += 1;
                if t.dropped == 1 {
                    defmt::warn!(
                        "sample {} before any Configure message: dropped (and every one after it until a Configure)",
                        seq
                    );
                }
            }
            Reply::Send(m @ Message::Estimate(est)) => {
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
                // The reply itself (no second message on the stack).
                self.link.send(m);
            }
            Reply::Rejected(reason) => {
                t.rejected += 1;
                if t.rejected <= 5 || matches!(reason, RejectReason::Filter(_)) {
                    defmt::warn!("sample {} rejected: {}", seq, reason);
                }
            }
            _ => self.send_reply(),
        }
    }

    /// Whether the sample just handled is the one after which
    /// `selftest=checkpoint-at=N` checkpoints and restores.
    fn selftest_due(&self, msg: &Message) -> bool {
        matches!(msg, Message::Sample(_))
            && self.args.checkpoint_at != 0
            && self.totals.samples == self.args.checkpoint_at
    }

    /// `Finish`: the estimator of record over the log, the final estimate.
    #[inline(never)]
    fn finish(&mut self) -> Flow {
        rollcal_mark_finish_start();
        // A request, not `&Message::Finish`: that constant would be
        // message-sized (3 KB of flash).
        self.session
            .request_into(Request::Finish, &mut self.log, self.reply);
        rollcal_mark_finish_end();
        match &*self.reply {
            Reply::Send(Message::Estimate(est)) => match est.kind {
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
            },
            Reply::Error(e) => defmt::error!("Finish: no estimate ({})", e),
            _ => {}
        }
        self.send_reply();
        if self.args.exit_on_request {
            self.totals.logged = u32::try_from(self.log.len()).unwrap_or(u32::MAX);
            return Flow::Exit;
        }
        Flow::Continue
    }

    /// `Checkpoint`: restore the calibrator. The log keeps its records;
    /// the calibrator takes it back to the checkpoint's `logged` count at
    /// its next sample.
    #[inline(never)]
    fn restore(&mut self, msg: &Message) {
        self.session.handle_into(msg, &mut self.log, self.reply);
        match &*self.reply {
            Reply::Error(e) => defmt::warn!("checkpoint refused: {}", e),
            _ => {
                if let Message::Checkpoint(cp) = msg {
                    defmt::info!(
                        "restored from a checkpoint at seq {}: {} records logged, {} in the log",
                        cp.progress.last_seq,
                        cp.progress.logged,
                        self.log.len()
                    );
                }
                self.tell_frame_errors();
            }
        }
    }

    /// `selftest=checkpoint-at=N`: `CheckpointRequest` → (wire frame) →
    /// `Reset` → `Checkpoint` from the decoded frame, through the session,
    /// as if the host had sent them. The checkpoint is the session's reply
    /// (the static slot), its frame is in the reply buffer, and it is
    /// decoded into `slot` (the static slot of received messages): no
    /// message on the stack.
    #[inline(never)]
    fn selftest_checkpoint(&mut self, slot: &mut Message) {
        let Some(n) = self.selftest_frame_checkpoint() else {
            return;
        };
        let logged = self.log.len();
        defmt::info!(
            "selftest: checkpoint after sample {} ({} bytes framed, {} records logged); Reset; restore",
            self.totals.samples,
            n,
            logged
        );
        self.selftest_reset();
        // A device that lost its RAM: the log as the flash holds it.
        let layout = self.log.layout();
        self.log.reopen(layout);
        self.selftest_restore(n, slot);
    }

    /// The session's checkpoint, framed into the reply buffer (no second
    /// 4 KB buffer on the stack; nothing is sent until the restore has
    /// decoded it). Returns the frame's length.
    #[inline(never)]
    fn selftest_frame_checkpoint(&mut self) -> Option<usize> {
        self.session
            .request_into(Request::Checkpoint, &mut self.log, self.reply);
        let Reply::Send(cp @ Message::Checkpoint(_)) = &*self.reply else {
            defmt::error!("selftest: no checkpoint");
            return None;
        };
        match encode(cp, self.link.out) {
            Ok(n) => Some(n),
            Err(e) => {
                defmt::error!("selftest: cannot encode the checkpoint: {}", e);
                None
            }
        }
    }

    #[inline(never)]
    fn selftest_reset(&mut self) {
        self.session
            .request_into(Request::Reset, &mut self.log, self.reply);
        if let Reply::Error(e) = &*self.reply {
            defmt::error!("selftest: reset refused: {}", e);
        }
    }

    /// Decodes the checkpoint frame of length `n` in the reply buffer into
    /// `slot` and restores from it.
    #[inline(never)]
    fn selftest_restore(&mut self, n: usize, slot: &mut Message) {
        // The frame without its delimiter.
        let body = self
            .link
            .out
            .get_mut(..n.saturating_sub(1))
            .unwrap_or(&mut []);
        match decode_frame_into(body, slot) {
            Ok(()) if matches!(slot, Message::Checkpoint(_)) => self.restore(slot),
            Ok(()) => defmt::error!("selftest: the checkpoint frame decoded to another message"),
            Err(e) => defmt::error!("selftest: the checkpoint frame does not decode: {}", e),
        }
    }
}

/// Runs the calibrator on the UART stream. Returns when a `Finish` arrives
/// and `args.exit_on_request` is set; otherwise never. Out of line: its
/// frame (the decoded message) is not `main`'s, which the synthetic run
/// pays too.
#[inline(never)]
pub fn run(args: &Args) -> Totals {
    // SAFETY: UART0 is used by nothing else in this program.
    let uart = unsafe { Uart::new(crate::uart::UART0_BASE) };
    // SAFETY: likewise UART1.
    let tx = args
        .reply_uart1
        .then(|| unsafe { Uart::new(crate::uart::UART1_BASE) });
    let Some(flash) = Ssram::take() else {
        defmt::panic!("the sample log's device is already in use");
    };
    let Some(State {
        session,
        decoder,
        out,
        message,
        reply,
    }) = state()
    else {
        defmt::panic!("the stream state is already in use");
    };
    let mut stream = Stream {
        args,
        link: Link { uart, tx, out },
        session,
        reply,
        log: Log::open(flash, PackedLayout::AccelGimbal),
        totals: Totals::default(),
        frame_errors: 0,
    };
    defmt::info!("waiting for frames on UART0");
    loop {
        let byte = loop {
            if let Some(b) = stream.link.uart.try_read() {
                break b;
            }
        };
        // Decoded into the static slot: no message (3 KB) in this frame.
        let Some(frame) = decoder.push_byte_into(byte, message) else {
            continue;
        };
        match frame {
            Ok(()) => {
                if stream.handle(message) == Flow::Exit {
                    defmt::info!("Finish answered; decoder {}", decoder.stats());
                    stream.log.report();
                    return stream.totals;
                }
                if stream.selftest_due(message) {
                    stream.selftest_checkpoint(message);
                }
            }
            Err(e) => {
                let n = decoder.stats().errors();
                if n <= 5 {
                    defmt::warn!("frame rejected: {}", e);
                }
                stream.frame_errors = n;
                stream.tell_frame_errors();
            }
        }
    }
}
