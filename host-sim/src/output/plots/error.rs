//! The error figure ([`plot_group`], [`plot_group_marked`]): per state a
//! row of two panels, the log panel over the whole run and the linear zoom
//! on the converged part (`error_panels.rs`), under a shared header.

use std::ops::Range;
use std::path::Path;

use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor;

use super::error_panels::{draw_log_panel, draw_zoom_panel};
use super::style::*;
use super::style::{Area, DrawResult};

/// One state's time history, all in its display unit `unit` (″ for the
/// angles; °/h, ppm, µg, … for the instrument terms).
#[derive(Clone, Copy, Debug)]
pub struct Curve<'a> {
    /// State name, e.g. `"thaT_1"`: the panel label.
    pub label: &'a str,
    /// The display unit of the values, named on the axes.
    pub unit: &'a str,
    /// Estimate − truth per period.
    pub error: &'a [f64],
    /// Filter σ per period: drawn as the ±3σ band.
    pub sigma: &'a [f64],
    /// σ_CRLB per period: drawn as the ±3σ_CRLB lines.
    pub crlb: &'a [f64],
}

/// Size (width, height) in pixels of the figure [`plot_group`] writes for
/// `panels` curves.
pub fn figure_size(panels: usize) -> (u32, u32) {
    let rows = u32::try_from(panels).unwrap_or(u32::MAX);
    (
        WIDTH,
        HEADER_HEIGHT.saturating_add(PANEL_HEIGHT.saturating_mul(rows)),
    )
}

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
/// `t0_s` of every [`crate::sim::segments::CommandSegment`] but the first) drawn
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

/// "final: error … ″, 3σ … ″, 3σ_CRLB … ″" (in the curve's unit) from the
/// last finite values.
fn final_summary(c: &Curve<'_>) -> Option<String> {
    let last = |v: &[f64]| v.iter().rev().copied().find(|x| x.is_finite());
    let u = c.unit;
    let e = last(c.error)?;
    let mut s = format!("final: error {} {u}", fmt_value(e));
    if let Some(sig) = last(c.sigma) {
        s.push_str(&format!(", 3σ {} {u}", fmt_value(3.0 * sig)));
    }
    if let Some(cr) = last(c.crlb) {
        s.push_str(&format!(", 3σ_CRLB {} {u}", fmt_value(3.0 * cr)));
    }
    Some(s)
}
