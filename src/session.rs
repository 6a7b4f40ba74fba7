//! The protocol, once: every [`Message`] a calibrator receives, turned into
//! what it does and what it sends back. The firmware and `host-sim
//! calibrate` both drive this one implementation (docs/wire.md).
//!
//! | message | effect | reply |
//! |---|---|---|
//! | `Configure` | a new calibrator of the named configuration, from the prior (its first sample empties the log) | — |
//! | `Sample` | one period ([`Calibrator::push_logged`]) | an `Estimate` at the configured cadence |
//! | `EstimateRequest` | — | the running `Estimate` |
//! | `Finish` | the final passes over the log ([`Calibrator::finish_in`], in the session's filter) | the final `Estimate` |
//! | `CheckpointRequest` | — | a `Checkpoint` |
//! | `Checkpoint` | restore from it; the log is taken back to the records it counted (a log that survived a device reset continues) | — |
//! | `Reset` | restart from the prior (its first sample empties the log) | — |
//! | `Estimate` | ignored (a calibrator's own output) | — |
//!
//! A `Sample` before any `Configure` cannot be processed: it is counted in
//! [`SessionStats::unconfigured`] (the host may [`Session::configure`] with
//! settings of its own first). A device that asks itself for one of the
//! four messages without payload (`Finish`, `Reset`, …) passes a
//! [`Request`] to [`Session::request`]: the same answer, without a
//! message-sized constant in its image.

use nalgebra::RealField;

use crate::calibrator::{self, Calibrator, RejectReason};
use crate::ekf::Filter;
use crate::estimator::{EstimatorOptions, SampleLog};
#[allow(unused_imports)] // the configurations left out of a build (cargo features)
use crate::models::{ConfigId, M1Pa, M1Ps, M2Ps, M3Pa, M3Ps, M4Pa, M4Ps, Model};
use crate::wire::{CalibratorConfig, Checkpoint, Estimate, Message, Progress, SinglePassReason};

/// A calibrator of any of the seven configurations (the value-level side of
/// [`crate::with_config!`]).
// The variants differ in size by their covariance; no heap to box them.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum AnyCalibrator<T: RealField + Copy> {
    /// M1-pa.
    #[cfg(feature = "m1-pa")]
    M1Pa(Calibrator<T, M1Pa, 12, 3>),
    /// M1-ps.
    #[cfg(feature = "m1-ps")]
    M1Ps(Calibrator<T, M1Ps, 15, 3>),
    /// M2-ps.
    #[cfg(feature = "m2-ps")]
    M2Ps(Calibrator<T, M2Ps, 18, 6>),
    /// M3-pa.
    #[cfg(feature = "m3-pa")]
    M3Pa(Calibrator<T, M3Pa, 15, 3>),
    /// M3-ps.
    #[cfg(feature = "m3-ps")]
    M3Ps(Calibrator<T, M3Ps, 18, 3>),
    /// M4-pa.
    #[cfg(feature = "m4-pa")]
    M4Pa(Calibrator<T, M4Pa, 12, 3>),
    /// M4-ps.
    #[cfg(feature = "m4-ps")]
    M4Ps(Calibrator<T, M4Ps, 15, 3>),
}

/// A filter of any of the seven configurations: the one in which a
/// session runs `Finish`'s passes ([`AnyCalibrator::finish`]). The session
/// keeps it, so a firmware that holds its session in static memory has no
/// filter on its stack under the passes (the M7's 5.8 KB f64 M2-ps filter).
// The variants differ in size by their covariance; no heap to box them.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum AnyFilter<T: RealField + Copy> {
    /// M1-pa.
    #[cfg(feature = "m1-pa")]
    M1Pa(Filter<T, M1Pa, 12, 3>),
    /// M1-ps.
    #[cfg(feature = "m1-ps")]
    M1Ps(Filter<T, M1Ps, 15, 3>),
    /// M2-ps.
    #[cfg(feature = "m2-ps")]
    M2Ps(Filter<T, M2Ps, 18, 6>),
    /// M3-pa.
    #[cfg(feature = "m3-pa")]
    M3Pa(Filter<T, M3Pa, 15, 3>),
    /// M3-ps.
    #[cfg(feature = "m3-ps")]
    M3Ps(Filter<T, M3Ps, 18, 3>),
    /// M4-pa.
    #[cfg(feature = "m4-pa")]
    M4Pa(Filter<T, M4Pa, 12, 3>),
    /// M4-ps.
    #[cfg(feature = "m4-ps")]
    M4Ps(Filter<T, M4Ps, 15, 3>),
}

