//! The integration kit: a calibrator [`Device`] a firmware drives with the
//! bytes it receives, that hands back the bytes to send, keeps the sample
//! log in a region of any `embedded-storage` [`NorFlash`] and resumes after
//! a reset from what the flash kept (feature `flash-log`).
//!
//! What the firmware writes is its HAL: the UART (or any byte link) and the
//! flash driver. The device does the rest:
//!
//! | the firmware calls | the device |
//! |---|---|
//! | [`DeviceCell::take`] once | the device, in a `static`, built in place (no stack copy, no `unsafe` in the firmware) |
//! | [`Device::start`]`(flash, region)` at boot | opens the flash region, resumes the configuration, the last checkpoint and the samples logged after it |
//! | [`Device::push_byte`] per received byte | decodes frames, acts on them ([`crate::session`]), returns the reply's bytes |
//! | [`Device::idle`] when idle (once a period) | erases ahead of need, writes the due checkpoint: one erase or one record a call |
//!
//! # Flash region
//!
//! The region (whole erase sectors) holds two banks of control records
//! (the `Configure` and the last checkpoint, [`control`]) and then the
//! sample log ([`FlashLog`]): with 4 KiB sectors and the full model,
//! 2 × 16 KiB of control and, for the paper's 5 400 periods of M2-ps,
//! 280 KiB of log ([`Device::region_len`] gives the size a run needs).
//!
//! # When the flash is written and erased
//!
//! - A `Sample` writes one log record (one `write`).
//! - A `Configure` or `Reset` writes a control record with the
//!   configuration (and no checkpoint) at once: in the bank
//!   [`Device::idle`] erased, or, if it was not called since the last
//!   record, after erasing that bank there.
//! - A checkpoint becomes due after the run's first sample, every
//!   [`Device::checkpoint_every`] samples and after a restore; the next
//!   [`Device::idle`] writes it (a control record: the configuration and
//!   the checkpoint, ≈ 13 KB for the full model).
//! - Erases happen in [`Device::idle`] (one sector a call), except the one a
//!   new run's first sample makes (the log's first sector still holds the
//!   previous run's records until then) and the bank a `Configure` needs
//!   when `idle` did not erase it.
//!
//! # After a reset
//!
//! [`Device::start`] reads the newest complete control record: it
//! configures the session from its `Configure`, restores its checkpoint,
//! and runs the filter over the log's records after it
//! ([`crate::calibrator::Calibrator::replay_log`]); the host's next sample
//! continues the run (a sample lost in the reset is a gap the calibrator
//! bridges). A record of another format version, a `Configure` of another
//! protocol version or of a model this build does not hold, or a log of
//! another run is recognised and not resumed from ([`Resume::refused`]).
//!
//! # Examples
//!
//! The whole integration (a RAM stand-in for the HAL's flash, bytes from
//! a recorded stream for the UART): see `examples/device.rs`.
//!
//! ```
//! # use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
//! # struct Ram(Vec<u8>);
//! # impl ErrorType for Ram { type Error = NorFlashErrorKind; }
//! # impl ReadNorFlash for Ram {
//! #     const READ_SIZE: usize = 1;
//! #     fn read(&mut self, o: u32, b: &mut [u8]) -> Result<(), Self::Error> {
//! #         b.copy_from_slice(self.0.get(o as usize..o as usize + b.len()).ok_or(NorFlashErrorKind::OutOfBounds)?);
//! #         Ok(())
//! #     }
//! #     fn capacity(&self) -> usize { self.0.len() }
//! # }
//! # impl NorFlash for Ram {
//! #     const WRITE_SIZE: usize = 4;
//! #     const ERASE_SIZE: usize = 4096;
//! #     fn erase(&mut self, f: u32, t: u32) -> Result<(), Self::Error> { self.0[f as usize..t as usize].fill(0xFF); Ok(()) }
//! #     fn write(&mut self, o: u32, b: &[u8]) -> Result<(), Self::Error> { self.0[o as usize..o as usize + b.len()].copy_from_slice(b); Ok(()) }
//! # }
//! use rollcal::device::{DeviceCell, Idle};
//! use rollcal::models::ConfigId;
//! use rollcal::wire::{encode, CalibratorConfig, Message};
//!
//! static DEVICE: DeviceCell<Ram, f64> = DeviceCell::new();
//!
//! let device = DEVICE.take().expect("taken once");
//! let flash = Ram(vec![0xFF; 512 * 1024]);
//! let resume = device.start(flash, 0..512 * 1024).map_err(|(_, e)| e)?;
//! assert_eq!(resume.config, None); // an empty flash: nothing to resume
//!
//! // The host configures it (the bytes a UART would deliver).
//! let mut frame = [0u8; 512];
//! let n = encode(&Message::Configure(CalibratorConfig::paper(ConfigId::M2Ps)), &mut frame)?;
//! for &b in &frame[..n] {
//!     assert!(device.push_byte(b).is_empty()); // no reply to a Configure
//! }
//! while device.idle() != Idle::Nothing {} // erase ahead
//! assert_eq!(device.session().calibrator().map(|c| c.settings().config), Some(ConfigId::M2Ps));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod cell;
pub mod control;

