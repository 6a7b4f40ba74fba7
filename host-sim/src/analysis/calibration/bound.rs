//! The bound at the estimate of `calibrate` without a truth, and the
//! calibrator's final values as a filter for the report.

use rollcal::ekf::{self, FilterConfig};
use rollcal::estimator::LogRecord;
use rollcal::models::Model;
use rollcal::observability::Observability;
use rollcal::wire::CalibratorConfig;

use crate::analysis::runner;
use crate::analysis::verdict::Verdict;
use crate::analysis::Error;
use crate::sim::truth::PeriodSample;

/// The bound σ (rad) of every state at the estimate along the received
/// path, and the observability verdict of each, for `calibrate` without a
/// truth. The initial state is the estimator of record's own start of the
/// log: the final estimate `x_end` integrated back through every record
/// ([`rollcal::estimator::back_propagate`], what the next linearised pass
/// would start from); the bound is [`runner::bound`]'s recursion
/// ([`Observability`]) from it; the null space is that of the information
/// matrix along the same records linearised at zero state (as
/// `observability`), the verdict [`Verdict::of_bound`].
/// With `x_end` `None` the bound starts at `x_start` instead.
pub fn bound_at_estimate(
    settings: &CalibratorConfig,
    x_end: Option<&[f64]>,
    x_start: &[f64],
    records: &[LogRecord<f64>],
) -> Result<(Vec<f64>, Vec<Verdict>), Error> {
    fn typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        cfg: FilterConfig<f64>,
        x_end: Option<&[f64]>,
        x_start: &[f64],
        sigma0: &[f64],
        records: &[LogRecord<f64>],
    ) -> Result<(Vec<f64>, Vec<Verdict>), Error> {
        use rollcal::observability::{COEF_THRESHOLD, RANK_TOLERANCE};
        let vector = |v: &[f64]| {
            nalgebra::SVector::<f64, N>::from_iterator(
                v.iter().copied().chain(std::iter::repeat(0.0)),
            )
        };
        let x0 = match x_end {
            None => vector(x_start),
            Some(x_end) => {
                let mut frame = rollcal::command::CommandFrame::aligned(cfg.env.earth_rate_n);
                for r in records.iter().filter(|r| r.has_valid_period()) {
                    let p = frame.period(&r.dtheta_cmd, r.dt);
                    frame.advance(&p);
                }
                let mut storage = records.to_vec();
                let mut log = rollcal::estimator::SliceLog::from_records(&mut storage);
                rollcal::estimator::back_propagate::<f64, N, _>(
                    M::LAYOUT,
                    &cfg.env,
                    &vector(x_end),
                    &frame,
                    &mut log,
                )
                .map_err(|source| Error::Estimator {
                    context: "the start of the log".into(),
                    source,
                })?
                .0
            }
        };
        let prior = vector(sigma0);
        let e = |e: ekf::Error| Error::filter("the bound at the estimate", e);
        let mut at = Observability::<f64, M, N, Z>::new(cfg, x0, prior).map_err(e)?;
        let mut zero = Observability::<f64, M, N, Z>::new(cfg, nalgebra::SVector::zeros(), prior)
            .map_err(e)?;
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
        |M, N, Z| typed::<M, N, Z>(cfg, x_end, x_start, &sigma0, records)
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
