//! The likely cause of a data warning (`data verdict: warning`): each
//! usual mistake is tried on the calibrator's own log, and the one with
//! which the data fit the model is named.
//!
//! The candidates, in this order:
//!
//! 1. **the noise level**: the accelerometer (and gimbal) noise that fits
//!    the last pass's innovations, `σ²_fit = σ² + mean(ν²) − mean(S)` per
//!    sensor (the innovation's variance is the noise's plus the predicted
//!    part `S − R`), fitted again to the innovations of a run with it;
//! 2. **the error model**: the full model (the instruments' own errors)
//!    where the installation model ran;
//! 3. **a term the platform file leaves out** (full model): a failed
//!    `left_out` check ([`super::left_out`]), confirmed when the data fit
//!    the model with the term (the run that tested it);
//! 4. **the Earth rate or a sign**: the Earth rate off (or on, at the
//!    platform file's latitude), the latitude's sign; one accelerometer
//!    axis, gimbal angle or commanded-increment axis negated, two
//!    accelerometer axes swapped: screened by pass 1's mean NIS over the
//!    last 80 % of the log (the first 20 % is the cold start), the two
//!    best run in full;
//! 5. **the latitude**: the one whose pass 1 fits best (a 10° grid, then
//!    refined), run in full.
//!
//! A candidate is run in full only when the ones before it did not fit; a candidate is the cause when the estimator of
//! record with it gives data that pass every check ([`checks::judge_updates`]).
//! When none does, the cause named is a failed `left_out` check's term, or
//! else the failed checks' signature: a term the model lacks.

use nalgebra::Vector3;
use rollcal::ekf::FilterConfig;
use rollcal::estimator::{self, EstimatorOptions, LogRecord, SliceLog};
use rollcal::geometry::earth_rate_n;
use rollcal::models::{ErrorModel, Model};
use rollcal::wire::CalibratorConfig;

use super::left_out::LeftOut;
use crate::analysis::checks::{self, DataVerdict, Judgement};
use crate::analysis::runner::{self, Update};
use crate::sim::segments::command_segments;

/// Share of the log left out of the screening NIS (the cold start).
const SCREEN_SKIP: f64 = 0.2;

/// A warning whose worst check is less than this many band half-widths
/// from the band's middle (1 is its edge) is marginal: a clean log's false
/// alarms are each at most 14 % beyond the edge (docs/own-platform.md), the
/// mistakes of the candidates below hundreds of times.
pub const MARGINAL: f64 = 1.5;

/// What a candidate gave: the last pass's updates, pass 1's screening
/// NIS, and the state and covariance at the end of the last pass.
pub(super) struct Trial {
    /// The last pass's accepted updates.
    pub updates: Vec<Update>,
    /// Pass 1's mean NIS over the last 80 % of the log.
    pub screen_nis: f64,
    /// The state at the end of the last pass (internal units).
    pub state: Vec<f64>,
    /// Its covariance, row-major (internal units²).
    pub covariance: Vec<f64>,
}

/// One candidate: what it changes, and the settings and records with it.
struct Candidate {
    cause: String,
    settings: CalibratorConfig,
    records: Option<Vec<LogRecord<f64>>>,
}