use core::ops::Range;

use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};
use nalgebra::RealField;

pub use cell::DeviceCell;

use crate::estimator::{EstimatorOptions, FlashLog, LogError, LogRecord, PackedLayout, SampleLog};
use crate::models::{ConfigId, ErrorModel};
use crate::session::{message_slot, Reply, Request, Session, SessionError};
use crate::wire::{
    decode_frame_into, encode, encode_refusal, CalibratorConfig, Decoder, FrameError, Message,
    MAX_FRAME_LEN,
};
use control::{bank_len, Header, Read, CONFIG_FRAME_MAX, HEADER, MAX_ALIGN};

/// Bytes of the device's frame buffer: a frame of the largest message the
/// build holds, and room to pad it to a flash write. One buffer receives a
/// frame and then holds the reply's bytes (returned by
/// [`Device::push_byte`], sent before the next byte arrives) and the flash
/// records.
pub const OUT_LEN: usize = MAX_FRAME_LEN + MAX_ALIGN;

/// The default [`Device::checkpoint_every`]: samples between checkpoints
/// (5 minutes of 1 s periods; at most that many samples are replayed after
/// a reset).
pub const DEFAULT_CHECKPOINT_EVERY: u32 = 300;

/// Why [`Device::start`] could not use the flash (it is given back).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum DeviceError {
    /// The region is not whole erase sectors, is past the device's
    /// capacity, or has no room for the control banks and one sector of
    /// log.
    Region,
    /// The device's write or read size does not divide
    /// [`control::MAX_ALIGN`] bytes, or its sizes do not fit the log
    /// ([`crate::estimator::FlashLogError::Geometry`]).
    Geometry,
    /// The device failed while it was read.
    Flash(NorFlashErrorKind),
}

impl core::fmt::Display for DeviceError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DeviceError::Region => f.write_str(
                "flash region is not whole sectors, is out of the device or too small for the control banks and the log",
            ),
            DeviceError::Geometry => {
                f.write_str("flash device's write, read or erase size does not fit the device")
            }
            DeviceError::Flash(k) => write!(f, "flash device failed: {k}"),
        }
    }
}

impl core::error::Error for DeviceError {}

/// Why what the flash held was not (wholly) resumed from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ResumeRefusal {
    /// A control record of another format version (the number).
    Format(u8),
    /// A stored frame does not decode (another protocol version, or
    /// damaged).
    Frame(FrameError),
    /// A stored frame is not the message it should be.
    Unexpected,
    /// The session refused the stored `Configure` or checkpoint (a model
    /// this build does not hold, another model's checkpoint, …).
    Session(SessionError),
    /// The sample log is not the checkpoint's run (another epoch, or fewer
    /// records than it counts): the checkpoint is restored, the final
    /// answer is a single pass.
    LogOfAnotherRun,
}

impl core::fmt::Display for ResumeRefusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ResumeRefusal::Format(v) => write!(
                f,
                "the flash holds control records of format {v}, this build reads {}",
                control::FORMAT
            ),
            ResumeRefusal::Frame(e) => write!(f, "a stored frame does not decode: {e}"),
            ResumeRefusal::Unexpected => f.write_str("a stored frame is not the expected message"),
            ResumeRefusal::Session(e) => write!(f, "the stored configuration was refused: {e}"),
            ResumeRefusal::LogOfAnotherRun => {
                f.write_str("the sample log is not the stored checkpoint's run")
            }
        }
    }
}

impl core::error::Error for ResumeRefusal {}

/// What [`Device::start`] resumed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Resume {
    /// The configuration resumed (`None`: nothing stored, or refused).
    pub config: Option<(ConfigId, ErrorModel)>,
    /// The samples the restored checkpoint counted (`None`: no checkpoint;
    /// the calibrator starts from the prior).
    pub checkpoint: Option<u32>,
    /// The log's records after the checkpoint, run through the filter again.
    pub replayed: u32,
    /// The last sample's sequence number after the resume (the host's next
    /// one continues it).
    pub last_seq: Option<u32>,
    /// Why the flash's records were not (wholly) resumed from.
    pub refused: Option<ResumeRefusal>,
}

/// What one [`Device::idle`] call did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Idle {
    /// Nothing to do.
    Nothing,
    /// Erased one sector (of the log or of a control bank).
    Erased,
    /// Wrote the due checkpoint.
    Checkpointed,
    /// The flash failed ([`DeviceStats::last_flash_error`]).
    Failed,
}

/// The device's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceStats {
    /// Messages decoded and acted on.
    pub messages: u32,
    /// Frames sent (their bytes returned by [`Device::push_byte`]).
    pub sent: u32,
    /// Control records written (configurations and checkpoints).
    pub records: u32,
    /// Of those, with a checkpoint.
    pub checkpoints: u32,
    /// Sectors erased by [`Device::idle`] and by a `Configure`.
    pub erases: u32,
    /// Flash operations of the control records or of `idle` that failed.
    pub flash_errors: u32,
    /// The last such failure.
    pub last_flash_error: Option<NorFlashErrorKind>,
}

