//! PNG figures of estimator runs (as the paper's figs 1–28): per state, the
//! estimation error against time, the filter's ±3σ band and the Cramér–Rao
//! bound σ_CRLB.
//!
//! Each state gets one row of two panels sharing the time axis `t [s]`:
//! - left, **log scale** over the whole run: |error|, 3σ of the filter and
//!   3σ_CRLB (shows the convergence from the prior, ~3600″, down to the
//!   converged level, and how σ compares to σ_CRLB);
//! - right, **linear zoom** on the converged part: the signed error, the
//!   shaded ±3σ band and the ±3σ_CRLB lines, from the time the converged
//!   part starts (after 20 % of the run and after 3σ has settled within
//!   twice its final value) to the end. The y-range is
//!   ±1.5 × max(|error|, 3σ, 3σ_CRLB) over that part, so nothing is clipped:
//!   the early transient is not in this panel (it is on the left, whole).
//!
//! The filter's 3σ is a solid vermilion line drawn *over* a wide dark
//! dashed 3σ_CRLB line: where the filter reaches the bound both stay
//! visible (the dashes stick out on both sides of the solid line). Path
//! segment switches ([`crate::segments`]) are thin vertical purple lines in
//! every panel ([`plot_group_marked`]).
//!
//! Text is rendered with the DejaVu Sans font embedded in the binary
//! (`assets/DejaVuSans.ttf`, licence next to it) through plotters'
//! `ab_glyph` backend: no system font or font library is needed.
//!
//! Non-finite values (NaN, ±inf) are skipped (the curve is broken there);
//! invalid input (empty, mismatched lengths, too many panels) and I/O
//! failures are returned as `Err(String)`.

use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor;

/// One state's time history, all in the display unit (arcseconds).
#[derive(Clone, Copy, Debug)]
pub struct Curve<'a> {
    /// State name, e.g. `"thaT_1"`: the panel label.
    pub label: &'a str,
    /// Estimate − truth per period (″).
    pub error: &'a [f64],
    /// Filter σ per period (″): drawn as the ±3σ band.
    pub sigma: &'a [f64],
    /// σ_CRLB per period (″): drawn as the ±3σ_CRLB lines.
    pub crlb: &'a [f64],
}

/// Figure width (px).
pub const WIDTH: u32 = 1000;
/// Height of one state's row of panels (px).
pub const PANEL_HEIGHT: u32 = 250;
/// Height of the title and legend strip at the top (px).
pub const HEADER_HEIGHT: u32 = 64;
/// Largest number of curves (rows) in one figure.
pub const MAX_PANELS: usize = 24;

/// Size (width, height) in pixels of the figure [`plot_group`] writes for
/// `panels` curves.
pub fn figure_size(panels: usize) -> (u32, u32) {
    let rows = u32::try_from(panels).unwrap_or(u32::MAX);
    (
        WIDTH,
        HEADER_HEIGHT.saturating_add(PANEL_HEIGHT.saturating_mul(rows)),
    )
}

/// The embedded font (DejaVu Sans, Bitstream Vera licence).
static FONT_TTF: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");
/// Family name the font is registered under (plotters' default family).
const FAMILY: &str = "sans-serif";

