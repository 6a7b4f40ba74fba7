//! The bound at the estimate of `calibrate` without a truth, and the
//! calibrator's final values as a filter for the report.

use rollcal::ekf::{self, FilterConfig};
use rollcal::estimator::{LogRecord, LogStart};
use rollcal::models::Model;
use rollcal::observability::Observability;
use rollcal::wire::CalibratorConfig;

use crate::analysis::runner;
use crate::analysis::verdict::Verdict;
use crate::analysis::Error;
use crate::sim::truth::PeriodSample;

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
/// prior estimate, pass 1's ([`LogStart::state`] of zero). The null space
/// is that of the information matrix along the same records linearised at
/// the start's prior estimate (zero state at the path's start, as
/// `observability`), the verdict [`Verdict::of_bound`] (a state the model
/// does not estimate, or a nuisance that wanders: its own word,
/// [`crate::analysis::verdict::special`]).
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
        let states = M::states();
        let verdicts = (0..N)
            .map(|i| {
                let group = states.get(i).map(|s| s.group);
                group
                    .and_then(|g| crate::analysis::verdict::special(g, prior[i]))
                    .unwrap_or_else(|| Verdict::of_bound(part[i] > COEF_THRESHOLD, ratio[i]))
            })
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
