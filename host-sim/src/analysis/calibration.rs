//! The calibrator run on a stream, as `calibrate` drives it: the no_std
//! session ([`rollcal::session::Session`]) with the host's sample log, the
//! NIS and failures of every accepted sample, the estimator of record's
//! final passes with their covariance, the calibrator settings of a
//! scenario or platform file, and the bound at the estimate without a
//! truth.

use nalgebra::RealField;
use rollcal::calibrator::RejectReason;
use rollcal::ekf::{self, FilterConfig, Options};
use rollcal::estimator::{
    EstimatorOptions, LogError, LogRecord, LogStart, PackedLayout, PassEvent, SampleLog,
};
use rollcal::models::{ConfigId, ErrorModel, Model};
use rollcal::observability::Observability;
use rollcal::session::{Covariance, PassObserver, Reply, Session};
use rollcal::wire::{CalibratorConfig, Estimate, Message};

use crate::analysis::runner;
use crate::analysis::verdict::Verdict;
use crate::analysis::Error;
use crate::sim::scenario::{Platform, Scenario, DEG};
use crate::sim::truth::PeriodSample;

/// Calibrator settings equal to `runner::filter_config` of the scenario
/// (so that the stream's filter is `run`'s filter), for error model
/// `errors` with the scenario's instrument prior.
pub fn calibrator_config(
    sc: &Scenario,
    id: ConfigId,
    errors: ErrorModel,
    earth_rate: bool,
) -> CalibratorConfig {
    platform_config(&Platform::of_scenario(sc), id, errors, earth_rate)
}

/// Calibrator settings of a platform file (the `Configure` message a
/// platform with these settings would send), for error model `errors`.
pub fn platform_config(
    p: &Platform,
    id: ConfigId,
    errors: ErrorModel,
    earth_rate: bool,
) -> CalibratorConfig {
    let f = runner::filter_config_of(&p.site, &p.noise, earth_rate, Options::default());
    let mut c = CalibratorConfig::paper(id);
    c.sigma_accel_g = f.sigma_accel;
    c.sigma_gyro_rad_s = f.sigma_gyro;
    c.sigma_gimbal_rad = f.sigma_gimbal;
    c.earth_rate_n = f.env.earth_rate_n.into();
    c.gravity_n = f.env.gravity_n.into();
    c.prior_sigma_rad = p.prior.sigma_deg * DEG;
    c.limits.period_s = p.timing.period_s;
    c.errors = errors;
    c.instrument_prior = p.instruments.prior.to_wire();
    c.wander = match errors {
        ErrorModel::Installation => rollcal::models::Wander::none(),
        ErrorModel::Full => p.instruments.wander.to_model(),
    };
    c
}

/// How the host's sample log keeps a record.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LogStorage {
    /// Every record as the calibrator logs it.
    #[default]
    Exact,
    /// Each record rounded as a compact log stores it (the firmware's log
    /// in flash, `rollcal::estimator::FlashLog`, and `PackedLog`: 2⁻⁴⁰ rad,
    /// 2⁻²⁷ g, 2π/2²⁴ rad), so that the final passes are the device's to
    /// the last bit.
    Packed,
}

/// The host's sample log: a vector that grows as needed.
pub struct VecLog<T: RealField + Copy = f64> {
    /// The records, as the final passes read them.
    pub records: Vec<LogRecord<T>>,
    /// How a record is kept.
    pub storage: LogStorage,
}

impl<T: RealField + Copy> Default for VecLog<T> {
    fn default() -> Self {
        Self {
            records: Vec::new(),
            storage: LogStorage::default(),
        }
    }
}

impl<T: RealField + Copy> VecLog<T> {
    /// The records in f64 (exact for f32).
    pub fn records_f64(&self) -> Vec<LogRecord<f64>> {
        let f = |v: T| v.to_subset().unwrap_or(f64::NAN);
        self.records
            .iter()
            .map(|r| LogRecord {
                dt: r.dt,
                dtheta_cmd: r.dtheta_cmd,
                observation: r.observation.map(|o| ekf::Observation {
                    accel_mean: o.accel_mean.map(f),
                    gimbal: o.gimbal.map(|g| g.map(f)),
                }),
            })
            .collect()
    }
}

