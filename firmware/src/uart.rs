//! Polling driver for the ARM CMSDK APB UART of QEMU's mps2 boards
//! (UART0 at `0x4000_4000`, wired to QEMU's first `-serial` device).
//!
//! Registers (CMSDK APB UART TRM; QEMU `hw/char/cmsdk-apb-uart.c`):
//! `DATA` (+0x00), `STATE` (+0x04: bit 0 TX full, bit 1 RX full),
//! `CTRL` (+0x08: bit 0 TX enable, bit 1 RX enable), `BAUDDIV` (+0x10).
//!
//! QEMU's model holds one received byte: its chardev backend offers the next
//! byte only when `STATE.RXFULL` is clear (the device "can receive"), so a
//! guest that polls `STATE` and reads `DATA` never loses input, however slowly
//! it reads. Transmission is immediate (the byte is written to the chardev).

use core::ptr::{read_volatile, write_volatile};

/// UART0 of the mps2-an386/an500 boards (QEMU's first `-serial`).
pub const UART0_BASE: usize = 0x4000_4000;
/// UART1 of the mps2-an386/an500 boards (QEMU's second `-serial`).
pub const UART1_BASE: usize = 0x4000_5000;

const DATA: usize = 0x00;
const STATE: usize = 0x04;
const CTRL: usize = 0x08;
const BAUDDIV: usize = 0x10;

const STATE_TX_FULL: u32 = 1 << 0;
const STATE_RX_FULL: u32 = 1 << 1;
const CTRL_TX_EN: u32 = 1 << 0;
const CTRL_RX_EN: u32 = 1 << 1;

/// A polled CMSDK APB UART.
pub struct Uart {
    base: usize,
}

impl Uart {
    /// Enables transmitter and receiver of the UART at `base`.
    ///
    /// # Safety
    /// `base` must be the address of a CMSDK APB UART that nothing else uses.
    pub unsafe fn new(base: usize) -> Self {
        let u = Self { base };
        // The divisor only matters to QEMU as "≥ 16" (below that it logs a
        // guest error); 25 MHz / 16 is fast enough to be irrelevant here.
        u.write_reg(BAUDDIV, 16);
        u.write_reg(CTRL, CTRL_TX_EN | CTRL_RX_EN);
        u
    }

    fn reg(&self, off: usize) -> *mut u32 {
        (self.base + off) as *mut u32
    }

    fn read_reg(&self, off: usize) -> u32 {
        // SAFETY: `new` was given the address of the device's register block.
        unsafe { read_volatile(self.reg(off)) }
    }

    fn write_reg(&self, off: usize, v: u32) {
        // SAFETY: as in `read_reg`.
        unsafe { write_volatile(self.reg(off), v) }
    }

    /// The received byte, if one is waiting.
    pub fn try_read(&mut self) -> Option<u8> {
        if self.read_reg(STATE) & STATE_RX_FULL != 0 {
            Some(self.read_reg(DATA) as u8)
        } else {
            None
        }
    }

    /// Writes all of `bytes`, waiting while the transmit buffer is full.
    pub fn write_all(&mut self, bytes: &[u8]) {
        for &b in bytes {
            while self.read_reg(STATE) & STATE_TX_FULL != 0 {}
            self.write_reg(DATA, u32::from(b));
        }
    }
}
