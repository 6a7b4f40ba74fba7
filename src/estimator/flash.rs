//! A [`SampleLog`] in NOR flash through the `embedded-storage` traits
//! ([`NorFlash`]): any HAL that implements them stores the calibration's
//! samples with no code of the integrator's (feature `flash-log`).
//!
//! # Slots
//!
//! Records are [`PackedLog`](super::PackedLog)'s compact encoding (27 bytes,
//! 36 for M2-ps), in slots of [`FlashLog::slot_len`] bytes: a multiple of
//! the device's `WRITE_SIZE` and `READ_SIZE`, so that a record is one
//! aligned `write` and one aligned `read`. A slot never straddles an erase
//! sector (the few bytes past a sector's last whole slot stay unused):
//!
//! | bytes | field |
//! |---|---|
//! | 0–3 | epoch (`u32`, little-endian): the run the record belongs to |
//! | 4–7 | sequence number: the record's index in the log (`u32`) |
//! | 8–11 | period length `dt` (s, `f32`: the wire's, kept exactly) |
//! | 12 … 12+n−1 | the packed record (n = 27 or 36) |
//! | 12+n … 12+n+3 | CRC-32 ([`crate::wire::crc32`]) of the bytes before it |
//! | the rest | padding, left erased (`0xFF`) |
//!
//! That is 43 bytes for the accelerometer-only layout and 52 for M2-ps,
//! rounded up to the write and read sizes: 44 and 52 bytes per period
//! with 4-byte words, 48 and 56 with 8-byte words, 48 and 64 with 16-byte
//! ones. With 4-byte words and 4 KiB sectors (93 and 78 slots a sector)
//! the paper's 5 400 periods take 59 sectors (236 KiB) and 70 sectors
//! (280 KiB) (`cargo test --release -p rollcal --test it flash_log::
//! -- --nocapture` prints it).
//!
//! # Writing
//!
//! Every record is one `write` of one slot, at the next unused slot (the
//! *head*); a sector is erased when the head enters it, before its first
//! write (one erase per `ERASE_SIZE` bytes of log; [`FlashLog::format`]
//! erases the whole region at once, for an integrator who wants no erase
//! inside the filter period). A slot is written once between erases, as
//! the trait requires.
//!
//! # Power cuts
//!
//! A cut during a `write` leaves that slot torn: its CRC does not match and
//! [`FlashLog::open`] skips it, so the cut loses that record only (the
//! next record goes to the slot after it). A cut during an erase leaves a
//! sector the head had not entered yet; it is erased again. Nothing else is
//! kept in RAM that the flash does not also say: `open` rebuilds the whole
//! state by reading every slot of the region once.
//!
//! # Truncating
//!
//! [`SampleLog::truncate`] rewrites nothing: the records from `len` on are
//! forgotten in RAM, and the next record, numbered `len`, goes to the head
//! as the start of a new *segment* (logical index → slot); `open` sees the
//! smaller sequence number and forgets the same records. The cost is the
//! slots the forgotten records keep until the next run, and one entry of
//! the segment table (`S` entries of 8 bytes, [`DEFAULT_SEGMENTS`]): a torn
//! write skipped or a sector skipped also starts one. Once the table is
//! full, `append` returns [`LogError::Full`]. `truncate(0)` (a reset or a
//! new configuration) starts a new run instead: a new epoch, written from
//! the region's start again, and the older epoch's records are ignored
//! (`open` takes the run of the greatest epoch). A truncation is durable
//! once a record has been appended after it: a cut before that brings the
//! forgotten records back, which the calibrator, whose own count of logged
//! records decides ([`crate::calibrator::Calibrator::push_logged`]),
//! truncates again.
//!
//! # Errors
//!
//! A failed `write` or `erase` is [`LogError::Storage`] (nothing is counted;
//! a failed write's slot is skipped), a failed read makes
//! [`SampleLog::get`] return `None`; [`FlashLog::last_error`] keeps the
//! device's error kind. A record whose `dt` is not exactly an `f32` (the
//! wire's are) or whose values are out of the packed ranges is
//! [`LogError::Unrepresentable`].

