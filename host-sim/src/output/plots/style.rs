//! The shared style of every figure: size constants, the embedded font,
//! the colours, the title and legend text, tick labels and value formats,
//! the finite ranges and the clipped polylines, the switch lines.

use std::ops::Range;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor;

pub const WIDTH: u32 = 1000;
/// Height of one state's row of panels (px).
pub const PANEL_HEIGHT: u32 = 250;
/// Height of the title and legend strip at the top (px).
pub const HEADER_HEIGHT: u32 = 64;
/// Largest number of curves (rows) in one figure.
pub const MAX_PANELS: usize = 24;

/// The embedded font (DejaVu Sans, Bitstream Vera licence).
pub(super) static FONT_TTF: &[u8] = include_bytes!("../../../assets/DejaVuSans.ttf");
/// Family name the font is registered under (plotters' default family).
pub(super) const FAMILY: &str = "sans-serif";

/// Registers the embedded font with plotters (once per process).
pub(super) fn ensure_font() -> Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FAMILY, FontStyle::Normal, FONT_TTF).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err("plots: the embedded font could not be parsed".to_string())
    }
}

// Colours (colour-blind-safe pair: blue error, vermilion filter band).
pub(super) const ERROR_COLOUR: RGBColor = RGBColor(0, 90, 181);
pub(super) const FILTER_COLOUR: RGBColor = RGBColor(213, 94, 0);
pub(super) const BAND_COLOUR: RGBColor = RGBColor(250, 215, 190);
pub(super) const CRLB_COLOUR: RGBColor = RGBColor(30, 30, 30);
pub(super) const GRID_BOLD: RGBColor = RGBColor(215, 215, 215);
pub(super) const GRID_LIGHT: RGBColor = RGBColor(238, 238, 238);
pub(super) const LOG_COLOUR_BAND: RGBColor = RGBColor(253, 235, 222);
pub(super) const SWITCH_COLOUR: RGBColor = RGBColor(150, 90, 190);
/// Width of the 3σ_CRLB dashes (px): wider than the filter's line on top.
pub(super) const CRLB_WIDTH: u32 = 5;

/// Range of the finite times, widened if degenerate.
pub(super) fn time_range(t_s: &[f64]) -> Option<Range<f64>> {
    let (lo, hi) = finite_min_max(t_s.iter().copied())?;
    if hi > lo {
        Some(lo..hi)
    } else {
        let pad = if lo.abs() > 0.0 { lo.abs() * 0.5 } else { 1.0 };
        Some(lo - pad..hi + pad)
    }
}

pub(super) fn finite_min_max(v: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    v.filter(|x| x.is_finite()).fold(None, |acc, x| match acc {
        None => Some((x, x)),
        Some((lo, hi)) => Some((lo.min(x), hi.max(x))),
    })
}

pub(super) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
pub(super) type DrawResult<'a> =
    Result<(), DrawingAreaErrorKind<<BitMapBackend<'a> as DrawingBackend>::ErrorType>>;

pub(super) fn font(size: f64) -> TextStyle<'static> {
    (FAMILY, size).into_font().color(&BLACK)
}

/// The figure's title, centred at the top of its header `area`, in `size`
/// points.
pub(super) fn draw_title<'a>(area: &Area<'a>, title: &str, size: f64) -> DrawResult<'a> {
    let (w, _) = area.dim_in_pixel();
    let centre = i32::try_from(w / 2).unwrap_or(0);
    let style = font(size).pos(text_anchor::Pos::new(
        text_anchor::HPos::Center,
        text_anchor::VPos::Top,
    ));
    area.draw(&Text::new(title.to_string(), (centre, 8), style))
}

/// The style of a legend label: left-aligned, vertically centred on its
/// swatch.
pub(super) fn legend_label() -> TextStyle<'static> {
    font(15.0).pos(text_anchor::Pos::new(
        text_anchor::HPos::Left,
        text_anchor::VPos::Center,
    ))
}

/// Vertical lines at the switch times inside `t`, over the y-range `y`.
pub(super) fn draw_switches<
    DB: DrawingBackend,
    Y: plotters::coord::ranged1d::Ranged<ValueType = f64>,
>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<plotters::coord::types::RangedCoordf64, Y>>,
    switches: &[f64],
    t: &Range<f64>,
    y: (f64, f64),
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    for &ts in switches {
        if ts.is_finite() && ts > t.start && ts < t.end {
            chart.draw_series(std::iter::once(PathElement::new(
                vec![(ts, y.0), (ts, y.1)],
                SWITCH_COLOUR.stroke_width(1),
            )))?;
        }
    }
    Ok(())
}

