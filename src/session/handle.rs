//! [`Session::handle`]: each message acted on by its own out-of-line
//! function, the reply written into the caller's slot.

use nalgebra::RealField;

use super::{AnyCalibrator, Reply, Request, Session, SessionError};
use crate::calibrator::Passed;
use crate::estimator::{EstimatorOptions, SampleLog};
use crate::wire::{CalibratorConfig, Checkpoint, Estimate, Message, Sample};

impl<T: RealField + Copy> Session<T> {
    /// Acts on one message; `log` is the sample log of the run.
    ///
    /// # Examples
    ///
    /// A run as a device receives it: `Configure`, the samples, `Finish`.
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
    /// use rollcal::models::ConfigId;
    /// use rollcal::session::{Reply, Session};
    /// use rollcal::wire::{CalibratorConfig, EstimateKind, Message, Sample};
    ///
    /// let mut session = Session::<f64>::new(None, EstimatorOptions::default());
    /// let mut records = [LogRecord::predicted(0.0, Vector3::zeros()); 20];
    /// let mut log = SliceLog::new(&mut records);
    /// let settings = CalibratorConfig {
    ///     estimate_every: 0, // no running estimates
    ///     ..CalibratorConfig::paper(ConfigId::M4Pa)
    /// };
    /// let configure = Message::Configure(settings);
    /// assert_eq!(session.handle(&configure, &mut log), Reply::Nothing);
    /// for seq in 0..20 {
    ///     let sample = Message::Sample(Sample {
    ///         seq,
    ///         t_us: (u64::from(seq) + 1) * 1_000_000,
    ///         dt: 1.0,
    ///         dtheta_cmd: settings.earth_rate_n, // at rest
    ///         c_cn_quat: [1.0, 0.0, 0.0, 0.0],
    ///         accel_mean: [0.0, 1.0, 0.0],
    ///         gimbal: None,
    ///     });
    ///     assert_eq!(session.handle(&sample, &mut log), Reply::Nothing);
    /// }
    /// match session.handle(&Message::Finish, &mut log) {
    ///     Reply::Send(Message::Estimate(e)) => {
    ///         assert!(matches!(e.kind, EstimateKind::Final { .. }));
    ///         assert_eq!((e.config, e.seq, e.state.len()), (ConfigId::M4Pa, 19, 12));
    ///     }
    ///     other => panic!("{other:?}"),
    /// }
    /// assert_eq!(session.stats().errors, 0);
    /// ```
    pub fn handle(&mut self, msg: &Message, log: &mut (dyn SampleLog<T> + '_)) -> Reply {
        let mut reply = Reply::Nothing;
        self.handle_into(msg, log, &mut reply);
        reply
    }

    /// [`Session::handle`] with the reply written into `reply` (what it
    /// held is replaced). A reply is message-sized (a checkpoint's size of
    /// the build's largest model whatever it holds: ≈ 1.8 KB for the
    /// installation model's 18 states, ≈ 12.8 KB for the full model's 54):
    /// a firmware that keeps the slot in static memory has none on its
    /// stack. Every reply is written straight into
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

    /// [`Session::handle_into`] with one slot for the message and its
    /// reply, for a firmware with room for one message: `slot` holds
    /// `Reply::Send(message)`, the message received (a decoder writes it
    /// there, [`crate::wire::Decoder::push_byte_into`]), and becomes the
    /// reply, the same as [`Session::handle_into`]'s. A slot that holds no
    /// message (any other [`Reply`]) is left [`Reply::Nothing`] and nothing
    /// is done. The integration kit ([`crate::device`]) keeps one such slot
    /// (a checkpoint's size: 13.0 KB with the full model) instead of a
    /// message and a reply.
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
    /// use rollcal::models::ConfigId;
    /// use rollcal::session::{Reply, Session};
    /// use rollcal::wire::{CalibratorConfig, Message};
    ///
    /// let mut session = Session::<f64>::new(None, EstimatorOptions::default());
    /// let mut records: [LogRecord<f64>; 0] = [];
    /// let mut log = SliceLog::new(&mut records);
    /// let mut slot = Reply::Send(Message::Configure(CalibratorConfig::paper(ConfigId::M1Pa)));
    /// session.handle_in_place(&mut slot, &mut log);
    /// assert_eq!(slot, Reply::Nothing);
    /// // The slot takes the next message, and then its reply.
    /// slot = Reply::Send(Message::CheckpointRequest);
    /// session.handle_in_place(&mut slot, &mut log);
    /// assert!(matches!(slot, Reply::Send(Message::Checkpoint(_))));
    /// ```
    pub fn handle_in_place(&mut self, slot: &mut Reply, log: &mut (dyn SampleLog<T> + '_)) {
        let received = match slot {
            Reply::Send(msg) => Received::of(msg),
            _ => {
                *slot = Reply::Nothing;
                return;
            }
        };
        match received {
            Some(received) => self.act_on(received, log, slot),
            // A checkpoint, read where it is, then replaced by the reply.
            None => {
                let restored = match slot {
                    Reply::Send(Message::Checkpoint(cp)) => self.restore(cp),
                    _ => Ok(()),
                };
                Self::acted(restored, slot);
            }
        }
        self.count(slot);
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
        match (Received::of(msg), msg) {
            (Some(received), _) => self.act_on(received, log, reply),
            (None, Message::Checkpoint(cp)) => {
                let restored = self.restore(cp);
                Self::acted(restored, reply);
            }
            // Not reached: `Received::of` is `None` for a checkpoint only.
            (None, _) => *reply = Reply::Nothing,
        }
    }

    /// [`Session::act`] of a message without checkpoint, copied out of
    /// wherever it was decoded.
    fn act_on(&mut self, received: Received, log: &mut (dyn SampleLog<T> + '_), reply: &mut Reply) {
        match received {
            Received::Configure(settings) => {
                let configured = self.configure(settings);
                Self::acted(configured, reply);
            }
            Received::Ignored => {
                self.stats.ignored = self.stats.ignored.saturating_add(1);
                *reply = Reply::Nothing;
            }
            Received::Sample(s) => match self.cal.as_mut() {
                Some(cal) => Self::sample(cal, &s, log, reply),
                None => {
                    self.stats.unconfigured = self.stats.unconfigured.saturating_add(1);
                    *reply = Reply::Error(SessionError::NotConfigured);
                }
            },
            Received::Request(request) => self.act_request(request, log, reply),
        }
    }

    /// A restore from `cp` (what a `Checkpoint` message does; also the
    /// integration kit's resume). The log follows the calibrator's count of
    /// what it logged (Calibrator::push_logged): kept across a restore when
    /// it still holds those records, emptied after a reset.
    pub(crate) fn restore(&mut self, cp: &Checkpoint) -> Result<(), SessionError> {
        match self.cal.as_mut() {
            Some(cal) => cal.restore(cp).map_err(SessionError::Calibrator),
            None => Err(SessionError::NotConfigured),
        }
    }

    /// `reply` becomes what an action without a message to send answers.
    fn acted(result: Result<(), SessionError>, reply: &mut Reply) {
        *reply = match result {
            Ok(()) => Reply::Nothing,
            Err(e) => Reply::Error(e),
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
            Request::Finish => Self::finish(cal, log, &self.passes, reply),
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

    /// The final passes in the calibrator's own filter, the running one
    /// kept meanwhile in the reply slot as a checkpoint
    /// ([`AnyCalibrator::finish_in_place`]): the session holds one filter.
    /// In two halves ([`AnyCalibrator::finish_passes`], then
    /// [`Session::send_answer`]) so that no estimate is in a frame below
    /// which the passes run (firmware stack).
    #[inline(never)]
    fn finish(
        cal: &mut AnyCalibrator<T>,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        reply: &mut Reply,
    ) {
        let Some(saved) = checkpoint_slot(reply) else {
            // Not reached: `checkpoint_slot` has just made the slot one.
            return Self::estimate(cal, reply);
        };
        let passed = cal.finish_passes(saved, log, passes, &mut |_, _| {});
        Self::send_answer(cal, passed, reply);
    }

    /// The answer of the passes into `reply`, once the running filter is
    /// put back from the checkpoint the slot holds.
    #[inline(never)]
    fn send_answer(cal: &mut AnyCalibrator<T>, passed: Passed, reply: &mut Reply) {
        let estimate = match reply {
            Reply::Send(Message::Checkpoint(saved)) => cal.finish_answer(passed, saved),
            // Not reached: the slot holds the checkpoint `finish` saved.
            _ => cal.estimate(),
        };
        Self::send_estimate(estimate, reply);
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

    /// `reply` becomes the calibrator's checkpoint, written in place
    /// ([`AnyCalibrator::checkpoint_into`]): the slot is made a checkpoint
    /// of no states first unless it holds one, so no checkpoint-sized value
    /// is in this frame (23.4 KB with the full model in f64). In two
    /// steps, the message in the reply, then the checkpoint in the message
    /// (as the decoder makes its slot one, `wire::in_place`): a
    /// `Reply::Send(Message::Checkpoint(..))` written at once was built on
    /// the stack, its empty vectors' storage with it, and copied (a 23.4 KB
    /// frame on the M7, issue 43).
    #[inline(never)]
    fn checkpoint(cal: &AnyCalibrator<T>, reply: &mut Reply) {
        if let Some(cp) = checkpoint_slot(reply) {
            cal.checkpoint_into(cp);
        }
    }
}

/// The message in `slot`, made `Reply::Send(..)` first unless it is (in
/// two steps: a small message into the slot, then whatever the caller
/// writes into it, so that no message-sized value is built on the stack);
/// `None` is not reached. The session's checkpoint slot and the
/// integration kit's one slot ([`crate::device`]) both go through it.
pub(crate) fn message_slot(slot: &mut Reply) -> Option<&mut Message> {
    if !matches!(slot, Reply::Send(_)) {
        *slot = Reply::Send(Message::Finish);
    }
    match slot {
        Reply::Send(msg) => Some(msg),
        _ => None,
    }
}

/// The reply slot made a checkpoint message (unless it holds one: what it
/// holds is kept), in place: the checkpoint in it (`None` is not reached).
fn checkpoint_slot(reply: &mut Reply) -> Option<&mut Checkpoint> {
    let msg = message_slot(reply)?;
    if !matches!(msg, Message::Checkpoint(_)) {
        empty_checkpoint(msg);
    }
    match msg {
        Message::Checkpoint(cp) => Some(cp),
        _ => None,
    }
}

/// A received message other than a checkpoint, copied out of its slot (a
/// few hundred bytes at most, where a message is a checkpoint's size), so
/// that the slot can take the reply.
enum Received {
    Configure(CalibratorConfig),
    Sample(Sample),
    Request(Request),
    /// `Estimate`, `Refused`: a calibrator's own output.
    Ignored,
}

impl Received {
    /// `msg` copied, `None` for a checkpoint (read where it is).
    fn of(msg: &Message) -> Option<Self> {
        Some(match msg {
            Message::Configure(settings) => Received::Configure(*settings),
            Message::Sample(s) => Received::Sample(*s),
            Message::Estimate(_) | Message::Refused(_) => Received::Ignored,
            Message::EstimateRequest => Received::Request(Request::Estimate),
            Message::Finish => Received::Request(Request::Finish),
            Message::CheckpointRequest => Received::Request(Request::Checkpoint),
            Message::Reset => Received::Request(Request::Reset),
            Message::Checkpoint(_) => return None,
        })
    }
}

/// `*msg` becomes a checkpoint of no states, in a frame of its own.
#[inline(never)]
fn empty_checkpoint(msg: &mut Message) {
    *msg = Message::Checkpoint(Checkpoint::empty());
}
