//! The σ(t) convergence figure of the HTML report ([`plot_convergence`]):
//! three log-scale panels per row, the filter's σ over the σ_CRLB dashes,
//! the segment switches marked.

use std::ops::Range;
use std::path::Path;

use plotters::element::DashedPathElement;
use plotters::prelude::*;

use super::style::*;
use super::style::{Area, DrawResult};

/// One parameter's σ(t) for [`plot_convergence`], in its display unit
/// `unit`, per point of the shared time axis.
#[derive(Clone, Copy, Debug)]
pub struct SigmaSeries<'a> {
    /// State name: the panel label (with the unit).
    pub label: &'a str,
    /// The display unit (″ for the angles; °/h, ppm, µg, …).
    pub unit: &'a str,
    /// Filter σ.
    pub sigma: &'a [f64],
    /// σ_CRLB, when known.
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
    draw_convergence(&root, title, t_s, &t, series, switches)
        .map_err(|e| format!("plots: drawing {}: {e}", path.display()))?;
    root.present()
        .map_err(|e| format!("plots: writing {}: {e}", path.display()))?;
    Ok(())
}

/// The whole convergence figure on `root`: header, then one panel per
/// series.
fn draw_convergence<'a>(
    root: &Area<'a>,
    title: &str,
    t_s: &[f64],
    t: &Range<f64>,
    series: &[SigmaSeries<'_>],
    switches: &[f64],
) -> DrawResult<'a> {
    root.fill(&WHITE)?;
    let (header, body) = root.split_vertically(HEADER_HEIGHT);
    draw_title(&header, title, 20.0)?;
    let label = legend_label();
    let y = 46;
    header.draw(&PathElement::new(
        vec![(40, y), (70, y)],
        FILTER_COLOUR.stroke_width(2),
    ))?;
    header.draw(&Text::new("filter σ", (78, y), label.clone()))?;
    if series.iter().any(|s| s.crlb.is_some()) {
        header.draw(&DashedPathElement::new(
            vec![(260, y), (290, y)],
            6,
            4,
            CRLB_COLOUR.stroke_width(CRLB_WIDTH),
        ))?;
        header.draw(&Text::new("σ_CRLB", (298, y), label.clone()))?;
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
        draw_convergence_panel(area, t_s, t, s, switches)?;
    }
    Ok(())
}

/// One series' panel: σ and σ_CRLB on a log scale over the whole run.
fn draw_convergence_panel<'a>(
    area: &Area<'a>,
    t_s: &[f64],
    t: &Range<f64>,
    s: &SigmaSeries<'_>,
    switches: &[f64],
) -> DrawResult<'a> {
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
        .caption(format!("{} [{}]", s.label, s.unit), font(15.0))
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
    draw_switches(&mut chart, switches, t, (lo, hi))?;
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
    Ok(())
}
