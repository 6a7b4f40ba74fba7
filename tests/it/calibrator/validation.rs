//! Samples one at a time: the calibrator is the filter on them, bad ones
//! are rejected by reason without touching it, and estimates come at the
//! cadence.

use super::*;

#[test]
fn the_calibrator_is_the_filter_on_the_f32_samples() {
    let (sc, data) = samples(200);
    let cfg = settings(&sc, ConfigId::M2Ps, 0);
    let mut cal = M2PsCalibrator::<f64>::new(cfg).unwrap();
    let fc = filter_config(&sc, Options::default());
    let s0 = nalgebra::SVector::<f64, 18>::repeat(sc.prior_sigma_rad);
    let mut f = M2PsFilter::<f64>::new(fc, nalgebra::SVector::zeros(), s0).unwrap();
    let v = |a: [f32; 3]| nalgebra::Vector3::new(a[0] as f64, a[1] as f64, a[2] as f64);
    for s in &data {
        assert_eq!(cal.push(s), Ok(None));
        let obs = Observation {
            accel_mean: v(s.accel_mean),
            gimbal: s.gimbal.map(v),
        };
        f.step(&s.dtheta_cmd.into(), s.dt as f64, &obs).unwrap();
    }
    assert_eq!(cal.filter(), &f);
    let e = cal.estimate();
    assert_eq!(e.seq, data.last().unwrap().seq);
    assert_eq!(e.updates, 200);
    assert_eq!(e.progress.accepted, 200);
    assert_eq!(e.progress.rejects.total(), 0);
    assert!(e.progress.last_nis.is_finite());
    assert_eq!(e.state.as_slice(), f.state().as_slice());
}

/// One bad variant of `good` (the sample after `prev`; `old` an earlier
/// one) per reason a sample is rejected for.
fn bad_samples(good: Sample, prev: Sample, old: Sample) -> Vec<(RejectReason, Sample)> {
    let nan = f32::NAN;
    vec![
        (
            RejectReason::NonFinite,
            Sample {
                accel_mean: [0.0, nan, 0.0],
                ..good
            },
        ),
        (
            RejectReason::NonFinite,
            Sample {
                dtheta_cmd: [f64::INFINITY, 0.0, 0.0],
                ..good
            },
        ),
        (
            RejectReason::NonFinite,
            Sample {
                gimbal: Some([0.0, 0.0, f32::NEG_INFINITY]),
                ..good
            },
        ),
        (RejectReason::NonFinite, Sample { dt: nan, ..good }),
        (RejectReason::Period, Sample { dt: 2.0, ..good }),
        (RejectReason::Period, Sample { dt: -1.0, ..good }),
        (
            RejectReason::AccelRange,
            Sample {
                accel_mean: [0.0, 1e6, 0.0],
                ..good
            },
        ),
        (
            RejectReason::IncrementRange,
            Sample {
                dtheta_cmd: [3.0, 0.0, 0.0],
                ..good
            },
        ),
        (
            RejectReason::GimbalRange,
            Sample {
                gimbal: Some([100.0, 0.0, 0.0]),
                ..good
            },
        ),
        (
            RejectReason::MissingGimbal,
            Sample {
                gimbal: None,
                ..good
            },
        ),
        (RejectReason::Duplicate, prev),
        (RejectReason::OutOfOrder, old),
        (
            RejectReason::TimeBackwards,
            Sample {
                t_us: prev.t_us,
                ..good
            },
        ),
        (
            RejectReason::TimeMismatch,
            Sample {
                t_us: good.t_us + 500_000,
                ..good
            },
        ),
    ]
}

#[test]
fn bad_samples_are_rejected_by_reason_and_leave_the_filter_untouched() {
    let (sc, data) = samples(60);
    let mut cal = M2PsCalibrator::<f64>::new(settings(&sc, ConfigId::M2Ps, 0)).unwrap();
    for s in &data[..30] {
        cal.push(s).unwrap();
    }
    let good = data[30];
    let prev = data[29];
    let nan = f32::NAN;
    let cases = bad_samples(good, prev, data[10]);
    for (reason, bad) in &cases {
        let before = cal.clone();
        assert_eq!(cal.push(bad), Err(*reason), "{bad:?}");
        assert_eq!(cal.filter(), before.filter(), "{reason:?}");
        assert_eq!(
            cal.progress().rejects.total(),
            before.progress().rejects.total() + 1
        );
        assert_eq!(cal.progress().last_seq, before.progress().last_seq);
    }
    let r = cal.progress().rejects;
    assert_eq!(
        (
            r.non_finite,
            r.period,
            r.accel_range,
            r.increment_range,
            r.gimbal_range
        ),
        (4, 2, 1, 1, 1)
    );
    assert_eq!(
        (
            r.missing_gimbal,
            r.duplicate,
            r.out_of_order,
            r.time_backwards,
            r.time_mismatch
        ),
        (1, 1, 1, 1, 1)
    );
    // The good sample is still accepted afterwards, as if nothing happened.
    let mut clean = M2PsCalibrator::<f64>::new(settings(&sc, ConfigId::M2Ps, 0)).unwrap();
    for s in &data[..31] {
        clean.push(s).unwrap();
    }
    cal.push(&good).unwrap();
    assert_eq!(cal.filter(), clean.filter());
    // A pa configuration ignores the gimbal angles entirely.
    let mut pa = M1PaCalibrator::<f64>::new(settings(&sc, ConfigId::M1Pa, 0)).unwrap();
    pa.push(&Sample {
        gimbal: None,
        ..data[0]
    })
    .unwrap();
    pa.push(&Sample {
        gimbal: Some([nan; 3]),
        ..data[1]
    })
    .unwrap();
    assert_eq!(pa.progress().accepted, 2);
}

#[test]
fn estimates_come_at_the_cadence() {
    let (sc, data) = samples(100);
    let mut cal = M1PaCalibrator::<f64>::new(settings(&sc, ConfigId::M1Pa, 7)).unwrap();
    let mut at = Vec::new();
    for s in &data {
        if let Some(e) = cal.push(s).unwrap() {
            assert_eq!(e.seq, s.seq);
            assert_eq!(e.config, ConfigId::M1Pa);
            assert_eq!(e.state.len(), 12);
            assert!(e.sigma.iter().all(|v| *v > 0.0 && v.is_finite()));
            at.push(e.progress.accepted);
        }
    }
    assert_eq!(at, (1..=14).map(|k| 7 * k).collect::<Vec<u32>>());
    // A rejected sample does not count toward the cadence.
    let mut cal = M1PaCalibrator::<f64>::new(settings(&sc, ConfigId::M1Pa, 2)).unwrap();
    assert_eq!(cal.push(&data[0]), Ok(None));
    assert!(cal.push(&data[0]).is_err());
    assert!(cal.push(&data[1]).unwrap().is_some());
    // Settings for another configuration are refused.
    assert!(M1PaCalibrator::<f64>::new(settings(&sc, ConfigId::M2Ps, 2)).is_err());
}
