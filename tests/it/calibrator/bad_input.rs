//! Bad input (issue 43): a `Configure` whose data-sheet figure is negative,
//! not finite, or absurd is refused with the field named, and a restore of
//! a checkpoint of another model, configuration or version is refused; both
//! leave the session as it was, bit for bit.

use super::{bytes, samples, settings};
use rollcal::calibrator;
use rollcal::estimator::{EstimatorOptions, SliceLog};
use rollcal::models::{ConfigId, ErrorModel, Wander};
use rollcal::session::{AnyCalibrator, Reply, Session, SessionError};
use rollcal::wire::{
    CalibratorConfig, ConfigField, FrameDecoder, Message, RefusalReason, Sample, VERSION,
};

/// The realistic scenario's wandering errors, every one of them
/// modelled, so that every time is in use (the tests' one copy).
fn realistic() -> Wander<f64> {
    crate::support::realistic_wander()
}

/// A session running the full M1-pa model with the realistic wander, fed
/// the first 60 samples of the paper stream (a state worth keeping).
fn running_session(data: &[Sample], cfg: CalibratorConfig) -> Session<f64> {
    let mut session = Session::<f64>::new(None, EstimatorOptions::default());
    let mut log = SliceLog::new(&mut []);
    assert_eq!(
        session.handle(&Message::Configure(cfg), &mut log),
        Reply::Nothing
    );
    for s in data {
        let _ = session.handle(&Message::Sample(*s), &mut log);
    }
    session
}

/// The session's state on the wire: its settings and its checkpoint.
fn state(session: &Session<f64>) -> (Vec<u8>, Vec<u8>) {
    let cal = session.calibrator().expect("configured");
    (
        bytes(&Message::Configure(*cal.settings())),
        bytes(&Message::Checkpoint(cal.checkpoint())),
    )
}

/// Every data-sheet field: negative, NaN, +∞, beyond its bound, and (not
/// zero) below its smallest value are refused with that field named (the
/// session's error, the wire's refusal and its text), the session left as
/// it was bit for bit; its bounds themselves and zero where allowed are
/// accepted.
#[test]
fn a_configure_with_a_bad_figure_is_refused_naming_the_field_and_changes_nothing() {
    let (sc, data) = samples(60);
    let good = CalibratorConfig {
        errors: ErrorModel::Full,
        wander: realistic(),
        ..settings(&sc, ConfigId::M1Pa, 30)
    };
    assert_eq!(good.invalid_field(), None);
    let mut session = running_session(&data, good);
    let before = state(&session);
    let mut log = SliceLog::new(&mut []);
    let mut refused = 0;
    for field in ConfigField::ALL {
        let b = field.bounds();
        let bad = [
            -1.0,
            -b.min,
            f64::NAN,
            f64::INFINITY,
            b.max * 10.0,
            b.min / 10.0,
        ]
        .into_iter()
        .chain((!b.zero).then_some(0.0));
        for v in bad {
            let mut cfg = good;
            *field.value_mut(&mut cfg) = v;
            let m = Message::Configure(cfg);
            let Reply::Error(e) = session.handle(&m, &mut log) else {
                panic!("{field} = {v} accepted")
            };
            assert_eq!(
                e,
                SessionError::Calibrator(calibrator::Error::InvalidField(field)),
                "{field} = {v}"
            );
            let refusal = e.refusal(m.tag());
            assert_eq!(
                (refusal.message, refusal.reason),
                (3, RefusalReason::InvalidField(field)),
                "{field} = {v}"
            );
            assert!(
                refusal.reason.to_string().starts_with(field.as_str()),
                "{}",
                refusal.reason
            );
            assert_eq!(
                state(&session),
                before,
                "{field} = {v}: the session as it was"
            );
            refused += 1;
        }
        // The bounds themselves (and zero where it means "not modelled")
        // are accepted, by a fresh session.
        for v in [b.min, b.max].into_iter().chain(b.zero.then_some(0.0)) {
            let mut cfg = good;
            *field.value_mut(&mut cfg) = v;
            assert_eq!(cfg.invalid_field(), None, "{field} = {v}");
            AnyCalibrator::<f64>::new(cfg).unwrap_or_else(|e| panic!("{field} = {v}: {e}"));
        }
    }
    // 18 fields × 6 values, and a zero for the accelerometer noise and
    // the three times in use.
    assert_eq!(refused, 18 * 6 + 4);
}