use core::marker::PhantomData;
use core::num::NonZeroU32;
use core::ops::Range;

use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};
use nalgebra::RealField;

use super::log::{LogError, LogRecord, SampleLog};
use super::packed::{pack, unpack, Bits, PackedLayout};
use crate::wire::crc32;

/// Largest slot (bytes): a device whose `WRITE_SIZE` or `READ_SIZE` needs
/// a larger one is refused ([`FlashLogError::Geometry`]).
pub const MAX_SLOT: usize = 256;

/// Default size of the segment table (entries): the truncations to a
/// non-zero length, torn writes and skipped sectors one run can hold.
pub const DEFAULT_SEGMENTS: usize = 32;

/// Bytes before the packed record: epoch, sequence number, `dt`.
const HEADER: usize = 12;
/// Bytes of the CRC after it.
const CRC: usize = 4;

/// Why [`FlashLog::open`] refused the device or region.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FlashLogError {
    /// The region is empty, not a whole number of erase sectors, or past
    /// the device's capacity.
    Region,
    /// The device's sizes do not fit: a slot would exceed [`MAX_SLOT`] or
    /// `ERASE_SIZE`, a sector is not a multiple of the write and read
    /// sizes, or the segment table has no entry.
    Geometry,
    /// The device failed while the log was read.
    Flash(NorFlashErrorKind),
}

impl core::fmt::Display for FlashLogError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FlashLogError::Region => {
                f.write_str("flash log region is empty, not whole sectors or out of the device")
            }
            FlashLogError::Geometry => {
                f.write_str("flash device's write, read or erase size does not fit the log")
            }
            FlashLogError::Flash(k) => write!(f, "flash device failed: {k}"),
        }
    }
}

impl core::error::Error for FlashLogError {}

/// Logical records `start …` are at slots `slot …` (up to the next
/// segment's start or the log's length).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Segment {
    start: u32,
    slot: u32,
}

/// What a slot holds.
enum Slot {
    /// Every byte `0xFF`.
    Erased,
    /// Written but not a whole record (a torn write, a partly erased
    /// sector).
    Torn,
    /// A record whose CRC matches.
    Valid { epoch: u32, index: u32 },
}

/// Greatest common divisor.
const fn gcd(mut a: usize, mut b: usize) -> usize {
    while b != 0 {
        let r = a % b;
        a = b;
        b = r;
    }
    a
}

