//! A log may start anywhere on the path: the second half of the recorded
//! paper stream (samples 2701–5400, the computed frame half a turn about
//! South and a quarter about East from its start) calibrates as a log of
//! its own, from the start its first sample reports; a stream that `Reset`s
//! and starts again there gives the same answer; a restore finds the start
//! again; a log from the path's start is aligned exactly, as before.

use super::*;

use nalgebra::{SVector, Vector3};
use rollcal::estimator::{EstimatorOptions, LogRecord, LogStart, SliceLog};
use rollcal::geometry::{angle_between, dcm, dcm_from_quaternion, rotation_vector};
use rollcal::models::{M1Pa, M2Ps, M4Pa};
use rollcal::session::{Reply, Session};
use rollcal::wire::{Estimate, EstimateKind};

/// Index of the first sample of the second half (sample 2701).
const HALF: usize = 2700;

/// The paper scenario's installation errors (scenarios/paper.toml, °, ps
/// frame): θgC, θgT, θaC, θaT, λ.
const TRUTH_DEG: [[f64; 3]; 5] = [
    [0.3, -0.3, 0.2],
    [0.1, 0.2, -0.1],
    [0.2, 0.1, -0.1],
    [0.1, -0.1, 0.2],
    [0.2, -0.1, 0.1],
];

fn truth_rad(group: usize) -> Vector3<f64> {
    Vector3::from(TRUTH_DEG[group]) * core::f64::consts::PI / 180.0
}

/// The true parameters (every state after the attitude) of `id`: M2-ps
/// θgC, θgT, θaC, θaT, λ; M1-pa θgC^pa (`R(θgC^pa) = R(−θaC) R(θgC)`),
/// θgT, θaT.
fn true_parameters(id: ConfigId) -> Vec<f64> {
    let groups: Vec<Vector3<f64>> = match id {
        ConfigId::M2Ps => (0..5).map(truth_rad).collect(),
        ConfigId::M1Pa => vec![
            rotation_vector(&(dcm(&-truth_rad(2)) * dcm(&truth_rad(0)))),
            truth_rad(1),
            truth_rad(3),
        ],
        other => panic!("no truth written out for {other}"),
    };
    groups.iter().flat_map(|v| v.iter().copied()).collect()
}

/// `data` pushed into a new calibrator of `cfg` with a log; the final
/// answer and the log's start.
fn calibrate<M: Model<N, Z> + Clone, const N: usize, const Z: usize>(
    cfg: CalibratorConfig,
    data: &[Sample],
) -> (Estimate, LogStart) {
    let mut cal = Calibrator::<f64, M, N, Z>::new(cfg).unwrap();
    let mut records = vec![LogRecord::predicted(0.0, Vector3::zeros()); data.len()];
    let mut log = SliceLog::new(&mut records);
    for s in data {
        cal.push_logged(s, &mut log).unwrap();
    }
    let start = cal.log_start(&mut log).unwrap();
    let (answer, _) = cal.finish(&mut log, &EstimatorOptions::default(), |_| {});
    (answer, start)
}

/// The worst |error|/σ over the parameters whose σ is below a tenth of the
/// prior (the ones the half path observes), and how many there are.
fn worst_parameter(id: ConfigId, e: &Estimate, prior: f64) -> (f64, usize) {
    let truth = true_parameters(id);
    let judged: Vec<f64> = truth
        .iter()
        .enumerate()
        .map(|(k, t)| (e.state[k + 3] - t, e.sigma[k + 3]))
        .filter(|(_, s)| *s < 0.1 * prior)
        .map(|(err, s)| err.abs() / s)
        .collect();
    (judged.iter().copied().fold(0.0, f64::max), judged.len())
}

#[test]
fn a_log_that_starts_mid_path_is_calibrated_from_the_start_its_first_sample_reports() {
    let (sc, data) = samples(5400);
    let half = &data[HALF..];
    let reported = dcm_from_quaternion(&half[0].c_cn_quat.map(f64::from), 1e-5).unwrap();
    for id in [ConfigId::M2Ps, ConfigId::M1Pa] {
        let cfg = settings(&sc, id, 0);
        let (answer, start) = match id {
            ConfigId::M2Ps => calibrate::<M2Ps, 18, 6>(cfg, half),
            _ => calibrate::<M1Pa, 12, 3>(cfg, half),
        };
        // The start: the first report walked back over its period, half a
        // turn and a quarter from the path's start.
        assert!(!start.is_aligned());
        let turned = angle_between(start.c_cn(), &nalgebra::Matrix3::identity());
        assert!(turned > 1.0, "{turned} rad");
        let over_the_period = angle_between(start.c_cn(), &reported);
        assert!(
            (over_the_period - 0.1f64.to_radians()).abs() < 1e-6,
            "{over_the_period}"
        );
        // The estimator of record, not pass 1, over every sample.
        assert!(
            matches!(
                answer.kind,
                EstimateKind::Final {
                    converged: true,
                    ..
                }
            ),
            "{id}: {:?}",
            answer.kind
        );
        assert_eq!(answer.progress.accepted, 2700);
        assert_eq!(answer.progress.rejects.total(), 0);
        let (worst, judged) = worst_parameter(id, &answer, cfg.prior_sigma_rad);
        eprintln!(
            "{id}, samples 2701–5400: {judged} parameters observed, worst |error|/σ {worst:.2}"
        );
        assert!(judged >= 9, "{id}: {judged}");
        assert!(worst < 4.0, "{id}: {worst}");
    }
}

