//! [`Error`]: why reading or writing a stream, a CSV log or a truth sidecar
//! failed. Its `Display` is the one-line message the command line prints.

use std::fmt;

use rollcal::models::ConfigId;

/// Why an input or output of [`crate::io`] failed.
#[derive(Debug)]
pub enum Error {
    /// A file could not be opened (`cannot open PATH: …`).
    Open {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A serial device could not be opened.
    OpenSerial {
        /// The device.
        path: String,
        /// Its baud rate.
        baud: u32,
        /// Why.
        source: serialport::Error,
    },
    /// A read failed (`cannot read PATH: …`; `stdin` for the standard input).
    Read {
        /// The file, device or `stdin`.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A write failed (`cannot write PATH: …`).
    Write {
        /// The file or device.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// What the bytes were fed to refused them (e.g. the calibrator's
    /// session): its message.
    Stopped(String),
    /// A frame could not be encoded.
    Encode(rollcal::wire::EncodeError),
    /// A CSV log that cannot be read: the line and column, and why.
    Csv(String),
    /// The settings of an input cannot be had: a platform file or scenario
    /// that does not load, options that contradict it, a CSV log without a
    /// configuration.
    Settings(String),
    /// A file that is not a truth sidecar.
    NotSidecar {
        /// The file.
        path: String,
        /// Why.
        source: serde_json::Error,
    },
    /// A truth sidecar of another configuration.
    SidecarConfig {
        /// The file.
        path: String,
        /// The configuration it holds (its JSON value).
        found: serde_json::Value,
        /// The configuration of the stream.
        expected: ConfigId,
    },
    /// A truth sidecar without one of its arrays.
    SidecarArray {
        /// The file.
        path: String,
        /// The missing key.
        key: String,
    },
    /// A truth sidecar array of the wrong length.
    SidecarLength {
        /// The file.
        path: String,
        /// The key.
        key: String,
        /// Its length.
        found: usize,
        /// The length it must have.
        expected: usize,
    },
    /// The Cramér–Rao bound of a sidecar could not be computed.
    Bound(rollcal::ekf::Error),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Open { path, source } => write!(f, "cannot open {path}: {source}"),
            Error::OpenSerial { path, baud, source } => {
                write!(f, "cannot open serial device {path} at {baud} Bd: {source}")
            }
            Error::Read { path, source } => write!(f, "cannot read {path}: {source}"),
            Error::Write { path, source } => write!(f, "cannot write {path}: {source}"),
            Error::Stopped(m) | Error::Csv(m) | Error::Settings(m) => f.write_str(m),
            Error::Encode(e) => write!(f, "{e}"),
            Error::NotSidecar { path, source } => {
                write!(f, "{path} is not a truth sidecar: {source}")
            }
            Error::SidecarConfig {
                path,
                found,
                expected,
            } => write!(f, "{path} holds the truth of {found}, not {expected}"),
            Error::SidecarArray { path, key } => write!(f, "{path}: no '{key}' array"),
            Error::SidecarLength {
                path,
                key,
                found,
                expected,
            } => write!(f, "{path}: '{key}' has {found} values, not {expected}"),
            Error::Bound(e) => write!(f, "Cramér–Rao bound: {e}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Open { source, .. }
            | Error::Read { source, .. }
            | Error::Write { source, .. } => Some(source),
            Error::OpenSerial { source, .. } => Some(source),
            Error::NotSidecar { source, .. } => Some(source),
            _ => None,
        }
    }
}