/// Functions the device calls around its work, for a firmware that times
/// it or adjusts a configuration ([`Device::set_hooks`]). Each defaults to
/// doing nothing.
#[derive(Clone, Copy, Debug)]
pub struct Hooks {
    /// Before a `Sample` is acted on (one filter period and its log record).
    pub before_sample: fn(),
    /// After it.
    pub after_sample: fn(),
    /// Before a `Finish` is acted on (the estimator of record).
    pub before_finish: fn(),
    /// After it.
    pub after_finish: fn(),
    /// A received `Configure`'s settings, before the session acts on them:
    /// a firmware that forces some of its own (filter options, the estimate
    /// cadence) changes them here.
    pub configure: fn(&mut CalibratorConfig),
}

impl Hooks {
    /// Hooks that do nothing.
    pub const NONE: Hooks = Hooks {
        before_sample: nothing,
        after_sample: nothing,
        before_finish: nothing,
        after_finish: nothing,
        configure: keep,
    };
}

impl Default for Hooks {
    fn default() -> Self {
        Self::NONE
    }
}

fn nothing() {}

fn keep(_: &mut CalibratorConfig) {}

/// The sample log in flash, the control banks, and what is due.
struct Store<F, T: RealField + Copy> {
    log: FlashLog<F, T>,
    /// The region's start (bank 0; bank 1 follows it).
    base: u32,
    /// Bytes of a bank.
    bank: u32,
    /// The bank of the newest record (`None`: none).
    active: Option<u32>,
    /// The newest record's generation.
    generation: u32,
    /// Sectors of the spare bank erased so far (from its start).
    spare_erased: u32,
    /// The log's epoch and count of the stored checkpoint.
    stored: Option<(u32, u32)>,
    /// A checkpoint is to be written at the next `idle`.
    due: bool,
}

/// A log that holds nothing: the session's log before [`Device::start`]
/// (every sample is then a single-pass run).
struct NoLog;

impl<T: RealField + Copy> SampleLog<T> for NoLog {
    fn append(&mut self, _: &LogRecord<T>) -> Result<(), LogError> {
        Err(LogError::Storage)
    }
    fn len(&self) -> usize {
        0
    }
    fn get(&mut self, _: usize) -> Option<LogRecord<T>> {
        None
    }
    fn truncate(&mut self, _: usize) {}
}

/// The calibrator device (see the [module docs](self)): a session, the
/// frame decoder, the reply buffer and the sample log in flash. `F` is the
/// HAL's flash driver, `T` the estimator's scalar (`f32` on a single
/// precision FPU, `f64` on a Cortex-M7).
///
/// Its size is the session's (its calibrator: `Finish` runs in the
/// calibrator's own filter, the running one kept meanwhile in the message
/// slot), one frame buffer and one message slot of the build's largest
/// model: 87.3 KB in `f64` and 58.8 KB in `f32` with the full model's 54
/// states (`cargo test --release -p rollcal --test it device:: --
/// --nocapture` prints it); keep it in a [`DeviceCell`].
pub struct Device<F, T: RealField + Copy> {
    session: Session<T>,
    /// Its buffer also holds the reply's bytes and the flash records
    /// between frames ([`Decoder::spare_buffer`]).
    decoder: Decoder<OUT_LEN>,
    /// The message received (`Reply::Send(message)`, as the decoder wrote
    /// it), then the session's reply to it
    /// ([`Session::handle_in_place`]), and the flash records' messages.
    slot: Reply,
    store: Option<Store<F, T>>,
    checkpoint_every: u32,
    hooks: Hooks,
    /// The tag of the last message acted on.
    last_tag: Option<u8>,
    stats: DeviceStats,
}

impl<F: NorFlash, T: RealField + Copy> Default for Device<F, T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<F: NorFlash, T: RealField + Copy> Device<F, T> {
    /// A device without flash (by value: on a firmware, use
    /// [`DeviceCell`], which builds it in place).
    pub fn new() -> Self {
        Self {
            session: Session::new(None, EstimatorOptions::default()),
            decoder: Decoder::new(),
            slot: Reply::Nothing,
            store: None,
            checkpoint_every: DEFAULT_CHECKPOINT_EVERY,
            hooks: Hooks::NONE,
            last_tag: None,
            stats: DeviceStats::default(),
        }
    }

