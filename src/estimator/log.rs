//! The sample log the multi-pass estimator replays: one [`LogRecord`] per
//! filter period, kept in storage the caller provides.
//!
//! The estimator reads the log, never owns it: [`SampleLog`] is the whole
//! interface (append, length, read record `k` by value), and [`SliceLog`]
//! implements it over a slice of records in RAM that the caller allocates
//! (a `static`, a stack array, or a `Vec` on a host).
//!
//! # Size
//!
//! The paper's run is 5400 periods. A record of `f64` is 88 bytes in RAM
//! (`size_of::<LogRecord<f64>>()`), 475 kB for the run; a record of `f32`
//! is 64 bytes, 346 kB (its period and increment stay `f64`, see
//! [`LogRecord`]). That is more RAM than most microcontrollers have,
//! hence the trait: the log can live in external flash or FRAM.
//!
//! # Backing the log with external flash or FRAM
//!
//! For NOR flash behind `embedded-storage`'s `NorFlash` (any HAL's),
//! `FlashLog` (feature `flash-log`, `estimator::flash`) does all of the
//! following with the packed records. Otherwise an integrator implements
//! [`SampleLog`] over the device as an array of fixed-size records:
//!
//! - **Fixed-size records.** Encode every record in the same number of
//!   bytes `SIZE` whether or not it holds a measurement: a flag byte
//!   (bit 0: measurement present, bit 1: gimbal angles present, bit 7: record
//!   committed), `dt`, `Δθc` (3), accelerometer mean (3) and gimbal angles
//!   (3), e.g. as little-endian `f32` (41 bytes, padded to 44 or 48). The
//!   wire protocol delivers `f32` ([`crate::wire::Sample`]), so an `f32`
//!   record stores exactly what the calibrator received; widen to `T` on
//!   read.
//! - **Address = base + k·SIZE.** Record `k` of the run is at a fixed
//!   address; [`SampleLog::get`] is one random read of `SIZE` bytes (the
//!   estimator reads each record once per pass forwards, and once more
//!   backwards between passes, i.e. in reverse address order).
//! - **Write-ahead on append.** [`SampleLog::append`] first programs the
//!   record's bytes at `base + len·SIZE`, then marks it committed (a last
//!   byte written after the data, or the flag's bit 7 cleared on NOR flash
//!   where programming only clears bits), and only then counts it in
//!   [`SampleLog::len`]. After a reset the length is recovered by scanning
//!   for the first uncommitted record, so a torn write loses at most the
//!   record being written. NOR flash must be erased before it is
//!   programmed: erase the whole region when a run starts (erasing is slow,
//!   do not erase sector by sector inside the filter period). FRAM needs no
//!   erase and no wear levelling at one write per second.
//! - **Read by index.** [`SampleLog::get`] returns `None` for `k ≥ len`,
//!   and also when the device fails or the record does not decode (the
//!   estimator then stops with [`super::EstimatorError::Read`] instead of
//!   using a corrupt period).
//! - **A log that cannot hold the whole run must say so.** When the region
//!   is full, `append` returns [`LogError::Full`] and stores nothing; a
//!   device error returns [`LogError::Storage`]. The estimator then sees
//!   only the records that were stored: the caller must treat a run whose
//!   log overflowed as truncated (report it, or size the region for the
//!   longest run: 5400 records of 48 bytes are 259 kB, which fits a 4 Mbit
//!   (512 kB) FRAM or any SPI NOR flash of 4 Mbit or more).
//!
//! A sketch over a byte-addressable FRAM (any `read(addr, buf)` /
//! `write(addr, bytes)` driver; here a RAM stand-in):
//!
//! ```
//! use nalgebra::Vector3;
//! use rollcal::ekf::Observation;
//! use rollcal::estimator::{LogError, LogRecord, SampleLog};
//!
//! const SIZE: usize = 64;
//!
//! /// Stand-in for an FRAM chip driver.
//! struct Fram([u8; 4 * SIZE]);
//!
//! struct FramLog {
//!     fram: Fram,
//!     base: usize,
//!     capacity: usize,
//!     len: usize,
//! }
//!
//! fn put(bytes: &mut [u8], at: usize, v: f32) {
//!     if let Some(dst) = bytes.get_mut(at..at + 4) {
//!         dst.copy_from_slice(&v.to_le_bytes());
//!     }
//! }
//!
//! fn take(bytes: &[u8], at: usize) -> Option<f32> {
//!     Some(f32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
//! }
//!
//! // The period and the commanded increment are f64 in every precision.
//! fn put64(bytes: &mut [u8], at: usize, v: f64) {
//!     if let Some(dst) = bytes.get_mut(at..at + 8) {
//!         dst.copy_from_slice(&v.to_le_bytes());
//!     }
//! }
//!
//! fn take64(bytes: &[u8], at: usize) -> Option<f64> {
//!     Some(f64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?))
//! }
//!
//! impl SampleLog<f32> for FramLog {
//!     fn append(&mut self, r: &LogRecord<f32>) -> Result<(), LogError> {
//!         if self.len >= self.capacity {
//!             return Err(LogError::Full);
//!         }
//!         let mut b = [0u8; SIZE];
//!         let obs = r.observation;
//!         let gimbal = obs.and_then(|o| o.gimbal);
//!         b[0] = u8::from(obs.is_some()) | (u8::from(gimbal.is_some()) << 1);
//!         put64(&mut b, 8, r.dt);
//!         let accel = obs.map_or(Vector3::zeros(), |o| o.accel_mean);
//!         let g = gimbal.unwrap_or_else(Vector3::zeros);
//!         for i in 0..3 {
//!             put64(&mut b, 16 + 8 * i, r.dtheta_cmd[i]);
//!             put(&mut b, 40 + 4 * i, accel[i]);
//!             put(&mut b, 52 + 4 * i, g[i]);
//!         }
//!         let at = self.base + self.len * SIZE;
//!         // Write-ahead: data first, then the commit flag, then the length.
//!         let dst = self.fram.0.get_mut(at..at + SIZE).ok_or(LogError::Storage)?;
//!         dst.copy_from_slice(&b);
//!         dst[0] |= 0x80;
//!         self.len += 1;
//!         Ok(())
//!     }
//!
//!     fn len(&self) -> usize {
//!         self.len
//!     }
//!
//!     fn truncate(&mut self, len: usize) {
//!         self.len = self.len.min(len);
//!     }
//!
//!     fn get(&mut self, k: usize) -> Option<LogRecord<f32>> {
//!         if k >= self.len {
//!             return None;
//!         }
//!         let at = self.base + k * SIZE;
//!         let b = self.fram.0.get(at..at + SIZE)?;
//!         if b[0] & 0x80 == 0 {
//!             return None; // not committed: torn write
//!         }
//!         let v = |at: usize| -> Option<Vector3<f32>> {
//!             Some(Vector3::new(take(b, at)?, take(b, at + 4)?, take(b, at + 8)?))
//!         };
//!         let observation = if b[0] & 1 != 0 {
//!             Some(Observation {
//!                 accel_mean: v(40)?,
//!                 gimbal: if b[0] & 2 != 0 { Some(v(52)?) } else { None },
//!             })
//!         } else {
//!             None
//!         };
//!         Some(LogRecord {
//!             dt: take64(b, 8)?,
//!             dtheta_cmd: Vector3::new(take64(b, 16)?, take64(b, 24)?, take64(b, 32)?),
//!             observation,
//!         })
//!     }
//! }
//!
//! let mut log = FramLog { fram: Fram([0; 4 * SIZE]), base: 0, capacity: 4, len: 0 };
//! let r = LogRecord::measured(
//!     1.0,
//!     Vector3::new(1e-3, 0.0, 0.0),
//!     Observation { accel_mean: Vector3::new(0.0, 1.0, 0.0), gimbal: None },
//! );
//! for _ in 0..4 {
//!     log.append(&r).unwrap();
//! }
//! assert_eq!(log.append(&r), Err(LogError::Full));
//! assert_eq!(log.get(3), Some(r));
//! ```

