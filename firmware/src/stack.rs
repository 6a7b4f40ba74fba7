//! Stack high-water mark by painting: fill the unused stack with a pattern
//! at start-up, and later find the lowest word that was overwritten.

use core::ptr::{addr_of, read_volatile, write_volatile};

const PAINT: u32 = 0xCDCD_CDCD;
/// Bytes below the current stack pointer left unpainted (the painter's own
/// frame and a margin).
const MARGIN: usize = 256;

extern "C" {
    static _stack_start: u32;
    static __ebss: u32;
    static __euninit: u32;
}

fn bounds() -> (usize, usize) {
    // SAFETY: linker-provided symbols; only their addresses are used.
    let top = addr_of!(_stack_start) as usize;
    let bottom = addr_of!(__euninit) as usize;
    let ebss = addr_of!(__ebss) as usize;
    (top, bottom.max(ebss).next_multiple_of(4))
}

fn sp() -> usize {
    let x = 0u32;
    addr_of!(x) as usize
}

/// Paints the stack below the caller's frame. Call once, early.
pub fn paint() {
    let (_, bottom) = bounds();
    let end = sp().saturating_sub(MARGIN) & !3;
    let mut a = bottom;
    while a < end {
        // SAFETY: [bottom, sp − margin) is unused stack memory owned by us.
        unsafe { write_volatile(a as *mut u32, PAINT) };
        a += 4;
    }
}

/// Peak stack use since [`paint`] in bytes (from the top of RAM), and the
/// size of the stack region (top of RAM to the end of static data).
pub fn peak() -> (usize, usize) {
    let (top, bottom) = bounds();
    let mut a = bottom;
    // SAFETY: reads of stack memory between the end of .bss and the top.
    while a < top && unsafe { read_volatile(a as *const u32) } == PAINT {
        a += 4;
    }
    (top - a, top - bottom)
}