    /// Bytes of flash a region needs for the control banks and `periods`
    /// periods of `config`'s log on a device `F`.
    ///
    /// ```
    /// # use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
    /// # struct Nor;
    /// # impl ErrorType for Nor { type Error = NorFlashErrorKind; }
    /// # impl ReadNorFlash for Nor {
    /// #     const READ_SIZE: usize = 1;
    /// #     fn read(&mut self, _: u32, _: &mut [u8]) -> Result<(), Self::Error> { Ok(()) }
    /// #     fn capacity(&self) -> usize { 1 << 24 }
    /// # }
    /// # impl NorFlash for Nor {
    /// #     const WRITE_SIZE: usize = 4;
    /// #     const ERASE_SIZE: usize = 4096;
    /// #     fn erase(&mut self, _: u32, _: u32) -> Result<(), Self::Error> { Ok(()) }
    /// #     fn write(&mut self, _: u32, _: &[u8]) -> Result<(), Self::Error> { Ok(()) }
    /// # }
    /// use rollcal::device::Device;
    /// use rollcal::models::{ConfigId, ErrorModel};
    ///
    /// // The paper's 5 400 periods of M2-ps, with the full model's checkpoints.
    /// let n = Device::<Nor, f64>::region_len(ConfigId::M2Ps, ErrorModel::Full, 5400);
    /// assert_eq!(n % 4096, 0);
    /// assert!(n > 280 * 1024);
    /// ```
    pub fn region_len(config: ConfigId, errors: ErrorModel, periods: u32) -> usize {
        let erase = F::ERASE_SIZE.max(1);
        let layout = PackedLayout::for_measurements(config.layout_with(errors).z());
        let slot = FlashLog::<F, T>::slot_len_of(layout).max(1);
        let per_sector = (erase / slot).max(1);
        let sectors = (periods as usize).div_ceil(per_sector);
        2 * bank_len(erase) + sectors.saturating_add(1) * erase
    }

    /// Opens `region` of `flash` (whole erase sectors: the control banks,
    /// then the sample log) and resumes what it holds: the stored
    /// configuration, its checkpoint and the samples logged after it. An
    /// empty or unusable record leaves the session unconfigured (the host's
    /// `Configure` starts a run). Call it once at boot, before any byte.
    ///
    /// # Errors
    ///
    /// The device is given back with [`DeviceError`] when the region or the
    /// device's sizes do not fit, or it cannot be read.
    #[allow(clippy::result_large_err)]
    #[inline(never)]
    pub fn start(&mut self, flash: F, region: Range<u32>) -> Result<Resume, (F, DeviceError)> {
        let erase = F::ERASE_SIZE;
        let (w, r) = (F::WRITE_SIZE.max(1), F::READ_SIZE.max(1));
        if !MAX_ALIGN.is_multiple_of(w) || !MAX_ALIGN.is_multiple_of(r) {
            return Err((flash, DeviceError::Geometry));
        }
        let Ok(bank) = u32::try_from(bank_len(erase)) else {
            return Err((flash, DeviceError::Region));
        };
        let log_start = bank
            .checked_mul(2)
            .and_then(|b| b.checked_add(region.start))
            .filter(|s| *s < region.end && bank > 0);
        let Some(log_start) = log_start else {
            return Err((flash, DeviceError::Region));
        };
        let log_region = log_start..region.end;
        let mut flash = flash;
        let (newest, other_format) = match newest_record(&mut flash, region.start, bank) {
            Ok(found) => found,
            Err(e) => return Err((flash, e)),
        };
        // The larger layout's slots must fit too (a `Configure` may ask
        // for it later).
        let flash = match FlashLog::<F, T>::open_or_return(
            flash,
            log_region.clone(),
            PackedLayout::AccelGimbal,
        ) {
            Ok(log) => log.into_inner(),
            Err((flash, e)) => return Err((flash, e.into())),
        };
        let log = match FlashLog::<F, T>::open_or_return(
            flash,
            log_region.clone(),
            PackedLayout::Accel,
        ) {
            Ok(log) => log,
            Err((flash, e)) => return Err((flash, e.into())),
        };
        self.store = Some(Store {
            log,
            base: region.start,
            bank,
            active: None,
            generation: 0,
            spare_erased: 0,
            stored: None,
            due: false,
        });
        // What a reset leaves: no calibrator, no partial frame.
        self.session.clear(None, EstimatorOptions::default());
        self.decoder.clear();
        self.last_tag = None;
        self.stats = DeviceStats::default();
        let mut resume = Resume {
            refused: other_format.map(ResumeRefusal::Format),
            ..Resume::default()
        };
        if let Some((bank, header)) = newest {
            self.resume(bank, &header, &mut resume);
        }
        Ok(resume)
    }

    /// The session (its calibrator and counters).
    pub fn session(&self) -> &Session<T> {
        &self.session
    }

    /// The sample log, once [`Device::start`] has opened it.
    pub fn log(&self) -> Option<&FlashLog<F, T>> {
        self.store.as_ref().map(|s| &s.log)
    }

    /// The frame decoder (its counts of frames and of rejected ones).
    pub fn decoder(&self) -> &Decoder<OUT_LEN> {
        &self.decoder
    }

    /// The device's counters.
    pub fn stats(&self) -> &DeviceStats {
        &self.stats
    }

    /// Samples between checkpoints (default [`DEFAULT_CHECKPOINT_EVERY`]).
    pub fn checkpoint_every(&self) -> u32 {
        self.checkpoint_every
    }

