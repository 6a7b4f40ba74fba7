//! The posterior Cramér–Rao bound of a run: at its end, and after every
//! record.

use rollcal::ekf::{self, FilterConfig};
use rollcal::estimator::{LogRecord, LogStart};
use rollcal::models::{ConfigId, ErrorModel, Model};
use rollcal::observability::Observability;

use super::config::initial;
use super::context::SimulatedRun;
use crate::sim::scenario::Scenario;
use crate::sim::truth::Simulation;

/// Posterior Cramér–Rao bound σ (rad) of every state after the periods
/// `records`, from the true initial state `truth0` (rad; missing trailing
/// states are zero) at the log's start `start` (the path's start for a
/// simulated run) with prior σ `sigma0` of every state (internal units), model
/// `errors`, and the noise
/// levels of `cfg` (its options are ignored): [`Observability`] along the
/// true trajectory, a record without measurement being a period that is
/// only predicted (docs/model.md §Observability, item 3). The one computation of the bound.
pub fn bound(
    id: ConfigId,
    errors: ErrorModel,
    cfg: FilterConfig<f64>,
    truth0: &[f64],
    start: &LogStart,
    sigma0: &[f64],
    records: &[LogRecord<f64>],
) -> Result<Vec<f64>, ekf::Error> {
    fn typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        cfg: FilterConfig<f64>,
        truth0: &[f64],
        start: &LogStart,
        sigma0: &[f64],
        records: &[LogRecord<f64>],
    ) -> Result<Vec<f64>, ekf::Error> {
        let (x, s) = initial::<N>(truth0, sigma0);
        let mut obs = Observability::<f64, M, N, Z>::new(cfg, x, s)?;
        obs.start_at(start.c_cn())?;
        for r in records {
            obs.record(r)?;
        }
        Ok(obs.crlb_sigma().iter().copied().collect())
    }
    rollcal::with_model!(id, errors, |M, N, Z| typed::<M, N, Z>(
        cfg, truth0, start, sigma0, records
    ))
}

/// [`bound`] after every record: σ_CRLB (rad) of every state per record
/// (for the σ(t) figures).
pub fn bound_history(
    id: ConfigId,
    errors: ErrorModel,
    cfg: FilterConfig<f64>,
    truth0: &[f64],
    start: &LogStart,
    sigma0: &[f64],
    records: &[LogRecord<f64>],
) -> Result<Vec<Vec<f64>>, ekf::Error> {
    fn typed<M: Model<N, Z>, const N: usize, const Z: usize>(
        cfg: FilterConfig<f64>,
        truth0: &[f64],
        start: &LogStart,
        sigma0: &[f64],
        records: &[LogRecord<f64>],
    ) -> Result<Vec<Vec<f64>>, ekf::Error> {
        let (x, s) = initial::<N>(truth0, sigma0);
        let mut obs = rollcal::observability::Bound::<f64, M, N, Z>::bound_only(cfg, x, s)?;
        obs.start_at(start.c_cn())?;
        let mut out = Vec::with_capacity(records.len());
        for r in records {
            obs.record(r)?;
            out.push(obs.crlb_sigma().iter().copied().collect());
        }
        Ok(out)
    }
    rollcal::with_model!(id, errors, |M, N, Z| typed::<M, N, Z>(
        cfg, truth0, start, sigma0, records
    ))
}

/// Posterior Cramér–Rao bound σ (rad) of every state at the end of `sim`
/// ([`bound`] over all its periods, from its true initial state, with the
/// scenario's prior and noise levels: [`SimulatedRun::crlb`]).
pub fn crlb_sigma(
    id: ConfigId,
    scenario: &Scenario,
    sim: &Simulation,
    earth_rate: bool,
) -> Result<Vec<f64>, ekf::Error> {
    SimulatedRun::new(id, scenario, sim, earth_rate).crlb()
}
