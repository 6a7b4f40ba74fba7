//! Wire frames of a recorded run (docs/wire.md): a simulated period as
//! the platform would send it, frames appended to a byte stream, and the
//! reading of a file, stdin or a serial port until its end (or until it is
//! idle); the frame and reject counters as JSON.

use std::io::Read;
use std::time::{Duration, Instant as Clock};

use nalgebra::Vector3;
use rollcal::wire::{encode, DecoderStats, Message, Sample, MAX_FRAME_LEN};

use super::Error;
use crate::sim::truth::PeriodSample;

/// Format of a recorded log.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Binary wire frames (docs/wire.md).
    Frames,
    /// CSV, one line per period (docs/csv.md).
    Csv,
}

/// A simulated period as the platform would send it (f32 fields but the
/// commanded increment, f64; the timestamp is the end of the period in µs).
pub fn to_sample(s: &PeriodSample) -> Sample {
    let f = |v: &Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
    Sample {
        seq: s.k,
        t_us: (s.truth.t * 1e6).round() as u64,
        dt: s.dt as f32,
        dtheta_cmd: s.dtheta_cmd.into(),
        accel_mean: f(&s.accel_mean),
        gimbal: Some(f(&s.gimbal)),
        c_cn_quat: rollcal::geometry::quaternion_from_dcm(&s.truth.c_c_n).map(|v| v as f32),
    }
}

/// `record` writes binary frames: to stdout (`out` = `-`) only when stdout
/// is not a terminal (`stdout_is_terminal`).
pub fn refuse_terminal(out: &str, stdout_is_terminal: bool) -> Result<(), String> {
    if out == "-" && stdout_is_terminal {
        return Err(
            "record writes binary frames: give --out FILE, or redirect or pipe stdout (e.g. | host-sim calibrate --input -)"
                .into(),
        );
    }
    Ok(())
}

/// Appends the frame of `m` to `out`.
pub fn push_frame(out: &mut Vec<u8>, m: &Message) -> Result<(), Error> {
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode(m, &mut buf).map_err(Error::Encode)?;
    out.extend_from_slice(buf.get(..n).unwrap_or_default());
    Ok(())
}

/// Whether `input` is a character device (a serial port, a
/// pseudo-terminal), not a file or `-`.
pub fn is_device(input: &str) -> bool {
    if input == "-" {
        return false;
    }
    let Ok(meta) = std::fs::metadata(input) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        meta.file_type().is_char_device()
    }
    #[cfg(not(unix))]
    {
        !meta.is_file()
    }
}

/// A byte source being read: a serial port can be written back to.
trait Source: Read {
    /// Writes `bytes` back (a serial port); elsewhere there is nowhere to
    /// write them.
    fn write_back(&mut self, bytes: &[u8]) -> std::io::Result<()>;
}

impl<R: Read> Source for ReadOnly<R> {
    fn write_back(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        if bytes.is_empty() {
            return Ok(());
        }
        Err(std::io::Error::other(
            "replies can be written back only to a serial device",
        ))
    }
}

/// A file or stdin: read only.
struct ReadOnly<R>(R);

impl<R: Read> Read for ReadOnly<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

/// A serial port, written back to.
struct Port(Box<dyn serialport::SerialPort>);

impl Read for Port {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

impl Source for Port {
    fn write_back(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        use std::io::Write;
        self.0.write_all(bytes)?;
        self.0.flush()
    }
}

/// Reads an input until its end (or, for a serial port, until it has been
/// idle for `idle`: then `Some(idle)`), feeding `on_bytes`; what it returns
/// is written back to a serial port (replies; it must return nothing for a
/// file or stdin).
pub fn read_input(
    input: &str,
    baud: u32,
    idle: Duration,
    mut on_bytes: impl FnMut(&[u8]) -> Result<Vec<u8>, String>,
) -> Result<Option<Duration>, Error> {
    let mut buf = vec![0u8; 4096];
    let mut drain = |r: &mut dyn Source, serial: bool| -> Result<Option<Duration>, Error> {
        let mut last = Clock::now();
        loop {
            match r.read(&mut buf) {
                Ok(0) if !serial => return Ok(None),
                Ok(n) => {
                    if n > 0 {
                        last = Clock::now();
                    }
                    let back =
                        on_bytes(buf.get(..n).unwrap_or_default()).map_err(Error::Stopped)?;
                    r.write_back(&back).map_err(|source| Error::Write {
                        path: input.into(),
                        source,
                    })?;
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) if serial && e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(source) => {
                    return Err(Error::Read {
                        path: input.into(),
                        source,
                    })
                }
            }
            if serial && last.elapsed() > idle {
                return Ok(Some(idle));
            }
        }
    };
    if input == "-" {
        return drain(&mut ReadOnly(std::io::stdin().lock()), false);
    }
    let open = |source| Error::Open {
        path: input.into(),
        source,
    };
    std::fs::metadata(input).map_err(open)?;
    if is_device(input) {
        let port = serialport::new(input, baud)
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|source| Error::OpenSerial {
                path: input.into(),
                baud,
                source,
            })?;
        drain(&mut Port(port), true)
    } else {
        let f = std::fs::File::open(input).map_err(open)?;
        drain(&mut ReadOnly(f), false)
    }
}

/// The whole of a text input (a file or `-` for stdin).
pub fn read_text(input: &str) -> Result<String, Error> {
    if input == "-" {
        let mut text = String::new();
        std::io::stdin()
            .lock()
            .read_to_string(&mut text)
            .map_err(|source| Error::Read {
                path: "stdin".into(),
                source,
            })?;
        return Ok(text);
    }
    std::fs::read_to_string(input).map_err(|source| Error::Open {
        path: input.into(),
        source,
    })
}

/// The reject counters as JSON.
pub fn reject_json(c: &rollcal::wire::RejectCounts) -> serde_json::Value {
    serde_json::to_value(c).unwrap_or_default()
}

/// The decoder's frame counters as JSON.
pub fn frames_json(s: &DecoderStats) -> serde_json::Value {
    serde_json::to_value(s).unwrap_or_default()
}

/// Writes `bytes` to the serial device `input` (opened again at `baud`):
/// what is sent back after the stream has ended.
pub fn write_device(input: &str, baud: u32, bytes: &[u8]) -> Result<(), Error> {
    use std::io::Write;
    let mut port = serialport::new(input, baud)
        .timeout(Duration::from_millis(1000))
        .open()
        .map_err(|source| Error::OpenSerial {
            path: input.into(),
            baud,
            source,
        })?;
    port.write_all(bytes)
        .and_then(|()| port.flush())
        .map_err(|source| Error::Write {
            path: input.into(),
            source,
        })
}
