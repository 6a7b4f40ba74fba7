//! A compact [`SampleLog`]: 27 bytes per period for the accelerometer-only
//! configurations, 36 for M2-ps (against 44 / 88 for a [`super::SliceLog`]
//! record of `f32` / `f64`).
//!
//! # Record layout
//!
//! Every record takes the same number of bytes, [`PackedLayout::record_len`],
//! at `k · record_len` in the caller's byte slice (so a flash or FRAM
//! backing addresses record `k` directly, as the [`super::log`] module docs
//! describe). A record is one little-endian bit string (bit `i` is bit
//! `i % 8` of byte `i / 8`):
//!
//! | bits | field |
//! |---|---|
//! | 0 | the period has a measurement |
//! | 1 | the measurement has gimbal angles |
//! | 2–6 | index of the period length `dt` in the table of distinct lengths (5 bits) |
//! | 7–46, 47–86, 87–126 | commanded increment `Δθc` x, y, z: two's complement, 40 bits, in units of 2⁻⁴⁰ rad (range ±0.5 rad) |
//! | 127–155, 156–184, 185–213 | accelerometer mean x, y, z: two's complement, 29 bits, in units of 2⁻²⁷ g (range ±2 g) |
//! | 214–237, 238–261, 262–285 | gimbal angles `(α, β, γ)` (M2-ps layout only): two's complement, 24 bits, in units of 2π/2²⁴ rad (range ±π) |
//!
//! The accelerometer-only layout is 27 bytes (bits 214–215 zero), the
//! M2-ps one 36 (bits 286–287 zero).
//!
//! # What is kept, what is rounded
//!
//! - **The period lengths** are kept exactly (in `T`), once each, in a table
//!   of at most [`MAX_PERIODS`] distinct values the caller provides: a
//!   platform's filter period is fixed. One whose `dt` jitters from period
//!   to period fills the table: `append` then refuses the record
//!   ([`LogError::Unrepresentable`]) and the final answer says the log is
//!   incomplete; use a [`super::SliceLog`] there.
//! - **The commanded increments** are rounded to 2⁻⁴⁰ rad = 9.1e-13 rad.
//!   They need far more resolution than the measurements: their rounding is
//!   not noise but a bias that lasts a whole path segment (the Earth rate's
//!   share of an increment, ~4e-8 rad, changes slowly), and they cannot come
//!   from a table (that share changes every period). Rounded to `f32` (a
//!   relative 6e-8) they moved the M1-pa answer by 0.11σ, to a fixed 2⁻³⁰ rad
//!   by 0.9σ.
//! - **The accelerometer means** are rounded to 2⁻²⁷ g = 7.5e-9 g (error
//!   ≤ 3.7e-9 g, 0.004 of the paper's 1e-6 g noise; the wire's own `f32`
//!   spacing is 1.2e-7 g at 1 g). One bit less (2⁻²⁶ g, with 2π/2²³ rad
//!   gimbal steps) moved the M2-ps answer by 0.012–0.013σ.
//! - **The gimbal angles** are rounded to 3.7e-7 rad = 0.077″ (error
//!   ≤ 0.039″ against a 10″ noise).
//!
//! Over the paper's run and a scenario it was not designed on, the final
//! answer moves by less than 0.01σ against the unrounded log (`host-sim`'s
//! `packed_log` test measures it). A value beyond its range is refused
//! ([`LogError::Unrepresentable`]; the calibrator's default limits are 2 g
//! and 0.1 rad).
//!
//! ```
//! use nalgebra::Vector3;
//! use rollcal::ekf::Observation;
//! use rollcal::estimator::{LogRecord, PackedLayout, PackedLog, SampleLog};
//!
//! let layout = PackedLayout::Accel;
//! let mut bytes = [0u8; 4 * 27];
//! let mut periods = [0.0f64; 4];
//! let mut log = PackedLog::new(&mut bytes, &mut periods, layout);
//! assert_eq!(log.capacity(), 4);
//! let obs = Observation { accel_mean: Vector3::new(0.25, -0.5, 0.83), gimbal: None };
//! let r = LogRecord::measured(1.0, Vector3::new(1.2e-5, 3e-6, -1.745e-3), obs);
//! log.append(&r).unwrap();
//! let back = log.get(0).unwrap();
//! assert_eq!(back.dt, 1.0);
//! assert!((back.dtheta_cmd - r.dtheta_cmd).amax() <= 4.6e-13);
//! let err = back.observation.unwrap().accel_mean - obs.accel_mean;
//! assert!(err.amax() <= 3.8e-9);
//! ```

