//! The CSV log (docs/csv.md): one line per filter period with the
//! quantities of a wire [`Sample`] (docs/wire.md), for platforms that log
//! to a file rather than send frames.
//!
//! Floats are written with Rust's shortest round-trip representation
//! (`{}` of `f32`/`f64`) and the time as an exact decimal of its
//! microseconds, so frames → CSV → frames is lossless: every field of
//! every sample comes back bit for bit.

use nalgebra::{Matrix3, Vector3};
use rollcal::command::CommandFrame;
use rollcal::geometry::{euler_angles, wrap_angles};
use rollcal::wire::{CalibratorConfig, Sample};

use super::Error;

/// Column names, in the order `record --format csv` writes them.
pub const COLUMNS: [&str; 16] = [
    "seq",
    "t_s",
    "dt_s",
    "dtheta_x_rad",
    "dtheta_y_rad",
    "dtheta_z_rad",
    "accel_x_g",
    "accel_y_g",
    "accel_z_g",
    "gimbal_alpha_rad",
    "gimbal_beta_rad",
    "gimbal_gamma_rad",
    "ccn_qw",
    "ccn_qx",
    "ccn_qy",
    "ccn_qz",
];

/// Columns every log must have (the first nine).
const REQUIRED: usize = 9;
/// Index of the first gimbal column and of the first quaternion column.
const GIMBAL: usize = 9;
const QUAT: usize = 12;

/// The header line (no newline).
pub fn header() -> String {
    COLUMNS.join(",")
}

/// One sample as a CSV line (no newline); empty gimbal fields without
/// gimbal angles.
pub fn line(s: &Sample) -> String {
    let mut f: Vec<String> = Vec::with_capacity(COLUMNS.len());
    f.push(s.seq.to_string());
    f.push(format!("{}.{:06}", s.t_us / 1_000_000, s.t_us % 1_000_000));
    f.push(s.dt.to_string());
    f.extend(s.dtheta_cmd.iter().map(|v| v.to_string()));
    f.extend(s.accel_mean.iter().map(|v| v.to_string()));
    match s.gimbal {
        Some(g) => f.extend(g.iter().map(|v| v.to_string())),
        None => f.extend([String::new(), String::new(), String::new()]),
    }
    f.extend(s.c_cn_quat.iter().map(|v| v.to_string()));
    f.join(",")
}

/// The whole log: header, then one line per sample.
pub fn write(samples: &[Sample]) -> String {
    let mut out = String::with_capacity(samples.len() * 200 + 200);
    out.push_str(&header());
    out.push('\n');
    for s in samples {
        out.push_str(&line(s));
        out.push('\n');
    }
    out
}

/// A parsed log.
#[derive(Clone, Debug, PartialEq)]
pub struct Log {
    /// The samples, in file order.
    pub samples: Vec<Sample>,
    /// Whether the log had the `ccn_q*` columns (else the quaternions are
    /// zero until [`fill_frames`]).
    pub has_frames: bool,
    /// The header's columns that are none of [`COLUMNS`] (a temperature, a
    /// status word, …), in file order: read past, not used.
    pub ignored: Vec<String>,
    /// Whether the log had the gimbal columns.
    pub has_gimbal: bool,
    /// The line of each sample in the file (1-based, counting every line),
    /// for messages about a sample.
    pub lines: Vec<usize>,
}

impl Log {
    /// The note for the user about the ignored columns, if any.
    pub fn ignored_note(&self) -> Option<String> {
        (!self.ignored.is_empty()).then(|| {
            let names: Vec<String> = self.ignored.iter().map(|n| format!("'{n}'")).collect();
            format!(
                "note: column(s) {} ignored: not one of docs/csv.md's ({})",
                names.join(", "),
                header()
            )
        })
    }
}

/// Parses a log. Blank lines and lines starting with `#` are skipped; the
/// first other line is the header. Columns of another name than
/// [`COLUMNS`]' are ignored ([`Log::ignored`]). Errors are one line and
/// name the line number (1-based) and the column.
pub fn parse(text: &str) -> Result<Log, Error> {
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim_end_matches('\r')))
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((hline, head)) = lines.next() else {
        return Err(Error::Csv("the CSV log is empty (no header line)".into()));
    };
    let h = parse_header(hline, head).map_err(Error::Csv)?;
    let mut samples = Vec::new();
    let mut numbers = Vec::new();
    for (n, l) in lines {
        samples.push(parse_line(&h, n, l).map_err(Error::Csv)?);
        numbers.push(n);
    }
    Ok(Log {
        samples,
        has_frames: h.has_frames,
        ignored: h.ignored,
        has_gimbal: h.has_gimbal,
        lines: numbers,
    })
}

