//! The NIS and whitened innovations figure of the HTML report
//! ([`plot_innovations`]): top, the moving mean of the NIS in its 99 % χ²
//! band; bottom, every whitened component with the ±3 lines.

use std::ops::Range;
use std::path::Path;

use plotters::prelude::*;

use super::style::*;
use super::style::{Area, DrawResult};

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
    /// The names of the whitened components, in order (e.g. `accel x`),
    /// for the legend of the bottom panel (`component k` when absent).
    pub components: &'a [&'a str],
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
///
/// # Examples
///
/// ```
/// use host_sim::output::plots::moving_average;
///
/// assert_eq!(moving_average(&[2.0, 4.0, 6.0, 8.0], 2), [2.0, 3.0, 5.0, 7.0]);
/// ```
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
    draw_innovations(&root, title, u, &avg, &t, switches)
        .map_err(|e| format!("plots: drawing {}: {e}", path.display()))?;
    root.present()
        .map_err(|e| format!("plots: writing {}: {e}", path.display()))?;
    Ok(())
}

/// The whole innovations figure on `root`: header, NIS panel, whitened
/// innovations panel; `avg`: the NIS moving mean.
fn draw_innovations<'a>(
    root: &Area<'a>,
    title: &str,
    u: &Innovations<'_>,
    avg: &[f64],
    t: &Range<f64>,
    switches: &[f64],
) -> DrawResult<'a> {
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
    header.draw(&Text::new("segment switch", (695, y), label.clone()))?;
    header.draw(&plotters::element::DashedPathElement::new(
        vec![(830, y), (860, y)],
        2,
        3,
        CRLB_COLOUR.stroke_width(1),
    ))?;
    header.draw(&Text::new(format!("expected {}", u.dof), (868, y), label))?;
    let (top, bottom) = body.split_vertically(300);
    draw_nis_panel(&top, u, avg, t, switches)?;
    let (strip, bottom) = bottom.split_vertically(24);
    draw_component_legend(&strip, u)?;
    draw_white_panel(&bottom, u, t, switches)
}

/// The legend of the whitened components: each component's colour and
/// name, then the ±3 dashes.
fn draw_component_legend<'a>(strip: &Area<'a>, u: &Innovations<'_>) -> DrawResult<'a> {
    let label = legend_label();
    let y = 12;
    let mut x = 40;
    let z = u
        .white
        .iter()
        .map(Vec::len)
        .max()
        .unwrap_or(0)
        .min(COMPONENT_COLOURS.len());
    for (k, colour) in COMPONENT_COLOURS.iter().enumerate().take(z) {
        let name = u
            .components
            .get(k)
            .map_or_else(|| format!("component {}", k + 1), |n| (*n).to_string());
        strip.draw(&Circle::new((x + 6, y), 4, colour.filled()))?;
        let advance = strip
            .estimate_text_size(&name, &label)
            .map(|(w, _)| i32::try_from(w).unwrap_or(80))
            .unwrap_or(80);
        strip.draw(&Text::new(name, (x + 16, y), label.clone()))?;
        x += 16 + advance + 24;
    }
    strip.draw(&plotters::element::DashedPathElement::new(
        vec![(x, y), (x + 30, y)],
        5,
        3,
        CRLB_COLOUR.stroke_width(1),
    ))?;
    strip.draw(&Text::new("±3", (x + 38, y), label))?;
    Ok(())
}

/// Top: the NIS moving mean (log scale) in its band, the dof dotted.
fn draw_nis_panel<'a>(
    top: &Area<'a>,
    u: &Innovations<'_>,
    avg: &[f64],
    t: &Range<f64>,
    switches: &[f64],
) -> DrawResult<'a> {
    // Top: NIS moving average.
    let vals = avg
        .iter()
        .copied()
        .chain([u.band.0, u.band.1, u.dof as f64])
        .filter(|v| v.is_finite() && *v > 0.0);
    let (lo, hi) = finite_min_max(vals).unwrap_or((0.1, 10.0));
    let (lo, hi) = ((lo / 1.5).min(hi / 10.0), hi * 1.5);
    let mut chart = ChartBuilder::on(top)
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
    draw_switches(&mut chart, switches, t, (lo, hi))?;
    for seg in clipped(u.t_s, avg, lo, hi, true) {
        chart.draw_series(LineSeries::new(seg, ERROR_COLOUR.stroke_width(2)))?;
    }
    Ok(())
}

/// Bottom: every whitened innovation component as dots, the ±3 lines.
fn draw_white_panel<'a>(
    bottom: &Area<'a>,
    u: &Innovations<'_>,
    t: &Range<f64>,
    switches: &[f64],
) -> DrawResult<'a> {
    // Bottom: whitened innovations.
    let m = u
        .white
        .iter()
        .flatten()
        .filter(|v| v.is_finite())
        .fold(4.0_f64, |m, v| m.max(v.abs() * 1.05));
    let mut chart = ChartBuilder::on(bottom)
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
    draw_switches(&mut chart, switches, t, (-m, m))?;
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
}
