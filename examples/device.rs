//! A firmware integration over the kit ([`rollcal::device`]), as it would
//! run on a flight computer, with the HAL's two drivers stood in for on
//! the host: the UART delivers the recorded paper stream
//! (`tests/data/paper_seed1.bin`: `Configure` for M2-ps, 5400 `Sample`
//! frames) and then a `Finish`; the flash is a NOR device in RAM. Half way
//! through the stream the power is cut: the board boots again, the device
//! resumes from the flash alone, and the UART goes on where it was.
//!
//! The firmware's own code is between the `glue` marks: 29 lines (a test,
//! `device::the_example_glue_is_at_most_60_lines`, counts them).
//!
//! `cargo run --release --example device`

use std::collections::VecDeque;
use std::process::ExitCode;

use embedded_storage::nor_flash::{ErrorType, NorFlash, NorFlashErrorKind, ReadNorFlash};
use rollcal::device::DeviceCell;
use rollcal::wire::{self, EstimateKind, Message, MAX_FRAME_LEN};

/// The HAL's drivers (stand-ins: on a board these come with the chip).
mod hal {
    use super::*;

    /// A NOR flash of 512 KiB, 4 KiB sectors, 4-byte words, as a HAL's
    /// driver implements `embedded-storage` (here in RAM, kept over a
    /// reset as a flash is).
    pub struct Flash(pub Vec<u8>);

    impl ErrorType for Flash {
        type Error = NorFlashErrorKind;
    }

    impl ReadNorFlash for Flash {
        const READ_SIZE: usize = 1;
        fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
            let at = offset as usize;
            let src = self.0.get(at..at + bytes.len());
            bytes.copy_from_slice(src.ok_or(NorFlashErrorKind::OutOfBounds)?);
            Ok(())
        }
        fn capacity(&self) -> usize {
            self.0.len()
        }
    }

    impl NorFlash for Flash {
        const WRITE_SIZE: usize = 4;
        const ERASE_SIZE: usize = 4096;
        fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
            let dst = self.0.get_mut(from as usize..to as usize);
            dst.ok_or(NorFlashErrorKind::OutOfBounds)?.fill(0xFF);
            Ok(())
        }
        fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
            let at = offset as usize;
            let dst = self.0.get_mut(at..at + bytes.len());
            let dst = dst.ok_or(NorFlashErrorKind::OutOfBounds)?;
            for (d, s) in dst.iter_mut().zip(bytes) {
                *d &= *s; // NOR: a write only clears bits
            }
            Ok(())
        }
    }

    /// A UART: bytes in from the host, frames out to it.
    pub struct Uart {
        pub rx: VecDeque<u8>,
        pub tx: Vec<Vec<u8>>,
    }

    impl Uart {
        pub fn read_byte(&mut self) -> Option<u8> {
            self.rx.pop_front()
        }
        pub fn write_all(&mut self, bytes: &[u8]) {
            self.tx.push(bytes.to_vec());
        }
    }
}

// glue: begin
use hal::{Flash, Uart};

/// The flash region the calibration owns (the whole device here).
const REGION: core::ops::Range<u32> = 0..512 * 1024;

/// One boot of the board: the device resumes from the flash, then takes
/// every byte the UART gives (up to `bytes` of them) and is idle between.
fn boot(
    cell: &'static DeviceCell<Flash, f64>,
    flash: Flash,
    uart: &mut Uart,
    bytes: usize,
) -> Flash {
    let Some(device) = cell.take() else {
        unreachable!("each boot has its own device");
    };
    match device.start(flash, REGION) {
        Ok(resume) => println!("boot: {resume:?}"),
        Err((_, e)) => println!("boot: no flash log ({e})"),
    }
    for _ in 0..bytes {
        let Some(byte) = uart.read_byte() else { break };
        let reply = device.push_byte(byte);
        if !reply.is_empty() {
            uart.write_all(reply);
        }
        if byte == 0 {
            device.idle(); // between frames: erase ahead, write a due checkpoint
        }
    }
    device.release().unwrap_or(Flash(Vec::new()))
}

/// Two boots: a power cut half way through the stream.
static FIRST_BOOT: DeviceCell<Flash, f64> = DeviceCell::new();
static AFTER_THE_CUT: DeviceCell<Flash, f64> = DeviceCell::new();
// glue: end

/// The recorded stream: one `Configure`, then one `Sample` per period.
const STREAM: &[u8] = include_bytes!("../tests/data/paper_seed1.bin");

const ARCSEC: f64 = std::f64::consts::PI / 180.0 / 3600.0;

fn run() -> Result<(), String> {
    let mut bytes = STREAM.to_vec();
    let mut frame = [0u8; MAX_FRAME_LEN];
    let n = wire::encode(&Message::Finish, &mut frame).map_err(|e| format!("encode: {e}"))?;
    bytes.extend_from_slice(frame.get(..n).unwrap_or_default());
    let mut uart = hal::Uart {
        rx: bytes.into_iter().collect(),
        tx: Vec::new(),
    };
    let flash = boot(
        &FIRST_BOOT,
        Flash(vec![0xFF; 512 * 1024]),
        &mut uart,
        STREAM.len() / 2,
    );
    println!(
        "power cut after {} of {} bytes",
        STREAM.len() / 2,
        STREAM.len()
    );
    boot(&AFTER_THE_CUT, flash, &mut uart, usize::MAX);

    let mut last = uart.tx.pop().ok_or("no reply at all")?;
    let n = last.len();
    let body = last.get_mut(..n.saturating_sub(1)).unwrap_or_default();
    let Message::Estimate(e) = wire::decode_frame(body).map_err(|e| e.to_string())? else {
        return Err("the last reply is not an Estimate".into());
    };
    let EstimateKind::Final { passes, converged } = e.kind else {
        return Err(format!(
            "the answer is not the estimator of record: {:?}",
            e.kind
        ));
    };
    println!(
        "final estimate of record: {passes} passes (converged {converged}), {} samples, \
         {} estimates sent; phi = ({:.2}, {:.2}, {:.2})\" (sigma {:.3}\")",
        e.progress.accepted,
        uart.tx.len() + 1,
        e.state[0] / ARCSEC,
        e.state[1] / ARCSEC,
        e.state[2] / ARCSEC,
        e.sigma[0] / ARCSEC,
    );
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("device: {e}");
            ExitCode::FAILURE
        }
    }
}