use nalgebra::{RealField, Vector3};

use super::log::{LogError, LogRecord, SampleLog};
use crate::ekf::Observation;

/// Most distinct period lengths a [`PackedLog`] can index (5 bits).
pub const MAX_PERIODS: usize = 32;

/// Bytes of the fields every layout has.
const WORD_BYTES: usize = 27;
/// Bytes of the largest record.
const MAX_RECORD: usize = 36;

/// A fixed-point field: `bits` wide (≤ 48), two's complement, `scale`
/// units per physical unit, from bit `at` of the record.
#[derive(Clone, Copy)]
struct Field {
    at: usize,
    bits: u32,
    scale: f64,
}

impl Field {
    const fn new(at: usize, bits: u32, scale: f64) -> Self {
        Self { at, bits, scale }
    }

    /// `v` in the field's units, two's complement in `bits` bits; `None`
    /// out of range.
    fn quantise<T: RealField + Copy>(self, v: T) -> Option<u64> {
        let v: f64 = nalgebra::try_convert(v)?;
        let q = libm::round(v * self.scale);
        let max = ((1u64 << (self.bits - 1)) - 1) as f64;
        if !q.is_finite() || q.abs() > max {
            return None;
        }
        Some((q as i64 as u64) & ((1u64 << self.bits) - 1))
    }

    fn store(self, record: &mut [u8; MAX_RECORD + 8], q: u64) {
        put_bits(record, self.at, self.bits, q);
    }

    fn load<T: RealField + Copy>(self, record: &[u8; MAX_RECORD + 8]) -> T {
        let raw = get_bits(record, self.at, self.bits) as i64;
        let signed = (raw << (64 - self.bits)) >> (64 - self.bits);
        nalgebra::convert(signed as f64 / self.scale)
    }
}

/// The 8 bytes from byte `at / 8` as a little-endian word (zeros past the
/// end).
fn window(record: &[u8; MAX_RECORD + 8], at: usize) -> u64 {
    let mut w = [0u8; 8];
    if let Some(src) = record.get(at / 8..at / 8 + 8) {
        w.copy_from_slice(src);
    }
    u64::from_le_bytes(w)
}

/// Writes the low `bits` (≤ 48) of `v` at bit `at` (ORs into zeros).
fn put_bits(record: &mut [u8; MAX_RECORD + 8], at: usize, bits: u32, v: u64) {
    let shift = (at % 8) as u32;
    let w = window(record, at) | ((v & ((1u64 << bits) - 1)) << shift);
    if let Some(dst) = record.get_mut(at / 8..at / 8 + 8) {
        dst.copy_from_slice(&w.to_le_bytes());
    }
}

/// Reads `bits` (≤ 48) bits at bit `at`.
fn get_bits(record: &[u8; MAX_RECORD + 8], at: usize, bits: u32) -> u64 {
    (window(record, at) >> (at % 8)) & ((1u64 << bits) - 1)
}

const G_UNITS: f64 = (1u64 << 27) as f64;
const GIMBAL_UNITS: f64 = (1u64 << 24) as f64 / core::f64::consts::TAU;
/// Bits of the period-length index, from bit 2.
const PERIOD_BITS: u32 = 5;
const RAD_UNITS: f64 = (1u64 << 40) as f64;
/// `Δθc` x, y, z: 40 bits of 2⁻⁴⁰ rad each, from bit 7.
const DTHETA: [Field; 3] = [
    Field::new(7, 40, RAD_UNITS),
    Field::new(47, 40, RAD_UNITS),
    Field::new(87, 40, RAD_UNITS),
];
/// Accelerometer means: 29 bits of 2⁻²⁷ g each, from bit 127.
const ACCEL: [Field; 3] = [
    Field::new(127, 29, G_UNITS),
    Field::new(156, 29, G_UNITS),
    Field::new(185, 29, G_UNITS),
];
/// Gimbal angles: 24 bits of 2π/2²⁴ rad each, from bit 214.
const GIMBAL: [Field; 3] = [
    Field::new(214, 24, GIMBAL_UNITS),
    Field::new(238, 24, GIMBAL_UNITS),
    Field::new(262, 24, GIMBAL_UNITS),
];
const HAS_OBSERVATION: u8 = 1;
const HAS_GIMBAL: u8 = 2;

