//! Progress on stderr, the one implementation every subcommand uses
//! (`calibrate`, `paper`, `montecarlo`, `remedies`, `design`).
//!
//! On a terminal it is one line redrawn with `\r` (at most ten times a
//! second); in a log (stderr redirected to a file or a pipe) it is a plain
//! line every [`LOG_STEP_PERCENT`] % of the total. Either way
//! [`Progress::finish`] prints a last line with the final count, so the
//! count a log ends with is the count that was reached.

use std::io::{IsTerminal, Write};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// A log line is printed every this many percent of the total.
pub const LOG_STEP_PERCENT: u64 = 5;

/// Minimum time between two redraws of the terminal line.
const REDRAW: Duration = Duration::from_millis(100);

/// Width of the terminal bar (characters).
const BAR: usize = 20;

struct State {
    stage: String,
    total: u64,
    /// Last log bucket printed (`percent / LOG_STEP_PERCENT`) of this stage.
    bucket: Option<u64>,
    last_draw: Option<Instant>,
    /// Count and detail of the last line printed.
    printed: Option<(u64, String)>,
    finished: bool,
    out: Box<dyn Write + Send>,
}

/// Progress of `total` units of work named `unit` (e.g. "runs").
pub struct Progress {
    label: String,
    unit: String,
    terminal: bool,
    t0: Instant,
    state: Mutex<State>,
}

impl Progress {
    /// Progress on stderr; a terminal bar when stderr is a terminal, log
    /// lines otherwise.
    pub fn stderr(label: &str, total: u64, unit: &str) -> Self {
        let terminal = std::io::stderr().is_terminal();
        Self::to_writer(label, total, unit, terminal, Box::new(std::io::stderr()))
    }

    /// Progress written to `out`, as on a terminal (`terminal`) or in a log.
    pub fn to_writer(
        label: &str,
        total: u64,
        unit: &str,
        terminal: bool,
        out: Box<dyn Write + Send>,
    ) -> Self {
        Self {
            label: label.to_string(),
            unit: unit.to_string(),
            terminal,
            t0: Instant::now(),
            state: Mutex::new(State {
                stage: String::new(),
                total,
                bucket: None,
                last_draw: None,
                printed: None,
                finished: false,
                out,
            }),
        }
    }

    /// `done` units are done; `detail` is appended to the line.
    pub fn update(&self, done: u64, detail: &str) {
        let Ok(mut st) = self.state.lock() else {
            return;
        };
        self.draw(&mut st, done, detail, false);
    }

    /// Like [`Progress::update`], within a named stage of `total` units
    /// (a new stage starts its percentages anew).
    pub fn stage(&self, stage: &str, done: u64, total: u64, detail: &str) {
        let Ok(mut st) = self.state.lock() else {
            return;
        };
        if st.stage != stage {
            st.stage = stage.to_string();
            st.bucket = None;
            st.last_draw = None;
        }
        st.total = total;
        self.draw(&mut st, done, detail, false);
    }

    /// The last line, with the final count `done`, always printed (once).
    pub fn finish(&self, done: u64, detail: &str) {
        let Ok(mut st) = self.state.lock() else {
            return;
        };
        if st.finished {
            return;
        }
        self.draw(&mut st, done, detail, true);
        st.finished = true;
    }

    fn draw(&self, st: &mut State, done: u64, detail: &str, last: bool) {
        if st.finished {
            return;
        }
        let total = st.total.max(1);
        let percent = done.saturating_mul(100) / total;
        let now = Instant::now();
        if self.terminal {
            if !last && st.last_draw.is_some_and(|t| now - t < REDRAW) && done < st.total {
                return;
            }
            st.last_draw = Some(now);
        } else {
            let bucket = percent / LOG_STEP_PERCENT;
            if last {
                // The final line, unless the log already ends with it.
                if st
                    .printed
                    .as_ref()
                    .is_some_and(|(n, d)| *n == done && d == detail)
                {
                    return;
                }
            } else if st.bucket.is_some_and(|b| bucket <= b) {
                return;
            }
            st.bucket = Some(bucket);
        }
        st.printed = Some((done, detail.to_string()));
        let line = self.line(st, done, percent, detail, now);
        let text = if self.terminal {
            let filled = usize::try_from(percent.min(100)).unwrap_or(100) * BAR / 100;
            // One terminal row, or `\r` would redraw only its last part
            // (the last line, which ends the row, is written whole).
            let width = std::env::var("COLUMNS")
                .ok()
                .and_then(|c| c.parse::<usize>().ok())
                .unwrap_or(80)
                .saturating_sub(1);
            let full = format!(
                "[{}{}] {line}",
                "=".repeat(filled),
                " ".repeat(BAR - filled)
            );
            let row: String = if last {
                full
            } else {
                full.chars().take(width.max(BAR + 2)).collect()
            };
            format!("\r{row}\x1b[K{}", if last { "\n" } else { "" })
        } else {
            format!("{line}\n")
        };
        // Progress is best effort: a closed stderr must not stop the work.
        let _ = st.out.write_all(text.as_bytes());
        let _ = st.out.flush();
    }

    fn line(&self, st: &State, done: u64, percent: u64, detail: &str, now: Instant) -> String {
        let stage = if st.stage.is_empty() {
            String::new()
        } else {
            format!("{}: ", st.stage)
        };
        let detail = if detail.is_empty() {
            String::new()
        } else {
            format!(", {detail}")
        };
        format!(
            "{}: {stage}{done}/{} {} ({percent} %){detail}, {:.1} s",
            self.label,
            st.total,
            self.unit,
            (now - self.t0).as_secs_f64()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[derive(Clone, Default)]
    struct Buf(Arc<Mutex<Vec<u8>>>);
    impl Write for Buf {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0
                .lock()
                .map_err(|_| std::io::ErrorKind::Other)?
                .extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    impl Buf {
        fn text(&self) -> String {
            String::from_utf8_lossy(&self.0.lock().unwrap()).into_owned()
        }
    }

    #[test]
    fn a_log_gets_a_line_every_five_percent_and_the_final_count() {
        let buf = Buf::default();
        let p = Progress::to_writer("calibrate", 5400, "samples", false, Box::new(buf.clone()));
        for i in 1..=5124 {
            p.update(i, "");
        }
        p.finish(5400, "0 rejected");
        let text = buf.text();
        assert!(!text.contains('\r'), "{text}");
        let lines: Vec<&str> = text.lines().collect();
        // 0 %, 5 %, …, 90 % (5124 is 94 %), then the final line.
        assert_eq!(lines.len(), 20, "{text}");
        let last = lines.last().unwrap();
        assert!(
            last.contains("5400/5400 samples (100 %), 0 rejected"),
            "{last}"
        );
    }

    #[test]
    fn a_terminal_bar_ends_at_the_final_count() {
        let buf = Buf::default();
        let p = Progress::to_writer("runs", 100, "runs", true, Box::new(buf.clone()));
        for i in 1..=97 {
            p.update(i, "");
        }
        p.finish(100, "");
        let text = buf.text();
        assert!(text.starts_with('\r') && text.ends_with('\n'), "{text:?}");
        let last = text.rsplit('\r').next().unwrap();
        assert!(last.contains("100/100 runs (100 %)"), "{last:?}");
    }
}