/// The bounds as a refusal prints them.
#[test]
fn the_bounds_print_short() {
    for (field, text) in [
        (ConfigField::SigmaAccel, "1e-12..0.1 g"),
        (ConfigField::GyroMarkovSigma, "0 or 1e-15..4.848e-3 rad/s"),
        (ConfigField::GyroRandomWalk, "0 or 1e-15..8.080e-5 rad/s/√s"),
        (ConfigField::AccelRandomWalk, "0 or 1e-12..1.667e-3 g/√s"),
        (ConfigField::PriorKg, "0 or 1e-12..0.1"),
        (ConfigField::PriorK2, "0 or 1e-12..0.01 g/g²"),
        (ConfigField::WarmupTau, "0.001..1e7 s"),
    ] {
        assert_eq!(field.bounds().to_string(), text, "{field}");
    }
    assert_eq!(
        RefusalReason::InvalidField(ConfigField::PriorK2).to_string(),
        "instrument_prior.k2 is not finite, negative or outside 0 or 1e-12..0.01 g/g²"
    );
}

/// A time whose σ is zero is not read (only finite and not negative is
/// asked of it), one in use may not be zero; the gimbal noise may be zero
/// only where gimbal angles are not measured.
#[test]
fn a_time_is_checked_where_it_is_used_and_the_gimbal_noise_where_it_is_measured() {
    let w = Wander {
        gyro_markov_sigma: 0.0,
        gyro_markov_tau_s: 1e12,
        ..realistic()
    };
    assert_eq!(w.invalid_field(), None);
    let w = Wander {
        gyro_markov_tau_s: 0.0,
        ..realistic()
    };
    assert_eq!(w.invalid_field(), Some(ConfigField::GyroMarkovTau));
    let w = Wander {
        gyro_markov_sigma: 0.0,
        gyro_markov_tau_s: -1.0,
        ..realistic()
    };
    assert_eq!(w.invalid_field(), Some(ConfigField::GyroMarkovTau));
    let w = Wander {
        gyro_warmup_sigma: 0.0,
        accel_warmup_sigma: 0.0,
        warmup_tau_s: 0.0,
        ..realistic()
    };
    assert_eq!(w.invalid_field(), None);
    let no_gimbal = CalibratorConfig {
        sigma_gimbal_rad: 0.0,
        ..CalibratorConfig::paper(ConfigId::M1Pa)
    };
    assert_eq!(no_gimbal.invalid_field(), None);
    let gimbal = CalibratorConfig {
        config: ConfigId::M2Ps,
        ..no_gimbal
    };
    assert_eq!(gimbal.invalid_field(), Some(ConfigField::SigmaGimbal));
    assert_eq!(
        AnyCalibrator::<f64>::new(gimbal).err(),
        Some(calibrator::Error::InvalidField(ConfigField::SigmaGimbal))
    );
}

/// The filter refuses a wander outside the bounds too (one check:
/// `Wander::invalid_field`), `NonFiniteInput` for a NaN and `OutOfRange`
/// for an absurd figure, in both precisions.
#[test]
fn the_filter_refuses_the_same_wander() {
    use rollcal::ekf::{Filter, FilterConfig};
    use rollcal::models::M1PaFull;
    let cfg = CalibratorConfig {
        errors: ErrorModel::Full,
        wander: realistic(),
        ..CalibratorConfig::paper(ConfigId::M1Pa)
    };
    let sigma0 = nalgebra::SVector::<f64, 48>::repeat(1e-3);
    let x0 = nalgebra::SVector::<f64, 48>::zeros();
    let with = |w: Wander<f64>| {
        let mut f = FilterConfig::<f64>::from(&cfg);
        f.wander = w;
        Filter::<f64, M1PaFull, 48, 3>::new(f, x0, sigma0).err()
    };
    let with32 = |w: Wander<f64>| {
        let mut f = FilterConfig::<f32>::from(&cfg);
        f.wander = w.to_precision();
        Filter::<f32, M1PaFull, 48, 3>::new(f, x0, sigma0.cast()).err()
    };
    assert_eq!((with(realistic()), with32(realistic())), (None, None));
    let absurd = Wander {
        accel_markov_sigma: 1.0,
        ..realistic()
    };
    let nan = Wander {
        warmup_tau_s: f64::NAN,
        ..realistic()
    };
    for (w, e) in [
        (absurd, rollcal::Error::OutOfRange),
        (nan, rollcal::Error::NonFiniteInput),
    ] {
        assert_eq!((with(w), with32(w)), (Some(e), Some(e)));
    }
}