macro_rules! each {
    ($any:expr, $c:ident => $body:expr) => {
        match $any {
            #[cfg(feature = "m1-pa")]
            AnyCalibrator::M1Pa($c) => $body,
            #[cfg(feature = "m1-ps")]
            AnyCalibrator::M1Ps($c) => $body,
            #[cfg(feature = "m2-ps")]
            AnyCalibrator::M2Ps($c) => $body,
            #[cfg(feature = "m3-pa")]
            AnyCalibrator::M3Pa($c) => $body,
            #[cfg(feature = "m3-ps")]
            AnyCalibrator::M3Ps($c) => $body,
            #[cfg(feature = "m4-pa")]
            AnyCalibrator::M4Pa($c) => $body,
            #[cfg(feature = "m4-ps")]
            AnyCalibrator::M4Ps($c) => $body,
        }
    };
}

impl<T: RealField + Copy> AnyCalibrator<T> {
    /// A calibrator of `settings.config` at the prior.
    pub fn new(settings: CalibratorConfig) -> Result<Self, calibrator::Error> {
        let mut slot = None;
        Self::build_into(&mut slot, settings)?;
        slot.ok_or(calibrator::Error::ConfigMismatch {
            expected: ConfigId::first_built(),
            found: settings.config,
        })
    }

    /// Puts a calibrator of `settings.config` at the prior into `slot`
    /// (whatever it held; untouched on error). Each configuration is built
    /// by its own out-of-line function, so a firmware's stack holds one
    /// configuration's temporaries, not seven (37 KB of frame on the M7
    /// before); the prior is checked first and the calibrator then built
    /// straight into `slot`, with no `Result` holding it (12.3 KB of frame
    /// on the M7 before, 2.0 KB now).
    pub fn build_into(
        slot: &mut Option<Self>,
        settings: CalibratorConfig,
    ) -> Result<(), calibrator::Error> {
        match settings.config {
            #[cfg(feature = "m1-pa")]
            ConfigId::M1Pa => Self::build_one(slot, settings, Self::M1Pa),
            #[cfg(feature = "m1-ps")]
            ConfigId::M1Ps => Self::build_one(slot, settings, Self::M1Ps),
            #[cfg(feature = "m2-ps")]
            ConfigId::M2Ps => Self::build_one(slot, settings, Self::M2Ps),
            #[cfg(feature = "m3-pa")]
            ConfigId::M3Pa => Self::build_one(slot, settings, Self::M3Pa),
            #[cfg(feature = "m3-ps")]
            ConfigId::M3Ps => Self::build_one(slot, settings, Self::M3Ps),
            #[cfg(feature = "m4-pa")]
            ConfigId::M4Pa => Self::build_one(slot, settings, Self::M4Pa),
            #[cfg(feature = "m4-ps")]
            ConfigId::M4Ps => Self::build_one(slot, settings, Self::M4Ps),
            // A configuration left out of this build (cargo features).
            #[allow(unreachable_patterns)]
            found => Err(calibrator::Error::ConfigMismatch {
                expected: ConfigId::first_built(),
                found,
            }),
        }
    }

    /// [`AnyCalibrator::build_into`] for one configuration.
    #[inline(never)]
    fn build_one<M: Model<N, Z> + Clone, const N: usize, const Z: usize>(
        slot: &mut Option<Self>,
        settings: CalibratorConfig,
        variant: impl FnOnce(Calibrator<T, M, N, Z>) -> Self,
    ) -> Result<(), calibrator::Error> {
        let variance = Calibrator::<T, M, N, Z>::prior_variance(&settings)?;
        *slot = Some(variant(Calibrator::with_prior_variance(
            settings, &variance,
        )));
        Ok(())
    }

    /// The calibrator's settings.
    pub fn settings(&self) -> &CalibratorConfig {
        each!(self, c => c.settings())
    }

