//! The two panels of a row of the error figure: the log panel (|error|,
//! 3σ, 3σ_CRLB over the whole run) and the linear zoom on the converged
//! part, with the ranges they are drawn over.

use std::ops::Range;

use plotters::prelude::*;

use super::style::*;
use super::style::{Area, DrawResult};
use super::Curve;

/// Left panel: |error|, 3σ and 3σ_CRLB on a log axis over the whole run.
pub(super) fn draw_log_panel<'a>(
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
        .y_desc(format!("|error|, 3σ [{}]", c.unit))
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
pub(super) fn draw_zoom_panel<'a>(
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
        .y_desc(format!("error [{}]", c.unit))
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