/// The likely cause of the data warning of `judgement` (the calibration
/// of `records` with `settings`; `updates`: its last pass's;
/// `latitude_deg`: the platform's, for switching an absent Earth rate on;
/// `left_out`: the test of the terms the platform file leaves out, when
/// made), or `None` when the verdict is not a warning or the warning is the
/// path's alone.
pub fn likely_cause(
    settings: &CalibratorConfig,
    records: &[LogRecord<f64>],
    updates: &[Update],
    judgement: &Judgement,
    latitude_deg: Option<f64>,
    left_out: Option<&LeftOut>,
) -> Option<String> {
    let DataVerdict::Warning { failed } = &judgement.verdict else {
        return None;
    };
    if failed.iter().all(|c| c.name == "gimbal_lock") {
        return None;
    }
    // A marginal warning is what a log the model describes gives once in a
    // hundred (each false alarm just outside its band): no cause to name.
    let worst = failed
        .iter()
        .filter(|c| c.name != "gimbal_lock")
        .map(checks::excess)
        .fold(0.0, f64::max);
    if worst < MARGINAL {
        return Some(format!(
            "likely cause: none needed: the warning is marginal (the worst check is {worst:.2} band half-widths from the band's middle, its edge is at 1; a log the model describes is flagged like this with probability ≤ {}): a longer or another log tells",
            checks::FALSE_ALARM
        ));
    }
    let base = mean_nis(updates);
    let z = settings.config.layout().z() as f64;
    if let Some(found) = fit_noise(settings, records, updates, base) {
        return Some(found);
    }
    if settings.errors == ErrorModel::Installation {
        let full = Candidate {
            cause: "the instruments' own errors (accelerometer bias or scale factor, gyro drift), which the installation model takes as calibrated: calibrate again with --errors full".into(),
            settings: CalibratorConfig {
                errors: ErrorModel::Full,
                ..*settings
            },
            records: None,
        };
        if let Some(found) = confirm(&full, records, base) {
            return Some(found);
        }
    }
    let missing = left_out.map(|l| lacking(l, failed)).unwrap_or_default();
    if let Some(l) = left_out.filter(|_| !missing.is_empty()) {
        let segments = command_segments(records.iter().map(|r| (r.dt, r.dtheta_cmd.into())));
        if matches!(
            checks::judge_updates(&l.updates, &segments).verdict,
            DataVerdict::Consistent
        ) {
            return Some(format!(
                "likely cause: {missing} (with it the data fit the model: mean NIS {}, not {})",
                shown(mean_nis(&l.updates)),
                shown(base)
            ));
        }
    }
    let by_screening = |cands: Vec<Candidate>| -> Vec<Candidate> {
        let mut s: Vec<(f64, Candidate)> = cands
            .into_iter()
            .filter_map(|c| {
                let recs = c.records.as_deref().unwrap_or(records);
                trial(&c.settings, recs, 1).map(|t| ((t.screen_nis - z).abs(), c))
            })
            .filter(|(d, _)| d.is_finite())
            .collect();
        s.sort_by(|a, b| a.0.total_cmp(&b.0));
        s.into_iter().map(|(_, c)| c).take(2).collect()
    };
    let mut cands = earth_candidates(settings, latitude_deg);
    cands.extend(sign_candidates(settings, records));
    for c in by_screening(cands) {
        if let Some(found) = confirm(&c, records, base) {
            return Some(found);
        }
    }
    if let Some(found) =
        latitude_candidate(settings, records, latitude_deg).and_then(|c| confirm(&c, records, base))
    {
        return Some(found);
    }
    if !missing.is_empty() {
        return Some(format!(
            "likely cause: {missing} (with it the data do not fit the model either: another cause too)"
        ));
    }
    Some(signature(failed, settings.errors))
}

/// The terms of the failed `left_out` checks of `failed`, as a cause:
/// what each is, the platform file's key, its estimate, and the remedy;
/// empty when none failed.
fn lacking(l: &LeftOut, failed: &[checks::Check]) -> String {
    let named: Vec<String> = l
        .findings
        .iter()
        .filter_map(|f| {
            let c = failed
                .iter()
                .find(|c| c.name == "left_out" && c.scope == f.wald.scope)?;
            Some(format!(
                "{} ({}.{} = 0): estimated, the data give {} (x̂ᵀP⁻¹x̂ = {:.1}, above {:.1}): give it its σ",
                f.term.what, f.term.table, f.term.key, f.estimate, c.statistic, c.band.1
            ))
        })
        .collect();
    if named.is_empty() {
        return String::new();
    }
    format!(
        "a term the platform file leaves out: {}",
        named.join("; and ")
    )
}

/// The candidate's cause when the data fit with it (every check passes),
/// with the mean NIS before and after.
fn confirm(c: &Candidate, records: &[LogRecord<f64>], base: f64) -> Option<String> {
    let recs = c.records.as_deref().unwrap_or(records);
    let t = trial(&c.settings, recs, estimator::DEFAULT_MAX_PASSES)?;
    let segments = command_segments(recs.iter().map(|r| (r.dt, r.dtheta_cmd.into())));
    let j = checks::judge_updates(&t.updates, &segments);
    matches!(j.verdict, DataVerdict::Consistent).then(|| {
        format!(
            "likely cause: {} (with it the data fit the model: mean NIS {}, not {})",
            c.cause,
            shown(mean_nis(&t.updates)),
            shown(base)
        )
    })
}

