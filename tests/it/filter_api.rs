//! Bad input to the filter is an error, never a panic, and leaves the filter
//! as it was; the NIS gate rejects an update.

use crate::support;

use nalgebra::{SVector, Vector3};
use rollcal::ekf::{M2PsFilter, Observation, Options};
use rollcal::Error;

/// A sample of the recorded paper stream (noise seed 1) in f64.
struct Period {
    dtheta_cmd: Vector3<f64>,
    dt: f64,
    accel_mean: Vector3<f64>,
    gimbal: Vector3<f64>,
}

fn samples() -> Vec<Period> {
    support::paper_stream()
        .1
        .iter()
        .map(|s| {
            let (dt, dtheta_cmd) = support::period(s);
            let obs = support::observation(s);
            Period {
                dtheta_cmd,
                dt,
                accel_mean: obs.accel_mean,
                gimbal: obs.gimbal.unwrap(),
            }
        })
        .collect()
}

fn filter(options: Options) -> M2PsFilter<f64> {
    let settings = support::paper_stream().0;
    let cfg = support::filter_config(&settings, options);
    M2PsFilter::new(
        cfg,
        SVector::zeros(),
        SVector::repeat(settings.prior_sigma_rad),
    )
    .unwrap()
}

#[test]
fn bad_input_is_rejected_and_leaves_the_filter_untouched() {
    bad_input_leaves(false);
}

/// The same for the linearised filter: a rejected step also leaves its
/// nominal (which `predict` moves) where it was.
#[test]
fn bad_input_leaves_the_linearised_filter_and_its_nominal_untouched() {
    bad_input_leaves(true);
}

/// Twenty good steps, then bad input in every place a step reads it; with
/// `linearised`, about the estimate after ten steps as the nominal.
fn bad_input_leaves(linearised: bool) {
    let samples = samples();
    let mut f = filter(Options::default());
    for (k, s) in samples.iter().take(20).enumerate() {
        if linearised && k == 10 {
            f.set_nominal(Some(*f.state()));
        }
        f.step(
            &s.dtheta_cmd,
            s.dt,
            &Observation {
                accel_mean: s.accel_mean,
                gimbal: Some(s.gimbal),
            },
        )
        .unwrap();
    }
    assert_eq!(f.nominal().is_some(), linearised);
    let before = f.clone();
    let s = &samples[20];
    let good = Observation {
        accel_mean: s.accel_mean,
        gimbal: Some(s.gimbal),
    };
    let nan = Vector3::new(f64::NAN, 0.0, 0.0);
    let inf = Vector3::new(0.0, f64::INFINITY, 0.0);
    let cases: [(Vector3<f64>, f64, Observation<f64>, Error); 6] = [
        (nan, s.dt, good, Error::NonFiniteInput),
        (s.dtheta_cmd, f64::NAN, good, Error::NonFiniteInput),
        (s.dtheta_cmd, 0.0, good, Error::InvalidPeriod),
        (s.dtheta_cmd, -1.0, good, Error::InvalidPeriod),
        (
            s.dtheta_cmd,
            s.dt,
            Observation {
                accel_mean: inf,
                gimbal: Some(s.gimbal),
            },
            Error::NonFiniteInput,
        ),
        (
            s.dtheta_cmd,
            s.dt,
            Observation {
                accel_mean: s.accel_mean,
                gimbal: None,
            },
            Error::MissingGimbal,
        ),
    ];
    for (d, dt, obs, expected) in cases {
        assert_eq!(f.step(&d, dt, &obs).unwrap_err(), expected);
        assert_eq!(f, before, "a rejected step changed the filter ({expected})");
    }
    assert!(f.update(&good).is_err(), "update without predict");
    f.step(&s.dtheta_cmd, s.dt, &good).unwrap();
    assert_eq!(f.updates(), before.updates() + 1);
}

#[test]
fn nis_gate_rejects_an_outlier() {
    let samples = samples();
    let mut f = filter(Options {
        nis_gate: 100.0,
        ..Options::default()
    });
    for s in samples.iter().take(200) {
        f.step(
            &s.dtheta_cmd,
            s.dt,
            &Observation {
                accel_mean: s.accel_mean,
                gimbal: Some(s.gimbal),
            },
        )
        .unwrap();
    }
    let s = &samples[200];
    let outlier = Observation {
        accel_mean: s.accel_mean + Vector3::new(1e-3, 0.0, 0.0),
        gimbal: Some(s.gimbal),
    };
    let p_before = f.covariance();
    assert_eq!(
        f.step(&s.dtheta_cmd, s.dt, &outlier).unwrap_err(),
        Error::Gated
    );
    assert_eq!(f.updates(), 200, "a gated update is not counted");
    // The prediction stands (time moved on); the measurement did not enter.
    assert!(f.covariance()[(0, 0)] >= p_before[(0, 0)]);
}