use nalgebra::{RealField, Vector3};

use crate::ekf::Observation;

/// One filter period as the estimator replays it.
///
/// A record with a measurement is one [`crate::ekf::Filter::step`]; a record
/// without one is a period that is only predicted
/// ([`crate::ekf::Filter::predict`]), e.g. a missing sample the calibrator
/// bridged: the platform still moved by `dtheta_cmd` over `dt`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogRecord<T: RealField + Copy> {
    /// Period length `T` (s), strictly positive. Double precision whatever
    /// `T`: the period drives the nominal trajectory ([`crate::ekf::Filter`]).
    pub dt: f64,
    /// Commanded angle increment `Δθc = ∫ωc dt` over the period (rad,
    /// components in the computed frame c). Double precision whatever `T`:
    /// f32's rounding of an increment is a bias over a path segment.
    pub dtheta_cmd: Vector3<f64>,
    /// The period's measurement: accelerometer mean over the period (g,
    /// instrument axes) and, for M2, the gimbal angles `(α, β, γ)` at its end
    /// (rad). `None`: the period is predicted only.
    pub observation: Option<Observation<T>>,
}

impl<T: RealField + Copy> LogRecord<T> {
    /// A measured period: length `dt` (s), commanded increment `dtheta_cmd`
    /// (rad, c frame) and its measurement.
    pub fn measured(dt: f64, dtheta_cmd: Vector3<f64>, observation: Observation<T>) -> Self {
        Self {
            dt,
            dtheta_cmd,
            observation: Some(observation),
        }
    }

    /// A period without measurement (predicted only): length `dt` (s) and
    /// commanded increment `dtheta_cmd` (rad, c frame).
    pub fn predicted(dt: f64, dtheta_cmd: Vector3<f64>) -> Self {
        Self {
            dt,
            dtheta_cmd,
            observation: None,
        }
    }