/// Registers the embedded font with plotters (once per process).
fn ensure_font() -> Result<(), String> {
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
const ERROR_COLOUR: RGBColor = RGBColor(0, 90, 181);
const FILTER_COLOUR: RGBColor = RGBColor(213, 94, 0);
const BAND_COLOUR: RGBColor = RGBColor(250, 215, 190);
const CRLB_COLOUR: RGBColor = RGBColor(30, 30, 30);
const GRID_BOLD: RGBColor = RGBColor(215, 215, 215);
const GRID_LIGHT: RGBColor = RGBColor(238, 238, 238);
const LOG_COLOUR_BAND: RGBColor = RGBColor(253, 235, 222);
const SWITCH_COLOUR: RGBColor = RGBColor(150, 90, 190);
/// Width of the 3σ_CRLB dashes (px): wider than the filter's line on top.
const CRLB_WIDTH: u32 = 5;

/// Writes one PNG: a figure titled `title` with one panel per curve
/// (stacked vertically, shared time axis `t_s` in seconds). Every slice of
/// every curve must have the length of `t_s`; non-finite points are skipped.
/// The image is [`figure_size`]`(curves.len())` pixels.
pub fn plot_group(
    path: &Path,
    title: &str,
    t_s: &[f64],
    curves: &[Curve<'_>],
) -> Result<(), String> {
    plot_group_marked(path, title, t_s, curves, &[])
}

/// [`plot_group`] with the path's segment switches (times in s, e.g. the
/// `t0_s` of every [`crate::segments::CommandSegment`] but the first) drawn
/// as vertical lines in every panel; non-finite times are skipped.
pub fn plot_group_marked(
    path: &Path,
    title: &str,
    t_s: &[f64],
    curves: &[Curve<'_>],
    switches: &[f64],
) -> Result<(), String> {
    validate(t_s, curves)?;
    let t_range = time_range(t_s).ok_or("plots: no finite time value in t_s")?;
    ensure_font()?;
    let (w, h) = figure_size(curves.len());
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    draw_figure(&root, title, t_s, t_range, curves, switches)
        .map_err(|e| format!("plots: drawing {}: {e}", path.display()))?;
    root.present()
        .map_err(|e| format!("plots: writing {}: {e}", path.display()))?;
    Ok(())
}

fn validate(t_s: &[f64], curves: &[Curve<'_>]) -> Result<(), String> {
    if t_s.is_empty() {
        return Err("plots: empty time axis".to_string());
    }
    if curves.is_empty() {
        return Err("plots: no curve to draw".to_string());
    }
    if curves.len() > MAX_PANELS {
        return Err(format!(
            "plots: {} curves, at most {MAX_PANELS} per figure",
            curves.len()
        ));
    }
    for c in curves {
        for (what, v) in [("error", c.error), ("sigma", c.sigma), ("crlb", c.crlb)] {
            if v.len() != t_s.len() {
                return Err(format!(
                    "plots: curve {:?}: {what} has {} values, t_s has {}",
                    c.label,
                    v.len(),
                    t_s.len()
                ));
            }
        }
    }
    Ok(())
}

/// Range of the finite times, widened if degenerate.
fn time_range(t_s: &[f64]) -> Option<Range<f64>> {
    let (lo, hi) = finite_min_max(t_s.iter().copied())?;
    if hi > lo {
        Some(lo..hi)
    } else {
        let pad = if lo.abs() > 0.0 { lo.abs() * 0.5 } else { 1.0 };
        Some(lo - pad..hi + pad)
    }
}

fn finite_min_max(v: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    v.filter(|x| x.is_finite()).fold(None, |acc, x| match acc {
        None => Some((x, x)),
        Some((lo, hi)) => Some((lo.min(x), hi.max(x))),
    })
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
type DrawResult<'a> =
    Result<(), DrawingAreaErrorKind<<BitMapBackend<'a> as DrawingBackend>::ErrorType>>;

fn draw_figure<'a>(
    root: &Area<'a>,
    title: &str,
    t_s: &[f64],
    t_range: Range<f64>,
    curves: &[Curve<'_>],
    switches: &[f64],
) -> DrawResult<'a> {
    root.fill(&WHITE)?;
    let (header, body) = root.split_vertically(HEADER_HEIGHT);
    draw_header(&header, title, !switches.is_empty())?;
    let rows = body.split_evenly((curves.len(), 1));
    for (row, c) in rows.iter().zip(curves) {
        draw_row(row, t_s, t_range.clone(), c, switches)?;
    }
    Ok(())
}

fn font(size: f64) -> TextStyle<'static> {
    (FAMILY, size).into_font().color(&BLACK)
}

/// The figure's title, centred at the top of its header `area`, in `size`
/// points.
fn draw_title<'a>(area: &Area<'a>, title: &str, size: f64) -> DrawResult<'a> {
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
fn legend_label() -> TextStyle<'static> {
    font(15.0).pos(text_anchor::Pos::new(
        text_anchor::HPos::Left,
        text_anchor::VPos::Center,
    ))
}

/// Title and the legend shared by all panels.
fn draw_header<'a>(area: &Area<'a>, title: &str, switches: bool) -> DrawResult<'a> {
    draw_title(area, title, 22.0)?;

    // Legend: swatches + labels, centred.
    let y = 48;
    let label = legend_label();
    let items: [(&str, u8); 5] = [
        ("error (left: |error|)", 0),
        ("±3σ filter", 1),
        ("±3σ_CRLB", 2),
        ("segment switch", 4),
        ("left: log, whole run — right: linear, converged part", 3),
    ];
    let mut x = 24;
    for (text, kind) in items {
        if kind == 4 && !switches {
            continue;
        }
        match kind {
            0 => area.draw(&PathElement::new(
                vec![(x, y), (x + 30, y)],
                ERROR_COLOUR.stroke_width(2),
            ))?,
            1 => {
                area.draw(&Rectangle::new(
                    [(x, y - 6), (x + 30, y + 6)],
                    BAND_COLOUR.filled(),
                ))?;
                area.draw(&PathElement::new(
                    vec![(x, y - 6), (x + 30, y - 6)],
                    FILTER_COLOUR.stroke_width(1),
                ))?;
                area.draw(&PathElement::new(
                    vec![(x, y + 6), (x + 30, y + 6)],
                    FILTER_COLOUR.stroke_width(1),
                ))?;
            }
            2 => area.draw(&DashedPathElement::new(
                vec![(x, y), (x + 30, y)],
                6,
                4,
                CRLB_COLOUR.stroke_width(CRLB_WIDTH),
            ))?,
            4 => area.draw(&PathElement::new(
                vec![(x + 15, y - 9), (x + 15, y + 9)],
                SWITCH_COLOUR.stroke_width(2),
            ))?,
            _ => {
                x += 20;
                area.draw(&Text::new(text.to_string(), (x, y), label.clone()))?;
                continue;
            }
        }
        area.draw(&Text::new(text.to_string(), (x + 38, y), label.clone()))?;
        let advance = area
            .estimate_text_size(text, &label)
            .map(|(tw, _)| i32::try_from(tw).unwrap_or(200))
            .unwrap_or(200);
        x += 38 + advance + 30;
    }
    Ok(())
}