/// A mean NIS as printed: 3 decimals, or 4 digits in exponent form when
/// huge.
fn shown(nis: f64) -> String {
    if nis.abs() >= 1e5 {
        format!("{nis:.3e}")
    } else {
        format!("{nis:.3}")
    }
}

fn mean_nis(updates: &[Update]) -> f64 {
    updates.iter().map(|u| u.nis).sum::<f64>() / updates.len().max(1) as f64
}

/// The noise levels that fit, when one is off by more than 20 %: fitted
/// to the last pass's innovations, the estimator run with them, fitted
/// again to its innovations (a wrong noise level also gates updates and
/// skews the covariance), at most four times, until every check passes.
fn fit_noise(
    settings: &CalibratorConfig,
    records: &[LogRecord<f64>],
    updates: &[Update],
    base: f64,
) -> Option<String> {
    let mut c = noise_candidate(settings, settings, updates)?;
    for _ in 0..4 {
        let t = trial(&c.settings, records, estimator::DEFAULT_MAX_PASSES)?;
        let segments = command_segments(records.iter().map(|r| (r.dt, r.dtheta_cmd.into())));
        if matches!(
            checks::judge_updates(&t.updates, &segments).verdict,
            DataVerdict::Consistent
        ) {
            return Some(format!(
                "likely cause: {} (with it the data fit the model: mean NIS {}, not {})",
                c.cause,
                shown(mean_nis(&t.updates)),
                shown(base)
            ));
        }
        c = noise_candidate(settings, &c.settings, &t.updates)?;
    }
    None
}

/// The noise σ that fits the innovations of sensor components `comps`
/// over the last 80 % of the updates (the first carry the prior's
/// transient in `S`): `σ²_fit = σ² + mean(ν²) − mean(S)`; `None` when it
/// cannot be had.
fn fitted_sigma(updates: &[Update], comps: std::ops::Range<usize>, sigma: f64) -> Option<f64> {
    let skip = (updates.len() as f64 * SCREEN_SKIP) as usize;
    let (mut nu2, mut s, mut n) = (0.0, 0.0, 0usize);
    for u in updates.iter().skip(skip) {
        for i in comps.clone() {
            if let (Some(v), Some(d)) = (u.nu.get(i), u.s_diag.get(i)) {
                nu2 += v * v;
                s += d;
                n += 1;
            }
        }
    }
    if n == 0 {
        return None;
    }
    let var = sigma * sigma + (nu2 - s) / n as f64;
    (var > 0.0).then(|| var.sqrt())
}

/// The platform's noise levels (`settings`) replaced by those that fit
/// `updates` (the innovations of a run with `with`), when one of them is
/// off by more than 20 %.
fn noise_candidate(
    settings: &CalibratorConfig,
    with: &CalibratorConfig,
    updates: &[Update],
) -> Option<Candidate> {
    let z = settings.config.layout().z();
    let accel = fitted_sigma(updates, z - 3..z, with.sigma_accel_g)?;
    let gimbal = (z == 6)
        .then(|| fitted_sigma(updates, 0..3, with.sigma_gimbal_rad))
        .flatten();
    let off = |fit: f64, was: f64| !(0.8..=1.25).contains(&(fit / was));
    let mut parts = Vec::new();
    let mut s = *settings;
    if off(accel, settings.sigma_accel_g) {
        parts.push(format!(
            "noise.accel_g = {:.3e} g fits the data (the platform's is {:.3e} g)",
            accel, settings.sigma_accel_g
        ));
        s.sigma_accel_g = accel;
    }
    if let Some(g) = gimbal.filter(|g| off(*g, settings.sigma_gimbal_rad)) {
        let arcsec = 180.0 * 3600.0 / std::f64::consts::PI;
        parts.push(format!(
            "noise.gimbal_arcsec = {:.3} fits the data (the platform's is {:.3})",
            g * arcsec,
            settings.sigma_gimbal_rad * arcsec
        ));
        s.sigma_gimbal_rad = g;
    }
    (!parts.is_empty()).then(|| Candidate {
        cause: format!("the noise level: {}", parts.join(", ")),
        settings: s,
        records: None,
    })
}

/// The latitude (°) of an Earth rate `w` (NUE: `Ω [cos φ, sin φ, 0]`).
fn latitude_of(w: [f64; 3]) -> f64 {
    w[1].atan2(w[0]).to_degrees()
}

