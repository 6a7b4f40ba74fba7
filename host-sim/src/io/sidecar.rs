//! The truth sidecar of a recorded stream (`record --truth PATH`, read by
//! `calibrate --truth PATH`): the true final and initial states and the
//! Cramér–Rao σ of the recorded configuration, and the true instrument
//! errors (docs/model.md §Instrument errors), as JSON.

use std::path::Path;

use rollcal::models::{ConfigId, ErrorModel, Group};

use super::Error;
use crate::analysis::runner::SimulatedRun;
use crate::sim::instruments::{
    instrument_names, instrument_truth_state, instrument_units, INSTRUMENT_STATES,
};
use crate::sim::scenario::Scenario;
use crate::sim::truth::{truth_state, Simulation};

/// The sidecar of configuration `id` on the simulated run `sim` of
/// `sc` (seed `seed`, Earth rate `earth_rate`). Besides the configuration's
/// states it holds the 36 true instrument errors of the run at its end
/// (`instrument_names`, `instrument_units` (internal units: rad/s, rad/s/g,
/// 1, g, 1, 1/g) and `instrument_truth`: the wandering errors' persistent
/// parts and their nuisances then), the attitude states at the end of every
/// period (`attitude_history_rad`: they move, so a log that ends before the
/// path does is judged at its own end), and with `history` every state at
/// the end of every period (`history_rad`, `instrument_history`).
pub fn truth_json(
    id: ConfigId,
    sc: &Scenario,
    sim: &Simulation,
    seed: u64,
    earth_rate: bool,
    history: bool,
) -> Result<serde_json::Value, Error> {
    let run = SimulatedRun::new(id, sc, sim, earth_rate);
    let truth = run.truth_at_end();
    let truth0 = run.truth_at_start();
    let crlb = run.crlb().map_err(Error::Bound)?;
    let attitude = attitude_indices(id);
    let installation: Vec<Vec<f64>> = sim
        .samples
        .iter()
        .map(|s| truth_state(id, &sim.params, &s.truth))
        .collect();
    let attitude_history: Vec<Vec<f64>> = installation
        .iter()
        .map(|x| attitude.iter().map(|&i| x[i]).collect())
        .collect();
    let mut json = serde_json::json!({
        "config": id.as_str(),
        "scenario": sc.name,
        "seed": seed,
        "earth_rate": earth_rate,
        "duration_s": sc.timing.duration_s,
        "names": id.states().iter().map(|s| s.name).collect::<Vec<_>>(),
        "truth_rad": truth,
        "truth0_rad": truth0,
        "crlb_sigma_rad": crlb,
        "instrument_names": instrument_names(id).to_vec(),
        "instrument_units": instrument_units().to_vec(),
        "instrument_truth": instrument_truth_state(id, &sim.params, &sim.final_wander()).to_vec(),
        "attitude_history_rad": attitude_history,
    });
    if history {
        let instruments: Vec<Vec<f64>> = sim
            .samples
            .iter()
            .map(|s| instrument_truth_state(id, &sim.params, &s.wander).to_vec())
            .collect();
        json["history_rad"] = serde_json::json!(installation);
        json["instrument_history"] = serde_json::json!(instruments);
    }
    Ok(json)
}

/// The indices of configuration `id`'s attitude states (the states that
/// move along the path).
fn attitude_indices(id: ConfigId) -> Vec<usize> {
    id.states()
        .iter()
        .enumerate()
        .filter(|(_, s)| s.group == Group::Attitude)
        .map(|(i, _)| i)
        .collect()
}

/// Every state at the end of every period: the installation states (rad)
/// and the instrument errors (internal units), one row per period.
pub type History = (Vec<Vec<f64>>, Vec<Vec<f64>>);

/// The truth sidecar written by `record --truth`.
pub struct Sidecar {
    /// True final state (rad).
    pub truth: Vec<f64>,
    /// True initial state (rad), for the bound of the samples received.
    pub truth0: Option<Vec<f64>>,
    /// σ_CRLB of the full run (rad).
    pub crlb: Vec<f64>,
    /// Seed of the recorded run.
    pub seed: Option<u64>,
    /// Duration of the recorded run (s).
    pub duration_s: Option<f64>,
    /// The true instrument errors (internal units, the order of
    /// [`crate::sim::instruments`]); zero for a sidecar written before they
    /// were recorded.
    pub instruments: [f64; INSTRUMENT_STATES],
    /// The attitude states (rad) at the end of every period, when recorded.
    pub attitude_history: Option<Vec<Vec<f64>>>,
    /// Every installation state (rad) and every instrument error (internal
    /// units) at the end of every period, when recorded (`record
    /// --truth-history`).
    pub history: Option<History>,
    /// The configuration.
    pub config: ConfigId,
}