/// One state's row: label strip, then the log panel and the zoom panel.
fn draw_row<'a>(
    area: &Area<'a>,
    t_s: &[f64],
    t: Range<f64>,
    c: &Curve<'_>,
    switches: &[f64],
) -> DrawResult<'a> {
    let (strip, panels) = area.split_vertically(24);
    // Separator line and the state's label with its final values.
    let (w, _) = strip.dim_in_pixel();
    let w = i32::try_from(w).unwrap_or(1000);
    strip.draw(&PathElement::new(
        vec![(8, 1), (w - 8, 1)],
        RGBColor(170, 170, 170).stroke_width(1),
    ))?;
    let style = font(16.0).pos(text_anchor::Pos::new(
        text_anchor::HPos::Left,
        text_anchor::VPos::Center,
    ));
    strip.draw(&Text::new(c.label.to_string(), (14, 14), style))?;
    if let Some(summary) = final_summary(c) {
        let style = font(13.0).pos(text_anchor::Pos::new(
            text_anchor::HPos::Right,
            text_anchor::VPos::Center,
        ));
        strip.draw(&Text::new(summary, (w - 14, 14), style))?;
    }
    let (left, right) = panels.split_horizontally(WIDTH / 2);
    draw_log_panel(&left, t_s, t.clone(), c, switches)?;
    draw_zoom_panel(&right, t_s, t, c, switches)
}

/// Vertical lines at the switch times inside `t`, over the y-range `y`.
fn draw_switches<DB: DrawingBackend, Y: plotters::coord::ranged1d::Ranged<ValueType = f64>>(
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

/// "final: error …″, 3σ …″, 3σ_CRLB …″" from the last finite values.
fn final_summary(c: &Curve<'_>) -> Option<String> {
    let last = |v: &[f64]| v.iter().rev().copied().find(|x| x.is_finite());
    let e = last(c.error)?;
    let mut s = format!("final: error {}″", fmt_value(e));
    if let Some(sig) = last(c.sigma) {
        s.push_str(&format!(", 3σ {}″", fmt_value(3.0 * sig)));
    }
    if let Some(cr) = last(c.crlb) {
        s.push_str(&format!(", 3σ_CRLB {}″", fmt_value(3.0 * cr)));
    }
    Some(s)
}

/// One parameter's σ(t) along two paths (`host-sim design`), in the
/// display unit (arcseconds): `(t in s, σ)` points of path A and path B.
#[derive(Clone, Debug)]
pub struct SigmaCurve {
    /// State name: the panel label.
    pub label: &'static str,
    /// The target σ (″), drawn as a horizontal line.
    pub target: f64,
    /// Path A (the designed one).
    pub a: Vec<(f64, f64)>,
    /// Path B (the reference).
    pub b: Vec<(f64, f64)>,
}

/// Columns of [`plot_sigma_comparison`].
const SIGMA_COLUMNS: usize = 3;
/// Height of one row of [`plot_sigma_comparison`] (px).
const SIGMA_ROW_HEIGHT: u32 = 210;

/// Writes one PNG comparing σ(t) of every curve along two paths: one
/// log-scale panel per parameter (three per row), path A solid, path B
/// dashed, the target dotted; the time axis is shared.
pub fn plot_sigma_comparison(
    path: &Path,
    title: &str,
    a_label: &str,
    b_label: &str,
    curves: &[SigmaCurve],
) -> Result<(), String> {
    if curves.is_empty() {
        return Err("plots: no curve to draw".to_string());
    }
    if curves.len() > MAX_PANELS {
        return Err(format!(
            "plots: {} curves, at most {MAX_PANELS} per figure",
            curves.len()
        ));
    }
    let t_max = curves
        .iter()
        .flat_map(|c| c.a.iter().chain(&c.b))
        .map(|p| p.0)
        .filter(|t| t.is_finite())
        .fold(0.0, f64::max);
    if t_max <= 0.0 {
        return Err("plots: no finite time value".to_string());
    }
    ensure_font()?;
    let rows = curves.len().div_ceil(SIGMA_COLUMNS);
    let h = HEADER_HEIGHT + SIGMA_ROW_HEIGHT * u32::try_from(rows).unwrap_or(1);
    let root = BitMapBackend::new(path, (WIDTH + 200, h)).into_drawing_area();
    let draw = || -> DrawResult<'_> {
        root.fill(&WHITE)?;
        let (header, body) = root.split_vertically(HEADER_HEIGHT);
        draw_title(&header, title, 20.0)?;
        let label = legend_label();
        let y = 46;
        header.draw(&PathElement::new(
            vec![(40, y), (70, y)],
            ERROR_COLOUR.stroke_width(2),
        ))?;
        header.draw(&Text::new(
            format!("{a_label} path"),
            (78, y),
            label.clone(),
        ))?;
        header.draw(&DashedPathElement::new(
            vec![(300, y), (330, y)],
            5,
            3,
            FILTER_COLOUR.stroke_width(2),
        ))?;
        header.draw(&Text::new(
            format!("{b_label} path"),
            (338, y),
            label.clone(),
        ))?;
        header.draw(&DashedPathElement::new(
            vec![(560, y), (590, y)],
            2,
            3,
            CRLB_COLOUR.stroke_width(1),
        ))?;
        header.draw(&Text::new("target σ [″]", (598, y), label))?;
        let panels = body.split_evenly((rows, SIGMA_COLUMNS));
        for (area, c) in panels.iter().zip(curves) {
            let vals = || {
                c.a.iter()
                    .chain(&c.b)
                    .map(|p| p.1)
                    .chain(std::iter::once(c.target))
                    .filter(|v| v.is_finite() && *v > 0.0)
            };
            let lo = vals().fold(f64::INFINITY, f64::min);
            // The prior (3600″) dwarfs the converged part: show two decades
            // above the larger of the target and the final values.
            let hi_all = vals().fold(0.0, f64::max);
            let hi = (c.target * 100.0).min(hi_all).max(lo * 10.0);
            let y = (lo / 1.5)..(hi * 1.2);
            let mut chart = ChartBuilder::on(area)
                .caption(c.label, font(15.0))
                .margin(6)
                .x_label_area_size(28)
                .y_label_area_size(56)
                .build_cartesian_2d(0.0..t_max, y.clone().log_scale())?;
            chart
                .configure_mesh()
                .bold_line_style(GRID_BOLD)
                .light_line_style(TRANSPARENT)
                .x_labels(5)
                .y_labels(6)
                .x_label_formatter(&|v| fmt_tick(*v))
                .y_label_formatter(&|v| fmt_log_tick(*v))
                .x_desc("t [s]")
                .label_style(font(11.0))
                .axis_desc_style(font(12.0))
                .draw()?;
            let clip = |v: &[(f64, f64)]| -> Vec<(f64, f64)> {
                v.iter()
                    .filter(|p| p.0.is_finite() && p.1.is_finite() && p.1 > 0.0)
                    .map(|&(t, s)| (t, s.clamp(y.start, y.end)))
                    .collect()
            };
            chart.draw_series(DashedLineSeries::new(
                clip(&c.b),
                5,
                3,
                FILTER_COLOUR.stroke_width(2),
            ))?;
            chart.draw_series(LineSeries::new(clip(&c.a), ERROR_COLOUR.stroke_width(2)))?;
            chart.draw_series(DashedLineSeries::new(
                vec![(0.0, c.target), (t_max, c.target)],
                2,
                3,
                CRLB_COLOUR.stroke_width(1),
            ))?;
        }
        Ok(())
    };
    draw().map_err(|e| format!("plots: drawing {}: {e}", path.display()))?;
    root.present()
        .map_err(|e| format!("plots: writing {}: {e}", path.display()))?;
    Ok(())
}

