//! The protocol, once: every [`Message`] a calibrator receives, turned into
//! what it does and what it sends back. The firmware and `host-sim
//! calibrate` both drive this one implementation (docs/wire.md).
//!
//! | message | effect | reply |
//! |---|---|---|
//! | `Configure` | a new calibrator of the named configuration, from the prior (its first sample empties the log) | — |
//! | `Sample` | one period ([`Calibrator::push_logged`](crate::calibrator::Calibrator::push_logged)) | an `Estimate` at the configured cadence |
//! | `EstimateRequest` | — | the running `Estimate` |
//! | `Finish` | the final passes over the log in the calibrator's own filter, the running filter kept meanwhile in the reply slot and put back after ([`Calibrator::finish_in_place`](crate::calibrator::Calibrator::finish_in_place)): the calibrator is as it was, more samples may follow | the final `Estimate` |
//! | `CheckpointRequest` | — | a `Checkpoint` |
//! | `Checkpoint` | restore from it; the log is taken back to the records it counted (a log that survived a device reset continues) | — |
//! | `Reset` | restart from the prior (its first sample empties the log) | — |
//! | `Estimate`, `Refused` | ignored (a calibrator's own output) | — |
//!
//! A message the session cannot act on leaves it as it was and answers
//! [`Reply::Error`]; its wire form, which a calibrator sends back, is
//! [`SessionError::refusal`] ([`Message::Refused`]).
//!
//! A `Sample` before any `Configure` cannot be processed: it is counted in
//! [`SessionStats::unconfigured`] (the host may [`Session::configure`] with
//! settings of its own first). A device that asks itself for one of the
//! four messages without payload (`Finish`, `Reset`, …) passes a
//! [`Request`] to [`Session::request`]: the same answer, without a
//! message-sized constant in its image.

/// `$body` with `$c` bound to the calibrator of whichever configuration
/// `$any` holds.
macro_rules! each {
    ($any:expr, $c:ident => $body:expr) => {
        match $any {
            #[cfg(all(feature = "m1-pa", feature = "installation-model"))]
            AnyCalibrator::M1Pa($c) => $body,
            #[cfg(all(feature = "m1-ps", feature = "installation-model"))]
            AnyCalibrator::M1Ps($c) => $body,
            #[cfg(all(feature = "m2-ps", feature = "installation-model"))]
            AnyCalibrator::M2Ps($c) => $body,
            #[cfg(all(feature = "m3-pa", feature = "installation-model"))]
            AnyCalibrator::M3Pa($c) => $body,
            #[cfg(all(feature = "m3-ps", feature = "installation-model"))]
            AnyCalibrator::M3Ps($c) => $body,
            #[cfg(all(feature = "m4-pa", feature = "installation-model"))]
            AnyCalibrator::M4Pa($c) => $body,
            #[cfg(all(feature = "m4-ps", feature = "installation-model"))]
            AnyCalibrator::M4Ps($c) => $body,
            #[cfg(all(feature = "m1-pa", feature = "full-model"))]
            AnyCalibrator::M1PaFull($c) => $body,
            #[cfg(all(feature = "m1-ps", feature = "full-model"))]
            AnyCalibrator::M1PsFull($c) => $body,
            #[cfg(all(feature = "m2-ps", feature = "full-model"))]
            AnyCalibrator::M2PsFull($c) => $body,
            #[cfg(all(feature = "m3-pa", feature = "full-model"))]
            AnyCalibrator::M3PaFull($c) => $body,
            #[cfg(all(feature = "m3-ps", feature = "full-model"))]
            AnyCalibrator::M3PsFull($c) => $body,
            #[cfg(all(feature = "m4-pa", feature = "full-model"))]
            AnyCalibrator::M4PaFull($c) => $body,
            #[cfg(all(feature = "m4-ps", feature = "full-model"))]
            AnyCalibrator::M4PsFull($c) => $body,
        }
    };
}