impl Sidecar {
    /// The true final state of the model of `errors`: the installation
    /// states, then (full model) the instrument errors.
    pub fn truth_of(&self, errors: ErrorModel) -> Vec<f64> {
        with_instruments(&self.truth, &self.instruments, errors)
    }

    /// The true state of the model of `errors` at the end of period `k`
    /// (1-based) of the recorded path: the final state when `k` is the
    /// path's last period (or the periods were not recorded); otherwise
    /// the recorded history's, else the final state with the attitude
    /// states of period `k` (the parameters' truth is the path's end then).
    /// `None` when the sidecar does not reach period `k`.
    pub fn truth_at_period(&self, errors: ErrorModel, k: u32) -> Option<Vec<f64>> {
        let i = usize::try_from(k).ok()?.checked_sub(1)?;
        let periods = self
            .attitude_history
            .as_ref()
            .or(self.history.as_ref().map(|h| &h.0));
        match periods {
            None => return Some(self.truth_of(errors)),
            Some(p) if i + 1 == p.len() => return Some(self.truth_of(errors)),
            Some(p) if i >= p.len() => return None,
            Some(_) => {}
        }
        if let Some((installation, instruments)) = &self.history {
            let x = installation.get(i)?;
            let w = instruments.get(i)?;
            return Some(with_instruments(x, w, errors));
        }
        let attitude = self.attitude_history.as_ref()?.get(i)?;
        let mut x = self.truth.clone();
        for (&j, &v) in attitude_indices(self.config).iter().zip(attitude) {
            *x.get_mut(j)? = v;
        }
        Some(with_instruments(&x, &self.instruments, errors))
    }

    /// The true initial state of the model of `errors`, when recorded.
    pub fn truth0_of(&self, errors: ErrorModel) -> Option<Vec<f64>> {
        self.truth0
            .as_ref()
            .map(|t| with_instruments(t, &self.instruments, errors))
    }
}

fn with_instruments(x: &[f64], instruments: &[f64], errors: ErrorModel) -> Vec<f64> {
    let mut v = x.to_vec();
    if errors == ErrorModel::Full {
        v.extend_from_slice(instruments);
    }
    v
}

/// Reads the sidecar at `path`, which must hold the truth of `id`.
pub fn read_sidecar(path: &Path, id: ConfigId) -> Result<Sidecar, Error> {
    let name = || path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| Error::Read {
        path: name(),
        source,
    })?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|source| Error::NotSidecar {
        path: name(),
        source,
    })?;
    if v["config"].as_str() != Some(id.as_str()) {
        return Err(Error::SidecarConfig {
            path: name(),
            found: v["config"].clone(),
            expected: id,
        });
    }
    let floats = |key: &str| -> Result<Vec<f64>, Error> {
        v[key]
            .as_array()
            .map(|a| a.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect())
            .ok_or_else(|| Error::SidecarArray {
                path: name(),
                key: key.into(),
            })
    };
    /// The instrument states of a version-5 sidecar.
    const V5_INSTRUMENT_STATES: usize = 21;
    let instruments = match v.get("instrument_truth") {
        None => [0.0; INSTRUMENT_STATES],
        Some(_) => {
            let mut x = floats("instrument_truth")?;
            // A sidecar of protocol version 5 holds the 21 terms before
            // `k2` and the Gauss–Markov parts: those are zero.
            if x.len() == V5_INSTRUMENT_STATES {
                x.resize(INSTRUMENT_STATES, 0.0);
            }
            <[f64; INSTRUMENT_STATES]>::try_from(x.as_slice()).map_err(|_| {
                Error::SidecarLength {
                    path: name(),
                    key: "instrument_truth".into(),
                    found: x.len(),
                    expected: INSTRUMENT_STATES,
                }
            })?
        }
    };
    let rows = |key: &str| -> Option<Vec<Vec<f64>>> {
        v.get(key)?
            .as_array()?
            .iter()
            .map(|row| {
                row.as_array()
                    .map(|r| r.iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect())
            })
            .collect()
    };
    let history = rows("history_rad").zip(rows("instrument_history"));
    Ok(Sidecar {
        attitude_history: rows("attitude_history_rad"),
        history,
        config: id,
        truth: floats("truth_rad")?,
        truth0: floats("truth0_rad").ok(),
        crlb: floats("crlb_sigma_rad")?,
        seed: v["seed"].as_u64(),
        duration_s: v["duration_s"].as_f64(),
        instruments,
    })
}