/// The columns of a log's header line.
struct Header {
    /// Column index in the file of each of [`COLUMNS`].
    index: [Option<usize>; COLUMNS.len()],
    /// Number of columns of the header.
    columns: usize,
    /// Whether the gimbal columns are present.
    has_gimbal: bool,
    /// Whether the quaternion columns are present.
    has_frames: bool,
    /// The names of the columns that are none of [`COLUMNS`].
    ignored: Vec<String>,
}

/// Parses the header line `head` (line `hline`).
fn parse_header(hline: usize, head: &str) -> Result<Header, String> {
    // Column index of each named column in the file.
    let mut index = [None::<usize>; COLUMNS.len()];
    let mut ignored = Vec::new();
    let names: Vec<&str> = head.split(',').map(str::trim).collect();
    for (pos, name) in names.iter().enumerate() {
        let Some(k) = COLUMNS.iter().position(|c| c == name) else {
            ignored.push((*name).to_string());
            continue;
        };
        if index[k].replace(pos).is_some() {
            return Err(format!("line {hline}: column '{name}' appears twice"));
        }
    }
    if let Some(k) = (0..REQUIRED).find(|k| index[*k].is_none()) {
        return Err(format!(
            "line {hline}: the header has no column '{}' (required: {})",
            COLUMNS[k],
            COLUMNS[..REQUIRED].join(",")
        ));
    }
    let group = |from: usize, n: usize, what: &str| -> Result<bool, String> {
        let present = (from..from + n).filter(|k| index[*k].is_some()).count();
        if present != 0 && present != n {
            return Err(format!(
                "line {hline}: {what} columns {} must all be present or all absent",
                COLUMNS[from..from + n].join(",")
            ));
        }
        Ok(present == n)
    };
    let has_gimbal = group(GIMBAL, 3, "the gimbal")?;
    let has_frames = group(QUAT, 4, "the quaternion")?;
    Ok(Header {
        index,
        columns: names.len(),
        has_gimbal,
        has_frames,
        ignored,
    })
}

/// Parses line `n`, `l`, of a log with header `h`.
fn parse_line(h: &Header, n: usize, l: &str) -> Result<Sample, String> {
    let fields: Vec<&str> = l.split(',').map(str::trim).collect();
    if fields.len() != h.columns {
        return Err(format!(
            "line {n}: {} columns, the header has {}",
            fields.len(),
            h.columns
        ));
    }
    let field = |k: usize| {
        h.index[k]
            .and_then(|i| fields.get(i).copied())
            .unwrap_or("")
    };
    let bad = |k: usize| {
        format!(
            "line {n}: column {}: '{}' is not a number",
            COLUMNS[k],
            field(k)
        )
    };
    let f32_at = |k: usize| field(k).parse::<f32>().map_err(|_| bad(k));
    let f64_at = |k: usize| field(k).parse::<f64>().map_err(|_| bad(k));
    let seq = field(0).parse::<u32>().map_err(|_| {
        format!(
            "line {n}: column seq: '{}' is not a sequence number (0 to {})",
            field(0),
            u32::MAX
        )
    })?;
    let t = f64_at(1)?;
    let t_us = t * 1e6;
    if !(0.0..1.8e19).contains(&t_us) {
        return Err(format!(
            "line {n}: column t_s: {t} is not a time ≥ 0 s (microseconds must fit in 64 bits)"
        ));
    }
    let gimbal = if h.has_gimbal && (GIMBAL..GIMBAL + 3).any(|k| !field(k).is_empty()) {
        Some([f32_at(GIMBAL)?, f32_at(GIMBAL + 1)?, f32_at(GIMBAL + 2)?])
    } else {
        None
    };
    let c_cn_quat = if h.has_frames {
        [
            f32_at(QUAT)?,
            f32_at(QUAT + 1)?,
            f32_at(QUAT + 2)?,
            f32_at(QUAT + 3)?,
        ]
    } else {
        [0.0; 4]
    };
    Ok(Sample {
        seq,
        t_us: t_us.round() as u64,
        dt: f32_at(2)?,
        dtheta_cmd: [f64_at(3)?, f64_at(4)?, f64_at(5)?],
        accel_mean: [f32_at(6)?, f32_at(7)?, f32_at(8)?],
        gimbal,
        c_cn_quat,
    })
}