/// Three significant digits, no exponent for ordinary magnitudes.
fn fmt_value(v: f64) -> String {
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

/// Left panel: |error|, 3σ and 3σ_CRLB on a log axis over the whole run.
fn draw_log_panel<'a>(
    area: &Area<'a>,
    t_s: &[f64],
    t: Range<f64>,
    c: &Curve<'_>,
    switches: &[f64],
) -> DrawResult<'a> {
    let abs_err: Vec<f64> = c.error.iter().map(|e| e.abs()).collect();
    let three_sigma: Vec<f64> = c.sigma.iter().map(|s| 3.0 * s.abs()).collect();
    let three_crlb: Vec<f64> = c.crlb.iter().map(|s| 3.0 * s.abs()).collect();
    let y = log_range(t_s, t.clone(), &abs_err, &three_sigma, &three_crlb);
    let mut chart = ChartBuilder::on(area)
        .margin_left(8)
        .margin_right(14)
        .margin_top(6)
        .margin_bottom(4)
        .x_label_area_size(34)
        .y_label_area_size(62)
        .build_cartesian_2d(t.clone(), y.clone().log_scale())?;
    chart
        .configure_mesh()
        .bold_line_style(GRID_BOLD)
        // plotters' light lines on a log axis bunch up into grey bands.
        .light_line_style(TRANSPARENT)
        .x_labels(7)
        .y_labels(12)
        .x_label_formatter(&|v| fmt_tick(*v))
        .y_label_formatter(&|v| fmt_log_tick(*v))
        .x_desc("t [s]")
        .y_desc("|error|, 3σ [″]")
        .label_style(font(12.0))
        .axis_desc_style(font(13.0))
        .draw()?;
    let (lo, hi) = (y.start, y.end);
    // Light fill under 3σ: the region the |error| should stay in.
    for run in finite_runs(t_s, &three_sigma, |v| v > 0.0) {
        let mut poly: Vec<(f64, f64)> = run.iter().map(|&(x, v)| (x, v.clamp(lo, hi))).collect();
        if let (Some(&(x0, _)), Some(&(x1, _))) = (run.first(), run.last()) {
            poly.push((x1, lo));
            poly.push((x0, lo));
        }
        chart.draw_series(std::iter::once(Polygon::new(
            poly,
            LOG_COLOUR_BAND.filled(),
        )))?;
    }
    draw_switches(&mut chart, switches, &t, (lo, hi))?;
    // σ_CRLB under σ: wide dashes that stick out on both sides of the
    // filter's line where the filter reaches the bound.
    for seg in clipped(t_s, &three_crlb, lo, hi, true) {
        chart.draw_series(DashedLineSeries::new(
            seg,
            6,
            4,
            CRLB_COLOUR.stroke_width(CRLB_WIDTH),
        ))?;
    }
    for seg in clipped(t_s, &three_sigma, lo, hi, true) {
        chart.draw_series(LineSeries::new(seg, FILTER_COLOUR.stroke_width(2)))?;
    }
    for seg in clipped(t_s, &abs_err, lo, hi, true) {
        chart.draw_series(LineSeries::new(seg, ERROR_COLOUR.stroke_width(1)))?;
    }
    Ok(())
}

