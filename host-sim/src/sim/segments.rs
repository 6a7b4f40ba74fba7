//! Path segments recovered from the commanded increments of a log.
//!
//! A real log carries no path description, only the commanded angle
//! increment `Δθc` of every period (rad, computed frame c). About a fixed
//! axis the rotation rate is constant in the rotating frame, so `Δθc` stays
//! (nearly) constant within a constant-rate segment; the Earth-rate part
//! turns slowly with the frame, by about `|ω_ie|·|ω_path|·T²` per period,
//! far below a segment switch, which changes `Δθc` by the path rate itself.
//! A switch is where consecutive increments differ by more than
//! [`SWITCH_FRACTION`] of the larger of the two; switches in consecutive
//! periods (a switch inside a period) are one.

/// A switch between consecutive increments `a`, `b` (rad) is a change
/// `|b − a| > SWITCH_FRACTION · max(|a|, |b|)` (and above
/// [`SWITCH_FLOOR_RAD`]).
pub const SWITCH_FRACTION: f64 = 0.1;

/// Changes of the increment below this (rad) are never a switch (a log at
/// rest).
pub const SWITCH_FLOOR_RAD: f64 = 1e-12;

/// One constant-command segment of a log.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CommandSegment {
    /// Index of its first record (0-based).
    pub first: usize,
    /// One past the index of its last record.
    pub end: usize,
    /// Time at its start (s from the start of the log).
    pub t0_s: f64,
    /// Time at its end (s).
    pub t1_s: f64,
    /// Mean commanded rate over the segment (rad/s, computed-frame
    /// components).
    pub rate_rad_s: [f64; 3],
}

impl CommandSegment {
    /// Number of records in the segment.
    pub fn len(&self) -> usize {
        self.end.saturating_sub(self.first)
    }
    /// Whether the segment has no record.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Whether the log is at rest in this segment (rate below 1e-6 rad/s:
    /// a dwell; the Earth rate is 7.3e-5 rad/s).
    pub fn is_dwell(&self) -> bool {
        norm(&self.rate_rad_s) < 1e-6
    }
    /// A short description, e.g. `"0.100 °/s about (+0.00, +1.00, +0.00)"`.
    pub fn describe(&self) -> String {
        let w = norm(&self.rate_rad_s);
        if w < 1e-6 {
            return "dwell".into();
        }
        let [x, y, z] = self.rate_rad_s.map(|v| v / w);
        format!(
            "{:.3} °/s about ({x:+.2}, {y:+.2}, {z:+.2})",
            w.to_degrees()
        )
    }
}

fn norm(v: &[f64; 3]) -> f64 {
    v.iter().map(|c| c * c).sum::<f64>().sqrt()
}

fn switch(a: &[f64; 3], b: &[f64; 3]) -> bool {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let nd = norm(&d);
    nd > SWITCH_FLOOR_RAD && nd > SWITCH_FRACTION * norm(a).max(norm(b))
}

/// The constant-command segments of a log given as `(dt, Δθc)` per record
/// (period in s, commanded increment in rad). Empty for an empty log; a
/// one-period transition between two segments belongs to the later one.
pub fn command_segments(records: impl IntoIterator<Item = (f64, [f64; 3])>) -> Vec<CommandSegment> {
    let records: Vec<(f64, [f64; 3])> = records.into_iter().collect();
    // Record k starts a segment when its increment differs from record
    // k − 1's, unless record k − 1 started one (a switch inside a period).
    let mut starts: Vec<usize> = Vec::new();
    for (k, pair) in records.windows(2).enumerate() {
        if let [(_, a), (_, b)] = pair {
            if switch(a, b) && starts.last() != Some(&k) {
                starts.push(k + 1);
            }
        }
    }
    if !records.is_empty() {
        starts.insert(0, 0);
    }
    let mut out = Vec::with_capacity(starts.len());
    let mut t = 0.0;
    for (i, &first) in starts.iter().enumerate() {
        let end = starts.get(i + 1).copied().unwrap_or(records.len());
        let part = records.get(first..end).unwrap_or(&[]);
        let span: f64 = part.iter().map(|(dt, _)| dt).sum();
        let mut sum = [0.0; 3];
        for (_, d) in part {
            for (s, v) in sum.iter_mut().zip(d) {
                *s += v;
            }
        }
        out.push(CommandSegment {
            first,
            end,
            t0_s: t,
            t1_s: t + span,
            rate_rad_s: if span > 0.0 {
                sum.map(|v| v / span)
            } else {
                [0.0; 3]
            },
        });
        t += span;
    }
    out
}

/// The switch times of `segments` (s): the start of every segment but the
/// first.
pub fn switch_times(segments: &[CommandSegment]) -> Vec<f64> {
    segments.iter().skip(1).map(|s| s.t0_s).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(parts: &[(usize, [f64; 3])]) -> Vec<(f64, [f64; 3])> {
        parts
            .iter()
            .flat_map(|(n, d)| std::iter::repeat_n((1.0, *d), *n))
            .collect()
    }

    #[test]
    fn finds_switches_and_dwells() {
        let r = 0.1f64.to_radians();
        let s = command_segments(log(&[
            (10, [0.0, r, 0.0]),
            (5, [0.0; 3]),
            (7, [r, 0.0, 0.0]),
        ]));
        assert_eq!(s.len(), 3);
        assert_eq!((s[0].first, s[0].end), (0, 10));
        assert_eq!((s[1].first, s[1].end), (10, 15));
        assert!(s[1].is_dwell() && !s[0].is_dwell());
        assert_eq!((s[2].first, s[2].end, s[2].t1_s), (15, 22, 22.0));
        assert_eq!(switch_times(&s), [10.0, 15.0]);
        assert!((s[2].rate_rad_s[0] - r).abs() < 1e-15);
    }

    #[test]
    fn a_switch_inside_a_period_is_one_switch() {
        let r = 0.1f64.to_radians();
        let s = command_segments(log(&[
            (10, [0.0, r, 0.0]),
            (1, [0.5 * r, 0.5 * r, 0.0]),
            (10, [r, 0.0, 0.0]),
        ]));
        assert_eq!(s.len(), 2, "{s:?}");
        assert_eq!((s[1].first, s[1].end), (10, 21));
    }

    #[test]
    fn earth_rate_drift_is_not_a_switch() {
        let r = 0.1f64.to_radians();
        let recs: Vec<_> = (0..5400)
            .map(|k| {
                let a = r * k as f64;
                (1.0, [7e-5 * a.cos(), r + 7e-5 * a.sin(), 0.0])
            })
            .collect();
        assert_eq!(command_segments(recs).len(), 1);
        assert!(command_segments(Vec::new()).is_empty());
    }
}