/// Which fields a [`PackedLog`] stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PackedLayout {
    /// No gimbal angles (every configuration but M2-ps): 27 bytes.
    Accel,
    /// With the gimbal angles (M2-ps): 36 bytes.
    AccelGimbal,
}

impl PackedLayout {
    /// Bytes per record.
    pub const fn record_len(self) -> usize {
        match self {
            PackedLayout::Accel => WORD_BYTES,
            PackedLayout::AccelGimbal => MAX_RECORD,
        }
    }

    /// `record` as a compact log of this layout gives it back
    /// ([`PackedLog`], [`super::FlashLog`]): every value rounded to its
    /// field (module docs), `dt` kept; `None` when the log would refuse it
    /// ([`LogError::Unrepresentable`]: a value out of its field's range, or
    /// gimbal angles in [`PackedLayout::Accel`]). A host that wants the
    /// answer a device with such a log gives runs its passes over these
    /// (`host-sim calibrate --log packed`).
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use rollcal::ekf::Observation;
    /// use rollcal::estimator::{LogRecord, PackedLayout};
    ///
    /// let obs = Observation { accel_mean: Vector3::new(0.25, -0.5, 0.83), gimbal: None };
    /// let r = LogRecord::measured(1.0, Vector3::new(1.2e-5, 3e-6, -1.745e-3), obs);
    /// let back = PackedLayout::Accel.round_trip(&r).unwrap();
    /// assert_eq!(back.dt, 1.0);
    /// assert!((back.dtheta_cmd - r.dtheta_cmd).amax() <= 4.6e-13);
    /// assert!((back.observation.unwrap().accel_mean - obs.accel_mean).amax() <= 3.8e-9);
    /// ```
    pub fn round_trip<T: RealField + Copy>(self, record: &LogRecord<T>) -> Option<LogRecord<T>> {
        pack(self, record).map(|bits| unpack(&bits, record.dt))
    }

    /// The layout a configuration with `z` measurements per period needs:
    /// gimbal angles when it measures them (`z = 6`, M2-ps).
    pub const fn for_measurements(z: usize) -> Self {
        if z > 3 {
            PackedLayout::AccelGimbal
        } else {
            PackedLayout::Accel
        }
    }
}

/// A [`SampleLog`] of fixed-size packed records in a caller's byte slice,
/// with the distinct period lengths in a caller's table (see the
/// [module docs](self)).
#[derive(Debug)]
pub struct PackedLog<'a, T: RealField + Copy> {
    bytes: &'a mut [u8],
    periods: &'a mut [f64],
    used_periods: usize,
    layout: PackedLayout,
    len: usize,
    _scalar: core::marker::PhantomData<T>,
}

impl<'a, T: RealField + Copy> PackedLog<'a, T> {
    /// An empty log over `bytes` (capacity `bytes.len() / record_len`
    /// records) with the table of period lengths `periods` (at most
    /// [`MAX_PERIODS`] of its entries are used).
    pub fn new(bytes: &'a mut [u8], periods: &'a mut [f64], layout: PackedLayout) -> Self {
        Self {
            bytes,
            periods,
            used_periods: 0,
            _scalar: core::marker::PhantomData,
            layout,
            len: 0,
        }
    }

    /// Records the byte slice can hold.
    pub fn capacity(&self) -> usize {
        self.bytes.len() / self.layout.record_len()
    }

    /// The record layout.
    pub fn layout(&self) -> PackedLayout {
        self.layout
    }

    /// Distinct period lengths stored so far.
    pub fn periods_used(&self) -> usize {
        self.used_periods
    }

    /// Empties the log and its table of period lengths.
    pub fn clear(&mut self) {
        self.len = 0;
        self.used_periods = 0;
    }

    /// Index of `dt` in the table, added if new; `None` when the table is
    /// full.
    fn period_index(&mut self, dt: f64) -> Option<usize> {
        let table = self.periods.get(..self.used_periods)?;
        if let Some(i) = table.iter().position(|p| *p == dt) {
            return Some(i);
        }
        let i = self.used_periods;
        if i >= MAX_PERIODS {
            return None;
        }
        *self.periods.get_mut(i)? = dt;
        self.used_periods += 1;
        Some(i)
    }
}