/// A [`SampleLog`] of packed records in a region of a NOR flash (see the
/// [module docs](self)): power-cut safe, resumable with
/// [`FlashLog::open`]. `S` is the size of the segment table.
///
/// # Examples
///
/// A RAM stand-in for a HAL's flash driver (4-byte words, 1 KiB sectors):
///
/// ```
/// use embedded_storage::nor_flash::{
///     ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash,
/// };
/// use nalgebra::Vector3;
/// use rollcal::ekf::Observation;
/// use rollcal::estimator::{FlashLog, LogRecord, PackedLayout, SampleLog};
///
/// struct Ram([u8; 8192]);
///
/// impl ErrorType for Ram {
///     type Error = NorFlashErrorKind;
/// }
///
/// impl ReadNorFlash for Ram {
///     const READ_SIZE: usize = 1;
///     fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
///         let at = offset as usize;
///         let src = self.0.get(at..at + bytes.len()).ok_or(NorFlashErrorKind::OutOfBounds)?;
///         bytes.copy_from_slice(src);
///         Ok(())
///     }
///     fn capacity(&self) -> usize {
///         self.0.len()
///     }
/// }
///
/// impl NorFlash for Ram {
///     const WRITE_SIZE: usize = 4;
///     const ERASE_SIZE: usize = 1024;
///     fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
///         let dst = self.0.get_mut(from as usize..to as usize).ok_or(NorFlashErrorKind::OutOfBounds)?;
///         dst.fill(0xFF);
///         Ok(())
///     }
///     fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
///         let at = offset as usize;
///         let dst = self.0.get_mut(at..at + bytes.len()).ok_or(NorFlashErrorKind::OutOfBounds)?;
///         for (d, b) in dst.iter_mut().zip(bytes) {
///             *d &= *b; // NOR programming only clears bits
///         }
///         Ok(())
///     }
/// }
///
/// // The log in the device's second half: 4 sectors of 23 slots of 44 bytes.
/// let mut log = FlashLog::<_, f64>::open(Ram([0; 8192]), 4096..8192, PackedLayout::Accel)?;
/// assert_eq!((log.slot_len(), log.capacity()), (44, 92));
/// let obs = Observation { accel_mean: Vector3::new(0.0, 1.0, 0.0), gimbal: None };
/// let period = LogRecord::measured(1.0, Vector3::new(1e-3, 0.0, 7.3e-5), obs);
/// for _ in 0..30 {
///     log.append(&period)?;
/// }
/// // After a reset: the same records, read back from the device.
/// let mut log = FlashLog::<_, f64>::open(log.into_inner(), 4096..8192, PackedLayout::Accel)?;
/// assert_eq!(log.len(), 30);
/// let back = log.get(29).unwrap();
/// assert_eq!(back.dt, 1.0);
/// assert!((back.dtheta_cmd - period.dtheta_cmd).amax() <= 4.6e-13);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct FlashLog<F, T, const S: usize = DEFAULT_SEGMENTS> {
    flash: F,
    layout: PackedLayout,
    /// Region start (bytes from the device's start).
    base: u32,
    /// Sectors in the region.
    sectors: u32,
    /// Slot length (bytes).
    slot: u32,
    /// Slots per sector (at least one: `open` checks the slot fits in a
    /// sector; non-zero by type, so that no division can panic).
    per_sector: NonZeroU32,
    /// Epoch of the records of this run.
    epoch: u32,
    /// Epoch of the next run: above every epoch in the region.
    next_epoch: u32,
    /// Records in the log.
    len: u32,
    /// Next slot to write.
    head: u32,
    /// Sectors from `head`'s (or from the one after it when `head` is
    /// inside a sector) up to this one, excluded, hold no byte written
    /// since their erase at or after `head`.
    erased_to: u32,
    segments: [Segment; S],
    used: usize,
    last_error: Option<NorFlashErrorKind>,
    _scalar: PhantomData<fn() -> T>,
}

impl<F: NorFlash, T: RealField + Copy, const S: usize> FlashLog<F, T, S> {
    /// Slot length (bytes) of `layout` on this device: 16 bytes of header
    /// and CRC plus the packed record, rounded up to a multiple of the
    /// device's `WRITE_SIZE` and `READ_SIZE` (`usize::MAX` when they have no
    /// common multiple in range).
    pub const fn slot_len_of(layout: PackedLayout) -> usize {
        let w = if F::WRITE_SIZE == 0 { 1 } else { F::WRITE_SIZE };
        let r = if F::READ_SIZE == 0 { 1 } else { F::READ_SIZE };
        let Some(align) = (w / gcd(w, r)).checked_mul(r) else {
            return usize::MAX;
        };
        let raw = HEADER + layout.record_len() + CRC;
        match raw.div_ceil(align).checked_mul(align) {
            Some(n) => n,
            None => usize::MAX,
        }
    }

    /// The log in bytes `region` of `flash` (whole erase sectors), as a
    /// previous run left it: reads every slot once, takes the records of
    /// the newest run that were completely written, in order, and
    /// continues after the last of them. A blank or foreign region is an
    /// empty log (its sectors are erased when the log reaches them).
    ///
    /// Errors: [`FlashLogError::Region`], [`FlashLogError::Geometry`], or a
    /// failed read ([`FlashLogError::Flash`]).
    pub fn open(flash: F, region: Range<u32>, layout: PackedLayout) -> Result<Self, FlashLogError> {
        Self::open_or_return(flash, region, layout).map_err(|(_, e)| e)
    }

