//! `host-sim summary`: all seven configurations on one simulated run, one
//! line each.

use std::time::Instant;

use rollcal::models::{ConfigId, ErrorModel, Group};

use super::args::{load_scenario, CommonArgs};
use super::Error;
use crate::analysis::runner::{expected_observable, SimulatedRun};
use crate::output::report::group_of;
use crate::sim::truth::{simulate, SimOptions};

/// `host-sim summary`.
pub fn command(c: &CommonArgs) -> Result<(), Error> {
    let scenario = load_scenario(c.scenario.as_deref())?;
    super::args::note_instrument_prior(&scenario, c.errors);
    super::args::warn_full_first_pass(c);
    let earth_rate = !c.no_earth_rate && scenario.site.earth_rate;
    println!(
        "scenario '{}', seed {}, Earth rate {}, first-pass remedy {:?}, {} pass(es)",
        scenario.name,
        c.seed,
        if earth_rate { "on" } else { "off" },
        c.remedy,
        c.passes
    );
    if c.errors == ErrorModel::Full {
        println!("error model: full (the installation states and the instruments' 24 terms; the Gauss–Markov parts of the drift and the bias where the instruments wander)");
    }
    println!(
        "{:<7} {:>6} {:>12} {:>16} {:>14} {:>9}  {:>14}  data",
        "config", "states", "within 3σ", "observable ≤4σ", "max |err|/σ", "wall s", "installation"
    );
    let t_all = Instant::now();
    let sim = simulate(
        &scenario,
        SimOptions {
            seed: c.seed,
            noise: true,
            earth_rate,
        },
    );
    for id in ConfigId::ALL {
        let t0 = Instant::now();
        let r = SimulatedRun::new(id, &scenario, &sim, earth_rate)
            .with_errors(c.errors)
            .run(c.estimator(), None, false)
            .map_err(|e| format!("{id}: {e}"))?;
        let within = r.states.iter().filter(|s| s.ratio() <= 3.0).count();
        let obs: Vec<_> = r
            .states
            .iter()
            .filter(|s| expected_observable(id, s.name, group_of(s.group)))
            .collect();
        let obs_ok = obs.iter().filter(|s| s.ratio() <= 4.0).count();
        let max = r.states.iter().map(|s| s.ratio()).fold(0.0, f64::max);
        // The worst installation error (not the attitude, not an
        // instrument term), and the data checks of `calibrate`.
        let installation = r
            .states
            .iter()
            .filter(|s| s.info.group != Group::Attitude && !s.info.group.is_instrument())
            .map(|s| s.ratio())
            .fold(0.0, f64::max);
        let data = crate::analysis::checks::judge(&r).verdict;
        println!(
            "{:<7} {:>6} {:>9}/{:<2} {:>13}/{:<2} {:>14.2} {:>9.2}  {:>14.2}  {}",
            id.as_str(),
            r.states.len(),
            within,
            r.states.len(),
            obs_ok,
            obs.len(),
            max,
            t0.elapsed().as_secs_f64(),
            installation,
            data.word()
        );
    }
    println!(
        "total wall time {:.2} s (simulation included)",
        t_all.elapsed().as_secs_f64()
    );
    Ok(())
}