    /// Sets [`Device::checkpoint_every`] (at least 1).
    pub fn set_checkpoint_every(&mut self, samples: u32) {
        self.checkpoint_every = samples.max(1);
    }

    /// Sets the functions called around the device's work ([`Hooks`]).
    pub fn set_hooks(&mut self, hooks: Hooks) {
        self.hooks = hooks;
    }

    /// What the session answered to the last message (a reply to send, a
    /// rejected sample and why, a refusal, or nothing): for a firmware that
    /// logs or counts what happened. Read it before the next byte (the
    /// device's one message slot then takes the next message) or
    /// [`Device::idle`] (a record written leaves it [`Reply::Nothing`]).
    pub fn reply(&self) -> &Reply {
        &self.slot
    }

    /// The tag ([`Message::tag`]: `Sample` 0 … `Finish` 7) of the last
    /// message the device acted on; with [`Device::reply`] and
    /// [`DeviceStats::messages`], what a firmware logs of each.
    pub fn last_tag(&self) -> Option<u8> {
        self.last_tag
    }

    /// The flash, given back (the device then logs nothing).
    pub fn release(&mut self) -> Option<F> {
        self.store.take().map(|s| s.log.into_inner())
    }

    /// One received byte. Returns the bytes to send back (a whole frame,
    /// its delimiter included), empty when there is nothing to send: most
    /// bytes, a `Sample` between estimates, a `Configure`. Send them before
    /// the next call (they live in the device's buffer).
    pub fn push_byte(&mut self, byte: u8) -> &[u8] {
        let slot = &mut self.slot;
        // Decoded into the slot at the delimiter (the slot is untouched by
        // the other bytes: it holds the last reply until then).
        let decoded = self.decoder.push_byte_with(byte, |frame| {
            // The buffer has room for padding: a longer frame is as
            // oversized as one past the buffer.
            if frame.len() > MAX_FRAME_LEN {
                return Err(FrameError::Oversized);
            }
            match message_slot(slot) {
                Some(msg) => decode_frame_into(frame, msg),
                None => Err(FrameError::Malformed),
            }
        });
        let n = match decoded {
            None => 0,
            Some(Ok(())) => self.act(),
            Some(Err(_)) => {
                self.tell_frame_errors();
                0
            }
        };
        match self.decoder.spare_buffer() {
            Some(out) => out.get(..n).unwrap_or(&[]),
            None => &[],
        }
    }

    /// Received bytes (a DMA buffer): [`Device::push_byte`] of each, `send`
    /// called with every reply.
    pub fn push_bytes(&mut self, bytes: &[u8], mut send: impl FnMut(&[u8])) {
        for &b in bytes {
            let reply = self.push_byte(b);
            if !reply.is_empty() {
                send(reply);
            }
        }
    }

    /// Work for an idle moment, at most one flash erase or one control
    /// record a call: the sector after the log's head, the spare control
    /// bank, the due checkpoint. Call it between periods (once a period is
    /// enough) so that no erase falls inside one.
    pub fn idle(&mut self) -> Idle {
        let Some(store) = self.store.as_mut() else {
            return Idle::Nothing;
        };
        // The log's next sector first: a sample may need it next.
        match store.log.erase_ahead() {
            Ok(true) => {
                self.stats.erases = self.stats.erases.saturating_add(1);
                return Idle::Erased;
            }
            Ok(false) => {}
            Err(_) => {
                let e = store.log.last_error();
                return self.failed(e);
            }
        }
        match self.erase_spare_sector() {
            Ok(true) => return Idle::Erased,
            Ok(false) => {}
            Err(e) => return self.failed(Some(e)),
        }
        if self.store.as_ref().is_some_and(|s| s.due) {
            return match self.write_record(true) {
                Ok(()) => Idle::Checkpointed,
                // A frame is arriving in the buffer the record is
                // encoded in: at the next `idle`.
                Err(RecordError::Busy) => Idle::Nothing,
                Err(e) => self.failed(e.flash()),
            };
        }
        Idle::Nothing
    }

    fn failed(&mut self, e: Option<NorFlashErrorKind>) -> Idle {
        self.stats.flash_errors = self.stats.flash_errors.saturating_add(1);
        self.stats.last_flash_error = e.or(self.stats.last_flash_error);
        Idle::Failed
    }

