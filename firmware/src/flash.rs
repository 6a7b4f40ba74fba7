//! The sample log's storage: a NOR flash device over the mps2 boards'
//! SSRAM, behind `embedded-storage`'s [`NorFlash`] traits, so that the log
//! is `rollcal::estimator::FlashLog` exactly as on a flight computer whose
//! HAL implements them for its flash.
//!
//! The device is [`LOG_BYTES`] of the `LOG` region of `memory.x` (SSRAM2&3
//! from 0x2010_0000, NOLOAD: the start-up code neither copies nor zeroes
//! it). It behaves as a serial NOR chip: [`ERASE_SIZE`]-byte sectors that
//! an erase sets to `0xFF`; writes of whole [`WRITE_SIZE`]-byte words at
//! aligned offsets that only clear bits (a word written twice without an
//! erase holds the AND of both, as on a real chip); reads of any byte.
//! Misaligned or out-of-range calls fail as the traits specify
//! ([`check_erase`], [`check_write`], [`check_read`]), and the device
//! counts what the log asks of it ([`Ssram::stats`]).
//!
//! Under QEMU the SSRAM starts zeroed, which a NOR chip never is: every
//! slot then reads as a torn write, and `FlashLog::open` finds no record
//! and erases each sector as the log enters it.

use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicBool, Ordering};

use embedded_storage::nor_flash::{
    check_erase, check_read, check_write, ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash,
};

/// Bytes of the device: 128 sectors of 4 KiB, 9 984 periods of M2-ps (52
/// bytes a slot, 78 slots a sector) or 11 904 of the other configurations
/// (44 bytes, 93 a sector): the paper's 5 400 periods with room for a
/// restarted run's slots.
pub const LOG_BYTES: usize = 512 * 1024;
/// Erase sector (bytes): a serial NOR chip's 4 KiB sector.
pub const ERASE_SIZE: usize = 4096;
/// Program word (bytes).
pub const WRITE_SIZE: usize = 4;

/// The device's memory, in the `LOG` region. Only [`Ssram::take`] touches it.
#[link_section = ".log"]
static mut MEMORY: MaybeUninit<[u8; LOG_BYTES]> = MaybeUninit::uninit();

/// Set once [`Ssram::take`] has handed out [`MEMORY`].
static TAKEN: AtomicBool = AtomicBool::new(false);

/// What the log asked of the device.
#[derive(Clone, Copy, Debug, Default, defmt::Format)]
pub struct FlashStats {
    /// Sector erases.
    pub erases: u32,
    /// Write calls.
    pub writes: u32,
    /// Bytes written.
    pub bytes_written: u32,
    /// Read calls.
    pub reads: u32,
}

/// The NOR flash over SSRAM (see the module docs).
pub struct Ssram {
    mem: &'static mut [u8],
    stats: FlashStats,
}

impl Ssram {
    /// The device; `None` on a second call. Its bytes are whatever the
    /// memory holds (a log left by an earlier run, on a device that keeps
    /// it; zeros under QEMU).
    pub fn take() -> Option<Self> {
        if TAKEN.swap(true, Ordering::AcqRel) {
            return None;
        }
        // SAFETY: the flag above makes this the only reference ever made
        // to MEMORY. Bytes have no invalid values, and the region is RAM
        // that reads back what was last written (zeros at QEMU's start),
        // so every byte is initialised.
        let mem = unsafe { &mut *addr_of_mut!(MEMORY).cast::<[u8; LOG_BYTES]>() };
        Some(Self {
            mem,
            stats: FlashStats::default(),
        })
    }

    /// What the log has asked of the device so far.
    pub fn stats(&self) -> FlashStats {
        self.stats
    }

    /// The bytes of `offset .. offset + len`, checked by the caller.
    fn range(&mut self, offset: u32, len: usize) -> Result<&mut [u8], NorFlashErrorKind> {
        let at = offset as usize;
        self.mem
            .get_mut(at..at.checked_add(len).ok_or(NorFlashErrorKind::OutOfBounds)?)
            .ok_or(NorFlashErrorKind::OutOfBounds)
    }
}

impl ErrorType for Ssram {
    type Error = NorFlashErrorKind;
}

impl ReadNorFlash for Ssram {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
        check_read(self, offset, bytes.len())?;
        self.stats.reads = self.stats.reads.wrapping_add(1);
        bytes.copy_from_slice(self.range(offset, bytes.len())?);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.mem.len()
    }
}

impl NorFlash for Ssram {
    const WRITE_SIZE: usize = WRITE_SIZE;
    const ERASE_SIZE: usize = ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
        check_erase(self, from, to)?;
        let sectors = (to - from) / ERASE_SIZE as u32;
        self.range(from, (to - from) as usize)?.fill(0xFF);
        self.stats.erases = self.stats.erases.wrapping_add(sectors);
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
        check_write(self, offset, bytes.len())?;
        for (cell, b) in self.range(offset, bytes.len())?.iter_mut().zip(bytes) {
            // Programming only clears bits.
            *cell &= *b;
        }
        self.stats.writes = self.stats.writes.wrapping_add(1);
        self.stats.bytes_written = self.stats.bytes_written.wrapping_add(bytes.len() as u32);
        Ok(())
    }
}