impl<T: RealField + Copy> SampleLog<T> for VecLog<T> {
    /// With [`LogStorage::Packed`], the record as `FlashLog` gives it back
    /// (its period length must be an `f32`, as the wire's are), or refused
    /// as it refuses it.
    fn append(&mut self, r: &LogRecord<T>) -> Result<(), LogError> {
        let r = match self.storage {
            LogStorage::Exact => *r,
            LogStorage::Packed => PackedLayout::AccelGimbal
                .round_trip(r)
                .filter(|_| f64::from(r.dt as f32) == r.dt)
                .ok_or(LogError::Unrepresentable)?,
        };
        self.records.push(r);
        Ok(())
    }
    fn len(&self) -> usize {
        self.records.len()
    }
    fn truncate(&mut self, len: usize) {
        self.records.truncate(len);
    }
    fn get(&mut self, k: usize) -> Option<LogRecord<T>> {
        self.records.get(k).copied()
    }
}

/// The final answer of the session's calibrator.
pub struct Final {
    pub estimate: Estimate,
    /// NIS of every update of the last pass.
    pub nis: Vec<f64>,
    /// The accepted updates of the last pass.
    pub updates: Vec<runner::Update>,
    /// Time history of the last pass: (t, estimate, σ) per record.
    pub history: Vec<(f64, Vec<f64>, Vec<f64>)>,
    /// Covariance of the final filter, row-major (rad²; empty when the
    /// passes did not run).
    pub covariance: Vec<f64>,
}

/// The no_std session (the protocol, once) with the host's log and records
/// for the report.
pub struct Host<T: RealField + Copy> {
    pub session: Session<T>,
    /// Settings for a stream without a `Configure` message (`--platform`
    /// or `--scenario`), when the configuration is known.
    pub fallback: Option<CalibratorConfig>,
    /// The sample log since the last (re)start, for the final passes.
    pub log: VecLog<T>,
    /// NIS of every accepted update since the last (re)start.
    pub nis: Vec<f64>,
    /// Filter failures (sequence number, error).
    pub failures: Vec<(u32, ekf::Error)>,
    /// Where the fallback settings come from, for the note.
    pub fallback_of: String,
    /// Notes for the user (a missing `Configure`, a restart), to print
    /// after each [`Host::handle`].
    pub notes: Vec<String>,
    /// The error model every `Configure` is run with (`calibrate
    /// --errors`), whatever it asks for; `None`: the message's.
    pub errors: Option<ErrorModel>,
    /// The protocol version of the last frame of another version seen.
    pub other_version: Option<u8>,
}

impl<T: RealField + Copy> Host<T> {
    /// A host of a fresh session expecting configuration `expected` (if
    /// known), with the settings `fallback` for a stream without a
    /// `Configure`, taken from `fallback_of`.
    pub fn new(
        expected: Option<ConfigId>,
        fallback: Option<CalibratorConfig>,
        fallback_of: String,
    ) -> Self {
        Self {
            session: Session::new(expected, EstimatorOptions::default()),
            fallback,
            log: VecLog::default(),
            nis: Vec::new(),
            failures: Vec::new(),
            fallback_of,
            notes: Vec::new(),
            errors: None,
            other_version: None,
        }
    }

    /// Hands message `m` to the session (configuring it with the fallback
    /// settings at a first sample without a `Configure`), keeping the NIS
    /// and the failures of the accepted samples.
    pub fn handle(&mut self, m: Message) -> Result<(), String> {
        let m = match (m, self.errors) {
            (Message::Configure(settings), Some(errors)) => {
                Message::Configure(CalibratorConfig { errors, ..settings })
            }
            (m, _) => m,
        };
        match &m {
            Message::Sample(_) if self.session.calibrator().is_none() => {
                let Some(fallback) = self.fallback else {
                    return Err("the stream has no Configure message: give --config (and --platform FILE for the platform's settings)".into());
                };
                self.notes.push(format!(
                    "note: the stream has no Configure message; using the settings of {}",
                    self.fallback_of
                ));
                self.session
                    .configure(fallback)
                    .map_err(|e| format!("calibrator: {e}"))?;
            }
            Message::Configure(_) | Message::Reset => {
                if self.session.calibrator().is_some() {
                    self.notes.push(format!(
                        "\nnote: {} mid-stream: restarting the calibrator",
                        tag(&m)
                    ));
                }
                self.nis.clear();
                self.failures.clear();
            }
            _ => {}
        }
        match self.session.handle(&m, &mut self.log) {
            Reply::Error(e) => return Err(format!("{e}")),
            Reply::Rejected(RejectReason::Filter(e)) => {
                if let Message::Sample(s) = &m {
                    self.failures.push((s.seq, e));
                }
            }
            Reply::Nothing | Reply::Send(_) | Reply::Rejected(_) => {
                if let (Message::Sample(s), Some(cal)) = (&m, self.session.calibrator()) {
                    if cal.progress().last_seq == Some(s.seq) {
                        self.nis.push(cal.progress().last_nis);
                    }
                }
            }
        }
        Ok(())
    }

