//! Unit tests of the path design.

use rollcal::models::{ConfigId, ErrorModel};

use super::*;
use crate::sim::scenario::Scenario;

fn space() -> Space {
    Space {
        axes: ["north", "up", "east"]
            .iter()
            .map(|n| NamedAxis::named(n).unwrap())
            .collect(),
        tilted: true,
        max_rate_deg_s: 0.1,
        max_duration_s: 5400.0,
        max_rotations: 2,
        refine_starts: 1,
        dwell_steps: DWELL_STEPS_S.to_vec(),
    }
}

#[test]
fn patterns_are_whole_periods_and_distinct() {
    let p = coarse_patterns(&space(), 1.0);
    // 3 single rotations, then 3·2 ordered axis pairs × 4 × 4 angles.
    assert_eq!(p.len(), 3 + 6 * 16);
    for (i, a) in p.iter().enumerate() {
        assert!(a.rotations.iter().all(|r| r.periods(1.0).is_some()));
        assert!(!p[i + 1..].contains(a));
    }
    let n = neighbours(&p[5], &space(), 1.0);
    assert!(!n.is_empty());
    assert!(n.iter().all(|q| q != &p[5]));
}

#[test]
fn chunks_cover_the_periods_and_cut_the_last_rotation() {
    let s = space();
    let p = Pattern {
        rotations: vec![
            Rotation::new(s.axes[0].clone(), 90.0, 0.1),
            Rotation::new(s.axes[2].clone(), 45.0, 0.05),
        ],
        repeat: true,
    };
    assert_eq!(p.cycle_periods(1.0), Some(1800));
    let segs = p.segments(2000, 1.0);
    assert_eq!(segs.len(), 3);
    assert!((segs[2].angle_deg - 20.0).abs() < 1e-9);
    let total: u64 = p.chunks(2000, 1.0, 7).iter().map(|c| c.periods).sum();
    assert_eq!(total, 2000);
    assert!(p.chunks(2000, 1.0, 7).iter().all(|c| c.periods <= 7));
}

/// North 90° at 1°/s, dwell 60 s, east 180° at 1°/s, dwell 180 s.
fn with_dwells() -> Pattern {
    let s = space();
    let mut a = Rotation::new(s.axes[0].clone(), 90.0, 1.0);
    a.dwell_s = 60.0;
    let mut b = Rotation::new(s.axes[2].clone(), 180.0, 1.0);
    b.dwell_s = 180.0;
    Pattern {
        rotations: vec![a, b],
        repeat: true,
    }
}

#[test]
fn a_dwell_is_whole_periods_and_divides_the_coarse_step() {
    let p = with_dwells();
    assert_eq!(p.cycle_periods(1.0), Some(90 + 60 + 180 + 180));
    let problem = Problem::new(ConfigId::M1Pa, &Scenario::paper(), 60.0);
    // gcd(90, 60, 180, 180) = 30, within 10° at 1°/s: 10.
    let k = problem.step_periods(&p, 0, false);
    assert_eq!(k, 10);
    for (n, r) in [(90, false), (60, true), (180, false), (180, true)] {
        assert_eq!(n % k, 0, "{n} periods, dwell {r}");
    }
    // Every coarse piece is k whole periods (the last one cut at the
    // requested end), rotations and dwells alike, and the dwells are
    // exactly where they belong.
    let pieces = p.chunks(1234, 1.0, k);
    assert_eq!(pieces.iter().map(|c| c.periods).sum::<u64>(), 1234);
    let (last, body) = pieces.split_last().unwrap();
    assert!(body.iter().all(|c| c.periods == k));
    assert_eq!(last.periods, 1234 % k);
    let dwell: u64 = pieces.iter().filter(|c| c.dwell).map(|c| c.periods).sum();
    // Two whole cycles (1020 s, 480 s of dwell), then 90 + 60 + 64.
    assert_eq!(dwell, 2 * 240 + 60);
    // A budget that is not a multiple of the dwells' divisor shrinks k.
    assert_eq!(problem.step_periods(&p, 1234, false), 2);
    // The segments carry the dwells; the last rotation is cut.
    let segs = p.segments(1234, 1.0);
    let ds: Vec<(f64, f64)> = segs.iter().map(|g| (g.angle_deg, g.dwell_s)).collect();
    assert_eq!(
        ds,
        [
            (90.0, 60.0),
            (180.0, 180.0),
            (90.0, 60.0),
            (180.0, 180.0),
            (90.0, 60.0),
            (64.0, 0.0)
        ]
    );
    // Cut within a dwell: the dwell is cut at a whole period.
    let segs = p.segments(90 + 30, 1.0);
    assert_eq!(segs.len(), 1);
    assert_eq!((segs[0].angle_deg, segs[0].dwell_s), (90.0, 30.0));
}