    /// [`FlashLog::open`], giving the device back when the log cannot be
    /// opened (to try another region or layout, or to use it otherwise).
    ///
    /// # Examples
    ///
    /// ```
    /// # use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
    /// # struct Ram([u8; 4096]);
    /// # impl ErrorType for Ram { type Error = NorFlashErrorKind; }
    /// # impl ReadNorFlash for Ram {
    /// #     const READ_SIZE: usize = 1;
    /// #     fn read(&mut self, o: u32, b: &mut [u8]) -> Result<(), Self::Error> {
    /// #         b.copy_from_slice(self.0.get(o as usize..o as usize + b.len()).ok_or(NorFlashErrorKind::OutOfBounds)?);
    /// #         Ok(())
    /// #     }
    /// #     fn capacity(&self) -> usize { self.0.len() }
    /// # }
    /// # impl NorFlash for Ram {
    /// #     const WRITE_SIZE: usize = 4;
    /// #     const ERASE_SIZE: usize = 1024;
    /// #     fn erase(&mut self, f: u32, t: u32) -> Result<(), Self::Error> { self.0[f as usize..t as usize].fill(0xFF); Ok(()) }
    /// #     fn write(&mut self, o: u32, b: &[u8]) -> Result<(), Self::Error> { self.0[o as usize..o as usize + b.len()].copy_from_slice(b); Ok(()) }
    /// # }
    /// use rollcal::estimator::{FlashLog, FlashLogError, PackedLayout, SampleLog};
    ///
    /// // 1000..2000 is not whole sectors: refused, and the device comes back.
    /// let Err((ram, e)) = FlashLog::<_, f64>::open_or_return(Ram([0xFF; 4096]), 1000..2000, PackedLayout::Accel) else {
    ///     unreachable!()
    /// };
    /// assert_eq!(e, FlashLogError::Region);
    /// let log = FlashLog::<_, f64>::open(ram, 0..4096, PackedLayout::Accel)?;
    /// assert_eq!(log.len(), 0);
    /// # Ok::<(), FlashLogError>(())
    /// ```
    #[allow(clippy::result_large_err)]
    pub fn open_or_return(
        flash: F,
        region: Range<u32>,
        layout: PackedLayout,
    ) -> Result<Self, (F, FlashLogError)> {
        match Self::check_geometry(&flash, &region, layout) {
            Ok((sectors, slot32, per_sector)) => {
                let mut log = Self {
                    flash,
                    layout,
                    base: region.start,
                    sectors,
                    slot: slot32,
                    per_sector,
                    epoch: 0,
                    next_epoch: 0,
                    len: 0,
                    head: 0,
                    erased_to: 0,
                    segments: [Segment::default(); S],
                    used: 0,
                    last_error: None,
                    _scalar: PhantomData,
                };
                match log.scan() {
                    Ok(()) => Ok(log),
                    Err(e) => Err((log.flash, FlashLogError::Flash(e))),
                }
            }
            Err(e) => Err((flash, e)),
        }
    }

    /// What [`FlashLog::open`] checks of the device and region: the
    /// number of sectors, the slot length and the slots a sector holds.
    fn check_geometry(
        flash: &F,
        region: &Range<u32>,
        layout: PackedLayout,
    ) -> Result<(u32, u32, NonZeroU32), FlashLogError> {
        let erase = F::ERASE_SIZE;
        let slot = Self::slot_len_of(layout);
        // Slots start at multiples of their length inside a sector, so a
        // sector must be a multiple of the write and read sizes.
        let w = F::WRITE_SIZE.max(1);
        let r = F::READ_SIZE.max(1);
        if S == 0 || slot > MAX_SLOT || slot > erase || erase % w != 0 || erase % r != 0 {
            return Err(FlashLogError::Geometry);
        }
        let erase32 = u32::try_from(erase).map_err(|_| FlashLogError::Geometry)?;
        let slot32 = u32::try_from(slot).map_err(|_| FlashLogError::Geometry)?;
        let end_ok = usize::try_from(region.end).is_ok_and(|e| e <= flash.capacity());
        if !region.start.is_multiple_of(erase32)
            || !region.end.is_multiple_of(erase32)
            || region.end <= region.start
            || !end_ok
        {
            return Err(FlashLogError::Region);
        }
        let sectors = (region.end - region.start) / erase32;
        let Some(per_sector) = NonZeroU32::new(erase32 / slot32) else {
            return Err(FlashLogError::Geometry);
        };
        if sectors.checked_mul(per_sector.get()).is_none() {
            return Err(FlashLogError::Region);
        }
        Ok((sectors, slot32, per_sector))
    }

