//! Marker functions for instruction counting under QEMU.
//!
//! `tools/qemu-insnmark` counts the guest instructions executed between the
//! first instruction of a `*_start` marker and that of the matching `*_end`
//! marker. Each marker has its own body (a distinct volatile store), so the
//! linker cannot merge them, and none is inlined, so its address is the
//! address the plugin watches (`arm-none-eabi-nm` finds them by name).

use core::ptr::addr_of_mut;

static mut MARK: u32 = 0;

macro_rules! marker {
    ($name:ident, $v:expr) => {
        #[doc = concat!("Instruction-count marker `", stringify!($name), "`.")]
        #[no_mangle]
        #[inline(never)]
        pub extern "C" fn $name() {
            // SAFETY: a plain store to a private static on a single core.
            unsafe { core::ptr::write_volatile(addr_of_mut!(MARK), $v) }
        }
    };
}

marker!(rollcal_mark_period_start, 1);
marker!(rollcal_mark_period_end, 2);
marker!(rollcal_mark_finish_start, 3);
marker!(rollcal_mark_finish_end, 4);
marker!(rollcal_mark_frame_start, 5);
marker!(rollcal_mark_frame_end, 6);