    /// Its bookkeeping.
    pub fn progress(&self) -> &Progress {
        each!(self, c => c.progress())
    }

    /// [`Calibrator::push_logged`].
    pub fn push_logged(
        &mut self,
        s: &crate::wire::Sample,
        log: &mut (dyn SampleLog<T> + '_),
    ) -> Result<Option<Estimate>, RejectReason> {
        each!(self, c => c.push_logged(s, log))
    }

    /// [`Calibrator::estimate`] (running).
    pub fn estimate(&self) -> Estimate {
        each!(self, c => c.estimate())
    }

    /// [`Calibrator::finish_in`] (the final answer) in the filter held by
    /// `scratch`: one of this configuration when it holds one (what it
    /// held does not matter otherwise), else a copy of the running filter
    /// put there first. `on_update(pass, nis)` is called for every update
    /// of every pass (`nis` `None` for a period without measurement, or a
    /// refused update).
    pub fn finish(
        &self,
        scratch: &mut Option<AnyFilter<T>>,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        on_update: &mut dyn FnMut(u8, Option<T>),
    ) -> Estimate {
        // `$v`: the configuration's variant of both enums.
        macro_rules! finish_as {
            ($c:ident, $v:ident) => {
                finish_one(
                    $c,
                    scratch,
                    |any| match any {
                        AnyFilter::$v(f) => Some(f),
                        #[allow(unreachable_patterns)] // a build of one configuration
                        _ => None,
                    },
                    AnyFilter::$v,
                    log,
                    passes,
                    on_update,
                )
            };
        }
        match self {
            #[cfg(feature = "m1-pa")]
            AnyCalibrator::M1Pa(c) => finish_as!(c, M1Pa),
            #[cfg(feature = "m1-ps")]
            AnyCalibrator::M1Ps(c) => finish_as!(c, M1Ps),
            #[cfg(feature = "m2-ps")]
            AnyCalibrator::M2Ps(c) => finish_as!(c, M2Ps),
            #[cfg(feature = "m3-pa")]
            AnyCalibrator::M3Pa(c) => finish_as!(c, M3Pa),
            #[cfg(feature = "m3-ps")]
            AnyCalibrator::M3Ps(c) => finish_as!(c, M3Ps),
            #[cfg(feature = "m4-pa")]
            AnyCalibrator::M4Pa(c) => finish_as!(c, M4Pa),
            #[cfg(feature = "m4-ps")]
            AnyCalibrator::M4Ps(c) => finish_as!(c, M4Ps),
        }
    }

    /// [`Calibrator::checkpoint`].
    pub fn checkpoint(&self) -> Checkpoint {
        each!(self, c => c.checkpoint())
    }

    /// [`Calibrator::reset`].
    pub fn reset(&mut self) -> Result<(), calibrator::Error> {
        each!(self, c => c.reset())
    }

    /// Restores from `cp` with the current settings; on error the calibrator
    /// is unchanged.
    pub fn restore(&mut self, cp: &Checkpoint) -> Result<(), calibrator::Error> {
        let settings = *self.settings();
        each!(self, c => restore_into(c, settings, cp))
    }

    /// [`Calibrator::set_frame_errors`].
    pub fn set_frame_errors(&mut self, n: u32) {
        each!(self, c => c.set_frame_errors(n))
    }
}

/// [`Calibrator::restore_in_place`], in a frame of its own (one
/// configuration's temporaries on the stack, not seven).
#[inline(never)]
fn restore_into<
    T: RealField + Copy,
    M: crate::models::Model<N, Z> + Clone,
    const N: usize,
    const Z: usize,
>(
    c: &mut Calibrator<T, M, N, Z>,
    settings: CalibratorConfig,
    cp: &Checkpoint,
) -> Result<(), calibrator::Error> {
    c.restore_in_place(settings, cp)
}

/// [`AnyCalibrator::finish`] for one configuration: `of` is its variant of
/// [`AnyFilter`] (`None` for another), `wrap` makes one.
#[inline(never)]
fn finish_one<
    T: RealField + Copy,
    M: crate::models::Model<N, Z> + Clone,
    const N: usize,
    const Z: usize,
>(
    c: &Calibrator<T, M, N, Z>,
    scratch: &mut Option<AnyFilter<T>>,
    of: fn(&mut AnyFilter<T>) -> Option<&mut Filter<T, M, N, Z>>,
    wrap: fn(Filter<T, M, N, Z>) -> AnyFilter<T>,
    log: &mut (dyn SampleLog<T> + '_),
    passes: &EstimatorOptions,
    on_update: &mut dyn FnMut(u8, Option<T>),
) -> Estimate {
    if scratch.as_mut().and_then(of).is_none() {
        fill_scratch(scratch, c.filter(), wrap);
    }
    match scratch.as_mut().and_then(of) {
        Some(filter) => c.finish_in(filter, log, passes, |e| {
            on_update(
                e.pass,
                e.result.as_ref().ok().and_then(|r| r.map(|i| i.nis)),
            );
        }),
        // Not reached: `fill_scratch` has just put this variant there.
        None => c.single_pass(SinglePassReason::Estimator),
    }
}

/// `*scratch = Some(wrap(running.clone()))`, in a frame of its own: the
/// copy passes through this frame, which has returned before the passes
/// run.
#[inline(never)]
fn fill_scratch<T: RealField + Copy, M: Model<N, Z> + Clone, const N: usize, const Z: usize>(
    scratch: &mut Option<AnyFilter<T>>,
    running: &Filter<T, M, N, Z>,
    wrap: fn(Filter<T, M, N, Z>) -> AnyFilter<T>,
) {
    *scratch = Some(wrap(running.clone()));
}

/// A message without payload ([`Session::request`]): the same answer as
/// [`Session::handle`] of the message it names ([`Request::message`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Request {
    /// [`Message::EstimateRequest`]: the running estimate.
    Estimate,
    /// [`Message::Finish`]: the estimator of record over the log.
    Finish,
    /// [`Message::CheckpointRequest`]: a checkpoint of the calibrator.
    Checkpoint,
    /// [`Message::Reset`]: the calibrator back to its prior.
    Reset,
}

impl Request {
    /// All four.
    pub const ALL: [Request; 4] = [
        Request::Estimate,
        Request::Finish,
        Request::Checkpoint,
        Request::Reset,
    ];

