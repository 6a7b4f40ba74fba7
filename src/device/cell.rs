//! [`DeviceCell`]: a [`Device`] in a `static`, built in place the first
//! time it is taken. The crate's only `unsafe` code that hands out memory
//! is here, so that a firmware needs none.
#![allow(unsafe_code)]

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::ptr::addr_of_mut;
use core::sync::atomic::{AtomicBool, Ordering};

use embedded_storage::nor_flash::NorFlash;
use nalgebra::RealField;

use super::{Device, DeviceStats, Hooks, DEFAULT_CHECKPOINT_EVERY};
use crate::estimator::EstimatorOptions;
use crate::session::{Reply, Session};
use crate::wire::Decoder;

/// Room for a [`Device`] in a `static`: `const`-constructible, zero bytes
/// in the image (`.bss`), and the device built in place, field by field,
/// the first time it is taken ([`DeviceCell::take`]): no device-sized
/// value on the stack (87.3 KB with the full model in `f64`).
///
/// # Examples
///
/// ```
/// # use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
/// # struct Nor;
/// # impl ErrorType for Nor { type Error = NorFlashErrorKind; }
/// # impl ReadNorFlash for Nor {
/// #     const READ_SIZE: usize = 1;
/// #     fn read(&mut self, _: u32, _: &mut [u8]) -> Result<(), Self::Error> { Ok(()) }
/// #     fn capacity(&self) -> usize { 0 }
/// # }
/// # impl NorFlash for Nor {
/// #     const WRITE_SIZE: usize = 4;
/// #     const ERASE_SIZE: usize = 4096;
/// #     fn erase(&mut self, _: u32, _: u32) -> Result<(), Self::Error> { Ok(()) }
/// #     fn write(&mut self, _: u32, _: &[u8]) -> Result<(), Self::Error> { Ok(()) }
/// # }
/// use rollcal::device::DeviceCell;
///
/// static DEVICE: DeviceCell<Nor, f32> = DeviceCell::new();
///
/// let device = DEVICE.take();
/// assert!(device.is_some());
/// assert!(DEVICE.take().is_none()); // one device, one owner
/// ```
pub struct DeviceCell<F, T: RealField + Copy> {
    taken: AtomicBool,
    slot: UnsafeCell<MaybeUninit<Device<F, T>>>,
}

// SAFETY: the only access to `slot` is through `take`, which hands out one
// `&mut` for the program's life (the flag is swapped atomically); sending
// that reference to another thread moves the device, hence `F: Send`.
unsafe impl<F: Send, T: RealField + Copy + Send> Sync for DeviceCell<F, T> {}

impl<F, T: RealField + Copy> DeviceCell<F, T> {
    /// An empty cell (for a `static`).
    pub const fn new() -> Self {
        Self {
            taken: AtomicBool::new(false),
            slot: UnsafeCell::new(MaybeUninit::uninit()),
        }
    }
}

impl<F: NorFlash, T: RealField + Copy> DeviceCell<F, T> {
    /// The device, built in place; `None` after the first call. Out of
    /// line: the frame that builds it is gone before the device runs.
    // The flag makes the `&mut` unique (what `mut_from_ref` guards against).
    #[allow(clippy::mut_from_ref)]
    #[inline(never)]
    pub fn take(&'static self) -> Option<&'static mut Device<F, T>> {
        if self.taken.swap(true, Ordering::AcqRel) {
            return None;
        }
        let p = self.slot.get().cast::<Device<F, T>>();
        // SAFETY: the flag above makes this the only reference ever made
        // to the slot; every field is written before it is formed.
        unsafe {
            Session::init_at(
                addr_of_mut!((*p).session),
                None,
                EstimatorOptions::default(),
            );
            addr_of_mut!((*p).decoder).write(Decoder::new());
            addr_of_mut!((*p).slot).write(Reply::Nothing);
            addr_of_mut!((*p).store).write(None);
            addr_of_mut!((*p).checkpoint_every).write(DEFAULT_CHECKPOINT_EVERY);
            addr_of_mut!((*p).hooks).write(Hooks::NONE);
            addr_of_mut!((*p).last_tag).write(None);
            addr_of_mut!((*p).stats).write(DeviceStats::default());
            Some(&mut *p)
        }
    }
}

impl<F, T: RealField + Copy> Default for DeviceCell<F, T> {
    fn default() -> Self {
        Self::new()
    }
}