/// The bytes of a packed record, with 8 bytes of slack for the 64-bit
/// windows the fields are read and written through.
pub(super) type Bits = [u8; MAX_RECORD + 8];

/// `record`'s fields in `layout` (the period-length index left 0); `None`
/// when a value is out of its field's range or the record has gimbal
/// angles that `layout` does not store.
pub(super) fn pack<T: RealField + Copy>(
    layout: PackedLayout,
    record: &LogRecord<T>,
) -> Option<Bits> {
    let mut bits = [0u8; MAX_RECORD + 8];
    for (f, v) in DTHETA.iter().zip(record.dtheta_cmd.iter()) {
        let q = f.quantise(*v)?;
        f.store(&mut bits, q);
    }
    if let Some(obs) = &record.observation {
        let mut flags = HAS_OBSERVATION;
        for (f, v) in ACCEL.iter().zip(obs.accel_mean.iter()) {
            let q = f.quantise(*v)?;
            f.store(&mut bits, q);
        }
        if let Some(g) = obs.gimbal {
            if layout != PackedLayout::AccelGimbal {
                return None;
            }
            flags |= HAS_GIMBAL;
            for (f, v) in GIMBAL.iter().zip(g.iter()) {
                let q = f.quantise(*v)?;
                f.store(&mut bits, q);
            }
        }
        put_bits(&mut bits, 0, 2, u64::from(flags));
    }
    Some(bits)
}

/// The record whose fields are `bits` (as [`pack`] wrote them) and whose
/// period is `dt` (s).
pub(super) fn unpack<T: RealField + Copy>(bits: &Bits, dt: f64) -> LogRecord<T> {
    let flags = get_bits(bits, 0, 2) as u8;
    let [x, y, z] = DTHETA;
    let dtheta_cmd = Vector3::new(x.load(bits), y.load(bits), z.load(bits));
    let observation = (flags & HAS_OBSERVATION != 0).then(|| {
        let [ax, ay, az] = ACCEL;
        let [ga, gb, gc] = GIMBAL;
        Observation {
            accel_mean: Vector3::new(ax.load(bits), ay.load(bits), az.load(bits)),
            gimbal: (flags & HAS_GIMBAL != 0)
                .then(|| Vector3::new(ga.load(bits), gb.load(bits), gc.load(bits))),
        }
    });
    LogRecord {
        dt,
        dtheta_cmd,
        observation,
    }
}

impl<T: RealField + Copy> SampleLog<T> for PackedLog<'_, T> {
    fn append(&mut self, record: &LogRecord<T>) -> Result<(), LogError> {
        let n = self.layout.record_len();
        if self.len >= self.capacity() {
            return Err(LogError::Full);
        }
        let Some(mut bits) = pack(self.layout, record) else {
            return Err(LogError::Unrepresentable);
        };
        let at = self.len * n;
        if self.bytes.get(at..at + n).is_none() {
            return Err(LogError::Full);
        }
        let Some(index) = self.period_index(record.dt) else {
            return Err(LogError::Unrepresentable);
        };
        put_bits(&mut bits, 2, PERIOD_BITS, index as u64);
        match (self.bytes.get_mut(at..at + n), bits.get(..n)) {
            (Some(out), Some(src)) => out.copy_from_slice(src),
            _ => return Err(LogError::Full),
        }
        self.len += 1;
        Ok(())
    }

    fn len(&self) -> usize {
        self.len
    }

    fn get(&mut self, k: usize) -> Option<LogRecord<T>> {
        if k >= self.len {
            return None;
        }
        let n = self.layout.record_len();
        let mut bits = [0u8; MAX_RECORD + 8];
        bits.get_mut(..n)?
            .copy_from_slice(self.bytes.get(k * n..k * n + n)?);
        let index = get_bits(&bits, 2, PERIOD_BITS) as usize;
        let dt = *self.periods.get(..self.used_periods)?.get(index)?;
        Some(unpack(&bits, dt))
    }

    /// Forgets records from `len` on. The table of period lengths keeps its
    /// entries (an entry no record uses any more only costs a slot).
    fn truncate(&mut self, len: usize) {
        self.len = self.len.min(len);
    }
}