    /// The message this request stands for.
    pub fn message(self) -> Message {
        match self {
            Request::Estimate => Message::EstimateRequest,
            Request::Finish => Message::Finish,
            Request::Checkpoint => Message::CheckpointRequest,
            Request::Reset => Message::Reset,
        }
    }
}

/// Errors of a message the session could not act on. The session is left as
/// it was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SessionError {
    /// A `Configure` names another configuration than the one this session
    /// was told to run.
    ConfigMismatch {
        /// The configuration the session runs.
        expected: ConfigId,
        /// The one the message names.
        found: ConfigId,
    },
    /// The settings, or the checkpoint, were refused.
    Calibrator(calibrator::Error),
    /// A message that needs a calibrator came before any `Configure`.
    NotConfigured,
}

impl core::fmt::Display for SessionError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SessionError::ConfigMismatch { expected, found } => write!(
                f,
                "the stream configures {}, but this session runs {}",
                found.as_str(),
                expected.as_str()
            ),
            SessionError::Calibrator(e) => write!(f, "{e}"),
            SessionError::NotConfigured => f.write_str("no Configure message yet"),
        }
    }
}

impl core::error::Error for SessionError {}

/// What a message did.
// A Checkpoint reply is ~3 KB; no heap to box it.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Reply {
    /// Nothing to send.
    Nothing,
    /// Send this message back.
    Send(Message),
    /// The sample was rejected (counted by reason in the calibrator).
    Rejected(RejectReason),
    /// The message could not be acted on.
    Error(SessionError),
}

/// Counters of the session itself (the calibrator counts the samples).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SessionStats {
    /// Samples before any `Configure` (dropped).
    pub unconfigured: u32,
    /// `Configure` messages after the first (restarts), and `Reset`s.
    pub restarts: u32,
    /// Messages ignored (`Estimate`).
    pub ignored: u32,
    /// Messages that ended in a [`SessionError`].
    pub errors: u32,
}

