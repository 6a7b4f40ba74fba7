//! Why the calibrator rejected samples, and what most likely made it: the
//! first rejected sample of each reason ([`FirstRejects`], kept by the
//! host as the stream is read) and, from it and the counts, one finding per
//! reason ([`RejectFinding`]: the count, where the first one is, and the
//! likely cause: units, order, period, missing columns).

use rollcal::calibrator::RejectReason;
use rollcal::wire::{CalibratorConfig, RejectCounts, Sample};

/// The reasons in the order of [`RejectCounts`] and of its JSON keys.
pub const REASONS: [&str; 12] = [
    "non_finite",
    "period",
    "accel_range",
    "increment_range",
    "gimbal_range",
    "missing_gimbal",
    "duplicate",
    "out_of_order",
    "time_backwards",
    "time_mismatch",
    "frame_attitude",
    "filter",
];

/// The key of a reject reason ([`REASONS`]).
pub fn key(r: &RejectReason) -> &'static str {
    match r {
        RejectReason::NonFinite => "non_finite",
        RejectReason::Period => "period",
        RejectReason::AccelRange => "accel_range",
        RejectReason::IncrementRange => "increment_range",
        RejectReason::GimbalRange => "gimbal_range",
        RejectReason::MissingGimbal => "missing_gimbal",
        RejectReason::Duplicate => "duplicate",
        RejectReason::OutOfOrder => "out_of_order",
        RejectReason::TimeBackwards => "time_backwards",
        RejectReason::TimeMismatch => "time_mismatch",
        RejectReason::FrameAttitude => "frame_attitude",
        _ => "filter",
    }
}

/// The count of reason `key` in `c`.
pub fn count(c: &RejectCounts, key: &str) -> u32 {
    match key {
        "non_finite" => c.non_finite,
        "period" => c.period,
        "accel_range" => c.accel_range,
        "increment_range" => c.increment_range,
        "gimbal_range" => c.gimbal_range,
        "missing_gimbal" => c.missing_gimbal,
        "duplicate" => c.duplicate,
        "out_of_order" => c.out_of_order,
        "time_backwards" => c.time_backwards,
        "time_mismatch" => c.time_mismatch,
        "frame_attitude" => c.frame_attitude,
        _ => c.filter,
    }
}

/// The first rejected sample of a reason.
#[derive(Clone, Debug, PartialEq)]
pub struct FirstReject {
    /// The reason (its message).
    pub reason: String,
    /// The sample.
    pub sample: Sample,
    /// Its index among the samples the calibrator was given (0-based).
    pub index: usize,
    /// The last accepted sample's `(seq, t_us)` when it came.
    pub last: Option<(u32, u64)>,
}

/// The first rejected sample of every reason since the calibrator was
/// last (re)started, and the number of samples given to it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FirstRejects {
    /// Samples given to the calibrator.
    pub samples: usize,
    /// (reason key, first sample) in the order first seen.
    pub first: Vec<(&'static str, FirstReject)>,
}

impl FirstRejects {
    /// Notes that sample `s` (given as number [`FirstRejects::samples`])
    /// was rejected for `r`, the last accepted sample being `last`.
    pub fn note(&mut self, r: &RejectReason, s: &Sample, last: Option<(u32, u64)>) {
        let k = key(r);
        if !self.first.iter().any(|(f, _)| *f == k) {
            self.first.push((
                k,
                FirstReject {
                    reason: r.to_string(),
                    sample: *s,
                    index: self.samples,
                    last,
                },
            ));
        }
    }
}

/// Where the samples came from, for naming a sample.
#[derive(Clone, Copy, Debug, Default)]
pub struct SampleSource<'a> {
    /// The line of each sample in a CSV log (1-based), when the input is one.
    pub lines: Option<&'a [usize]>,
    /// Whether a CSV log has the gimbal columns (`None`: frames).
    pub has_gimbal: Option<bool>,
}

/// One reason of the rejected samples: how many, the first one and the
/// likely cause when the first sample says it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RejectFinding {
    /// The reason's key ([`REASONS`]).
    pub reason: &'static str,
    /// Samples rejected for it.
    pub count: u32,
    /// The first one: `line N, seq S` (CSV) or `sample N, seq S` (frames),
    /// with the offending value.
    pub first: String,
    /// What most likely made it, when the values tell.
    pub likely_cause: Option<String>,
}

/// The findings of every reason with a rejected sample, largest count
/// first (`settings`: the calibrator's, for the limits and the period).
pub fn findings(
    counts: &RejectCounts,
    first: &FirstRejects,
    settings: &CalibratorConfig,
    src: SampleSource<'_>,
) -> Vec<RejectFinding> {
    let mut out: Vec<RejectFinding> = REASONS
        .iter()
        .filter(|k| count(counts, k) > 0)
        .map(|&k| {
            let f = first.first.iter().find(|(r, _)| *r == k).map(|(_, f)| f);
            RejectFinding {
                reason: k,
                count: count(counts, k),
                first: f.map_or_else(
                    || "not seen (before a restart)".into(),
                    |f| where_(f, k, src),
                ),
                likely_cause: f.and_then(|f| cause(k, f, settings, src)),
            }
        })
        .collect();
    out.sort_by_key(|f| std::cmp::Reverse(f.count));
    out
}

