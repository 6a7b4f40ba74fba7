//! The compact sample log (`rollcal::estimator::PackedLog`, 36 B per period
//! for M2-ps, 27 B for the accelerometer-only configurations) against the
//! full-precision log: the estimator of record's final answer moves by less
//! than 0.01σ, on the paper's scenario and on a shipped scenario it was not
//! designed on, for M2-ps, M1-pa and M4-pa.
//!
//! The records are what the calibrator logs from the wire: commanded
//! increments as `f64`, accelerometer means and gimbal angles as `f32` (`wire::Sample`), widened to `f64`. The
//! packed log rounds the commanded increments to 2⁻⁴⁰ rad, the
//! accelerometer means to 2⁻²⁷ g and the gimbal angles to 2π/2²⁴ rad: the
//! difference measured here is that rounding alone.

use std::path::Path;

use host_sim::analysis::runner::{filter_config, log_record};
use host_sim::sim::scenario::Scenario;
use host_sim::sim::truth::{simulate, SimOptions};
use nalgebra::SVector;
use rollcal::estimator::{
    estimate, EstimatorOptions, LogRecord, PackedLayout, PackedLog, SampleLog, SliceLog,
    MAX_PERIODS,
};
use rollcal::models::{ConfigId, Model};
use rollcal::Options;

const DEG: f64 = std::f64::consts::PI / 180.0;

/// As received over the wire: `f32` measurements.
fn as_received(mut r: LogRecord<f64>) -> LogRecord<f64> {
    if let Some(o) = &mut r.observation {
        o.accel_mean = o.accel_mean.map(|v| f64::from(v as f32));
        o.gimbal = o.gimbal.map(|g| g.map(|v| f64::from(v as f32)));
    }
    r
}

/// Final state and σ of the estimator of record over `log`.
fn answer<M: Model<N, Z>, const N: usize, const Z: usize>(
    scenario: &Scenario,
    log: &mut dyn SampleLog<f64>,
    options: &EstimatorOptions,
) -> (SVector<f64, N>, SVector<f64, N>, u8) {
    let cfg = filter_config(scenario, true, Options::default());
    let sigma0 = SVector::<f64, N>::repeat(scenario.prior.sigma_deg * DEG);
    let out =
        estimate::<f64, M, N, Z, _, _>(&cfg, &SVector::zeros(), &sigma0, log, options, |_| {})
            .expect("the estimator of record runs");
    (*out.filter.state(), out.filter.sigma(), out.report.passes)
}

/// Max |Δx|/σ between the packed and the full log, and the packed log's
/// bytes per record.
fn compare<M: Model<N, Z>, const N: usize, const Z: usize>(scenario: &Scenario) -> (f64, usize) {
    let sim = simulate(
        scenario,
        SimOptions {
            seed: 1,
            noise: true,
            earth_rate: true,
        },
    );
    let mut records: Vec<LogRecord<f64>> = sim
        .samples
        .iter()
        .map(|s| {
            let mut r = as_received(log_record(s));
            if let Some(o) = r.observation.as_mut().filter(|_| Z <= 3) {
                o.gimbal = None; // not measured by the accelerometer-only models
            }
            r
        })
        .collect();
    let layout = PackedLayout::for_measurements(Z);
    let mut bytes = vec![0u8; records.len() * layout.record_len()];
    let mut table = [0.0f64; MAX_PERIODS];
    let mut packed = PackedLog::new(&mut bytes, &mut table, layout);
    for r in &records {
        if let Err(e) = packed.append(r) {
            panic!("record {} does not pack: {e} ({r:?})", packed.len());
        }
    }
    assert_eq!(packed.len(), records.len());
    let opts = EstimatorOptions::default();
    let (x_packed, _, passes_packed) = answer::<M, N, Z>(scenario, &mut packed, &opts);
    let (x_full, sigma, passes_full) =
        answer::<M, N, Z>(scenario, &mut SliceLog::from_records(&mut records), &opts);
    assert_eq!(passes_packed, passes_full);
    let worst = (x_packed - x_full).component_div(&sigma).amax();
    (worst, layout.record_len())
}

fn check(scenario: &Scenario, name: &str) {
    for id in [ConfigId::M2Ps, ConfigId::M1Pa, ConfigId::M4Pa] {
        let (worst, bytes) = rollcal::with_config!(id, |M, N, Z| compare::<M, N, Z>(scenario));
        eprintln!(
            "{name} {}: {bytes} B per period, max |Δx|/σ = {worst:.2e}",
            id.as_str()
        );
        assert_eq!(bytes, if id == ConfigId::M2Ps { 36 } else { 27 });
        assert!(
            worst < 0.01,
            "{name} {}: the packed log moved the answer by {worst:.3e}σ",
            id.as_str()
        );
    }
}

#[test]
fn packed_log_moves_the_paper_answer_by_less_than_a_hundredth_sigma() {
    check(&Scenario::paper(), "paper");
}

#[test]
fn packed_log_moves_another_scenarios_answer_by_less_than_a_hundredth_sigma() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/reordered-fast.toml");
    let scenario = Scenario::from_file(&path).expect("the shipped scenario loads");
    check(&scenario, "reordered-fast");
}