/// Right panel: signed error in the ±3σ band and between the ±3σ_CRLB
/// lines, linear axis zoomed on the converged part ([`zoom_half_range`]).
fn draw_zoom_panel<'a>(
    area: &Area<'a>,
    t_s: &[f64],
    t: Range<f64>,
    c: &Curve<'_>,
    switches: &[f64],
) -> DrawResult<'a> {
    let r = zoom_half_range(t_s, t.clone(), c);
    let (lo, hi) = (-r, r);
    // Only the converged part: from its first sample on.
    let from = converged_from(t_s, &t, c.sigma);
    let k0 = t_s
        .iter()
        .position(|ti| ti.is_finite() && *ti >= from)
        .unwrap_or(0);
    let tail = |v: &'_ [f64]| -> Vec<f64> { v.get(k0..).unwrap_or_default().to_vec() };
    let t_s = t_s.get(k0..).unwrap_or_default();
    let t = match time_range(t_s) {
        Some(r) if r.start >= t.start => r,
        _ => t,
    };
    let (error, sigma, crlb) = (tail(c.error), tail(c.sigma), tail(c.crlb));
    let mut chart = ChartBuilder::on(area)
        .margin_left(8)
        .margin_right(14)
        .margin_top(6)
        .margin_bottom(4)
        .x_label_area_size(34)
        .y_label_area_size(62)
        .build_cartesian_2d(t.clone(), lo..hi)?;
    // Approximate tick step of the 7 labels over 2r (sets the decimals).
    let step = 2.0 * r / 7.0;
    chart
        .configure_mesh()
        .bold_line_style(GRID_BOLD)
        .light_line_style(GRID_LIGHT)
        .max_light_lines(2)
        .x_labels(7)
        .y_labels(7)
        .x_label_formatter(&|v| fmt_tick(*v))
        .y_label_formatter(&|v| fmt_linear_tick(*v, step))
        .x_desc(format!(
            "t [s] (converged part, from {} s)",
            fmt_tick(t.start)
        ))
        .y_desc("error [″]")
        .label_style(font(12.0))
        .axis_desc_style(font(13.0))
        .draw()?;
    // ±3σ band (inside the frame: the range covers it).
    let plus: Vec<f64> = sigma.iter().map(|s| 3.0 * s.abs()).collect();
    let minus: Vec<f64> = plus.iter().map(|v| -v).collect();
    for run in finite_runs(t_s, &plus, |_| true) {
        let mut poly: Vec<(f64, f64)> = run.iter().map(|&(x, v)| (x, v.clamp(lo, hi))).collect();
        poly.extend(run.iter().rev().map(|&(x, v)| (x, (-v).clamp(lo, hi))));
        chart.draw_series(std::iter::once(Polygon::new(poly, BAND_COLOUR.filled())))?;
    }
    draw_switches(&mut chart, switches, &t, (lo, hi))?;
    let crlb_plus: Vec<f64> = crlb.iter().map(|s| 3.0 * s.abs()).collect();
    let crlb_minus: Vec<f64> = crlb_plus.iter().map(|v| -v).collect();
    for v in [&crlb_plus, &crlb_minus] {
        for seg in clipped(t_s, v, lo, hi, false) {
            chart.draw_series(DashedLineSeries::new(
                seg,
                6,
                4,
                CRLB_COLOUR.stroke_width(CRLB_WIDTH),
            ))?;
        }
    }
    for v in [&plus, &minus] {
        for seg in clipped(t_s, v, lo, hi, false) {
            chart.draw_series(LineSeries::new(seg, FILTER_COLOUR.stroke_width(2)))?;
        }
    }
    for seg in clipped(t_s, &error, lo, hi, false) {
        chart.draw_series(LineSeries::new(seg, ERROR_COLOUR.stroke_width(1)))?;
    }
    Ok(())
}

/// Start of the "converged part" of a curve: the later of 20 % into the run
/// and the time after which 3σ stays within twice its final value (so a
/// state that converges late is still zoomed on its converged level).
fn converged_from(t_s: &[f64], t: &Range<f64>, sigma: &[f64]) -> f64 {
    let fifth = t.start + 0.2 * (t.end - t.start);
    let finite = || {
        t_s.iter()
            .zip(sigma)
            .filter(|(ti, s)| ti.is_finite() && s.is_finite())
            .map(|(ti, s)| (*ti, s.abs()))
    };
    let Some((_, last)) = finite().next_back() else {
        return fifth;
    };
    let settled = finite()
        .filter(|&(_, s)| s > 2.0 * last)
        .map(|(ti, _)| ti)
        .fold(f64::NEG_INFINITY, f64::max);
    fifth.max(settled)
}

/// Half-range of the zoom panel: 1.5 × max(|error|, 3σ, 3σ_CRLB) over the
/// converged part ([`converged_from`]); 1 if nothing there is positive and
/// finite.
fn zoom_half_range(t_s: &[f64], t: Range<f64>, c: &Curve<'_>) -> f64 {
    let from = converged_from(t_s, &t, c.sigma);
    let mut m = 0.0_f64;
    for (i, &ti) in t_s.iter().enumerate() {
        if !(ti.is_finite() && ti >= from) {
            continue;
        }
        let vals = [
            c.error.get(i).map(|e| e.abs()),
            c.sigma.get(i).map(|s| 3.0 * s.abs()),
            c.crlb.get(i).map(|s| 3.0 * s.abs()),
        ];
        for v in vals.into_iter().flatten() {
            if v.is_finite() {
                m = m.max(v);
            }
        }
    }
    let r = 1.5 * m;
    if r.is_finite() && r > 1e-12 {
        r
    } else {
        1.0
    }
}