    /// Slots in the region: the records a run holds when no write was torn
    /// and no truncation left slots behind.
    pub fn capacity(&self) -> usize {
        self.total() as usize
    }

    /// Slots not used yet in this run.
    pub fn free(&self) -> usize {
        self.total().saturating_sub(self.head) as usize
    }

    /// Slot length (bytes): what one period costs on this device.
    pub fn slot_len(&self) -> usize {
        self.slot as usize
    }

    /// The record layout.
    pub fn layout(&self) -> PackedLayout {
        self.layout
    }

    /// Entries of the segment table in use (at most `S`).
    pub fn segments(&self) -> usize {
        self.used
    }

    /// The device's last error, if any: of a read, write or erase.
    pub fn last_error(&self) -> Option<NorFlashErrorKind> {
        self.last_error
    }

    /// The flash device, e.g. for what its driver counts.
    pub fn flash(&self) -> &F {
        &self.flash
    }

    /// The flash device, e.g. to reopen the log after a simulated reset.
    pub fn into_inner(self) -> F {
        self.flash
    }

    /// Reads the region again in `layout`, in place ([`FlashLog::open`]
    /// without giving up the device): the records the device holds in
    /// that layout.
    ///
    /// # Errors
    ///
    /// [`FlashLogError::Geometry`] when the device's sizes do not fit
    /// `layout`'s slots (the log is then as it was); [`FlashLogError::Flash`]
    /// when the device failed while it was read (the log then holds
    /// nothing, and its next record starts a new run).
    pub fn reopen(&mut self, layout: PackedLayout) -> Result<(), FlashLogError> {
        let end = self
            .sectors
            .checked_mul(self.erase_size())
            .and_then(|n| n.checked_add(self.base))
            .ok_or(FlashLogError::Region)?;
        let (sectors, slot, per_sector) =
            Self::check_geometry(&self.flash, &(self.base..end), layout)?;
        self.layout = layout;
        self.sectors = sectors;
        self.slot = slot;
        self.per_sector = per_sector;
        self.epoch = 0;
        self.next_epoch = 0;
        self.len = 0;
        self.head = 0;
        self.erased_to = 0;
        self.used = 0;
        self.scan().map_err(|e| {
            self.len = 0;
            self.used = 0;
            self.head = 0;
            self.erased_to = 0;
            FlashLogError::Flash(e)
        })
    }

    /// The device, for the control records an integration kit keeps beside
    /// the log ([`crate::device`]); the log's own region must not be
    /// written through it.
    pub(crate) fn flash_mut(&mut self) -> &mut F {
        &mut self.flash
    }

    /// The run the records belong to: a number that changes whenever the
    /// log starts a new run (`truncate(0)`), written in every record's slot.
    pub fn epoch(&self) -> u32 {
        self.epoch
    }