    /// Acts on the decoded message in `self.message`; returns the bytes of
    /// the reply in `self.out`.
    #[inline(never)]
    fn act(&mut self) -> usize {
        let Reply::Send(msg) = &mut self.slot else {
            return 0;
        };
        let tag = msg.tag();
        let kind = Kind::of(msg);
        if let Message::Configure(settings) = msg {
            (self.hooks.configure)(settings);
        }
        self.last_tag = Some(tag);
        self.stats.messages = self.stats.messages.saturating_add(1);
        let log: &mut dyn SampleLog<T> = match &mut self.store {
            Some(s) => &mut s.log,
            None => &mut NoLog,
        };
        let (before, after) = match kind {
            Kind::Sample => (self.hooks.before_sample, self.hooks.after_sample),
            Kind::Finish => (self.hooks.before_finish, self.hooks.after_finish),
            _ => (nothing as fn(), nothing as fn()),
        };
        before();
        self.session.handle_in_place(&mut self.slot, log);
        after();
        let acted = !matches!(self.slot, Reply::Error(_));
        match kind {
            Kind::Configure if acted => self.configured(),
            Kind::Reset if acted => self.record_now(),
            Kind::Restore if acted => {
                self.tell_frame_errors();
                if let Some(s) = self.store.as_mut() {
                    s.due = true;
                }
            }
            Kind::Sample => self.after_sample(),
            _ => {}
        }
        self.encode_reply(tag)
    }

    /// After a `Configure`: the log in its layout, the configuration
    /// recorded.
    // Out of line: its frame is not on the path of a period or `Finish`.
    #[inline(never)]
    fn configured(&mut self) {
        self.tell_frame_errors();
        let Some(settings) = self.session.calibrator().map(|c| *c.settings()) else {
            return;
        };
        self.use_layout(&settings);
        self.record_now();
    }

    /// A control record with the configuration only, now (a `Configure` or
    /// `Reset`: a stored checkpoint is no longer the run's).
    // Out of line: its frame is not on the path of a period or `Finish`.
    #[inline(never)]
    fn record_now(&mut self) {
        if self.store.is_none() {
            return;
        }
        loop {
            match self.erase_spare_sector() {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => {
                    self.failed(Some(e));
                    return;
                }
            }
        }
        if let Err(e) = self.write_record(false) {
            self.failed(e.flash());
        }
    }

    /// After a `Sample`: whether a checkpoint is due.
    // Out of line: its frame is not on the path of a period or `Finish`.
    #[inline(never)]
    fn after_sample(&mut self) {
        let Some(p) = self.session.calibrator().map(|c| *c.progress()) else {
            return;
        };
        let every = self.checkpoint_every;
        let Some(s) = self.store.as_mut() else {
            return;
        };
        if p.log_incomplete.is_some() || p.logged == 0 {
            return;
        }
        let epoch = s.log.epoch();
        s.due |= match s.stored {
            Some((e, logged)) if e == epoch => p.logged.saturating_sub(logged) >= every,
            _ => true,
        };
    }

    /// Encodes what the session answered into `self.out`; its length.
    // Out of line: its frame is not on the path of a period or `Finish`.
    #[inline(never)]
    fn encode_reply(&mut self, tag: u8) -> usize {
        let Some(out) = self.decoder.spare_buffer() else {
            return 0;
        };
        let sent = match &self.slot {
            Reply::Send(m) => encode(m, out).ok(),
            // The slot keeps the error ([`Device::reply`]).
            Reply::Error(e) => encode_refusal(&e.refusal(tag), out).ok(),
            Reply::Nothing | Reply::Rejected(_) => None,
        };
        match sent {
            Some(n) => {
                self.stats.sent = self.stats.sent.saturating_add(1);
                n
            }
            None => 0,
        }
    }

    fn tell_frame_errors(&mut self) {
        let n = self.decoder.stats().errors();
        if let Some(c) = self.session.calibrator_mut() {
            c.set_frame_errors(n);
        }
    }

    /// Erases the spare bank's next sector if it is not erased yet.
    // Out of line: its frame is not on the path of a period or `Finish`.
    #[inline(never)]
    fn erase_spare_sector(&mut self) -> Result<bool, NorFlashErrorKind> {
        let Some(s) = self.store.as_mut() else {
            return Ok(false);
        };
        let erase = u32::try_from(F::ERASE_SIZE).unwrap_or(u32::MAX);
        if s.spare_erased.saturating_mul(erase) >= s.bank {
            return Ok(false);
        }
        let from = s.spare_start() + s.spare_erased * erase;
        s.log
            .flash_mut()
            .erase(from, from + erase)
            .map_err(|e| e.kind())?;
        s.spare_erased += 1;
        self.stats.erases = self.stats.erases.saturating_add(1);
        Ok(true)
    }

    /// Writes a control record (the configuration, and the checkpoint when
    /// `checkpoint`) into the spare bank, which must be erased. The slot,
    /// whose message the record's were, is left [`Reply::Nothing`] (a
    /// record follows a `Configure` or `Reset` that answered nothing, or
    /// an answer already sent).
    // Out of line: its frame is not on the path of a period or `Finish`.
    #[inline(never)]
    fn write_record(&mut self, checkpoint: bool) -> Result<(), RecordError> {
        let written = self.write_record_via_slot(checkpoint);
        self.slot = Reply::Nothing;
        written
    }

