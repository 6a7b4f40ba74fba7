//! The σ(t) comparison of two paths (`host-sim design`,
//! [`plot_sigma_comparison`]): one log-scale panel per parameter, path A
//! solid, path B dashed, the target dotted, a floor (errors that wander)
//! solid in the switch colour.

use std::path::Path;

use plotters::element::DashedPathElement;
use plotters::prelude::*;

use super::style::*;
use super::style::{Area, DrawResult};

/// One parameter's σ(t) along two paths (`host-sim design`), in the
/// display unit (arcseconds): `(t in s, σ)` points of path A and path B.
#[derive(Clone, Debug)]
pub struct SigmaCurve {
    /// State name: the panel label.
    pub label: &'static str,
    /// The target σ (″, or the unit of the figure), drawn as a horizontal line.
    pub target: f64,
    /// The floor no path gets below (same unit), drawn as a horizontal
    /// line in the switch colour; `None`: none (a state without errors
    /// that wander).
    pub floor: Option<f64>,
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
///
/// # Examples
///
/// ```
/// use host_sim::output::plots::{plot_sigma_comparison, SigmaCurve};
///
/// let dir = std::env::temp_dir().join("host-sim-doc-sigma");
/// std::fs::create_dir_all(&dir)?;
/// let curve = SigmaCurve {
///     label: "thgC_x",
///     target: 1.0,
///     floor: None,
///     a: vec![(0.0, 3600.0), (600.0, 0.9)],
///     b: vec![(0.0, 3600.0), (1200.0, 0.9)],
/// };
/// let png = dir.join("sigma.png");
/// plot_sigma_comparison(&png, "σ_CRLB(t)", "designed", "reference", &[curve])?;
/// assert!(std::fs::metadata(&png)?.len() > 0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn plot_sigma_comparison(
    path: &Path,
    title: &str,
    a_label: &str,
    b_label: &str,
    curves: &[SigmaCurve],
) -> Result<(), String> {
    plot_sigma_comparison_in(path, title, a_label, b_label, curves, "″")
}

/// [`plot_sigma_comparison`] with the unit of the values and targets named
/// in the legend (`unit`: "″", or e.g. "°/h, °/h/g, ppm, µg" for the
/// instrument terms of the full model, each in its own unit).
pub fn plot_sigma_comparison_in(
    path: &Path,
    title: &str,
    a_label: &str,
    b_label: &str,
    curves: &[SigmaCurve],
    unit: &str,
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
    draw_sigma(&root, title, (a_label, b_label, unit), curves, rows, t_max)
        .map_err(|e| format!("plots: drawing {}: {e}", path.display()))?;
    root.present()
        .map_err(|e| format!("plots: writing {}: {e}", path.display()))?;
    Ok(())
}

/// The whole comparison figure on `root`: header, then one panel per curve
/// (`labels`: paths A and B, the unit of the targets).
fn draw_sigma<'a>(
    root: &Area<'a>,
    title: &str,
    labels: (&str, &str, &str),
    curves: &[SigmaCurve],
    rows: usize,
    t_max: f64,
) -> DrawResult<'a> {
    let (a_label, b_label, unit) = labels;
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
    header.draw(&Text::new(
        format!("target σ [{unit}]"),
        (598, y),
        label.clone(),
    ))?;
    if curves.iter().any(|c| c.floor.is_some()) {
        header.draw(&PathElement::new(
            vec![(840, y), (870, y)],
            SWITCH_COLOUR.stroke_width(2),
        ))?;
        header.draw(&Text::new("floor (errors that wander)", (878, y), label))?;
    }
    let panels = body.split_evenly((rows, SIGMA_COLUMNS));
    for (area, c) in panels.iter().zip(curves) {
        draw_sigma_panel(area, c, t_max)?;
    }
    Ok(())
}

/// One parameter's panel: σ(t) of both paths and the target, log scale.
fn draw_sigma_panel<'a>(area: &Area<'a>, c: &SigmaCurve, t_max: f64) -> DrawResult<'a> {
    let vals = || {
        c.a.iter()
            .chain(&c.b)
            .map(|p| p.1)
            .chain(std::iter::once(c.target))
            .chain(c.floor)
            .filter(|v| v.is_finite() && *v > 0.0)
    };
    let lo = vals().fold(f64::INFINITY, f64::min);
    // The prior (3600″) dwarfs the converged part: show two decades
    // above the larger of the target and the final values.
    let hi_all = vals().fold(0.0, f64::max);
    let hi = (c.target * 100.0).min(hi_all).max(lo * 10.0);
    let y = (lo / 1.5)..(hi * 1.2);
    let caption = match c.floor {
        Some(f) if c.target < f => format!("{} (target below its floor)", c.label),
        _ => c.label.to_string(),
    };
    let mut chart = ChartBuilder::on(area)
        .caption(caption, font(15.0))
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
    if let Some(f) = c.floor {
        chart.draw_series(LineSeries::new(
            vec![(0.0, f), (t_max, f)],
            SWITCH_COLOUR.stroke_width(2),
        ))?;
    }
    Ok(())
}