    /// Whether the period itself is usable: `dt` finite and strictly
    /// positive, `dtheta_cmd` finite. The filter rejects any other period
    /// ([`crate::ekf::Error::NonFiniteInput`],
    /// [`crate::ekf::Error::InvalidPeriod`]) and the estimator skips it when
    /// it walks the computed frame.
    pub fn has_valid_period(&self) -> bool {
        self.dt.is_finite() && self.dt > 0.0 && self.dtheta_cmd.iter().all(|v| v.is_finite())
    }
}

/// Why a record could not be appended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum LogError {
    /// The log is full; the record was not stored. The run is truncated
    /// from here on for the estimator.
    Full,
    /// The storage device failed to store the record.
    Storage,
    /// This log cannot encode the record (a value out of its range, or
    /// its table of distinct commands full: [`super::PackedLog`]).
    Unrepresentable,
}

impl core::fmt::Display for LogError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            LogError::Full => "sample log is full; the record was not stored",
            LogError::Storage => "sample log storage failed to store the record",
            LogError::Unrepresentable => "sample log cannot encode the record",
        })
    }
}

impl core::error::Error for LogError {}

/// Storage of the records of one run, in period order, provided by the
/// caller (see the [module docs](self) for flash or FRAM).
pub trait SampleLog<T: RealField + Copy> {
    /// Stores `record` as record number [`SampleLog::len`]. On error nothing
    /// is stored and the length is unchanged.
    fn append(&mut self, record: &LogRecord<T>) -> Result<(), LogError>;

    /// Number of records stored.
    fn len(&self) -> usize;

    /// Whether no record is stored.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Record `k` (0-based, in period order), by value; `None` when
    /// `k ≥ len()` or the storage cannot return it. `&mut self` because a
    /// device read (SPI, I²C) needs exclusive access to the bus driver.
    fn get(&mut self, k: usize) -> Option<LogRecord<T>>;

    /// Forgets every record from number `len` on (nothing when `len ≥
    /// len()`): a reset or a new configuration empties the log, a restore
    /// from a checkpoint takes it back to the records the checkpoint counted.
    fn truncate(&mut self, len: usize);
}

/// A [`SampleLog`] over a caller's slice of records in RAM: fills the slice
/// in order, then [`SampleLog::append`] returns [`LogError::Full`].
///
/// # Examples
///
/// ```
/// use nalgebra::Vector3;
/// use rollcal::estimator::{LogError, LogRecord, SampleLog, SliceLog};
///
/// let mut records = [LogRecord::<f64>::predicted(0.0, Vector3::zeros()); 2];
/// let mut log = SliceLog::new(&mut records);
/// let period = LogRecord::predicted(1.0, Vector3::new(0.0, 1e-3, 0.0));
/// log.append(&period)?;
/// log.append(&period)?;
/// assert_eq!(log.append(&period), Err(LogError::Full));
/// assert_eq!((log.len(), log.capacity()), (2, 2));
/// assert_eq!(log.get(1), Some(period));
/// log.truncate(1); // a restore from a checkpoint that counted one record
/// assert_eq!(log.records().len(), 1);
/// # Ok::<(), LogError>(())
/// ```
#[derive(Debug)]
pub struct SliceLog<'a, T: RealField + Copy> {
    buf: &'a mut [LogRecord<T>],
    len: usize,
}

impl<'a, T: RealField + Copy> SliceLog<'a, T> {
    /// An empty log over `buf`; its capacity is `buf.len()` records. The
    /// slice's previous contents are ignored (and overwritten by appends).
    pub fn new(buf: &'a mut [LogRecord<T>]) -> Self {
        Self { buf, len: 0 }
    }

    /// A full log whose records are the whole of `buf` (e.g. a run kept in
    /// RAM that survives a reset, or a host's recorded run); further appends
    /// return [`LogError::Full`].
    pub fn from_records(buf: &'a mut [LogRecord<T>]) -> Self {
        let len = buf.len();
        Self { buf, len }
    }

    /// Capacity in records.
    pub fn capacity(&self) -> usize {
        self.buf.len()
    }

    /// Forgets every record (keeps the storage).
    pub fn clear(&mut self) {
        self.len = 0;
    }

    /// The records stored, in period order.
    pub fn records(&self) -> &[LogRecord<T>] {
        self.buf.get(..self.len).unwrap_or(&[])
    }
}

impl<T: RealField + Copy> SampleLog<T> for SliceLog<'_, T> {
    fn append(&mut self, record: &LogRecord<T>) -> Result<(), LogError> {
        let slot = self.buf.get_mut(self.len).ok_or(LogError::Full)?;
        *slot = *record;
        self.len = self.len.saturating_add(1);
        Ok(())
    }

    fn len(&self) -> usize {
        self.len
    }

    fn truncate(&mut self, len: usize) {
        self.len = self.len.min(len);
    }

    fn get(&mut self, k: usize) -> Option<LogRecord<T>> {
        self.records().get(k).copied()
    }
}