#[test]
fn dwell_moves_are_proposed_in_whole_periods_only() {
    let s = space();
    let p = Pattern {
        rotations: vec![Rotation::new(s.axes[0].clone(), 90.0, 0.1)],
        repeat: true,
    };
    // The dwells of the neighbours that differ from `base` in the dwell
    // alone.
    let dwells = |q: &[Pattern], base: &Pattern| -> Vec<f64> {
        let b = &base.rotations[0];
        let mut d: Vec<f64> = q
            .iter()
            .map(|x| &x.rotations[0])
            .filter(|r| {
                r.axis == b.axis && r.angle_deg == b.angle_deg && r.rate_deg_s == b.rate_deg_s
            })
            .map(|r| r.dwell_s)
            .collect();
        d.sort_by(f64::total_cmp);
        d
    };
    // Insert 60, 180, 600 s.
    assert_eq!(dwells(&neighbours(&p, &s, 1.0), &p), [60.0, 180.0, 600.0]);
    // Lengthen, shorten, remove.
    let mut q = p.clone();
    q.rotations[0].dwell_s = 180.0;
    let n = neighbours(&q, &s, 1.0);
    assert_eq!(dwells(&n, &q), [0.0, 120.0, 240.0, 360.0, 780.0]);
    // With 40 s periods (90° at 0.1°/s = 900 s = 22.5 periods is not
    // whole; 120° is 30 periods): 60 and 180 s are not whole periods
    // and are never proposed, 600 s (15 periods) is.
    let mut r = p.clone();
    r.rotations[0].angle_deg = 120.0;
    assert_eq!(dwells(&neighbours(&r, &s, 40.0), &r), [600.0]);
    // No dwell moves without dwell steps (--no-dwells).
    let mut none = space();
    none.dwell_steps.clear();
    assert!(dwells(&neighbours(&p, &none, 1.0), &p).is_empty());
    // A dwell that is not whole periods makes the pattern unusable.
    let mut bad = p.clone();
    bad.rotations[0].dwell_s = 0.5;
    assert!(!bad.whole(1.0));
    assert!(bad.chunks(100, 1.0, 1).is_empty());
}

#[test]
fn targets_parse_and_override() {
    assert!(parse_target("thgC=1.5").is_ok());
    assert!(parse_target("thgC").is_err());
    assert!(parse_target("thgC=-1").is_err());
    assert!(parse_target("thgC=x").is_err());
    let id = ConfigId::M2Ps;
    let sigma = vec![1e-5; id.layout().n()];
    let t = targets(id, &sigma, 1.0, &[]).unwrap();
    assert_eq!(t.len(), 14);
    let t = targets(
        id,
        &sigma,
        1.0,
        &[TargetArg {
            name: "lam_y".into(),
            value: 30.0,
        }],
    )
    .unwrap();
    assert_eq!(t.len(), 15);
    assert!(targets(
        id,
        &sigma,
        1.0,
        &[TargetArg {
            name: "nope".into(),
            value: 1.0
        }]
    )
    .is_err());
}

