//! The session: checkpoints, resets, restores and finishes as if
//! uninterrupted, whatever its filter held, with replies into a slot and
//! requests as the messages they name.

use super::*;

#[test]
fn the_session_checkpoints_resets_restores_and_finishes_as_if_uninterrupted() {
    use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
    use rollcal::session::{Reply, Session, SessionError};
    use rollcal::wire::EstimateKind;
    let (sc, data) = samples(300);
    let cfg = settings(&sc, ConfigId::M2Ps, 0);
    let blank = LogRecord::predicted(1.0, nalgebra::Vector3::zeros());
    let run = |interrupt: bool| {
        let mut storage = vec![blank; 300];
        let mut log = SliceLog::new(&mut storage);
        let mut session = Session::<f64>::new(Some(ConfigId::M2Ps), EstimatorOptions::default());
        // Samples before Configure are counted and dropped.
        let early = session.handle(&Message::Sample(data[0]), &mut log);
        assert_eq!(early, Reply::Error(SessionError::NotConfigured));
        assert_eq!(
            session.handle(&Message::Configure(cfg), &mut log),
            Reply::Nothing
        );
        let mut saved = None;
        for (i, s) in data.iter().enumerate() {
            if interrupt && i == 120 {
                let Reply::Send(Message::Checkpoint(cp)) =
                    session.handle(&Message::CheckpointRequest, &mut log)
                else {
                    panic!("no checkpoint")
                };
                saved = Some(cp);
            }
            if interrupt && i == 180 {
                // A reset loses everything since; the restore brings back the
                // state of sample 120, and the log is taken back with it.
                assert_eq!(session.handle(&Message::Reset, &mut log), Reply::Nothing);
                let cp = over_the_wire(saved.take().unwrap());
                assert_eq!(
                    session.handle(&Message::Checkpoint(cp), &mut log),
                    Reply::Nothing
                );
                for s in &data[120..180] {
                    session.handle(&Message::Sample(*s), &mut log);
                }
            }
            assert!(!matches!(
                session.handle(&Message::Sample(*s), &mut log),
                Reply::Error(_) | Reply::Rejected(_)
            ));
        }
        let Reply::Send(Message::Estimate(fin)) = session.handle(&Message::Finish, &mut log) else {
            panic!("no final estimate")
        };
        (fin, session.stats().unconfigured)
    };
    let (plain, unconfigured) = run(false);
    let (interrupted, _) = run(true);
    assert_eq!(unconfigured, 1);
    assert!(
        matches!(plain.kind, EstimateKind::Final { .. }),
        "{:?}",
        plain.kind
    );
    assert_eq!(plain.state, interrupted.state);
    assert_eq!(plain.sigma, interrupted.sigma);
    assert_eq!(plain.kind, interrupted.kind);
    // A Configure for another configuration than the session runs is refused.
    let mut storage = vec![blank; 1];
    let mut log = SliceLog::new(&mut storage);
    let mut session = Session::<f64>::new(Some(ConfigId::M1Pa), EstimatorOptions::default());
    assert_eq!(
        session.handle(&Message::Configure(cfg), &mut log),
        Reply::Error(SessionError::ConfigMismatch {
            expected: ConfigId::M1Pa,
            found: ConfigId::M2Ps
        })
    );
}