    /// Erases the sector after the one the next record goes to, when it is
    /// not known erased: call it when the firmware is idle, and
    /// [`SampleLog::append`] never erases (it still erases, as a last
    /// resort, a sector it enters that was not erased ahead: the first
    /// record of a new run, whose sector 0 still held the previous run's).
    /// Returns whether it erased; at most one sector a call.
    ///
    /// # Errors
    ///
    /// [`LogError::Storage`] when the device failed ([`FlashLog::last_error`]).
    pub fn erase_ahead(&mut self) -> Result<bool, LogError> {
        let sector = self.head / self.per_sector;
        // The sector of the head itself (when it starts one) and the next.
        let wanted = sector.saturating_add(2).min(self.sectors);
        if self.erased_to >= wanted || self.erased_to < sector {
            // Enough erased, or the head is in a sector `append` erases
            // itself (a new run's first).
            return Ok(false);
        }
        if self.erased_to == sector && !self.head.is_multiple_of(self.per_sector.get()) {
            return Ok(false);
        }
        let from = self.offset(self.erased_to * self.per_sector.get());
        if let Err(e) = self.flash.erase(from, from + self.erase_size()) {
            self.last_error = Some(e.kind());
            return Err(LogError::Storage);
        }
        self.erased_to += 1;
        Ok(true)
    }

    /// Erases the whole region now and empties the log: the following
    /// appends erase nothing (erasing is slow; here it happens before a
    /// run, not inside a filter period). On a failed erase the log is
    /// empty and its sectors are erased again as the log reaches them.
    pub fn format(&mut self) -> Result<(), LogError> {
        self.restart();
        // Nothing is known erased until the erase has returned.
        self.head = 0;
        self.erased_to = 0;
        let end = self
            .sectors
            .checked_mul(self.erase_size())
            .and_then(|n| n.checked_add(self.base))
            .ok_or(LogError::Storage)?;
        if let Err(e) = self.flash.erase(self.base, end) {
            self.last_error = Some(e.kind());
            return Err(LogError::Storage);
        }
        self.erased_to = self.sectors;
        Ok(())
    }

    fn total(&self) -> u32 {
        self.sectors.saturating_mul(self.per_sector.get())
    }

    fn erase_size(&self) -> u32 {
        // Checked in `open`.
        u32::try_from(F::ERASE_SIZE).unwrap_or(u32::MAX)
    }

    /// Device offset of slot `p` (`p` < `total`).
    fn offset(&self, p: u32) -> u32 {
        let sector = p / self.per_sector;
        let within = p % self.per_sector;
        self.base + sector * self.erase_size() + within * self.slot
    }

    /// An empty log, the next run's epoch, written from the region's start.
    fn restart(&mut self) {
        self.len = 0;
        self.used = 0;
        self.epoch = self.next_epoch;
        self.next_epoch = self.next_epoch.wrapping_add(1);
        if self.head != 0 {
            self.head = 0;
            self.erased_to = 0;
        }
    }

    /// Reads slot `p` into `buf` and says what it holds.
    fn read_slot(&mut self, p: u32, buf: &mut [u8; MAX_SLOT]) -> Result<Slot, NorFlashErrorKind> {
        let n = self.slot as usize;
        let offset = self.offset(p);
        let bytes = buf.get_mut(..n).ok_or(NorFlashErrorKind::OutOfBounds)?;
        if let Err(e) = self.flash.read(offset, bytes) {
            let kind = e.kind();
            self.last_error = Some(kind);
            return Err(kind);
        }
        if bytes.iter().all(|b| *b == 0xFF) {
            return Ok(Slot::Erased);
        }
        let body = HEADER + self.layout.record_len();
        let word = |at: usize| -> Option<u32> {
            Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
        };
        match (bytes.get(..body), word(body), word(0), word(4)) {
            (Some(b), Some(crc), Some(epoch), Some(index)) if crc32(b) == crc => {
                Ok(Slot::Valid { epoch, index })
            }
            _ => Ok(Slot::Torn),
        }
    }

    /// Whether record `index` at slot `p` needs a new segment.
    fn needs_segment(&self, index: u32, p: u32) -> bool {
        let continues = index == self.len
            && self
                .segments
                .get(..self.used)
                .and_then(|s| s.last())
                .is_some_and(|s| s.slot.checked_add(self.len - s.start) == Some(p));
        !continues
    }