/// The budget search that stands in for a shortest-path search that found
/// no path scores that search's stage 1 for the budget instead of
/// evaluating it again: its result is the budget search's own, with a
/// budget whose length keeps every coarse step (1800 periods) and one that
/// changes some (1234: those are evaluated again).
#[test]
fn the_budget_search_reuses_an_unreached_stage_one() {
    let id = ConfigId::M1Pa;
    let mut problem = Problem::new(id, &Scenario::paper(), 60.0);
    // Targets no path meets.
    problem.targets = default_target_states(id)
        .into_iter()
        .map(|i| (i, 1e-12))
        .collect();
    let space = Space {
        axes: ["north", "east"]
            .iter()
            .map(|n| NamedAxis::named(n).unwrap())
            .collect(),
        tilted: false,
        max_rate_deg_s: 1.0,
        max_duration_s: 1800.0,
        max_rotations: 2,
        refine_starts: 1,
        dwell_steps: Vec::new(),
    };
    let quiet = |_: &str, _: usize, _: usize| {};
    for periods in [1800, 1234] {
        let mut kept = None;
        let reach = search_reusing(
            &problem,
            &space,
            Goal::Reach { cutoff: periods },
            &mut kept,
            &quiet,
        );
        assert!(
            matches!(reach, Err(DesignError::NoPathReaches { .. })),
            "{reach:?}"
        );
        assert!(kept.is_some());
        let budget = Goal::Budget { periods };
        let reused = search_reusing(&problem, &space, budget, &mut kept, &quiet).unwrap();
        assert!(kept.is_none());
        assert!(reused.stages[0].name.contains("scored for the budget"));
        let fresh = search(&problem, &space, budget, &quiet).unwrap();
        assert_eq!(reused.best.pattern, fresh.best.pattern, "{periods}");
        assert_eq!(reused.best.score, fresh.best.score, "{periods}");
        assert_eq!(reused.searched.pattern, fresh.searched.pattern);
        for (a, b) in reused.stages.iter().zip(&fresh.stages) {
            assert_eq!(a.candidates, b.candidates, "{}", a.name);
            assert_eq!(a.infeasible, b.infeasible, "{}", a.name);
            assert_eq!(a.best_score, b.best_score, "{}", a.name);
        }
        // The periods propagated: the shortest-path search's, and those of
        // the candidates evaluated again.
        let (a, b) = (reused.stages[0].periods, fresh.stages[0].periods);
        if periods == 1800 {
            assert_eq!(a, b);
        } else {
            assert!(a > b, "{a} {b}");
        }
    }
}

/// The floors of the targets are `analysis::floor`'s, laid on the drift
/// and bias states of the full model only (none without a wander, none
/// for the installation model), and a target below its floor is set apart
/// with it before any search.
#[test]
fn targets_below_their_floor_are_set_apart_with_it() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/realistic.toml");
    let s = Scenario::from_file(std::path::Path::new(path)).unwrap();
    let id = ConfigId::M2Ps;
    let floors = state_floors(id, ErrorModel::Full, &s);
    let by_group = crate::analysis::floor::scenario_floors(&s);
    let names = id.states_with(ErrorModel::Full);
    let named: Vec<&str> = floors.iter().map(|f| names[f.state].name).collect();
    assert_eq!(named, ["dg_x", "dg_y", "dg_z", "ba_x", "ba_y", "ba_z"]);
    for f in &floors {
        let g = names[f.state].group.as_str();
        let want = by_group.iter().find(|b| b.0 == g).unwrap().2;
        assert_eq!(f.floor, want, "{g}");
    }
    assert!(state_floors(id, ErrorModel::Installation, &s).is_empty());
    assert!(state_floors(id, ErrorModel::Full, &Scenario::paper()).is_empty());
    let ba_x = floors[3];
    let dg_y = floors[1];
    let targets = vec![
        (0, 1e-6),
        (dg_y.state, dg_y.floor.limit * 1.01),
        (ba_x.state, ba_x.floor.limit * 0.99),
    ];
    let (reachable, below) = split_below_floor(targets, &floors);
    assert_eq!(
        reachable,
        [(0, 1e-6), (dg_y.state, dg_y.floor.limit * 1.01)]
    );
    assert_eq!(
        below,
        [BelowFloor {
            state: ba_x.state,
            target: ba_x.floor.limit * 0.99,
            floor: ba_x.floor
        }]
    );
}
