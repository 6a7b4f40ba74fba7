//! Lost data: gaps bridged along the commanded motion (or the attitude
//! re-acquired), a huge gap at a bounded cost, a clock step re-anchored.

use super::*;

/// A filter told the true commanded increments of every period, lost ones
/// predicted without measurement: what bridging a gap should reproduce.
fn reference_m1pa(
    sc: &CalibratorConfig,
    data: &[Sample],
    lost: impl Fn(usize) -> bool,
) -> M1PaFilter<f64> {
    let fc = filter_config(sc, Options::default());
    let s0 = nalgebra::SVector::<f64, 12>::repeat(sc.prior_sigma_rad);
    let mut f = M1PaFilter::<f64>::new(fc, nalgebra::SVector::zeros(), s0).unwrap();
    let v = |a: [f32; 3]| nalgebra::Vector3::new(a[0] as f64, a[1] as f64, a[2] as f64);
    for (i, s) in data.iter().enumerate() {
        if lost(i) {
            f.predict(&s.dtheta_cmd.into(), s.dt as f64).unwrap();
        } else {
            let obs = Observation {
                accel_mean: v(s.accel_mean),
                gimbal: None,
            };
            match f.step(&s.dtheta_cmd.into(), s.dt as f64, &obs) {
                Ok(_) | Err(rollcal::ekf::Error::Gated) => {}
                Err(e) => panic!("period {i}: {e}"),
            }
        }
    }
    f
}

fn assert_same_estimate(e: &rollcal::wire::Estimate, f: &M1PaFilter<f64>, tol_sigma: f64) {
    let sig = f.sigma();
    for i in 0..12 {
        let d = (e.state[i] - f.state()[i]).abs();
        assert!(d < tol_sigma * sig[i], "state {i}: {d:e} vs σ {:e}", sig[i]);
        assert!((e.sigma[i] / sig[i] - 1.0).abs() < 1e-6, "σ of state {i}");
    }
}

#[test]
fn the_reported_frame_is_the_integrated_one() {
    let (sc, data) = samples(300);
    let mut cal = M1PaCalibrator::<f64>::new(settings(&sc, ConfigId::M1Pa, 0)).unwrap();
    for s in &data {
        cal.push(s).unwrap();
        let q = s.c_cn_quat.map(f64::from);
        let reported = rollcal::geometry::dcm_from_quaternion(&q, 1e-6).unwrap();
        let angle = rollcal::geometry::angle_between(&reported, &cal.filter().command_frame().c_cn);
        assert!(angle < 2e-7, "seq {}: {angle:e} rad", s.seq);
    }
}

#[test]
fn gaps_inside_a_segment_are_bridged_along_the_commanded_motion() {
    let (sc, data) = samples(600);
    let cfg = settings(&sc, ConfigId::M1Pa, 0);
    // A NaN sample, three lost ones and a burst of 250, all inside the first
    // path segment.
    let lost = |i: usize| i == 100 || (200..=202).contains(&i) || (300..550).contains(&i);
    let reference = reference_m1pa(&sc, &data, lost);
    let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
    for (i, s) in data.iter().enumerate() {
        let r = match i {
            100 => cal.push(&Sample {
                accel_mean: [f32::NAN; 3],
                ..*s
            }),
            _ if lost(i) => continue,
            _ => cal.push(s),
        };
        assert_eq!(r.is_ok(), i != 100, "{i}");
    }
    let e = cal.estimate();
    assert_eq!(e.progress.bridged, 254);
    assert_eq!(e.progress.reacquired, 0);
    assert_eq!(e.progress.rejects.non_finite, 1);
    assert_eq!(e.progress.accepted, 600 - 254);
    // The motion found is the commanded one: the same answer as the filter
    // told the true increments (to f32 rounding of the samples).
    assert_same_estimate(&e, &reference, 1e-4);
}

#[test]
fn a_gap_at_a_segment_switch_is_bridged_and_an_unknown_motion_reacquires() {
    // The paper's path turns from South to East at 1800 s and back at 2700 s.
    let (sc, data) = samples(3000);
    let cfg = settings(&sc, ConfigId::M1Pa, 0);
    // One frame lost on each side of the first switch, and bursts of 20 and
    // 1000 that contain it.
    for lost_range in [1799..1800, 1800..1801, 1790..1810, 1500..2500] {
        let lost = |i: usize| lost_range.contains(&i);
        let reference = reference_m1pa(&sc, &data[..2600], lost);
        let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
        for (i, s) in data[..2600].iter().enumerate() {
            if !lost(i) {
                cal.push(s).unwrap();
            }
        }
        let e = cal.estimate();
        assert_eq!(
            e.progress.bridged as usize,
            lost_range.len(),
            "{lost_range:?}"
        );
        assert_eq!(e.progress.reacquired, 0, "{lost_range:?}");
        assert_same_estimate(&e, &reference, 1e-4);
    }
    // A gap over both switches: the motion is not one switch; the attitude
    // is re-acquired, the calibration goes on and keeps the parameters.
    let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
    for s in &data[..1700] {
        cal.push(s).unwrap();
    }
    let before = cal.estimate();
    cal.push(&data[2800]).unwrap();
    let after = cal.estimate();
    assert_eq!(after.progress.reacquired, 1);
    assert_eq!(after.progress.reacquired_periods, 1100);
    assert_eq!(after.progress.bridged, 0);
    let prior = cfg.prior_sigma_rad;
    // ψ re-opened to the prior: one update after it, gravity has pinned the
    // two level directions but not the azimuth, whose σ stays near the
    // prior; the parameters' σ are kept.
    let psi_max = after.sigma[..3].iter().fold(0.0f64, |a, b| a.max(*b));
    assert!(psi_max > 0.5 * prior, "ψ σ {:?}", &after.sigma[..3]);
    // (Before the gap the azimuth had converged to ≈ 0.18° of the 1° prior.)
    let psi_before = before.sigma[..3].iter().fold(0.0f64, |a, b| a.max(*b));
    assert!(
        psi_before < 0.25 * prior,
        "ψ σ before {:?}",
        &before.sigma[..3]
    );
    for i in 3..12 {
        assert!(
            after.sigma[i] <= before.sigma[i] * (1.0 + 1e-9),
            "σ of state {i} grew"
        );
    }
    for s in &data[2801..] {
        cal.push(s).unwrap();
    }
    let end = cal.estimate();
    assert_eq!(end.progress.accepted, 1700 + 200);
    assert_eq!(end.progress.rejects.total(), 0);
    // The reported frame was adopted: the integrated one still matches it.
    let q = data[2999].c_cn_quat.map(f64::from);
    let reported = rollcal::geometry::dcm_from_quaternion(&q, 1e-6).unwrap();
    let angle = rollcal::geometry::angle_between(&reported, &cal.filter().command_frame().c_cn);
    assert!(angle < 1e-6, "{angle:e}");
}