/// The session: at most one calibrator, and the counters.
#[derive(Clone, Debug, PartialEq)]
pub struct Session<T: RealField + Copy> {
    cal: Option<AnyCalibrator<T>>,
    /// The filter `Finish` runs its passes in ([`AnyCalibrator::finish`]):
    /// the last `Finish`'s final filter, part of the session's state (and
    /// of its `==`).
    scratch: Option<AnyFilter<T>>,
    expected: Option<ConfigId>,
    passes: EstimatorOptions,
    stats: SessionStats,
}

impl<T: RealField + Copy> Session<T> {
    /// A session without a calibrator yet. `expected`: refuse a `Configure`
    /// for any other configuration (`None`: accept any). `passes`: the
    /// final passes run on `Finish`.
    pub fn new(expected: Option<ConfigId>, passes: EstimatorOptions) -> Self {
        Self {
            cal: None,
            scratch: None,
            expected,
            passes,
            stats: SessionStats::default(),
        }
    }

    /// The calibrator, once configured.
    pub fn calibrator(&self) -> Option<&AnyCalibrator<T>> {
        self.cal.as_ref()
    }

    /// The calibrator, once configured (e.g. for
    /// [`AnyCalibrator::set_frame_errors`]).
    pub fn calibrator_mut(&mut self) -> Option<&mut AnyCalibrator<T>> {
        self.cal.as_mut()
    }

    /// The session's counters.
    pub fn stats(&self) -> &SessionStats {
        &self.stats
    }

    /// The final passes run on `Finish`.
    pub fn passes(&self) -> &EstimatorOptions {
        &self.passes
    }

    /// (Re)configures: a new calibrator from the prior (its first sample
    /// empties the log).
    #[inline(never)]
    pub fn configure(&mut self, settings: CalibratorConfig) -> Result<(), SessionError> {
        if let Some(expected) = self.expected.filter(|e| *e != settings.config) {
            return Err(SessionError::ConfigMismatch {
                expected,
                found: settings.config,
            });
        }
        let restart = self.cal.is_some();
        // Built in place (no calibrator-sized temporaries in this frame).
        AnyCalibrator::build_into(&mut self.cal, settings).map_err(SessionError::Calibrator)?;
        if restart {
            self.stats.restarts = self.stats.restarts.saturating_add(1);
        }
        Ok(())
    }