/// Three significant digits, no exponent for ordinary magnitudes.
pub(super) fn fmt_value(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".to_string()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.2e}")
    } else {
        let digits = (2 - a.log10().floor() as i32).clamp(0, 5) as usize;
        format!("{v:.digits$}")
    }
}

/// Maximal runs of consecutive points whose t and value are finite and
/// satisfy `keep`.
pub(super) fn finite_runs(
    t_s: &[f64],
    v: &[f64],
    keep: impl Fn(f64) -> bool,
) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    for (&t, &y) in t_s.iter().zip(v) {
        if t.is_finite() && y.is_finite() && keep(y) {
            cur.push((t, y));
        } else if !cur.is_empty() {
            runs.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        runs.push(cur);
    }
    runs
}

/// The polyline (t, v) clipped to `lo ≤ y ≤ hi` (in log10 space if `log`,
/// where non-positive values are gaps), split into drawable segments.
pub(super) fn clipped(t_s: &[f64], v: &[f64], lo: f64, hi: f64, log: bool) -> Vec<Vec<(f64, f64)>> {
    type Map = fn(f64) -> f64;
    let (fwd, inv): (Map, Map) = if log {
        (f64::log10, |y| 10f64.powf(y))
    } else {
        (|y| y, |y| y)
    };
    let (flo, fhi) = (fwd(lo), fwd(hi));
    let mut out = Vec::new();
    for run in finite_runs(t_s, v, |y| !log || y > 0.0) {
        let mut seg: Vec<(f64, f64)> = Vec::new();
        let pts: Vec<(f64, f64)> = run.iter().map(|&(t, y)| (t, fwd(y))).collect();
        let inside = |y: f64| y >= flo && y <= fhi;
        if let Some(&(t0, y0)) = pts.first() {
            if inside(y0) {
                seg.push((t0, y0));
            }
        }
        for w in pts.windows(2) {
            let (&(ta, ya), &(tb, yb)) = match (w.first(), w.get(1)) {
                (Some(a), Some(b)) => (a, b),
                _ => continue,
            };
            // Clip segment a→b to the band in y (Liang–Barsky, y only).
            let (mut u0, mut u1) = (0.0_f64, 1.0_f64);
            let dy = yb - ya;
            if dy == 0.0 {
                if !inside(ya) {
                    u0 = 2.0;
                }
            } else {
                let (ua, ub) = ((flo - ya) / dy, (fhi - ya) / dy);
                u0 = u0.max(ua.min(ub));
                u1 = u1.min(ua.max(ub));
            }
            if u0 > u1 {
                if !seg.is_empty() {
                    out.push(std::mem::take(&mut seg));
                }
                continue;
            }
            let at = |u: f64| (ta + u * (tb - ta), ya + u * dy);
            if u0 > 0.0 {
                // Entering from outside: start a new segment.
                if !seg.is_empty() {
                    out.push(std::mem::take(&mut seg));
                }
                seg.push(at(u0));
            } else if seg.is_empty() {
                seg.push((ta, ya));
            }
            seg.push(at(u1));
            if u1 < 1.0 {
                out.push(std::mem::take(&mut seg));
            }
        }
        if !seg.is_empty() {
            out.push(seg);
        }
    }
    out.into_iter()
        .map(|s| s.into_iter().map(|(t, y)| (t, inv(y))).collect())
        .collect()
}

/// Time tick labels: integers for ordinary ranges.
pub(super) fn fmt_tick(v: f64) -> String {
    if v.abs() >= 10.0 || v == 0.0 {
        format!("{v:.0}")
    } else {
        fmt_value(v)
    }
}

/// Log-axis ticks: only decades are labelled ("0.01", "1", "1000", "1e-5").
pub(super) fn fmt_log_tick(v: f64) -> String {
    let e = v.log10();
    if (e - e.round()).abs() > 1e-6 {
        return String::new();
    }
    let e = e.round() as i32;
    if (-3..=4).contains(&e) {
        let digits = (-e).max(0) as usize;
        format!("{v:.digits$}")
    } else {
        format!("1e{e}")
    }
}

/// Linear ticks with as many decimals as the tick step needs.
pub(super) fn fmt_linear_tick(v: f64, step: f64) -> String {
    let digits = if step > 0.0 && step.is_finite() {
        (-step.log10().floor() as i32).clamp(0, 8) as usize
    } else {
        2
    };
    let s = format!("{v:.digits$}");
    // Avoid "-0.00".
    if s.starts_with('-') && s.trim_start_matches(['-', '0', '.']).is_empty() {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}
