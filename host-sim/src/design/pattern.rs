//! The paths of the search: a [`Rotation`] (constant rate, then an
//! optional dwell), a [`Pattern`] of rotations repeated until the path
//! ends, its [`Piece`]s of whole periods and its scenario segments, and the
//! reference path of a scenario as a pattern ([`pattern_of`]).

use crate::sim::scenario::{Axis, Scenario, Segment};

use super::{DesignError, NamedAxis};

/// One constant-rate rotation of a path, then an optional dwell.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Rotation {
    /// The axis.
    pub axis: NamedAxis,
    /// Angle (°); 0 only with a dwell (a pure dwell, e.g. in a reference
    /// path).
    pub angle_deg: f64,
    /// Rate (°/s).
    pub rate_deg_s: f64,
    /// Hold still this long after the rotation (s, whole periods): zero
    /// commanded path rate, as `dwell_s` of a scenario segment.
    #[serde(skip_serializing_if = "crate::sim::scenario::is_zero")]
    pub dwell_s: f64,
}

/// `x / period_s` if it is a whole number ≥ 0.
fn whole_periods(x: f64, period_s: f64) -> Option<u64> {
    let d = x / period_s;
    let r = d.round();
    (d.is_finite() && (d - r).abs() <= 1e-6 && r >= 0.0).then_some(r as u64)
}

impl Rotation {
    /// A rotation without a dwell.
    pub fn new(axis: NamedAxis, angle_deg: f64, rate_deg_s: f64) -> Self {
        Self {
            axis,
            angle_deg,
            rate_deg_s,
            dwell_s: 0.0,
        }
    }

    /// Whole periods of length `period_s` the rotation lasts (without the
    /// dwell), if whole and at least one (zero for a pure dwell).
    pub fn periods(&self, period_s: f64) -> Option<u64> {
        let r = whole_periods(self.angle_deg / self.rate_deg_s, period_s)?;
        let dwell = self.dwell_periods(period_s)?;
        (r >= 1 || (r == 0 && dwell >= 1)).then_some(r)
    }

    /// Whole periods of the dwell after the rotation, if whole.
    pub fn dwell_periods(&self, period_s: f64) -> Option<u64> {
        whole_periods(self.dwell_s, period_s)
    }

    /// Whole periods of the rotation and its dwell, if both are whole.
    pub fn total_periods(&self, period_s: f64) -> Option<u64> {
        Some(self.periods(period_s)? + self.dwell_periods(period_s)?)
    }
}

/// A piece of a path: `periods` periods of rotation `index` of the pattern,
/// rotating or (`dwell`) holding still after it.
#[derive(Clone, Copy, Debug)]
pub struct Piece<'a> {
    /// Index of the rotation in the pattern.
    pub index: usize,
    /// The rotation.
    pub rotation: &'a Rotation,
    /// Its dwell (zero path rate), not its rotation.
    pub dwell: bool,
    /// Whole periods.
    pub periods: u64,
}

/// A candidate: a pattern of rotations repeated until the path ends.
///
/// # Examples
///
/// ```
/// use host_sim::design::{NamedAxis, Pattern, Rotation};
///
/// let p = Pattern {
///     rotations: vec![
///         Rotation::new(NamedAxis::named("south")?, 180.0, 1.0),
///         Rotation::new(NamedAxis::named("east")?, 90.0, 1.0),
///     ],
///     repeat: true,
/// };
/// assert_eq!(p.describe(), "(south 180° @1°/s, east 90° @1°/s) repeated");
/// // 270 one-second periods per cycle; the first 200 cut within the second.
/// assert_eq!(p.cycle_periods(1.0), Some(270));
/// assert_eq!(p.segments(200, 1.0).len(), 2);
/// # Ok::<(), host_sim::design::DesignError>(())
/// ```
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Pattern {
    /// The rotations of one cycle.
    pub rotations: Vec<Rotation>,
    /// Whether the cycle repeats (false: the path is the rotations once,
    /// then the platform holds still).
    pub repeat: bool,
}

impl Pattern {
    /// Short text, e.g. `(south 180° @0.1°/s, east 90° @0.1°/s + dwell 60 s) repeated`.
    pub fn describe(&self) -> String {
        let parts: Vec<String> = self
            .rotations
            .iter()
            .map(|r| {
                let mut t = format!("{} {}° @{}°/s", r.axis.name, r.angle_deg, r.rate_deg_s);
                if r.dwell_s > 0.0 {
                    t.push_str(&format!(" + dwell {} s", r.dwell_s));
                }
                t
            })
            .collect();
        format!(
            "({}){}",
            parts.join(", "),
            if self.repeat { " repeated" } else { "" }
        )
    }

    /// Whether any rotation has a dwell.
    pub fn has_dwell(&self) -> bool {
        self.rotations.iter().any(|r| r.dwell_s > 0.0)
    }

