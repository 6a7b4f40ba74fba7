//! Where `calibrate --replies` sends the calibrator's replies (docs/wire.md:
//! the periodic `Estimate`s, the answers to the requests, `Finish`'s
//! answer, the refusals), as wire frames: a file, standard output, or back
//! on the serial device the stream comes from.

use std::io::Write;
use std::path::PathBuf;

use rollcal::wire::Message;

use super::stream::push_frame;
use super::Error;

/// Where the replies go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ReplyTarget {
    /// A file (created, or truncated).
    File(PathBuf),
    /// Standard output (`-`): the tables then go to standard error.
    Stdout,
    /// Back on the serial device of `--input` (`serial`).
    Serial,
}

/// The value parser of `--replies`: `-`, `serial`, or a path.
pub fn parse_target(s: &str) -> Result<ReplyTarget, String> {
    Ok(match s {
        "" => return Err("--replies needs a path, - or serial".into()),
        "-" => ReplyTarget::Stdout,
        "serial" => ReplyTarget::Serial,
        path => ReplyTarget::File(PathBuf::from(path)),
    })
}

/// The replies' destination once open, and how many frames went there.
pub struct ReplySink {
    out: Option<(String, Box<dyn Write>)>,
    serial: bool,
    /// Frames sent.
    pub frames: u64,
}

impl ReplySink {
    /// Opens `target` (`None`: the replies are dropped).
    pub fn open(target: Option<&ReplyTarget>) -> Result<Self, Error> {
        let out: Option<(String, Box<dyn Write>)> = match target {
            Some(ReplyTarget::File(p)) => {
                let f = std::fs::File::create(p).map_err(|source| Error::Write {
                    path: p.display().to_string(),
                    source,
                })?;
                Some((
                    p.display().to_string(),
                    Box::new(std::io::BufWriter::new(f)),
                ))
            }
            Some(ReplyTarget::Stdout) => Some(("stdout".into(), Box::new(std::io::stdout()))),
            Some(ReplyTarget::Serial) | None => None,
        };
        Ok(Self {
            out,
            serial: target == Some(&ReplyTarget::Serial),
            frames: 0,
        })
    }

    /// Sends `msgs` as frames: to the file or standard output, or returned
    /// for the caller to write back on the serial device (empty otherwise).
    pub fn send(&mut self, msgs: &[Message]) -> Result<Vec<u8>, Error> {
        if msgs.is_empty() || (self.out.is_none() && !self.serial) {
            return Ok(Vec::new());
        }
        let mut bytes = Vec::new();
        for m in msgs {
            push_frame(&mut bytes, m)?;
        }
        self.frames += msgs.len() as u64;
        match &mut self.out {
            Some((path, w)) => {
                w.write_all(&bytes)
                    .and_then(|()| w.flush())
                    .map_err(|source| Error::Write {
                        path: path.clone(),
                        source,
                    })?;
                Ok(Vec::new())
            }
            None => Ok(bytes),
        }
    }

    /// Whether replies go back on the serial device.
    pub fn to_serial(&self) -> bool {
        self.serial
    }
}
