//! `Finish`: the estimator of record over the log or the reason it is
//! not, a reset as a new calibrator, and the compact log.

use super::*;

#[test]
fn finish_is_the_estimator_of_record_over_the_log_or_says_why_not() {
    use rollcal::estimator::{estimate, EstimatorOptions, LogRecord, SliceLog};
    use rollcal::wire::{EstimateKind, SinglePassReason};
    let (sc, data) = samples(400);
    let cfg = settings(&sc, ConfigId::M1Pa, 0);
    let blank = LogRecord::predicted(1.0, nalgebra::Vector3::zeros());
    // Complete log, with a lost sample and a bridged gap in it.
    let mut storage = vec![blank; 400];
    let mut log = SliceLog::new(&mut storage);
    let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
    for (i, s) in data.iter().enumerate() {
        if i != 150 && !(200..210).contains(&i) {
            cal.push_logged(s, &mut log).unwrap();
        }
    }
    assert_eq!(cal.progress().logged, 400);
    assert_eq!(cal.progress().log_incomplete, None);
    let opts = EstimatorOptions::default();
    let (fin, filter) = cal.finish(&mut log, &opts, |_| {});
    let EstimateKind::Final { passes, .. } = fin.kind else {
        panic!("{:?}", fin.kind)
    };
    assert!(passes >= 2);
    // The very estimator of record, run by hand over the same log.
    let fc = filter_config(&sc, Options::default());
    let s0 = nalgebra::SVector::<f64, 12>::repeat(cfg.prior_sigma_rad);
    let by_hand = estimate::<f64, rollcal::models::M1Pa, 12, 3, _, _>(
        &fc,
        &nalgebra::SVector::zeros(),
        &s0,
        &mut log,
        &opts,
        |_| {},
    )
    .unwrap();
    let filter = filter.unwrap();
    assert_eq!(filter, by_hand.filter);
    assert_eq!(fin.state.as_slice(), by_hand.filter.state().as_slice());
    // In place, in a filter that held another run: the same outcome.
    let mut reused = cal.filter().clone();
    let report = rollcal::estimator::estimate_in(
        &mut reused,
        &fc,
        &nalgebra::SVector::zeros(),
        &s0,
        &mut log,
        &opts,
        |_| {},
    )
    .unwrap();
    assert_eq!(reused, by_hand.filter);
    assert_eq!(report, by_hand.report);
    // `finish_with`, the session's: the same estimate, the same final filter.
    let mut seen = None;
    let with = cal.finish_with(&mut log, &opts, |_| {}, |f| seen = Some(f.clone()));
    assert_eq!(with, fin);
    assert_eq!(seen.as_ref(), Some(&filter));
    // The running estimate is still there, and pass 1 differs from the answer.
    assert_eq!(cal.estimate().kind, EstimateKind::Running);
    // Without a log, a full log, a mismatched log: pass 1, with the reason.
    let mut unlogged = M1PaCalibrator::<f64>::new(cfg).unwrap();
    for s in &data {
        unlogged.push(s).unwrap();
    }
    let mut empty_storage = vec![blank; 1];
    let mut empty = SliceLog::new(&mut empty_storage);
    let (e, f) = unlogged.finish(&mut empty, &opts, |_| {});
    assert_eq!(
        e.kind,
        EstimateKind::SinglePass {
            reason: SinglePassReason::NoLog,
            logged: 0
        }
    );
    assert!(f.is_none());
    assert_eq!(e.state, unlogged.estimate().state);
    let mut small_storage = vec![blank; 100];
    let mut small = SliceLog::new(&mut small_storage);
    let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
    for s in &data {
        cal.push_logged(s, &mut small).unwrap();
    }
    let (e, _) = cal.finish(&mut small, &opts, |_| {});
    assert_eq!(
        e.kind,
        EstimateKind::SinglePass {
            reason: SinglePassReason::LogFull,
            logged: 100
        }
    );
    let mut other_storage = vec![blank; 400];
    let mut other = SliceLog::new(&mut other_storage);
    let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
    for s in &data[..10] {
        cal.push_logged(s, &mut other).unwrap();
    }
    let restored = M1PaCalibrator::<f64>::restore(cfg, &cal.checkpoint()).unwrap();
    let mut fresh_storage = vec![blank; 400];
    let mut fresh = SliceLog::new(&mut fresh_storage);
    let (e, _) = restored.finish(&mut fresh, &opts, |_| {});
    assert_eq!(
        e.kind,
        EstimateKind::SinglePass {
            reason: SinglePassReason::LogMismatch,
            logged: 10
        }
    );
}

/// `reset` (the filter restarted in place) leaves the calibrator equal to a
/// new one with the same settings, keeping only the receiver's count of
/// rejected frames.
#[test]
fn reset_is_a_new_calibrator_in_place() {
    use rollcal::estimator::{LogRecord, SliceLog};
    let (sc, data) = samples(40);
    let cfg = settings(&sc, ConfigId::M2Ps, 0);
    let blank = LogRecord::predicted(1.0, nalgebra::Vector3::zeros());
    let mut storage = vec![blank; 40];
    let mut log = SliceLog::new(&mut storage);
    let mut cal = M2PsCalibrator::<f64>::new(cfg).unwrap();
    for s in &data {
        cal.push_logged(s, &mut log).unwrap();
    }
    cal.set_frame_errors(3);
    let fresh = M2PsCalibrator::<f64>::new(cfg).unwrap();
    assert_ne!(cal.filter(), fresh.filter());
    cal.reset().unwrap();
    assert_eq!(cal.filter(), fresh.filter());
    assert_eq!(cal.settings(), fresh.settings());
    // (`Debug`: a fresh progress holds a NaN NIS, never `==` itself.)
    assert_eq!(
        format!("{:?}", cal.progress()),
        format!("{:?}", fresh.progress())
    );
    assert_eq!(cal.estimate().frame_errors, 3);
}

/// A stream that carries the gimbal angles (the recorded one does, for
/// every configuration) logs into the compact log of an
/// accelerometer-only configuration: the calibrator drops the angles it
/// does not use, the log holds the whole run, and `Finish` is the
/// estimator of record, not pass 1.
#[test]
fn an_accelerometer_only_calibrator_logs_a_stream_with_gimbal_angles_compactly() {
    use rollcal::estimator::{EstimatorOptions, PackedLayout, PackedLog};
    use rollcal::wire::EstimateKind;
    let (sc, data) = samples(600);
    assert!(data.iter().all(|s| s.gimbal.is_some()));
    let cfg = settings(&sc, ConfigId::M1Pa, 0);
    let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
    let (mut bytes, mut table) = (vec![0u8; 600 * 27], vec![0.0; 8]);
    let mut log = PackedLog::<f64>::new(&mut bytes, &mut table, PackedLayout::Accel);
    for s in &data {
        assert_eq!(cal.push_logged(s, &mut log), Ok(None));
    }
    assert_eq!(cal.progress().log_incomplete, None);
    assert_eq!(cal.progress().logged, 600);
    let (answer, _) = cal.finish(&mut log, &EstimatorOptions::default(), |_| {});
    assert!(
        matches!(answer.kind, EstimateKind::Final { .. }),
        "{:?}",
        answer.kind
    );
}