fn with_earth_rate(settings: &CalibratorConfig, w: Vector3<f64>) -> CalibratorConfig {
    CalibratorConfig {
        earth_rate_n: w.into(),
        ..*settings
    }
}

/// The platform's latitude (°): that of its Earth rate when on, else the
/// platform file's.
fn latitude(settings: &CalibratorConfig, latitude_deg: Option<f64>) -> Option<f64> {
    let w = settings.earth_rate_n;
    if w.iter().any(|v| *v != 0.0) {
        Some(latitude_of(w))
    } else {
        latitude_deg
    }
}

/// The Earth rate at latitude `lat` (°).
fn at(lat: f64) -> Vector3<f64> {
    earth_rate_n(rollcal::geometry::EARTH_RATE, lat.to_radians())
}

/// The Earth rate off (or on at the platform's latitude), and the
/// latitude negated.
fn earth_candidates(settings: &CalibratorConfig, latitude_deg: Option<f64>) -> Vec<Candidate> {
    let on = settings.earth_rate_n.iter().any(|v| *v != 0.0);
    let mut out = Vec::new();
    if on {
        out.push(Candidate {
            cause: "the Earth rate: the data fit with it off (site.earth_rate = false)".into(),
            settings: with_earth_rate(settings, Vector3::zeros()),
            records: None,
        });
    } else if let Some(lat) = latitude_deg {
        out.push(Candidate {
            cause: format!(
                "the Earth rate: the data fit with it on at latitude {lat}° (site.earth_rate = true)"
            ),
            settings: with_earth_rate(settings, at(lat)),
            records: None,
        });
    }
    if let Some(lat) = latitude(settings, latitude_deg).filter(|l| on && l.abs() > 0.5) {
        out.push(Candidate {
            cause: format!(
                "the latitude's sign: the data fit latitude {:.2}° (the platform's is {lat:.2}°)",
                -lat
            ),
            settings: with_earth_rate(settings, at(-lat)),
            records: None,
        });
    }
    out
}