    /// Where the log of the session's calibrator started
    /// ([`rollcal::calibrator::Calibrator::log_start`]; the path's start
    /// before it is configured).
    pub fn log_start(&mut self) -> Result<LogStart, Error> {
        match self.session.calibrator() {
            Some(cal) => cal
                .log_start(&mut self.log)
                .map_err(|source| Error::Estimator {
                    context: "the start of the log".into(),
                    source,
                }),
            None => Ok(LogStart::aligned()),
        }
    }

    /// The estimator of record over the log, at most `passes` passes,
    /// with the last pass's innovations, history and covariance.
    pub fn finish(&mut self, passes: u8) -> Option<Final> {
        let opts = EstimatorOptions {
            max_passes: passes,
            ..EstimatorOptions::default()
        };
        let cal = self.session.calibrator()?;
        let mut last = LastPass::default();
        let mut covariance = Covariance::new();
        let estimate = cal.finish_with_covariance(&mut self.log, &opts, &mut last, &mut covariance);
        let LastPass {
            nis,
            updates,
            history,
            ..
        } = last;
        let covariance = covariance.to_vec();
        Some(Final {
            estimate,
            nis,
            updates,
            history,
            covariance,
        })
    }
}

/// What [`Host::finish`] keeps of the passes of
/// [`rollcal::session::AnyCalibrator::finish_with_covariance`]: the last
/// pass's NIS, updates and history (time, estimate and σ after every
/// record).
#[derive(Default)]
struct LastPass {
    /// The pass being recorded (number, from 1; 0 before the first).
    pass: u8,
    /// Time at the end of the last record's period (s from the start of
    /// the log).
    t_s: f64,
    /// NIS of every accepted update of the pass.
    nis: Vec<f64>,
    /// Every accepted update of the pass.
    updates: Vec<runner::Update>,
    /// Time (s), estimate (rad) and σ (rad) after every record of the pass.
    history: Vec<(f64, Vec<f64>, Vec<f64>)>,
}

impl<T: RealField + Copy> PassObserver<T> for LastPass {
    fn step<M: Model<N, Z>, const N: usize, const Z: usize>(
        &mut self,
        e: &PassEvent<'_, T, M, N, Z>,
    ) {
        let f = |v: &T| v.to_subset().unwrap_or(f64::NAN);
        self.t_s = if e.index == 0 { 0.0 } else { self.t_s } + e.record.dt;
        let t = self.t_s;
        if e.pass != self.pass {
            (self.pass, self.nis, self.updates, self.history) =
                (e.pass, Vec::new(), Vec::new(), Vec::new());
        }
        if let Ok(Some(i)) = &e.result {
            let u = runner::Update::of(e.index, t, i);
            self.nis.push(u.nis);
            self.updates.push(u);
        }
        self.history.push((
            t,
            e.filter.state().iter().copied().collect(),
            e.filter.sigma().iter().map(f).collect(),
        ));
    }
}

fn tag(m: &Message) -> &'static str {
    match m {
        Message::Configure(_) => "Configure",
        Message::Reset => "Reset",
        _ => "message",
    }
}

/// The state (rad) at the log's start `start` of a run that ends at
/// `x_end` (rad; missing trailing states are zero): `x_end` integrated
/// back through every record ([`rollcal::estimator::back_propagate`], what
/// the next linearised pass would start from) from the end of the run (the
/// start's computed frame integrated forward through the records).
pub fn state_at_start(
    settings: &CalibratorConfig,
    start: &LogStart,
    x_end: &[f64],
    records: &[LogRecord<f64>],
) -> Result<Vec<f64>, Error> {
    fn typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        cfg: FilterConfig<f64>,
        start: &LogStart,
        x_end: &[f64],
        records: &[LogRecord<f64>],
    ) -> Result<Vec<f64>, Error> {
        let mut frame = start.frame(cfg.env.earth_rate_n);
        for r in records.iter().filter(|r| r.has_valid_period()) {
            let p = frame.period(&r.dtheta_cmd, r.dt);
            frame.advance(&p);
        }
        let mut storage = records.to_vec();
        let mut log = rollcal::estimator::SliceLog::from_records(&mut storage);
        let (x, _) = rollcal::estimator::back_propagate::<f64, N, _>(
            M::LAYOUT,
            &cfg.env,
            &padded::<N>(x_end),
            &frame,
            &mut log,
        )
        .map_err(|source| Error::Estimator {
            context: "the start of the log".into(),
            source,
        })?;
        Ok(x.iter().copied().collect())
    }
    let cfg = FilterConfig::<f64>::from(settings);
    rollcal::with_model!(
        settings.config,
        settings.errors,
        |M, N, Z| typed::<M, N, Z>(cfg, start, x_end, records)
    )
}