/// `Finish` runs its passes in the calibrator's own filter, the running
/// filter kept meanwhile in the reply slot and put back after
/// (`AnyCalibrator::finish_in_place`: a firmware's session holds one
/// filter): the answer is the calibrator's own `finish`, on a first and on
/// a repeated `Finish`, the calibrator is bit for bit what it was, and
/// samples after a `Finish` run on as if there had been none.
// Needs both configurations (the no-default-features build of .ci/run has
// M2-ps alone).
#[cfg(all(feature = "m1-pa", feature = "m2-ps"))]
#[test]
fn the_sessions_finish_is_the_calibrators_and_leaves_it_as_it_was() {
    use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
    use rollcal::session::{AnyCalibrator, Reply, Session};
    use rollcal::wire::{Estimate, EstimateKind};
    let (sc, data) = samples(200);
    let blank = LogRecord::predicted(1.0, nalgebra::Vector3::zeros());
    let opts = EstimatorOptions::default();
    let mut session = Session::<f64>::new(None, opts);
    let same = |a: &Estimate, b: &Estimate| {
        assert!(matches!(a.kind, EstimateKind::Final { .. }), "{:?}", a.kind);
        assert_eq!(a, b);
    };
    let own = |cal: Option<&AnyCalibrator<f64>>, log: &mut SliceLog<'_, f64>| match cal {
        Some(AnyCalibrator::M2Ps(c)) => c.finish(log, &opts, |_| {}).0,
        Some(AnyCalibrator::M1Pa(c)) => c.finish(log, &opts, |_| {}).0,
        #[cfg(feature = "full-model")]
        Some(AnyCalibrator::M2PsFull(c)) => c.finish(log, &opts, |_| {}).0,
        other => panic!("{other:?}"),
    };
    // The full model with errors that wander too: its predictions move
    // the wandering states' rows of the factor.
    let mut runs = vec![
        settings(&sc, ConfigId::M2Ps, 0),
        settings(&sc, ConfigId::M1Pa, 0),
    ];
    if cfg!(feature = "full-model") {
        runs.push(rollcal::wire::CalibratorConfig {
            errors: rollcal::models::ErrorModel::Full,
            wander: crate::support::realistic_wander(),
            ..settings(&sc, ConfigId::M2Ps, 0)
        });
    }
    let (early, late) = data.split_at(150);
    for run in runs {
        // The same run without any `Finish` until the end.
        let mut storage = vec![blank; data.len()];
        let mut log = SliceLog::new(&mut storage);
        let mut plain = Session::<f64>::new(None, opts);
        let configure = Message::Configure(run);
        assert_eq!(plain.handle(&configure, &mut log), Reply::Nothing);
        for s in &data {
            plain.handle(&Message::Sample(*s), &mut log);
        }
        let end = own(plain.calibrator(), &mut log);

        let mut storage = vec![blank; data.len()];
        let mut log = SliceLog::new(&mut storage);
        assert_eq!(session.handle(&configure, &mut log), Reply::Nothing);
        for s in early {
            session.handle(&Message::Sample(*s), &mut log);
        }
        let before = session.calibrator().cloned();
        let expected = own(before.as_ref(), &mut log);
        for _ in 0..2 {
            match session.handle(&Message::Finish, &mut log) {
                Reply::Send(Message::Estimate(e)) => same(&e, &expected),
                other => panic!("{other:?}"),
            }
            assert_eq!(session.calibrator(), before.as_ref());
        }
        for s in late {
            session.handle(&Message::Sample(*s), &mut log);
        }
        assert_eq!(session.calibrator(), plain.calibrator());
        match session.handle(&Message::Finish, &mut log) {
            Reply::Send(Message::Estimate(e)) => same(&e, &end),
            other => panic!("{other:?}"),
        }
    }
}