/// The latitude whose pass 1 fits best (screening NIS nearest the
/// measurement size: a 10° grid over ±90°, then the best refined by
/// halving steps to 0.01°), when it is more than 0.05° from the platform's.
fn latitude_candidate(
    settings: &CalibratorConfig,
    records: &[LogRecord<f64>],
    latitude_deg: Option<f64>,
) -> Option<Candidate> {
    let lat = latitude(settings, latitude_deg)?;
    let z = settings.config.layout().z() as f64;
    let score = |l: f64| {
        trial(&with_earth_rate(settings, at(l)), records, 1)
            .map_or(f64::INFINITY, |t| (t.screen_nis - z).abs())
    };
    let (mut best, mut s_best) = (-9..=9)
        .map(|k| f64::from(k) * 10.0)
        .map(|l| (l, score(l)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .filter(|b| b.1.is_finite())?;
    let mut step = 5.0;
    while step >= 0.01 {
        for l in [best - step, best + step].map(|l: f64| l.clamp(-90.0, 90.0)) {
            let s = score(l);
            if s < s_best {
                (best, s_best) = (l, s);
            }
        }
        step /= 2.0;
    }
    ((best - lat).abs() > 0.05).then(|| Candidate {
        cause: format!(
            "the latitude: the data fit latitude {best:.2}° (the platform's is {lat:.2}°)"
        ),
        settings: with_earth_rate(settings, at(best)),
        records: None,
    })
}

/// One axis negated (accelerometers, gimbal angles, commanded
/// increments), two accelerometer axes swapped.
fn sign_candidates(settings: &CalibratorConfig, records: &[LogRecord<f64>]) -> Vec<Candidate> {
    let xyz = ["x", "y", "z"];
    let mut out = Vec::new();
    let map = |f: &dyn Fn(&mut LogRecord<f64>)| -> Vec<LogRecord<f64>> {
        records
            .iter()
            .map(|r| {
                let mut r = *r;
                f(&mut r);
                r
            })
            .collect()
    };
    let mut push = |cause: String, records: Vec<LogRecord<f64>>| {
        out.push(Candidate {
            cause,
            settings: *settings,
            records: Some(records),
        })
    };
    for (i, axis) in xyz.iter().enumerate() {
        push(
            format!("a sign: the data fit with accel_{axis}_g negated (the log's accelerometer {axis} axis points the other way)"),
            map(&|r| {
                if let Some(o) = r.observation.as_mut() {
                    o.accel_mean[i] = -o.accel_mean[i];
                }
            }),
        );
        push(
            format!("a sign: the data fit with dtheta_{axis}_rad negated (the commanded increment's {axis} axis points the other way)"),
            map(&|r| r.dtheta_cmd[i] = -r.dtheta_cmd[i]),
        );
    }
    if settings.config.layout().gimbal_obs {
        for (i, name) in ["alpha", "beta", "gamma"].iter().enumerate() {
            push(
                format!("a sign: the data fit with gimbal_{name}_rad negated"),
                map(&|r| {
                    if let Some(g) = r.observation.as_mut().and_then(|o| o.gimbal.as_mut()) {
                        g[i] = -g[i];
                    }
                }),
            );
        }
    }
    for (i, j) in [(0, 1), (1, 2), (0, 2)] {
        push(
            format!(
                "the axis order: the data fit with accel_{}_g and accel_{}_g swapped",
                xyz[i], xyz[j]
            ),
            map(&|r| {
                if let Some(o) = r.observation.as_mut() {
                    o.accel_mean.swap_rows(i, j);
                }
            }),
        );
    }
    out
}

/// What the failed checks say when no candidate makes the data fit.
fn signature(failed: &[checks::Check], errors: ErrorModel) -> String {
    let has = |name: &str| failed.iter().any(|c| c.name == name);
    let what = if has("bias") || has("whiteness") {
        "an error the model does not carry: the per-segment means or the lag-1 autocorrelation of the innovations are off, the signature of a constant or slowly varying term"
    } else {
        "the noise or the model: the mean NIS is off"
    };
    let model = match errors {
        ErrorModel::Installation => "installation",
        ErrorModel::Full => "full",
    };
    format!(
        "likely cause: a term the {model} model lacks — {what} (none of the noise level, the error model, the Earth rate, the latitude, a sign or the axis order makes the data fit)"
    )
}

/// The estimator of record over `records` with `settings`, at most
/// `passes` passes: the last pass's updates, pass 1's mean NIS over the
/// last 80 % of the log, the final state and covariance. `None` when the
/// estimator refuses.
pub(super) fn trial(
    settings: &CalibratorConfig,
    records: &[LogRecord<f64>],
    passes: u8,
) -> Option<Trial> {
    fn typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        settings: &CalibratorConfig,
        records: &[LogRecord<f64>],
        passes: u8,
    ) -> Option<Trial> {
        let cfg = FilterConfig::<f64>::from(settings);
        let sigma0 = runner::prior_sigma_of(settings);
        let s0 = nalgebra::SVector::<f64, N>::from_iterator(
            sigma0
                .iter()
                .copied()
                .chain(std::iter::repeat(settings.prior_sigma_rad)),
        );
        let mut storage = records.to_vec();
        let mut log = SliceLog::from_records(&mut storage);
        let skip = (records.len() as f64 * SCREEN_SKIP) as usize;
        let (mut pass, mut t, mut updates) = (0u8, 0.0, Vec::new());
        let (mut screen, mut screened) = (0.0, 0usize);
        let opts = EstimatorOptions {
            max_passes: passes,
            ..EstimatorOptions::default()
        };
        let out = estimator::estimate::<f64, M, N, Z, _, _>(
            &cfg,
            &nalgebra::SVector::zeros(),
            &s0,
            &mut log,
            &opts,
            |e| {
                if e.pass != pass {
                    (pass, t, updates) = (e.pass, 0.0, Vec::new());
                }
                t += e.record.dt;
                if let Ok(Some(i)) = &e.result {
                    let u = Update::of(e.index, t, i);
                    if e.pass == 1 && e.index >= skip {
                        screen += u.nis;
                        screened += 1;
                    }
                    updates.push(u);
                }
            },
        )
        .ok()?;
        Some(Trial {
            updates,
            state: out.filter.state().iter().copied().collect(),
            covariance: out
                .filter
                .covariance()
                .transpose()
                .iter()
                .copied()
                .collect(),
            screen_nis: if screened == 0 {
                f64::INFINITY
            } else {
                screen / screened as f64
            },
        })
    }
    rollcal::with_model!(
        settings.config,
        settings.errors,
        |M, N, Z| typed::<M, N, Z>(settings, records, passes)
    )
}