/// Fills the computed frame `C^c_n` of a log without `ccn_q*` columns by
/// integrating its commanded increments from `C^c_n(0) = I` (docs/model.md
/// §Measurement timing), as the filter does, for a calibrator of
/// `settings`. Such a log must have no missing sequence numbers (across a
/// gap the motion is unknown), and it must start where the path starts:
/// its first sample's specific force and gimbal angles within 5 prior σ
/// of what `C^c_n = I` gives, else a one-line error.
pub fn fill_frames(samples: &mut [Sample], settings: &CalibratorConfig) -> Result<(), Error> {
    let mut frame = CommandFrame::aligned(Vector3::from(settings.earth_rate_n));
    let mut last: Option<u32> = None;
    for (i, s) in samples.iter_mut().enumerate() {
        if let Some(prev) = last {
            if s.seq != prev.wrapping_add(1) {
                return Err(Error::Csv(format!(
                    "sequence {prev} is followed by {}: a log without the ccn_q* columns must have no gaps (the commanded motion across them is unknown)",
                    s.seq
                )));
            }
        }
        last = Some(s.seq);
        let period = frame.period(&Vector3::from(s.dtheta_cmd), f64::from(s.dt));
        frame.advance(&period);
        s.c_cn_quat = rollcal::geometry::quaternion_from_dcm(&frame.c_cn).map(|v| v as f32);
        if i == 0 {
            check_start(s, &frame.c_cn, settings)?;
        }
    }
    Ok(())
}

/// How far (in prior σ, [`CalibratorConfig::prior_sigma_rad`]) the first
/// sample of a log without `ccn_q*` columns may be from the path's start:
/// there the platform is on the computed frame `C^c_n = I` to within its
/// attitude's prior, and the installation errors are within theirs.
const START_PRIOR_SIGMAS: f64 = 5.0;

/// Checks that the first sample `s` of a log without `ccn_q*` columns,
/// whose period ends at the computed frame `c_cn` integrated from the
/// path's start, was taken there: its specific force within
/// [`START_PRIOR_SIGMAS`] prior σ of the direction `C^c_n` gives gravity,
/// and its gimbal angles (when logged) within as much of the Euler angles
/// of `C^c_n`. A log that starts elsewhere on the path would be calibrated
/// from the wrong frame; it needs its `ccn_q*` columns, which give the
/// start (docs/csv.md).
fn check_start(s: &Sample, c_cn: &Matrix3<f64>, settings: &CalibratorConfig) -> Result<(), Error> {
    let limit = START_PRIOR_SIGMAS * settings.prior_sigma_rad;
    let deg = |rad: f64| rad.to_degrees();
    let refuse = |what: String| {
        Err(Error::Csv(format!(
            "seq {}: a log without the ccn_q* columns is integrated from the path's start (C^c_n = I), but {what}, more than {:.1}° ({START_PRIOR_SIGMAS} prior σ) off: a log that starts elsewhere on the path needs the ccn_q* columns (docs/csv.md)",
            s.seq,
            deg(limit)
        )))
    };
    let f = Vector3::from(s.accel_mean).cast::<f64>();
    let g = c_cn * Vector3::from(settings.gravity_n);
    let angle = (f.dot(&g) / (f.norm() * g.norm())).clamp(-1.0, 1.0).acos();
    if angle > limit {
        return refuse(format!(
            "its first accelerometer means ({:.4}, {:.4}, {:.4}) g are {:.1}° from the gravity that frame gives ({:.4}, {:.4}, {:.4}) g",
            f.x,
            f.y,
            f.z,
            deg(angle),
            g.x,
            g.y,
            g.z
        ));
    }
    if let Some(gimbal) = s.gimbal {
        let expected = euler_angles(c_cn);
        let off = Vector3::from(gimbal).cast::<f64>() - expected;
        if wrap_angles(&off).amax() > limit {
            return refuse(format!(
                "its first gimbal angles ({:.2}, {:.2}, {:.2})° are far from that frame's ({:.2}, {:.2}, {:.2})°",
                deg(f64::from(gimbal[0])),
                deg(f64::from(gimbal[1])),
                deg(f64::from(gimbal[2])),
                deg(expected.x),
                deg(expected.y),
                deg(expected.z)
            ));
        }
    }
    Ok(())
}