    /// Records `index` (≤ `len`) at slot `p`: the log is then `index + 1`
    /// records long. `false` (and nothing changed) when that needs a
    /// segment and the table is full.
    fn place(&mut self, index: u32, p: u32) -> bool {
        if self.needs_segment(index, p) {
            let mut used = self.used;
            while used > 0
                && self
                    .segments
                    .get(used - 1)
                    .is_some_and(|s| s.start >= index)
            {
                used -= 1;
            }
            let Some(entry) = self.segments.get_mut(used) else {
                return false;
            };
            *entry = Segment {
                start: index,
                slot: p,
            };
            self.used = used + 1;
        }
        self.len = index + 1;
        true
    }

    /// Rebuilds the state from the region (see [`FlashLog::open`]).
    fn scan(&mut self) -> Result<(), NorFlashErrorKind> {
        let total = self.total();
        let mut buf = [0u8; MAX_SLOT];
        let mut newest: Option<u32> = None;
        // The newest run's last slot, and whether its rebuild overflowed
        // the segment table (the rest of the run is then unreachable).
        let mut last_of_run: Option<u32> = None;
        let mut overflow = false;
        // The last slot that is not erased.
        let mut last_written: Option<u32> = None;
        for p in 0..total {
            let slot = self.read_slot(p, &mut buf)?;
            if !matches!(slot, Slot::Erased) {
                last_written = Some(p);
            }
            let Slot::Valid { epoch, index } = slot else {
                continue;
            };
            if newest.is_none_or(|e| epoch > e) {
                // A newer run: written from the region's start after every
                // record seen so far, which it supersedes.
                newest = Some(epoch);
                self.len = 0;
                self.used = 0;
                overflow = false;
            }
            if newest == Some(epoch) {
                last_of_run = Some(p);
                // A sequence number past the length was never appended
                // after these records (append numbers `len`): ignored.
                if !overflow && index <= self.len && !self.place(index, p) {
                    overflow = true;
                }
            }
        }
        self.next_epoch = newest.map_or(0, |e| e.wrapping_add(1));
        // Sectors from here on hold nothing.
        let clean_from = last_written.map_or(0, |p| p / self.per_sector + 1);
        let Some(epoch) = newest.filter(|_| self.len > 0) else {
            // Empty: a new run from the region's start (whose sectors are
            // erased as it reaches them, unless the whole region is).
            self.restart();
            self.head = 0;
            self.erased_to = if clean_from == 0 { self.sectors } else { 0 };
            return Ok(());
        };
        self.epoch = epoch;
        let mut head = last_of_run.map_or(0, |p| p + 1);
        if !head.is_multiple_of(self.per_sector.get()) {
            // Inside a sector: skip a torn slot after the run's last
            // record (and anything else written in the sector's rest).
            let (from, end) = (head, (head / self.per_sector + 1) * self.per_sector.get());
            for p in from..end {
                if !matches!(self.read_slot(p, &mut buf)?, Slot::Erased) {
                    head = p + 1;
                }
            }
        }
        self.head = head;
        let sector = head / self.per_sector;
        self.erased_to = if !head.is_multiple_of(self.per_sector.get()) {
            sector + 1
        } else {
            sector
        };
        if clean_from <= self.erased_to {
            self.erased_to = self.sectors;
        }
        Ok(())
    }
}