/// Log axis range: from below the converged level (3σ_CRLB,
/// 3σ and the 10th percentile of the late |error|) to above the largest
/// value; the downward spikes of |error| at its zero crossings are clipped.
fn log_range(t_s: &[f64], t: Range<f64>, abs_err: &[f64], s3: &[f64], c3: &[f64]) -> Range<f64> {
    let positive = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .copied()
            .filter(|x| x.is_finite() && *x > 0.0)
            .collect()
    };
    let all: Vec<f64> = [positive(abs_err), positive(s3), positive(c3)].concat();
    let Some((_, max)) = finite_min_max(all.iter().copied()) else {
        return 1e-3..1.0;
    };
    let from = converged_from(t_s, &t, s3);
    let mut late_err: Vec<f64> = t_s
        .iter()
        .zip(abs_err)
        .filter(|(ti, e)| ti.is_finite() && **ti >= from && e.is_finite() && **e > 0.0)
        .map(|(_, e)| *e)
        .collect();
    late_err.sort_by(f64::total_cmp);
    let err_floor = late_err.get(late_err.len() / 10).copied();
    let sig_min = finite_min_max(positive(s3).into_iter().chain(positive(c3))).map(|(lo, _)| lo);
    let min = match (err_floor, sig_min) {
        (Some(a), Some(b)) => a.min(b),
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => max * 1e-3,
    };
    let hi = max * 1.5;
    // At least one decade (so a decade tick is labelled) and at most 12.
    let lo = (min / 1.5).max(hi * 1e-12).min(hi / 10.0);
    if lo.is_finite() && hi.is_finite() && lo > 0.0 && hi > lo {
        lo..hi
    } else {
        1e-3..1.0
    }
}