/// The first sample of reason `k`, named and with its offending value.
fn where_(f: &FirstReject, k: &str, src: SampleSource<'_>) -> String {
    let s = &f.sample;
    let at = match src.lines.and_then(|l| l.get(f.index)) {
        Some(line) => format!("line {line}, seq {}", s.seq),
        None => format!("sample {}, seq {}", f.index + 1, s.seq),
    };
    let value = match k {
        "period" => format!("dt = {} s", s.dt),
        "accel_range" => format!("accel = {:?}", s.accel_mean),
        "increment_range" => format!("dtheta = {:?}", s.dtheta_cmd),
        "gimbal_range" => format!("gimbal = {:?}", s.gimbal.unwrap_or_default()),
        "duplicate" | "out_of_order" => match f.last {
            Some((seq, _)) => format!("after seq {seq}"),
            None => String::new(),
        },
        "time_backwards" | "time_mismatch" => match f.last {
            Some((seq, t)) => format!(
                "t = {} s after seq {seq} at t = {} s, dt = {} s",
                s.t_us as f64 * 1e-6,
                t as f64 * 1e-6,
                s.dt
            ),
            None => String::new(),
        },
        "frame_attitude" => format!("quaternion norm {}", quaternion_norm(s)),
        _ => f.reason.clone(),
    };
    if value.is_empty() {
        at
    } else {
        format!("{at}: {value}")
    }
}

fn quaternion_norm(s: &Sample) -> f64 {
    s.c_cn_quat
        .iter()
        .map(|v| f64::from(*v) * f64::from(*v))
        .sum::<f64>()
        .sqrt()
}

/// Whether `v` is `want` within a relative `tol`.
fn near(v: f64, want: f64, tol: f64) -> bool {
    (v - want).abs() <= tol * want.abs()
}

/// The likely cause of reason `k` from its first sample `f`.
fn cause(
    k: &str,
    f: &FirstReject,
    settings: &CalibratorConfig,
    src: SampleSource<'_>,
) -> Option<String> {
    let s = &f.sample;
    let lim = &settings.limits;
    let deg = std::f64::consts::PI / 180.0;
    let max = |v: &[f64]| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    match k {
        "period" => {
            let dt = f64::from(s.dt);
            Some(if near(dt, 1000.0 * lim.period_s, 0.01) {
                format!("time in milliseconds: dt_s = {dt} for a period of {} s (t_s and dt_s are seconds)", lim.period_s)
            } else {
                format!(
                    "the platform's period ({} s, timing.period_s) is not the log's (dt_s = {dt} s): give the log's period",
                    lim.period_s
                )
            })
        }
        "accel_range" => {
            let a: Vec<f64> = s.accel_mean.iter().map(|v| f64::from(*v)).collect();
            let norm = a.iter().map(|v| v * v).sum::<f64>().sqrt();
            if near(norm, 9.80665, 0.05) {
                Some(format!("accelerometers in m/s² (|f| = {norm:.3}, 1 g = 9.807 m/s²): the log wants g"))
            } else if near(norm, 1000.0, 0.05) {
                Some(format!("accelerometers in mg (|f| = {norm:.1}): the log wants g"))
            } else if near(norm, 1e6, 0.05) {
                Some(format!("accelerometers in µg (|f| = {norm:.0}): the log wants g"))
            } else {
                None
            }
        }
        "increment_range" => {
            let m = max(&s.dtheta_cmd);
            (m * deg <= lim.max_increment_rad).then(|| {
                format!(
                    "increments in degrees ({m:.4} would be {:.6} rad): dtheta_*_rad are radians",
                    m * deg
                )
            })
        }
        "gimbal_range" => {
            let g: Vec<f64> = s.gimbal.unwrap_or_default().iter().map(|v| f64::from(*v)).collect();
            let m = max(&g);
            (m * deg <= lim.max_gimbal_rad).then(|| {
                format!("gimbal angles in degrees ({m:.3} would be {:.4} rad): gimbal_*_rad are radians", m * deg)
            })
        }
        "missing_gimbal" => Some(match src.has_gimbal {
            Some(false) => format!(
                "{} measures the gimbal angles: the log has no gimbal_alpha_rad, gimbal_beta_rad, gimbal_gamma_rad columns",
                settings.config
            ),
            Some(true) => format!("{} measures the gimbal angles: empty gimbal fields", settings.config),
            None => format!("{} measures the gimbal angles: the samples carry none", settings.config),
        }),
        "duplicate" => Some("the same sequence number twice: lines or frames repeated".into()),
        "out_of_order" => Some("the lines are out of order: sort the log by seq".into()),
        "time_backwards" | "time_mismatch" => time_cause(f),
        "frame_attitude" => Some(format!(
            "the ccn_q* quaternion is not a unit quaternion (norm {:.6}): [w, x, y, z] of C^c_n, normalised",
            quaternion_norm(s)
        )),
        "non_finite" => Some("a value that is not a number (NaN or inf) in the log".into()),
        _ => None,
    }
}

/// The likely cause of a timestamp that disagrees with the periods: the
/// ratio of the time elapsed to the periods elapsed since the last
/// accepted sample.
fn time_cause(f: &FirstReject) -> Option<String> {
    let s = &f.sample;
    let (seq, t) = f.last?;
    if s.seq <= seq {
        return Some("the lines are out of order: sort the log by seq".into());
    }
    let elapsed = (s.t_us as f64 - t as f64) * 1e-6;
    let periods = f64::from(s.seq - seq) * f64::from(s.dt);
    let ratio = elapsed / periods;
    Some(if near(ratio, 1000.0, 0.01) {
        "time in milliseconds: t_s advances 1000 per period of dt_s (t_s is seconds)".into()
    } else if near(ratio, 1e6, 0.01) {
        "time in microseconds: t_s advances 10⁶ per period of dt_s (t_s is seconds)".into()
    } else if ratio < 0.0 {
        "the timestamps go back: lines out of order, or the clock was reset".into()
    } else {
        format!("t_s advances {ratio:.4} times the periods dt_s: a clock of another rate, or dt_s not the period")
    })
}