    /// Acts on one message; `log` is the sample log of the run.
    pub fn handle(&mut self, msg: &Message, log: &mut (dyn SampleLog<T> + '_)) -> Reply {
        let mut reply = Reply::Nothing;
        self.handle_into(msg, log, &mut reply);
        reply
    }

    /// [`Session::handle`] with the reply written into `reply` (what it
    /// held is replaced). A reply is message-sized (≈ 3 KB, a checkpoint's
    /// size, whatever it holds): a firmware that keeps the slot in static
    /// memory has none on its stack. Every reply is written straight into
    /// the slot, and no frame below which the estimator runs holds a
    /// message.
    pub fn handle_into(
        &mut self,
        msg: &Message,
        log: &mut (dyn SampleLog<T> + '_),
        reply: &mut Reply,
    ) {
        self.act(msg, log, reply);
        self.count(reply);
    }

    /// [`Session::handle`] of a message without payload, given as a
    /// [`Request`]: a firmware that sends itself `&Message::Finish` holds a
    /// message-sized constant (3 KB of flash each, the size of the largest
    /// message) for a one-byte request.
    pub fn request(&mut self, request: Request, log: &mut (dyn SampleLog<T> + '_)) -> Reply {
        let mut reply = Reply::Nothing;
        self.request_into(request, log, &mut reply);
        reply
    }

    /// [`Session::request`] with the reply written into `reply`, as
    /// [`Session::handle_into`].
    pub fn request_into(
        &mut self,
        request: Request,
        log: &mut (dyn SampleLog<T> + '_),
        reply: &mut Reply,
    ) {
        self.act_request(request, log, reply);
        self.count(reply);
    }

    // By reference: a reply passed through by value is one more copy of a
    // message-sized value in the caller's frame (3 KB on a firmware stack).
    fn count(&mut self, reply: &Reply) {
        if matches!(reply, Reply::Error(_)) {
            self.stats.errors = self.stats.errors.saturating_add(1);
        }
    }

    // Each message has its own function, none inlined: a firmware's stack
    // holds the frame of one handler at a time, not of all of them (and
    // not of the seven configurations' calibrators at once). Every reply
    // is written into `reply`; a message is built only in the frames of
    // `send_estimate` and `checkpoint`, never in one below which the
    // estimator runs.
    fn act(&mut self, msg: &Message, log: &mut (dyn SampleLog<T> + '_), reply: &mut Reply) {
        match msg {
            Message::Configure(settings) => {
                *reply = match self.configure(*settings) {
                    Ok(()) => Reply::Nothing,
                    Err(e) => Reply::Error(e),
                }
            }
            Message::Estimate(_) => {
                self.stats.ignored = self.stats.ignored.saturating_add(1);
                *reply = Reply::Nothing;
            }
            Message::Sample(s) => match self.cal.as_mut() {
                Some(cal) => Self::sample(cal, s, log, reply),
                None => {
                    self.stats.unconfigured = self.stats.unconfigured.saturating_add(1);
                    *reply = Reply::Error(SessionError::NotConfigured);
                }
            },
            Message::EstimateRequest => self.act_request(Request::Estimate, log, reply),
            Message::Finish => self.act_request(Request::Finish, log, reply),
            Message::CheckpointRequest => self.act_request(Request::Checkpoint, log, reply),
            Message::Reset => self.act_request(Request::Reset, log, reply),
            // The log follows the calibrator's count of what it logged
            // (Calibrator::push_logged): kept across a restore when it
            // still holds those records, emptied after a reset.
            Message::Checkpoint(cp) => {
                *reply = match self.cal.as_mut() {
                    Some(cal) => match cal.restore(cp) {
                        Ok(()) => Reply::Nothing,
                        Err(e) => Reply::Error(SessionError::Calibrator(e)),
                    },
                    None => Reply::Error(SessionError::NotConfigured),
                }
            }
        }
    }

    fn act_request(
        &mut self,
        request: Request,
        log: &mut (dyn SampleLog<T> + '_),
        reply: &mut Reply,
    ) {
        let Some(cal) = self.cal.as_mut() else {
            *reply = Reply::Error(SessionError::NotConfigured);
            return;
        };
        match request {
            Request::Estimate => Self::estimate(cal, reply),
            Request::Finish => Self::finish(cal, &mut self.scratch, log, &self.passes, reply),
            Request::Checkpoint => Self::checkpoint(cal, reply),
            Request::Reset => {
                *reply = match cal.reset() {
                    Ok(()) => {
                        self.stats.restarts = self.stats.restarts.saturating_add(1);
                        Reply::Nothing
                    }
                    Err(e) => Reply::Error(SessionError::Calibrator(e)),
                }
            }
        }
    }

    #[inline(never)]
    fn sample(
        cal: &mut AnyCalibrator<T>,
        s: &crate::wire::Sample,
        log: &mut (dyn SampleLog<T> + '_),
        reply: &mut Reply,
    ) {
        match cal.push_logged(s, log) {
            Ok(Some(e)) => Self::send_estimate(e, reply),
            Ok(None) => *reply = Reply::Nothing,
            Err(r) => *reply = Reply::Rejected(r),
        }
    }

    #[inline(never)]
    fn finish(
        cal: &AnyCalibrator<T>,
        scratch: &mut Option<AnyFilter<T>>,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        reply: &mut Reply,
    ) {
        Self::send_estimate(cal.finish(scratch, log, passes, &mut |_, _| {}), reply);
    }

    // Out of line: the estimate (≈ 0.5 KB) is not in `act_request`'s frame,
    // below which `Finish` runs the estimator.
    #[inline(never)]
    fn estimate(cal: &AnyCalibrator<T>, reply: &mut Reply) {
        Self::send_estimate(cal.estimate(), reply);
    }

    /// `reply` becomes the message of `estimate`. Out of line: the message
    /// it builds is in this frame only, after the estimate is computed.
    #[inline(never)]
    fn send_estimate(estimate: Estimate, reply: &mut Reply) {
        *reply = Reply::Send(Message::Estimate(estimate));
    }

    #[inline(never)]
    fn checkpoint(cal: &AnyCalibrator<T>, reply: &mut Reply) {
        *reply = Reply::Send(Message::Checkpoint(cal.checkpoint()));
    }
}