/// A restore of a checkpoint of another error model (the installation
/// model's of the same configuration), of another configuration (the full
/// M2-ps model's), or framed for another protocol version is refused — the
/// first two by the session, the last by the decoder, which never hands it
/// on — and the session is left as it was, bit for bit.
#[test]
fn a_checkpoint_of_another_model_configuration_or_version_is_refused_and_changes_nothing() {
    let (sc, data) = samples(60);
    let full = CalibratorConfig {
        errors: ErrorModel::Full,
        wander: realistic(),
        ..settings(&sc, ConfigId::M1Pa, 30)
    };
    let mut session = running_session(&data, full);
    let before = state(&session);
    let mut log = SliceLog::new(&mut []);
    let installation = running_session(&data, settings(&sc, ConfigId::M1Pa, 30));
    let m2ps = running_session(
        &data[..0],
        CalibratorConfig {
            config: ConfigId::M2Ps,
            ..full
        },
    );
    for (other, reason) in [
        (
            &installation,
            RefusalReason::ErrorModelMismatch {
                expected: ErrorModel::Full,
                found: ErrorModel::Installation,
            },
        ),
        (
            &m2ps,
            RefusalReason::ConfigMismatch {
                expected: ConfigId::M1Pa,
                found: ConfigId::M2Ps,
            },
        ),
    ] {
        let restore = Message::Checkpoint(other.calibrator().unwrap().checkpoint());
        let Reply::Error(e) = session.handle(&restore, &mut log) else {
            panic!("restore accepted")
        };
        assert_eq!(e.refusal(restore.tag()).reason, reason);
        assert_eq!(state(&session), before, "{reason}: the session as it was");
    }
    // A calibrator's own checkpoint restored with a bad figure in the
    // settings given with it: refused naming the field, unchanged.
    let mut cal = rollcal::calibrator::M1PaFullCalibrator::<f64>::new(full).unwrap();
    for s in &data {
        let _ = cal.push(s);
    }
    let cp = cal.checkpoint();
    let bad = CalibratorConfig {
        wander: Wander {
            accel_markov_tau_s: -900.0,
            ..realistic()
        },
        ..full
    };
    assert_eq!(
        cal.restore_in_place(bad, &cp),
        Err(calibrator::Error::InvalidField(ConfigField::AccelMarkovTau))
    );
    assert_eq!(
        bytes(&Message::Checkpoint(cal.checkpoint())),
        bytes(&Message::Checkpoint(cp))
    );
    // The session's own checkpoint framed for another version: counted as
    // such, never decoded into a message.
    let own = bytes(&Message::Checkpoint(
        session.calibrator().unwrap().checkpoint(),
    ));
    let mut raw = cobs_decode(&own[..own.len() - 1]);
    raw[0] = VERSION - 1;
    let n = raw.len() - 4;
    let crc = rollcal::wire::crc32(&raw[..n]).to_le_bytes();
    raw[n..].copy_from_slice(&crc);
    let mut decoder = FrameDecoder::new();
    let mut got = Vec::new();
    let mut frame = crate::support::cobs_reference(&raw);
    frame.push(0);
    decoder.feed(&frame, |m| got.push(m));
    assert!(got.is_empty());
    assert_eq!(decoder.stats().wrong_version, 1);
    assert_eq!(state(&session), before);
}

/// COBS-decodes a frame without its delimiter.
fn cobs_decode(frame: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < frame.len() {
        let code = usize::from(frame[i]);
        out.extend_from_slice(&frame[i + 1..i + code]);
        i += code;
        if code < 0xff && i < frame.len() {
            out.push(0);
        }
    }
    out
}