#[test]
fn a_log_from_the_paths_start_is_aligned_exactly() {
    let (sc, data) = samples(5400);
    for n in [1, 2700, 5400] {
        let (_, start) = calibrate::<M1Pa, 12, 3>(settings(&sc, ConfigId::M1Pa, 0), &data[..n]);
        assert_eq!(start, LogStart::aligned(), "{n} samples");
        assert!(start.is_aligned());
    }
    // The first sample of the path is explained by C^c_n = I.
    let s = &data[0];
    let reported = dcm_from_quaternion(&s.c_cn_quat.map(f64::from), 1e-5).unwrap();
    let first = LogStart::of_first_sample(
        &reported,
        &Vector3::from(s.dtheta_cmd),
        f64::from(s.dt),
        &Vector3::from(sc.earth_rate_n),
        sc.limits.frame_tolerance_rad,
    );
    assert_eq!(first, LogStart::aligned());
}

/// The start the final passes find at the end (walked back through the
/// log) is the one the first sample gave, to the walk's rounding; it does
/// not depend on a checkpoint taken on the way, so the answer after a
/// restore is the uninterrupted one bit for bit.
#[test]
fn a_restored_calibrator_finds_the_start_of_its_log_again() {
    let (sc, data) = samples(5400);
    let half = &data[HALF..];
    let cfg = settings(&sc, ConfigId::M2Ps, 0);
    let s = &half[0];
    let reported = dcm_from_quaternion(&s.c_cn_quat.map(f64::from), 1e-5).unwrap();
    let acquired = LogStart::of_first_sample(
        &reported,
        &Vector3::from(s.dtheta_cmd),
        f64::from(s.dt),
        &Vector3::from(sc.earth_rate_n),
        sc.limits.frame_tolerance_rad,
    );
    let (uninterrupted, walked) = calibrate::<M2Ps, 18, 6>(cfg, half);
    let drift = angle_between(walked.c_cn(), acquired.c_cn());
    assert!(drift < 1e-12, "{drift} rad");

    let mut cal = M2PsCalibrator::<f64>::new(cfg).unwrap();
    let mut records = vec![LogRecord::predicted(0.0, Vector3::zeros()); half.len()];
    let mut log = SliceLog::new(&mut records);
    for (i, s) in half.iter().enumerate() {
        if i == 1300 {
            let cp = over_the_wire(cal.checkpoint());
            cal = Calibrator::restore(cfg, &cp).unwrap();
        }
        cal.push_logged(s, &mut log).unwrap();
    }
    assert_eq!(cal.log_start(&mut log).unwrap(), walked);
    let (answer, _) = cal.finish(&mut log, &EstimatorOptions::default(), |_| {});
    assert_eq!(
        bytes(&Message::Estimate(answer)),
        bytes(&Message::Estimate(uninterrupted))
    );
}

/// A stream that resets after sample 2700 and goes on: the session's
/// `Finish` is the calibration of samples 2701–5400 alone, bit for bit.
#[test]
fn a_stream_that_resets_mid_path_starts_again_where_it_is() {
    let (sc, data) = samples(5400);
    let cfg = settings(&sc, ConfigId::M2Ps, 0);
    let (alone, _) = calibrate::<M2Ps, 18, 6>(cfg, &data[HALF..]);
    let mut session = Session::<f64>::new(None, EstimatorOptions::default());
    let mut records = vec![LogRecord::predicted(0.0, Vector3::zeros()); data.len()];
    let mut log = SliceLog::new(&mut records);
    assert!(matches!(
        session.handle(&Message::Configure(cfg), &mut log),
        Reply::Nothing
    ));
    for (i, s) in data.iter().enumerate() {
        if i == HALF {
            assert!(matches!(
                session.handle(&Message::Reset, &mut log),
                Reply::Nothing
            ));
        }
        session.handle(&Message::Sample(*s), &mut log);
    }
    let Reply::Send(Message::Estimate(answer)) = session.handle(&Message::Finish, &mut log) else {
        panic!("Finish answers with an estimate");
    };
    assert_eq!(rollcal::estimator::SampleLog::len(&log), 2700);
    assert_eq!(
        bytes(&Message::Estimate(answer)),
        bytes(&Message::Estimate(alone))
    );
}

/// A first sample whose own period the filter refuses (here M4-pa, no
/// Earth rate, holding still with the computed frame at the quaternion
/// `[½, ½, ½, ½]`, exact in f32: its middle attitude angle exactly at
/// gimbal lock) is rejected and leaves the calibrator as it was: at its
/// prior on the path's start.
#[test]
fn a_refused_first_sample_leaves_the_calibrator_at_its_prior() {
    let (sc, _) = samples(1);
    let cfg = CalibratorConfig {
        earth_rate_n: [0.0; 3],
        ..settings(&sc, ConfigId::M4Pa, 0)
    };
    let mut cal = Calibrator::<f64, M4Pa, 12, 3>::new(cfg).unwrap();
    let fresh = cal.clone();
    let q = [0.5f32; 4];
    let sample = Sample {
        seq: 1,
        t_us: 1_000_000,
        dt: 1.0,
        dtheta_cmd: [0.0; 3],
        c_cn_quat: q,
        accel_mean: [1.0, 0.0, 0.0],
        gimbal: None,
    };
    let start = LogStart::of_first_sample(
        &dcm_from_quaternion(&q.map(f64::from), 1e-5).unwrap(),
        &Vector3::zeros(),
        1.0,
        &Vector3::zeros(),
        1e-5,
    );
    let beta = start.attitude(ConfigId::M4Pa.layout()).y;
    assert_eq!(beta, core::f64::consts::FRAC_PI_2);
    let r = cal.push(&sample);
    assert_eq!(
        r,
        Err(RejectReason::Filter(rollcal::ekf::Error::GimbalLock))
    );
    assert_eq!(cal.filter(), fresh.filter());
    assert_eq!(cal.progress().rejects.filter, 1);
    assert_eq!(cal.filter().state(), &SVector::<f64, 12>::zeros());
}