#[test]
fn restart_is_new_in_place_and_a_refused_restart_leaves_the_filter_untouched() {
    let settings = support::paper_stream().0;
    let cfg = support::filter_config(&settings, Options::default());
    let samples = samples();
    let mut f = filter(Options::default());
    for s in samples.iter().take(30) {
        let obs = Observation {
            accel_mean: s.accel_mean,
            gimbal: Some(s.gimbal),
        };
        f.step(&s.dtheta_cmd, s.dt, &obs).unwrap();
    }
    // A prediction pending, a nominal set: restart forgets both.
    let s = &samples[30];
    f.predict(&s.dtheta_cmd, s.dt).unwrap();
    f.set_nominal(Some(SVector::repeat(1e-4)));
    let before = f.clone();
    let x0 = SVector::repeat(2e-4);
    let sigma0 = SVector::repeat(settings.prior_sigma_rad);
    // Refused: a non-positive σ, a non-finite x0, an overflowing variance.
    let mut bad_sigma = sigma0;
    bad_sigma[7] = 0.0;
    let mut bad_x = x0;
    bad_x[2] = f64::NAN;
    assert_eq!(
        f.restart(cfg, x0, bad_sigma),
        Err(Error::CovarianceNotPositiveDefinite)
    );
    assert_eq!(f.restart(cfg, bad_x, sigma0), Err(Error::NonFiniteInput));
    assert_eq!(
        f.restart(cfg, x0, SVector::repeat(1e200)),
        Err(Error::NonFiniteInput)
    );
    assert_eq!(f, before);
    f.restart(cfg, x0, sigma0).unwrap();
    let fresh = M2PsFilter::<f64>::new(cfg, x0, sigma0).unwrap();
    assert_eq!(f, fresh);
    assert!(f
        .update(&Observation {
            accel_mean: s.accel_mean,
            gimbal: Some(s.gimbal),
        })
        .is_err_and(|e| e == Error::NoPrediction));
    // And it runs as the fresh one does, bit for bit.
    let mut g = fresh;
    for s in samples.iter().take(10) {
        let obs = Observation {
            accel_mean: s.accel_mean,
            gimbal: Some(s.gimbal),
        };
        assert_eq!(
            f.step(&s.dtheta_cmd, s.dt, &obs),
            g.step(&s.dtheta_cmd, s.dt, &obs)
        );
    }
    assert_eq!(f, g);
}

/// The research options (second-order dynamics, the iterated update) run
/// with the cargo feature `research-options` (default) and are refused
/// without it; the estimator of record's options run in every build.
/// `.ci/run` runs this test in both builds.
#[test]
fn research_options_run_only_in_a_build_that_holds_them() {
    use rollcal::ekf::RESEARCH_OPTIONS;
    let settings = support::paper_stream().0;
    let new = |options: Options| {
        M2PsFilter::<f64>::new(
            support::filter_config(&settings, options),
            SVector::zeros(),
            SVector::repeat(settings.prior_sigma_rad),
        )
    };
    for always in [
        Options::default(),
        Options::plain(),
        Options {
            second_order_mean: true,
            // Iterations that never apply (no update is iterated).
            iterations: 3,
            iterate_updates: 0,
            ..Options::default()
        },
    ] {
        assert!(always.is_built());
        assert!(new(always).is_ok());
    }
    let dynamics = Options {
        second_order_dynamics: true,
        ..Options::default()
    };
    let iterated = Options {
        iterations: 2,
        iterate_updates: 10,
        ..Options::default()
    };
    for research in [dynamics, iterated] {
        assert_eq!(research.is_built(), RESEARCH_OPTIONS);
        match (new(research), RESEARCH_OPTIONS) {
            (Ok(mut f), true) => {
                // And they run: one step of the recorded stream.
                let s = &samples()[0];
                let obs = Observation {
                    accel_mean: s.accel_mean,
                    gimbal: Some(s.gimbal),
                };
                f.step(&s.dtheta_cmd, s.dt, &obs).unwrap();
            }
            (Err(e), false) => assert_eq!(e, Error::UnsupportedOption),
            (result, built) => panic!(
                "research options built: {built}, filter: {:?}",
                result.err()
            ),
        }
    }
}