mod any;
mod covariance;
mod finish;
mod handle;

pub(crate) use handle::message_slot;

use nalgebra::RealField;

use crate::calibrator::{self, RejectReason};
use crate::estimator::EstimatorOptions;
use crate::models::ConfigId;
use crate::wire::{CalibratorConfig, Message, Refusal, RefusalReason};

pub use any::{AnyCalibrator, AnyFilter};
pub use covariance::{Covariance, PassObserver};

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

impl SessionError {
    /// The wire form of this error as the answer to the message tagged
    /// `message` ([`Message::tag`]): what a calibrator sends back
    /// ([`Message::Refused`], docs/wire.md §Refused).
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::estimator::{EstimatorOptions, SliceLog};
    /// use rollcal::session::{Reply, Session};
    /// use rollcal::wire::{Message, RefusalReason};
    ///
    /// let mut session = Session::<f64>::new(None, EstimatorOptions::default());
    /// let mut log = SliceLog::new(&mut []);
    /// let Reply::Error(e) = session.handle(&Message::Finish, &mut log) else {
    ///     unreachable!("a Finish before any Configure is refused")
    /// };
    /// let refusal = e.refusal(Message::Finish.tag());
    /// assert_eq!((refusal.message, refusal.reason), (7, RefusalReason::NotConfigured));
    /// ```
    pub fn refusal(&self, message: u8) -> Refusal {
        let reason = match *self {
            SessionError::NotConfigured => RefusalReason::NotConfigured,
            SessionError::ConfigMismatch { expected, found }
            | SessionError::Calibrator(calibrator::Error::ConfigMismatch { expected, found }) => {
                RefusalReason::ConfigMismatch { expected, found }
            }
            SessionError::Calibrator(calibrator::Error::ErrorModelMismatch { expected, found }) => {
                RefusalReason::ErrorModelMismatch { expected, found }
            }
            SessionError::Calibrator(calibrator::Error::CheckpointDimension) => {
                RefusalReason::CheckpointDimension
            }
            SessionError::Calibrator(calibrator::Error::CheckpointInvalid) => {
                RefusalReason::CheckpointInvalid
            }
            SessionError::Calibrator(calibrator::Error::Filter(e)) => RefusalReason::Filter(e),
            SessionError::Calibrator(calibrator::Error::InvalidField(field)) => {
                RefusalReason::InvalidField(field)
            }
        };
        Refusal { message, reason }
    }
}

/// What a message did.
// A Checkpoint reply is ~3 KB (~12.5 KB with `full-model`); no heap to box it.
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
            expected,
            passes,
            stats: SessionStats::default(),
        }
    }

    /// [`Session::new`] written at `p`, field by field (no session-sized
    /// value on the stack: [`crate::device::DeviceCell`]).
    ///
    /// # Safety
    ///
    /// `p` is valid for writes and aligned; what it held is overwritten
    /// without being dropped.
    #[cfg(feature = "flash-log")]
    #[allow(unsafe_code)]
    pub(crate) unsafe fn init_at(
        p: *mut Self,
        expected: Option<ConfigId>,
        passes: EstimatorOptions,
    ) {
        use core::ptr::addr_of_mut;
        // SAFETY: the caller's; each field of `*p` is written once.
        unsafe {
            addr_of_mut!((*p).cal).write(None);
            addr_of_mut!((*p).expected).write(expected);
            addr_of_mut!((*p).passes).write(passes);
            addr_of_mut!((*p).stats).write(SessionStats::default());
        }
    }

    /// Back to [`Session::new`]`(expected, passes)`, in place: the
    /// calibrator dropped, the counters
    /// cleared (no session-sized value on the stack, as an assignment of
    /// a new session may make).
    pub fn clear(&mut self, expected: Option<ConfigId>, passes: EstimatorOptions) {
        self.cal = None;
        self.expected = expected;
        self.passes = passes;
        self.stats = SessionStats::default();
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
}