    /// [`Device::write_record`], the slot holding its messages.
    fn write_record_via_slot(&mut self, checkpoint: bool) -> Result<(), RecordError> {
        let Some(settings) = self.session.calibrator().map(|c| *c.settings()) else {
            if let Some(s) = self.store.as_mut() {
                s.due = false;
            }
            return Ok(());
        };
        let Some(s) = self.store.as_mut() else {
            return Ok(());
        };
        let erase = u32::try_from(F::ERASE_SIZE).unwrap_or(u32::MAX);
        if s.spare_erased.saturating_mul(erase) < s.bank {
            return Err(RecordError::NotErased);
        }
        let Some(out) = self.decoder.spare_buffer() else {
            return Err(RecordError::Busy);
        };
        let at = s.spare_start();
        let msg = message_slot(&mut self.slot).ok_or(RecordError::Encode)?;
        *msg = Message::Configure(settings);
        let config_len = encode(msg, out)
            .ok()
            .filter(|n| *n <= CONFIG_FRAME_MAX)
            .ok_or(RecordError::Encode)?;
        write_padded::<F>(s.log.flash_mut(), at + HEADER as u32, out, config_len)?;
        let mut header = Header {
            generation: s.generation.wrapping_add(1),
            config_len: config_len as u32,
            ..Header::default()
        };
        if checkpoint {
            self.session
                .request_into(Request::Checkpoint, &mut s.log, &mut self.slot);
            let Reply::Send(cp) = &self.slot else {
                return Err(RecordError::Encode);
            };
            let n = encode(cp, out).map_err(|_| RecordError::Encode)?;
            let cp_at = at + (HEADER + CONFIG_FRAME_MAX) as u32;
            write_padded::<F>(s.log.flash_mut(), cp_at, out, n)?;
            let logged = self.session.calibrator().map_or(0, |c| c.progress().logged);
            header.checkpoint_len = n as u32;
            header.epoch = s.log.epoch();
            header.logged = logged;
        }
        s.log
            .flash_mut()
            .write(at, &header.to_bytes())
            .map_err(|e| RecordError::Flash(e.kind()))?;
        // The new record is complete: the other bank is the spare now.
        s.active = Some(s.spare_index());
        s.generation = header.generation;
        s.spare_erased = 0;
        s.stored = checkpoint.then_some((header.epoch, header.logged));
        s.due = false;
        self.stats.records = self.stats.records.saturating_add(1);
        if checkpoint {
            self.stats.checkpoints = self.stats.checkpoints.saturating_add(1);
        }
        Ok(())
    }

    /// [`Device::start`]'s resume from the record in `bank`.
    // Out of line: its frame is not on the path of a period or `Finish`.
    #[inline(never)]
    fn resume(&mut self, bank: u32, header: &Header, resume: &mut Resume) {
        let Some(s) = self.store.as_mut() else {
            return;
        };
        resume.refused = None;
        s.active = Some(bank);
        s.generation = header.generation;
        let at = s.base + bank * s.bank;
        // The configuration.
        if let Err(why) = self.read_frame(at + HEADER as u32, header.config_len) {
            resume.refused = Some(why);
            return;
        }
        let Reply::Send(Message::Configure(settings)) = self.slot else {
            resume.refused = Some(ResumeRefusal::Unexpected);
            return;
        };
        if let Err(e) = self.session.configure(settings) {
            resume.refused = Some(ResumeRefusal::Session(e));
            return;
        }
        self.use_layout(&settings);
        resume.config = Some((settings.config, settings.errors));
        if header.checkpoint_len == 0 {
            return;
        }
        // The checkpoint, and the records after it.
        let cp_at = at + (HEADER + CONFIG_FRAME_MAX) as u32;
        if let Err(why) = self.read_frame(cp_at, header.checkpoint_len) {
            resume.refused = Some(why);
            return;
        }
        if !matches!(self.slot, Reply::Send(Message::Checkpoint(_))) {
            resume.refused = Some(ResumeRefusal::Unexpected);
            return;
        }
        let Some(s) = self.store.as_mut() else {
            return;
        };
        let log_is_the_runs =
            s.log.epoch() == header.epoch && s.log.len() >= header.logged as usize;
        if !log_is_the_runs {
            // Another run's records: not this checkpoint's to continue.
            s.log.truncate(0);
            resume.refused = Some(ResumeRefusal::LogOfAnotherRun);
        }
        // The restore alone (what the session does with a `Checkpoint`).
        let restored = match &self.slot {
            Reply::Send(Message::Checkpoint(cp)) => self.session.restore(cp),
            _ => Err(SessionError::NotConfigured),
        };
        if let Err(e) = restored {
            resume.refused = Some(ResumeRefusal::Session(e));
            return;
        }
        resume.checkpoint = Some(header.logged);
        s.stored = Some((header.epoch, header.logged));
        if log_is_the_runs {
            if let Some(c) = self.session.calibrator_mut() {
                resume.replayed = c.replay_log(&mut s.log);
            }
        }
        resume.last_seq = self
            .session
            .calibrator()
            .and_then(|c| c.progress().last_seq);
        self.tell_frame_errors();
    }