/// The true state (rad) at the log's start `start`, from a truth sidecar's
/// initial state `truth0` (the path's start) and final state `truth_end`
/// (the end of the run): `truth0` for a log that starts at the path's
/// start, else `truth_end` integrated back through the records
/// ([`state_at_start`]; the model's trajectory without the gyro noise,
/// which moves the Jacobians of the bound by nothing measurable). `None`
/// at the path's start without `truth0`.
pub fn truth_at_start(
    settings: &CalibratorConfig,
    start: &LogStart,
    (truth0, truth_end): (Option<Vec<f64>>, &[f64]),
    records: &[LogRecord<f64>],
) -> Result<Option<Vec<f64>>, Error> {
    if start.is_aligned() {
        return Ok(truth0);
    }
    state_at_start(settings, start, truth_end, records).map(Some)
}

/// `v` as an `N`-vector, missing trailing values zero.
fn padded<const N: usize>(v: &[f64]) -> nalgebra::SVector<f64, N> {
    nalgebra::SVector::<f64, N>::from_iterator(v.iter().copied().chain(std::iter::repeat(0.0)))
}

/// The bound σ (rad) of every state at the estimate along the received
/// path, and the observability verdict of each, for `calibrate` without a
/// truth. The bound is [`runner::bound`]'s recursion ([`Observability`])
/// from `x_start` (rad) at the log's start `start`: the estimator of
/// record's own start of the log ([`state_at_start`] of the final
/// estimate), or, when the log is not the whole run (`None`), the start's
/// prior estimate, pass 1's ([`LogStart::state`] of zero). The null space is that of the
/// information matrix along the same records linearised at the start's
/// prior estimate (zero state at the path's start, as `observability`),
/// the verdict [`Verdict::of_bound`].
pub fn bound_at_estimate(
    settings: &CalibratorConfig,
    start: &LogStart,
    x_start: Option<&[f64]>,
    records: &[LogRecord<f64>],
) -> Result<(Vec<f64>, Vec<Verdict>), Error> {
    fn typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        cfg: FilterConfig<f64>,
        start: &LogStart,
        x_start: Option<&[f64]>,
        sigma0: &[f64],
        records: &[LogRecord<f64>],
    ) -> Result<(Vec<f64>, Vec<Verdict>), Error> {
        use rollcal::observability::{COEF_THRESHOLD, RANK_TOLERANCE};
        let prior = padded::<N>(sigma0);
        let e = |e: ekf::Error| Error::filter("the bound at the estimate", e);
        let cold = start.state(M::LAYOUT, &nalgebra::SVector::zeros());
        let x0 = x_start.map_or(cold, padded);
        let mut at = Observability::<f64, M, N, Z>::new(cfg, x0, prior).map_err(e)?;
        let mut zero = Observability::<f64, M, N, Z>::new(cfg, cold, prior).map_err(e)?;
        at.start_at(start.c_cn()).map_err(e)?;
        zero.start_at(start.c_cn()).map_err(e)?;
        for r in records {
            at.record(r).map_err(e)?;
            zero.record(r).map_err(e)?;
        }
        let part = zero.analyse(RANK_TOLERANCE).map_err(e)?.participation();
        let ratio = at.ratio();
        let verdicts = (0..N)
            .map(|i| Verdict::of_bound(part[i] > COEF_THRESHOLD, ratio[i]))
            .collect();
        Ok((at.crlb_sigma().iter().copied().collect(), verdicts))
    }
    let cfg = FilterConfig::<f64>::from(settings);
    let sigma0 = runner::prior_sigma_of(settings);
    rollcal::with_model!(
        settings.config,
        settings.errors,
        |M, N, Z| typed::<M, N, Z>(cfg, start, x_start, &sigma0, records)
    )
}

/// The calibrator's final values as a [`runner::DynFilter`], for the report.
pub struct CalibratorView {
    /// Estimate (rad).
    pub state: Vec<f64>,
    /// σ (rad).
    pub sigma: Vec<f64>,
    /// Covariance, row-major (rad²).
    pub covariance: Vec<f64>,
}

impl runner::DynFilter for CalibratorView {
    fn step(&mut self, _: &PeriodSample) -> Result<f64, ekf::Error> {
        Err(ekf::Error::NoPrediction)
    }
    fn state(&self) -> Vec<f64> {
        self.state.clone()
    }
    fn sigma(&self) -> Vec<f64> {
        self.sigma.clone()
    }
    fn covariance(&self) -> Vec<f64> {
        self.covariance.clone()
    }
}