/// `Configure` builds its calibrator in the session's slot, in place
/// (issue 43: no calibrator-sized temporary on a firmware's stack): the
/// calibrator is `AnyCalibrator::new`'s, `==` and bit for bit in what it
/// answers, whatever the slot held (nothing, a calibrator of another
/// configuration, one of the same that has run); and so is a filter built
/// by `Filter::new_in` into a slot holding one that has run.
#[cfg(all(feature = "m1-pa", feature = "m2-ps"))]
#[test]
fn configure_builds_in_place_the_new_calibrator_whatever_the_slot_held() {
    use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
    use rollcal::session::{AnyCalibrator, Reply, Session};
    let (sc, data) = samples(120);
    let blank = LogRecord::predicted(1.0, nalgebra::Vector3::zeros());
    let opts = EstimatorOptions::default();
    let mut session = Session::<f64>::new(None, opts);
    // The answers of a fresh calibrator of `cfg` (built by value) on `data`.
    let fresh_run = |cfg: CalibratorConfig| {
        let mut storage = vec![blank; data.len()];
        let mut log = SliceLog::new(&mut storage);
        let mut cal = AnyCalibrator::<f64>::new(cfg).unwrap();
        let running: Vec<_> = data
            .iter()
            .map(|s| cal.push_logged(s, &mut log).unwrap())
            .collect();
        let mut scratch = None;
        let fin = cal.finish(&mut scratch, &mut log, &opts, &mut |_, _| {});
        (running, fin)
    };
    // Nothing, then M2-ps over M2-ps (that has run), M1-pa over M2-ps, M2-ps
    // over M1-pa.
    for id in [
        ConfigId::M2Ps,
        ConfigId::M2Ps,
        ConfigId::M1Pa,
        ConfigId::M2Ps,
    ] {
        let cfg = settings(&sc, id, 10);
        let mut storage = vec![blank; data.len()];
        let mut log = SliceLog::new(&mut storage);
        let configure = Message::Configure(cfg);
        assert_eq!(session.handle(&configure, &mut log), Reply::Nothing);
        // (`==` of two calibrators at the prior is false: `last_nis` is NaN
        // before any update; their checkpoints' bytes carry every state.)
        let built = session.calibrator().unwrap();
        let fresh = AnyCalibrator::<f64>::new(cfg).unwrap();
        assert_eq!(built.settings(), fresh.settings());
        assert_eq!(
            bytes(&Message::Checkpoint(built.checkpoint())),
            bytes(&Message::Checkpoint(fresh.checkpoint()))
        );
        let running: Vec<_> = data
            .iter()
            .map(|s| match session.handle(&Message::Sample(*s), &mut log) {
                Reply::Nothing => None,
                Reply::Send(Message::Estimate(e)) => Some(e),
                other => panic!("{other:?}"),
            })
            .collect();
        let Reply::Send(Message::Estimate(fin)) = session.handle(&Message::Finish, &mut log) else {
            panic!("no final estimate")
        };
        assert_eq!((running, fin), fresh_run(cfg), "{id:?}");
    }
    // `Filter::new_in` into a slot whose filter has run (a prediction
    // pending, a nominal set) is `Filter::new`, and runs as it does.
    let cfg = settings(&sc, ConfigId::M2Ps, 0);
    let fcfg = filter_config(&cfg, Options::default());
    let (x0, sigma0) = (
        nalgebra::SVector::zeros(),
        nalgebra::SVector::repeat(cfg.prior_sigma_rad),
    );
    let mut slot = None;
    let f = M2PsFilter::<f64>::new_in(&mut slot, fcfg, x0, sigma0).unwrap();
    for s in &data[..20] {
        let obs = Observation {
            accel_mean: nalgebra::Vector3::from(s.accel_mean).map(f64::from),
            gimbal: s.gimbal.map(|g| nalgebra::Vector3::from(g).map(f64::from)),
        };
        let dtheta = nalgebra::Vector3::from(s.dtheta_cmd);
        f.step(&dtheta, f64::from(s.dt), &obs).unwrap();
    }
    f.predict(&nalgebra::Vector3::from(data[20].dtheta_cmd), 1.0)
        .unwrap();
    f.set_nominal(Some(nalgebra::SVector::repeat(1e-4)));
    let again = M2PsFilter::<f64>::new_in(&mut slot, fcfg, x0, sigma0).unwrap();
    assert_eq!(*again, M2PsFilter::<f64>::new(fcfg, x0, sigma0).unwrap());
}