    /// Every rotation and dwell is a whole number of periods.
    pub fn whole(&self, period_s: f64) -> bool {
        self.rotations
            .iter()
            .all(|r| r.total_periods(period_s).is_some())
    }

    /// The path's segments over its first `periods` periods (the last one
    /// cut at a whole period, within its rotation or its dwell), as
    /// scenario segments.
    pub fn segments(&self, periods: u64, period_s: f64) -> Vec<Segment> {
        let mut out: Vec<Segment> = Vec::new();
        // The previous piece: (rotation index, dwell).
        let mut last: Option<(usize, bool)> = None;
        for piece in self.chunks(periods, period_s, u64::MAX) {
            let r = piece.rotation;
            let span = period_s * piece.periods as f64;
            if piece.dwell {
                // After its own rotation: that segment's dwell; else (a pure
                // dwell) a segment of its own.
                match (last, out.last_mut()) {
                    (Some((i, _)), Some(seg)) if i == piece.index => {
                        seg.dwell_s = round_angle(seg.dwell_s + span);
                    }
                    _ => out.push(Segment {
                        axis: r.axis.to_axis(),
                        angle_deg: 0.0,
                        rate_deg_s: r.rate_deg_s,
                        dwell_s: round_angle(span),
                    }),
                }
                last = Some((piece.index, true));
                continue;
            }
            let angle = r.rate_deg_s * span;
            // A single repeated rotation (without dwells) is one continuous
            // segment.
            if let (Some((i, false)), Some(seg)) = (last, out.last_mut()) {
                let prev = &self.rotations[i];
                if prev.axis == r.axis && prev.rate_deg_s == r.rate_deg_s && seg.dwell_s == 0.0 {
                    seg.angle_deg = round_angle(seg.angle_deg + angle);
                    last = Some((piece.index, false));
                    continue;
                }
            }
            out.push(Segment {
                axis: r.axis.to_axis(),
                angle_deg: round_angle(angle),
                rate_deg_s: r.rate_deg_s,
                dwell_s: 0.0,
            });
            last = Some((piece.index, false));
        }
        out
    }

    /// Pieces of at most `k` periods covering the first `periods` periods:
    /// every rotation, then its dwell.
    pub fn chunks(&self, periods: u64, period_s: f64, k: u64) -> Vec<Piece<'_>> {
        let mut out = Vec::new();
        let mut left = periods;
        if self.rotations.is_empty() {
            return out;
        }
        'cycle: loop {
            for (i, r) in self.rotations.iter().enumerate() {
                let (Some(rot), Some(dwell)) = (r.periods(period_s), r.dwell_periods(period_s))
                else {
                    return out;
                };
                for (mut n, is_dwell) in [(rot, false), (dwell, true)] {
                    while n > 0 && left > 0 {
                        let m = n.min(k).min(left);
                        out.push(Piece {
                            index: i,
                            rotation: r,
                            dwell: is_dwell,
                            periods: m,
                        });
                        n -= m;
                        left -= m;
                    }
                }
                if left == 0 {
                    break 'cycle;
                }
            }
            if !self.repeat {
                break;
            }
        }
        out
    }

    /// Periods of one cycle, dwells included.
    pub fn cycle_periods(&self, period_s: f64) -> Option<u64> {
        self.rotations
            .iter()
            .map(|r| r.total_periods(period_s))
            .sum()
    }
}

pub(super) fn round_angle(a: f64) -> f64 {
    (a * 1e9).round() / 1e9
}

pub(super) fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The reference path (e.g. the paper's) as a non-repeating pattern, its
/// dwells included; the scenario's time after the path's end (the platform
/// holds still) is a dwell after the last segment.
pub fn pattern_of(s: &Scenario) -> Result<Pattern, DesignError> {
    let mut rotations = s
        .path
        .iter()
        .map(|seg| {
            let unit = seg
                .axis
                .unit()
                .map_err(|e| DesignError::Axis(e.to_string()))?;
            let name = match &seg.axis {
                Axis::Named(n) => n.to_ascii_lowercase(),
                Axis::Vector(v) => format!("[{}, {}, {}]", v[0], v[1], v[2]),
            };
            Ok(Rotation {
                axis: NamedAxis { name, unit },
                angle_deg: seg.angle_deg,
                rate_deg_s: seg.rate_deg_s,
                dwell_s: seg.dwell_s,
            })
        })
        .collect::<Result<Vec<_>, DesignError>>()?;
    let path_s: f64 = s.path.iter().map(Segment::duration_s).sum();
    let rest = round_angle(s.timing.duration_s - path_s);
    if let Some(last) = rotations.last_mut() {
        if rest > 0.0 {
            last.dwell_s = round_angle(last.dwell_s + rest);
        }
    }
    Ok(Pattern {
        rotations,
        repeat: false,
    })
}