    /// The log read in the layout of `settings` (reopened in place if it
    /// is read in another; a device that fails then leaves it empty).
    fn use_layout(&mut self, settings: &CalibratorConfig) {
        let layout =
            PackedLayout::for_measurements(settings.config.layout_with(settings.errors).z());
        let Some(s) = self.store.as_mut() else {
            return;
        };
        if s.log.layout() != layout && s.log.reopen(layout).is_err() {
            let e = s.log.last_error();
            self.failed(e);
        }
    }

    /// Reads the frame of `len` bytes at `at` and decodes it into the slot
    /// (`Reply::Send(message)`).
    fn read_frame(&mut self, at: u32, len: u32) -> Result<(), ResumeRefusal> {
        let Some(s) = self.store.as_mut() else {
            return Err(ResumeRefusal::Unexpected);
        };
        let r = F::READ_SIZE.max(1);
        let n = len as usize;
        let padded = n.div_ceil(r) * r;
        let out = self
            .decoder
            .spare_buffer()
            .ok_or(ResumeRefusal::Unexpected)?;
        let Some(buf) = out.get_mut(..padded).filter(|_| n >= 1) else {
            return Err(ResumeRefusal::Frame(FrameError::Oversized));
        };
        s.log
            .flash_mut()
            .read(at, buf)
            .map_err(|_| ResumeRefusal::Frame(FrameError::Truncated))?;
        // The frame without its delimiter.
        let body = out.get_mut(..n - 1).unwrap_or(&mut []);
        let msg = message_slot(&mut self.slot).ok_or(ResumeRefusal::Unexpected)?;
        decode_frame_into(body, msg).map_err(ResumeRefusal::Frame)
    }
}

/// Writes `buf[..n]`, padded with `0xFF` to the device's write size, at
/// `at`.
fn write_padded<F: NorFlash>(
    flash: &mut F,
    at: u32,
    buf: &mut [u8],
    n: usize,
) -> Result<(), RecordError> {
    let w = F::WRITE_SIZE.max(1);
    let padded = n.div_ceil(w) * w;
    let bytes = buf.get_mut(..padded).ok_or(RecordError::Encode)?;
    if let Some(pad) = bytes.get_mut(n..) {
        pad.fill(0xFF);
    }
    flash
        .write(at, bytes)
        .map_err(|e| RecordError::Flash(e.kind()))
}

/// Why a control record was not written ([`Device::write_record`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum RecordError {
    /// The flash failed.
    Flash(NorFlashErrorKind),
    /// The spare bank is not erased yet.
    NotErased,
    /// The record's message did not encode (not reached: the buffer holds
    /// the largest frame).
    Encode,
    /// A frame is arriving in the buffer the record is encoded in.
    Busy,
}

impl RecordError {
    /// The flash's error, if it was one.
    fn flash(self) -> Option<NorFlashErrorKind> {
        match self {
            RecordError::Flash(e) => Some(e),
            _ => None,
        }
    }
}

impl<F: NorFlash, T: RealField + Copy> Store<F, T> {
    fn spare_index(&self) -> u32 {
        match self.active {
            Some(0) => 1,
            _ => 0,
        }
    }

    fn spare_start(&self) -> u32 {
        self.base + self.spare_index() * self.bank
    }
}

/// The newest record and its bank, and the format version of a record of
/// another one.
type Found = (Option<(u32, Header)>, Option<u8>);

/// The newest control record of the two banks at `base` (`bank` bytes
/// each) and its bank, and the format version of a record of another one.
fn newest_record<F: NorFlash>(flash: &mut F, base: u32, bank: u32) -> Result<Found, DeviceError> {
    let mut newest: Option<(u32, Header)> = None;
    let mut other = None;
    for b in 0..2u32 {
        let mut bytes = [0u8; HEADER];
        flash
            .read(base + b * bank, &mut bytes)
            .map_err(|e| DeviceError::Flash(e.kind()))?;
        match Header::parse(&bytes) {
            Read::Empty => {}
            Read::OtherFormat(v) => other = Some(v),
            Read::Valid(h) => {
                let newer = newest.is_none_or(|(_, n)| h.generation > n.generation);
                if newer {
                    newest = Some((b, h));
                }
            }
        }
    }
    Ok((newest, other.filter(|_| newest.is_none())))
}

/// What a message is, for what the device does after the session.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Configure,
    Reset,
    Restore,
    Sample,
    Finish,
    Other,
}

impl Kind {
    fn of(m: &Message) -> Self {
        match m {
            Message::Configure(_) => Kind::Configure,
            Message::Reset => Kind::Reset,
            Message::Checkpoint(_) => Kind::Restore,
            Message::Sample(_) => Kind::Sample,
            Message::Finish => Kind::Finish,
            _ => Kind::Other,
        }
    }
}

impl From<crate::estimator::FlashLogError> for DeviceError {
    fn from(e: crate::estimator::FlashLogError) -> Self {
        match e {
            crate::estimator::FlashLogError::Region => DeviceError::Region,
            crate::estimator::FlashLogError::Flash(k) => DeviceError::Flash(k),
            _ => DeviceError::Geometry,
        }
    }
}