/// `Session::handle_into` and `request_into` (a reply slot the caller owns)
/// and `handle_in_place` (one slot for the message and its reply, the
/// integration kit's way) are `handle` and `request`: the same replies,
/// the same session after each message, whatever the slot held before (it
/// starts with a stale checkpoint, then keeps the last reply); and the
/// errors among them are counted.
#[test]
fn replies_into_a_slot_are_the_replies() {
    use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
    use rollcal::session::{Reply, Request, Session};
    let (sc, data) = samples(40);
    let cfg = settings(&sc, ConfigId::M1Pa, 10);
    let blank = LogRecord::predicted(1.0, nalgebra::Vector3::zeros());
    let mut storage = [vec![blank; 40], vec![blank; 40], vec![blank; 40]];
    let [a_storage, b_storage, c_storage] = &mut storage;
    let (mut a_log, mut b_log) = (SliceLog::new(a_storage), SliceLog::new(b_storage));
    let mut c_log = SliceLog::new(c_storage);
    let mut a = Session::<f64>::new(None, EstimatorOptions::default());
    let mut b = Session::<f64>::new(None, EstimatorOptions::default());
    let mut c = Session::<f64>::new(None, EstimatorOptions::default());
    // The message in the slot, the reply out of it.
    let mut in_place = |c: &mut Session<f64>, msg: &Message| {
        let mut one = Reply::Send(msg.clone());
        c.handle_in_place(&mut one, &mut c_log);
        one
    };
    let mut stale = M1PaCalibrator::<f64>::new(cfg).unwrap();
    for s in &data[..3] {
        let _ = stale.push(s);
    }
    let mut slot = Reply::Send(Message::Checkpoint(stale.checkpoint()));
    // Unconfigured first (errors), then a run with every request, a
    // restore from the checkpoint taken half-way, and a Finish.
    let mut messages = vec![Message::Sample(data[0]), Message::EstimateRequest];
    messages.push(Message::Configure(cfg));
    messages.extend(data[..20].iter().map(|s| Message::Sample(*s)));
    messages.push(Message::CheckpointRequest);
    let mut kinds = std::collections::BTreeSet::new();
    let mut errors = 0;
    for (k, msg) in messages.iter().enumerate() {
        let want = a.handle(msg, &mut a_log);
        b.handle_into(msg, &mut b_log, &mut slot);
        assert_eq!(slot, want, "message {k}");
        assert_eq!(a.stats(), b.stats(), "message {k}");
        assert_eq!(in_place(&mut c, msg), want, "message {k}");
        assert_eq!(a.stats(), c.stats(), "message {k}");
        kinds.insert(format!("{:?}", std::mem::discriminant(&want)));
        errors += u32::from(matches!(want, Reply::Error(_)));
    }
    let Reply::Send(Message::Checkpoint(cp)) = slot.clone() else {
        panic!("no checkpoint: {slot:?}");
    };
    for s in &data[20..] {
        let msg = Message::Sample(*s);
        let want = a.handle(&msg, &mut a_log);
        assert_eq!(want, {
            b.handle_into(&msg, &mut b_log, &mut slot);
            slot.clone()
        });
        assert_eq!(in_place(&mut c, &msg), want);
    }
    let restore = Message::Checkpoint(cp);
    let want = a.handle(&restore, &mut a_log);
    assert_eq!(want, {
        b.handle_into(&restore, &mut b_log, &mut slot);
        slot.clone()
    });
    assert_eq!(in_place(&mut c, &restore), want);
    for r in [
        Request::Estimate,
        Request::Finish,
        Request::Checkpoint,
        Request::Reset,
    ] {
        let want = a.request(r, &mut a_log);
        b.request_into(r, &mut b_log, &mut slot);
        assert_eq!(slot, want, "{r:?}");
        assert_eq!(in_place(&mut c, &r.message()), want, "{r:?}");
        kinds.insert(format!("{:?}", std::mem::discriminant(&want)));
        errors += u32::from(matches!(want, Reply::Error(_)));
    }
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
    assert_eq!(a.stats(), b.stats());
    assert_eq!(format!("{a:?}"), format!("{c:?}"));
    // A slot that holds no message: nothing done, the slot emptied.
    let mut empty = Reply::Rejected(rollcal::calibrator::RejectReason::NonFinite);
    c.handle_in_place(&mut empty, &mut c_log);
    assert_eq!(empty, Reply::Nothing);
    assert_eq!(format!("{a:?}"), format!("{c:?}"));
    // Nothing, Send and Error replies were all compared, and every error
    // was counted.
    assert_eq!(kinds.len(), 3, "{kinds:?}");
    assert_eq!(b.stats().errors, errors);
}

/// `Session::request(r)` is `Session::handle(&r.message())`: the same reply
/// and the same session after it, configured or not, on every request.
#[test]
fn a_request_is_the_message_it_names() {
    use rollcal::estimator::{EstimatorOptions, LogRecord, SampleLog, SliceLog};
    use rollcal::session::{Request, Session};
    let (sc, data) = samples(60);
    let cfg = settings(&sc, ConfigId::M1Pa, 0);
    let blank = LogRecord::predicted(1.0, nalgebra::Vector3::zeros());
    for configured in [false, true] {
        for r in Request::ALL {
            let mut storage = [vec![blank; 60], vec![blank; 60]];
            let [a_storage, b_storage] = &mut storage;
            let mut logs = [SliceLog::new(a_storage), SliceLog::new(b_storage)];
            let mut sessions =
                [(); 2].map(|()| Session::<f64>::new(None, EstimatorOptions::default()));
            if configured {
                for (session, log) in sessions.iter_mut().zip(logs.iter_mut()) {
                    session.handle(&Message::Configure(cfg), log);
                    for s in &data {
                        session.handle(&Message::Sample(*s), log);
                    }
                }
            }
            let [a, b] = &mut sessions;
            let [a_log, b_log] = &mut logs;
            assert_eq!(a.handle(&r.message(), a_log), b.request(r, b_log), "{r:?}");
            // (Debug: a reset's `last_nis` is NaN, which `==` never equals.)
            assert_eq!(format!("{a:?}"), format!("{b:?}"), "{r:?}");
            assert_eq!(a.stats(), b.stats(), "{r:?}");
            assert_eq!(SampleLog::len(&*a_log), SampleLog::len(&*b_log), "{r:?}");
        }
    }
}