/// A jump of the sequence number and the time by `extra` periods before
/// sample 1700 of the paper stream (M1-pa, no search for the motion across
/// a gap): the calibrator's estimate after the remaining samples, pushed
/// with the jump.
fn after_a_gap_of(extra: u32) -> rollcal::wire::Estimate {
    let (sc, data) = samples(3000);
    // No search for the motion: every gap is of unknown motion (a gap of
    // whole turns of the paper's path would be found).
    let mut cfg = settings(&sc, ConfigId::M1Pa, 0);
    cfg.limits.max_bridge = 0;
    let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
    for s in &data[..1700] {
        cal.push(s).unwrap();
    }
    let before = cal.estimate();
    for s in &data[1700..] {
        let moved = Sample {
            seq: s.seq + extra,
            t_us: s.t_us + u64::from(extra) * 1_000_000,
            ..*s
        };
        if let Err(e) = cal.push(&moved) {
            panic!("gap {extra}: sample {} refused: {e:?}", s.seq);
        }
        if s.seq == data[1700].seq {
            let p = cal.estimate().progress;
            assert_eq!((p.reacquired, p.reacquired_periods), (1, extra));
            for i in 3..12 {
                assert!(cal.estimate().sigma[i] <= before.sigma[i] * (1.0 + 1e-9));
            }
        }
    }
    let end = cal.estimate();
    assert_eq!(end.progress.accepted, 3000);
    assert_eq!(end.progress.rejects.total(), 0);
    let q = data[2999].c_cn_quat.map(f64::from);
    let reported = rollcal::geometry::dcm_from_quaternion(&q, 1e-6).unwrap();
    let angle = rollcal::geometry::angle_between(&reported, &cal.filter().command_frame().c_cn);
    assert!(angle < 1e-6, "{angle:e}");
    end
}

/// A gap of unknown motion longer than `MAX_UNKNOWN_GAP_PERIODS` periods is
/// predicted over its last that many periods only, so one sample's cost is
/// bounded: a jump of 2³² periods, which validation accepts when the time
/// jumps with it, took hours of predictions before (and this test with it).
/// The answer is then that of a gap of exactly that length, and the
/// calibration goes on with the parameters' information kept.
#[test]
fn a_huge_gap_costs_a_bounded_number_of_predictions() {
    use rollcal::calibrator::MAX_UNKNOWN_GAP_PERIODS;
    let exact = after_a_gap_of(MAX_UNKNOWN_GAP_PERIODS);
    for extra in [MAX_UNKNOWN_GAP_PERIODS + 1, u32::MAX - 3001] {
        let e = after_a_gap_of(extra);
        assert_eq!(e.state, exact.state, "{extra}");
        assert_eq!(e.sigma, exact.sigma, "{extra}");
    }
}

#[test]
fn a_clock_step_is_reanchored_once_confirmed() {
    let (sc, data) = samples(300);
    let cfg = settings(&sc, ConfigId::M1Pa, 0);
    let stepped: Vec<Sample> = data
        .iter()
        .map(|s| Sample {
            t_us: if s.seq > 150 {
                s.t_us + 2_000_000
            } else {
                s.t_us
            },
            ..*s
        })
        .collect();
    let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
    let outcomes: Vec<_> = stepped.iter().map(|s| cal.push(s).map(|_| ())).collect();
    // The first sample after the step is rejected and remembered; the next
    // one confirms the new time base. Only the first is lost (and bridged).
    assert_eq!(outcomes[150], Err(RejectReason::TimeMismatch));
    assert!(outcomes
        .iter()
        .enumerate()
        .all(|(i, r)| i == 150 || r.is_ok()));
    let p = *cal.progress();
    assert_eq!((p.clock_steps, p.bridged, p.accepted), (1, 1, 299));
    let reference = reference_m1pa(&sc, &data, |i| i == 150);
    assert_same_estimate(&cal.estimate(), &reference, 1e-4);
    // A single wrong timestamp is not a clock step: it loses only itself.
    let mut glitch = data.clone();
    glitch[100].t_us += 500_000;
    let mut cal = M1PaCalibrator::<f64>::new(cfg).unwrap();
    let outcomes: Vec<_> = glitch.iter().map(|s| cal.push(s).map(|_| ())).collect();
    assert_eq!(outcomes[100], Err(RejectReason::TimeMismatch));
    assert!(outcomes
        .iter()
        .enumerate()
        .all(|(i, r)| i == 100 || r.is_ok()));
    assert_eq!(cal.progress().clock_steps, 0);
}