impl<F: NorFlash, T: RealField + Copy, const S: usize> SampleLog<T> for FlashLog<F, T, S> {
    /// Writes the record at the next unused slot (erasing its sector first
    /// when the log enters it). Errors: [`LogError::Unrepresentable`],
    /// [`LogError::Full`] (no slot left, or the segment table is full),
    /// [`LogError::Storage`] (the device failed; the slot is skipped).
    fn append(&mut self, record: &LogRecord<T>) -> Result<(), LogError> {
        let Some(bits) = pack::<T>(self.layout, record) else {
            return Err(LogError::Unrepresentable);
        };
        let dt = record.dt as f32;
        if f64::from(dt) != record.dt {
            return Err(LogError::Unrepresentable);
        }
        let index = self.len;
        if index == u32::MAX {
            return Err(LogError::Full);
        }
        let mut p = self.head;
        let mut sector = p / self.per_sector;
        if !p.is_multiple_of(self.per_sector.get()) && self.erased_to <= sector {
            // The rest of this sector is not known to be erased (it cannot
            // be, by construction): go on in the next one.
            p = (sector + 1) * self.per_sector.get();
            sector += 1;
            self.head = p;
        }
        if p >= self.total() {
            return Err(LogError::Full);
        }
        if self.needs_segment(index, p) && self.used >= S {
            return Err(LogError::Full);
        }
        if self.erased_to <= sector {
            let from = self.offset(p);
            if let Err(e) = self.flash.erase(from, from + self.erase_size()) {
                self.last_error = Some(e.kind());
                return Err(LogError::Storage);
            }
            self.erased_to = sector + 1;
        }
        let n = self.layout.record_len();
        let mut buf = [0xFFu8; MAX_SLOT];
        let fields = bits.get(..n).ok_or(LogError::Unrepresentable)?;
        let parts: [(usize, &[u8]); 4] = [
            (0, &self.epoch.to_le_bytes()),
            (4, &index.to_le_bytes()),
            (8, &dt.to_le_bytes()),
            (HEADER, fields),
        ];
        for (at, src) in parts {
            buf.get_mut(at..at + src.len())
                .ok_or(LogError::Unrepresentable)?
                .copy_from_slice(src);
        }
        let crc = crc32(buf.get(..HEADER + n).ok_or(LogError::Unrepresentable)?);
        buf.get_mut(HEADER + n..HEADER + n + CRC)
            .ok_or(LogError::Unrepresentable)?
            .copy_from_slice(&crc.to_le_bytes());
        let bytes = buf
            .get(..self.slot as usize)
            .ok_or(LogError::Unrepresentable)?;
        let offset = self.offset(p);
        // The slot is used whatever the write does: a failed write may have
        // programmed part of it.
        self.head = p + 1;
        if let Err(e) = self.flash.write(offset, bytes) {
            self.last_error = Some(e.kind());
            return Err(LogError::Storage);
        }
        // Checked above: a segment, if needed, has an entry.
        if !self.place(index, p) {
            return Err(LogError::Full);
        }
        Ok(())
    }

    fn len(&self) -> usize {
        self.len as usize
    }

    /// Record `k`, read from the device and checked (CRC, run, sequence
    /// number); `None` for `k ≥ len()`, a failed read or a record that does
    /// not check.
    fn get(&mut self, k: usize) -> Option<LogRecord<T>> {
        let k = u32::try_from(k).ok().filter(|k| *k < self.len)?;
        let seg = self
            .segments
            .get(..self.used)?
            .iter()
            .rev()
            .find(|s| s.start <= k)
            .copied()?;
        let p = seg.slot.checked_add(k - seg.start)?;
        let mut buf = [0u8; MAX_SLOT];
        match self.read_slot(p, &mut buf).ok()? {
            Slot::Valid { epoch, index } if epoch == self.epoch && index == k => {}
            _ => return None,
        }
        let n = self.layout.record_len();
        let dt = f32::from_le_bytes(buf.get(8..12)?.try_into().ok()?);
        let mut bits: Bits = [0u8; core::mem::size_of::<Bits>()];
        bits.get_mut(..n)?
            .copy_from_slice(buf.get(HEADER..HEADER + n)?);
        Some(unpack(&bits, f64::from(dt)))
    }

    /// Forgets records from `len` on without writing (see the
    /// [module docs](self), "Truncating"); `truncate(0)` starts a new run.
    fn truncate(&mut self, len: usize) {
        let Ok(n) = u32::try_from(len) else {
            return;
        };
        if n >= self.len {
            return;
        }
        if n == 0 {
            self.restart();
            return;
        }
        while self.used > 0
            && self
                .segments
                .get(self.used - 1)
                .is_some_and(|s| s.start >= n)
        {
            self.used -= 1;
        }
        self.len = n;
    }
}