/// Maximal runs of consecutive points whose t and value are finite and
/// satisfy `keep`.
fn finite_runs(t_s: &[f64], v: &[f64], keep: impl Fn(f64) -> bool) -> Vec<Vec<(f64, f64)>> {
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
fn clipped(t_s: &[f64], v: &[f64], lo: f64, hi: f64, log: bool) -> Vec<Vec<(f64, f64)>> {
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
fn fmt_tick(v: f64) -> String {
    if v.abs() >= 10.0 || v == 0.0 {
        format!("{v:.0}")
    } else {
        fmt_value(v)
    }
}

/// Log-axis ticks: only decades are labelled ("0.01", "1", "1000", "1e-5").
fn fmt_log_tick(v: f64) -> String {
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
fn fmt_linear_tick(v: f64, step: f64) -> String {
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

/// One parameter's σ(t) for [`plot_convergence`], in the display unit
/// (arcseconds), per point of the shared time axis.
#[derive(Clone, Copy, Debug)]
pub struct SigmaSeries<'a> {
    /// State name: the panel label.
    pub label: &'a str,
    /// Filter σ (″).
    pub sigma: &'a [f64],
    /// σ_CRLB (″), when known.
    pub crlb: Option<&'a [f64]>,
}

/// Columns of [`plot_convergence`].
const CONVERGENCE_COLUMNS: usize = 3;
/// Height of one row of [`plot_convergence`] (px).
const CONVERGENCE_ROW_HEIGHT: u32 = 220;

/// Size (width, height) in pixels of the figure [`plot_convergence`] writes
/// for `panels` series.
pub fn convergence_size(panels: usize) -> (u32, u32) {
    let rows = u32::try_from(panels.div_ceil(CONVERGENCE_COLUMNS)).unwrap_or(u32::MAX);
    (
        WIDTH,
        HEADER_HEIGHT.saturating_add(CONVERGENCE_ROW_HEIGHT.saturating_mul(rows)),
    )
}

/// Writes one PNG of the σ(t) convergence of every series (three panels per
/// row, log-scale y over the whole range, so the transient from the prior is
/// not clipped): the filter's σ solid over the σ_CRLB dashes (when known),
/// segment switches as vertical lines.
pub fn plot_convergence(
    path: &Path,
    title: &str,
    t_s: &[f64],
    series: &[SigmaSeries<'_>],
    switches: &[f64],
) -> Result<(), String> {
    if t_s.is_empty() {
        return Err("plots: empty time axis".to_string());
    }
    if series.is_empty() {
        return Err("plots: no curve to draw".to_string());
    }
    if series.len() > MAX_PANELS {
        return Err(format!(
            "plots: {} curves, at most {MAX_PANELS} per figure",
            series.len()
        ));
    }
    for s in series {
        for (what, v) in [("sigma", Some(s.sigma)), ("crlb", s.crlb)] {
            if let Some(v) = v.filter(|v| v.len() != t_s.len()) {
                return Err(format!(
                    "plots: curve {:?}: {what} has {} values, t_s has {}",
                    s.label,
                    v.len(),
                    t_s.len()
                ));
            }
        }
    }
    let t = time_range(t_s).ok_or("plots: no finite time value in t_s")?;
    ensure_font()?;
    let (w, h) = convergence_size(series.len());
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    let draw = || -> DrawResult<'_> {
        root.fill(&WHITE)?;
        let (header, body) = root.split_vertically(HEADER_HEIGHT);
        draw_title(&header, title, 20.0)?;
        let label = legend_label();
        let y = 46;
        header.draw(&PathElement::new(
            vec![(40, y), (70, y)],
            FILTER_COLOUR.stroke_width(2),
        ))?;
        header.draw(&Text::new("filter σ [″]", (78, y), label.clone()))?;
        if series.iter().any(|s| s.crlb.is_some()) {
            header.draw(&DashedPathElement::new(
                vec![(260, y), (290, y)],
                6,
                4,
                CRLB_COLOUR.stroke_width(CRLB_WIDTH),
            ))?;
            header.draw(&Text::new("σ_CRLB [″]", (298, y), label.clone()))?;
        }
        header.draw(&PathElement::new(
            vec![(475, y - 9), (475, y + 9)],
            SWITCH_COLOUR.stroke_width(2),
        ))?;
        header.draw(&Text::new(
            "segment switch (log scale, whole run)",
            (490, y),
            label,
        ))?;
        let rows = series.len().div_ceil(CONVERGENCE_COLUMNS);
        let panels = body.split_evenly((rows, CONVERGENCE_COLUMNS));
        for (area, s) in panels.iter().zip(series) {
            let pos = |v: &[f64]| -> Vec<f64> {
                v.iter()
                    .copied()
                    .filter(|x| x.is_finite() && *x > 0.0)
                    .collect()
            };
            let vals: Vec<f64> = [pos(s.sigma), s.crlb.map(pos).unwrap_or_default()].concat();
            let (lo, hi) = finite_min_max(vals.into_iter()).unwrap_or((1e-3, 1.0));
            let (lo, hi) = ((lo / 1.5).min(hi / 10.0), hi * 1.5);
            let mut chart = ChartBuilder::on(area)
                .caption(s.label, font(15.0))
                .margin(6)
                .x_label_area_size(28)
                .y_label_area_size(56)
                .build_cartesian_2d(t.clone(), (lo..hi).log_scale())?;
            chart
                .configure_mesh()
                .bold_line_style(GRID_BOLD)
                .light_line_style(TRANSPARENT)
                .x_labels(5)
                .y_labels(8)
                .x_label_formatter(&|v| fmt_tick(*v))
                .y_label_formatter(&|v| fmt_log_tick(*v))
                .x_desc("t [s]")
                .label_style(font(11.0))
                .axis_desc_style(font(12.0))
                .draw()?;
            draw_switches(&mut chart, switches, &t, (lo, hi))?;
            if let Some(c) = s.crlb {
                for seg in clipped(t_s, c, lo, hi, true) {
                    chart.draw_series(DashedLineSeries::new(
                        seg,
                        6,
                        4,
                        CRLB_COLOUR.stroke_width(CRLB_WIDTH),
                    ))?;
                }
            }
            for seg in clipped(t_s, s.sigma, lo, hi, true) {
                chart.draw_series(LineSeries::new(seg, FILTER_COLOUR.stroke_width(2)))?;
            }
        }
        Ok(())
    };
    draw().map_err(|e| format!("plots: drawing {}: {e}", path.display()))?;
    root.present()
        .map_err(|e| format!("plots: writing {}: {e}", path.display()))?;
    Ok(())
}

/// The accepted updates for [`plot_innovations`].
#[derive(Clone, Copy, Debug)]
pub struct Innovations<'a> {
    /// Time of every update (s).
    pub t_s: &'a [f64],
    /// NIS of every update.
    pub nis: &'a [f64],
    /// Whitened innovation of every update (unit variance per component
    /// when the model holds; may be empty for an update).
    pub white: &'a [Vec<f64>],
    /// Degrees of freedom of one update's NIS (the measurement size).
    pub dof: usize,
    /// Moving-average window (updates).
    pub window: usize,
    /// The two-sided 99 % band of a mean of `window` NIS values.
    pub band: (f64, f64),
}

/// Size (width, height) in pixels of the figure of [`plot_innovations`].
pub const INNOVATIONS_SIZE: (u32, u32) = (WIDTH, HEADER_HEIGHT + 2 * 300);

/// Colours of the whitened innovation components.
const COMPONENT_COLOURS: [RGBColor; 6] = [
    RGBColor(0, 90, 181),
    RGBColor(213, 94, 0),
    RGBColor(0, 150, 100),
    RGBColor(200, 50, 140),
    RGBColor(120, 120, 120),
    RGBColor(230, 170, 0),
];

/// The moving average of `v` over the last `window` values (fewer at the
/// start).
pub fn moving_average(v: &[f64], window: usize) -> Vec<f64> {
    let w = window.max(1);
    let mut out = Vec::with_capacity(v.len());
    let mut sum = 0.0;
    for (k, x) in v.iter().enumerate() {
        sum += x;
        if k >= w {
            sum -= v.get(k - w).copied().unwrap_or(0.0);
        }
        out.push(sum / (k.min(w - 1) + 1) as f64);
    }
    out
}

/// Writes one PNG of the NIS and the whitened innovations over time: top,
/// the moving average of the NIS (log scale, whole range) with its 99 % χ²
/// band shaded and the degrees of freedom dotted; bottom, every whitened
/// innovation component as a dot with the ±3 lines (linear, the range
/// covers every value). Segment switches are vertical lines in both.
pub fn plot_innovations(
    path: &Path,
    title: &str,
    u: &Innovations<'_>,
    switches: &[f64],
) -> Result<(), String> {
    let n = u.t_s.len();
    if n == 0 {
        return Err("plots: no update to draw".to_string());
    }
    if u.nis.len() != n || u.white.len() != n {
        return Err(format!(
            "plots: {n} update times, {} NIS values, {} whitened innovations",
            u.nis.len(),
            u.white.len()
        ));
    }
    let t = time_range(u.t_s).ok_or("plots: no finite time value")?;
    ensure_font()?;
    let (w, h) = INNOVATIONS_SIZE;
    let root = BitMapBackend::new(path, (w, h)).into_drawing_area();
    // The band is that of a full window: the first window-1 means are not drawn.
    let mut avg = moving_average(u.nis, u.window);
    for v in avg.iter_mut().take(u.window.saturating_sub(1)) {
        *v = f64::NAN;
    }
    let draw = || -> DrawResult<'_> {
        root.fill(&WHITE)?;
        let (header, body) = root.split_vertically(HEADER_HEIGHT);
        draw_title(&header, title, 20.0)?;
        let label = legend_label();
        let y = 46;
        header.draw(&PathElement::new(
            vec![(40, y), (70, y)],
            ERROR_COLOUR.stroke_width(2),
        ))?;
        header.draw(&Text::new(
            format!("NIS, mean of {} updates", u.window),
            (78, y),
            label.clone(),
        ))?;
        header.draw(&Rectangle::new(
            [(330, y - 6), (360, y + 6)],
            BAND_COLOUR.filled(),
        ))?;
        header.draw(&Text::new(
            format!("99 % χ² band ({} dof per update)", u.dof),
            (368, y),
            label.clone(),
        ))?;
        header.draw(&PathElement::new(
            vec![(680, y - 9), (680, y + 9)],
            SWITCH_COLOUR.stroke_width(2),
        ))?;
        header.draw(&Text::new("segment switch", (695, y), label))?;
        let (top, bottom) = body.split_vertically(300);
        // Top: NIS moving average.
        let vals = avg
            .iter()
            .copied()
            .chain([u.band.0, u.band.1, u.dof as f64])
            .filter(|v| v.is_finite() && *v > 0.0);
        let (lo, hi) = finite_min_max(vals).unwrap_or((0.1, 10.0));
        let (lo, hi) = ((lo / 1.5).min(hi / 10.0), hi * 1.5);
        let mut chart = ChartBuilder::on(&top)
            .margin(8)
            .x_label_area_size(34)
            .y_label_area_size(62)
            .build_cartesian_2d(t.clone(), (lo..hi).log_scale())?;
        chart
            .configure_mesh()
            .bold_line_style(GRID_BOLD)
            .light_line_style(TRANSPARENT)
            .x_labels(7)
            .y_labels(10)
            .x_label_formatter(&|v| fmt_tick(*v))
            .y_label_formatter(&|v| fmt_log_tick(*v))
            .x_desc("t [s]")
            .y_desc("NIS (moving mean)")
            .label_style(font(12.0))
            .axis_desc_style(font(13.0))
            .draw()?;
        if u.band.0.is_finite() && u.band.1.is_finite() && u.band.1 > u.band.0 {
            let (b0, b1) = (u.band.0.clamp(lo, hi), u.band.1.clamp(lo, hi));
            chart.draw_series(std::iter::once(Rectangle::new(
                [(t.start, b0), (t.end, b1)],
                BAND_COLOUR.filled(),
            )))?;
        }
        chart.draw_series(DashedLineSeries::new(
            vec![(t.start, u.dof as f64), (t.end, u.dof as f64)],
            2,
            3,
            CRLB_COLOUR.stroke_width(1),
        ))?;
        draw_switches(&mut chart, switches, &t, (lo, hi))?;
        for seg in clipped(u.t_s, &avg, lo, hi, true) {
            chart.draw_series(LineSeries::new(seg, ERROR_COLOUR.stroke_width(2)))?;
        }
        // Bottom: whitened innovations.
        let m = u
            .white
            .iter()
            .flatten()
            .filter(|v| v.is_finite())
            .fold(4.0_f64, |m, v| m.max(v.abs() * 1.05));
        let mut chart = ChartBuilder::on(&bottom)
            .margin(8)
            .x_label_area_size(34)
            .y_label_area_size(62)
            .build_cartesian_2d(t.clone(), -m..m)?;
        chart
            .configure_mesh()
            .bold_line_style(GRID_BOLD)
            .light_line_style(GRID_LIGHT)
            .max_light_lines(1)
            .x_labels(7)
            .y_labels(9)
            .x_label_formatter(&|v| fmt_tick(*v))
            .y_label_formatter(&|v| fmt_linear_tick(*v, 2.0 * m / 9.0))
            .x_desc("t [s]")
            .y_desc("whitened innovation (unit σ)")
            .label_style(font(12.0))
            .axis_desc_style(font(13.0))
            .draw()?;
        draw_switches(&mut chart, switches, &t, (-m, m))?;
        for (k, colour) in COMPONENT_COLOURS.iter().enumerate() {
            let pts = u
                .t_s
                .iter()
                .zip(u.white)
                .filter_map(|(ti, wv)| wv.get(k).map(|v| (*ti, *v)))
                .filter(|(ti, v)| ti.is_finite() && v.is_finite())
                .map(|p| Circle::new(p, 1, colour.filled()));
            chart.draw_series(pts)?;
        }
        for v in [-3.0, 3.0] {
            chart.draw_series(DashedLineSeries::new(
                vec![(t.start, v), (t.end, v)],
                5,
                3,
                CRLB_COLOUR.stroke_width(1),
            ))?;
        }
        Ok(())
    };
    draw().map_err(|e| format!("plots: drawing {}: {e}", path.display()))?;
    root.present()
        .map_err(|e| format!("plots: writing {}: {e}", path.display()))?;
    Ok(())
}
