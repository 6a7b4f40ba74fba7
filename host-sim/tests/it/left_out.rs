//! A term the data have and the platform file leaves out (issue 41):
//! flagged with its likely cause named, or else an answer within 4σ of the
//! persistent truth — never "consistent" with a state beyond 4σ; and a
//! scenario with terms that wander calibrated with a platform file without
//! them is a legal combination (a warning, not an error). Deterministic:
//! every run is seeded. The rates over 100 seeds: `host-sim checks`
//! (docs/own-platform.md, "How often the checks are right").

use crate::support;
use host_sim::analysis::check_rates::{all_cases, run_case, Case, ANSWER_SIGMA};
use host_sim::analysis::checks::DataVerdict;
use host_sim::sim::scenario::Scenario;
use rollcal::models::{ConfigId, ErrorModel};

const REALISTIC: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/realistic.toml");

fn case(key: &str) -> Case {
    all_cases([10.0; 3])
        .into_iter()
        .find(|c| c.key == key)
        .unwrap()
}

/// M2-ps, full model, realistic scenario: a clean seed passes; k2 left
/// out is flagged and named; the warm-up left out and a linear creep of
/// the bias are flagged or within 4σ; no run is judged consistent with a
/// state beyond 4σ.
#[test]
fn a_left_out_term_is_flagged_or_harmless() {
    let sc = Scenario::from_file(std::path::Path::new(REALISTIC)).unwrap();
    let run = |key: &str, seed: u64| {
        run_case(
            ConfigId::M2Ps,
            ErrorModel::Full,
            &sc,
            seed,
            &case(key),
            true,
        )
        .unwrap()
    };
    let clean = run("clean", 1);
    assert_eq!(
        clean.judgement.verdict,
        DataVerdict::Consistent,
        "{:?}",
        clean.judgement
    );
    assert!(clean.worst.1 <= ANSWER_SIGMA, "{:?}", clean.worst);
    for (key, seed) in [("k2", 1), ("warmup", 1), ("warmup", 2), ("creep", 1)] {
        let o = run(key, seed);
        let warned = o.judgement.verdict.is_warning();
        let cause = o.judgement.cause.clone().unwrap_or_default();
        assert!(
            warned || o.worst.1 <= ANSWER_SIGMA,
            "{key} seed {seed}: consistent with {} {:.1}σ off",
            o.worst.0,
            o.worst.1
        );
        if key == "k2" {
            // 10 µg/g² moves ba by several σ: flagged, the term named.
            assert!(warned && o.worst.1 > ANSWER_SIGMA, "{key}: {:?}", o.worst);
            assert!(cause.contains("sigma_k2_ug_g2"), "{cause}");
            assert!(
                o.judgement
                    .checks
                    .iter()
                    .any(|c| c.name == "left_out" && !c.passed),
                "{:?}",
                o.judgement.checks
            );
        }
    }
}

/// The realistic scenario's log (terms that wander, a warm-up) with a
/// platform file of the full model that carries none of them: calibrated
/// (an answer with a data warning, exit 3), not refused as an error.
#[test]
fn wandering_truth_with_a_platform_file_without_them() {
    let dir = support::scratch("left-out-platform");
    let (csv, json, platform) = (dir.join("log.csv"), dir.join("c.json"), dir.join("p.toml"));
    let rec = support::host_sim()
        .args([
            "record",
            "--config",
            "M2-ps",
            "--scenario",
            REALISTIC,
            "--seed",
            "3",
        ])
        .args(["--format", "csv", "--out"])
        .arg(&csv)
        .output()
        .unwrap();
    support::assert_success(&rec);
    std::fs::write(
        &platform,
        "config = \"M2-ps\"\nerrors = \"full\"\n[site]\nlatitude_deg = 34.25\nearth_rate = true\n\
         [noise]\naccel_vrw_ug_rt_hz = 1.0\ngyro_arw_deg_rt_h = 0.0016666667\ngimbal_arcsec = 10.0\n\
         [timing]\nperiod_s = 1.0\n[prior]\nsigma_deg = 1.0\n",
    )
    .unwrap();
    let out = support::host_sim()
        .args(["calibrate", "--input"])
        .arg(&csv)
        .arg("--platform")
        .arg(&platform)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "{}", support::stderr(&out));
    let v = support::json_file(&json);
    assert_eq!(v["errors"], "full");
    assert_eq!(
        v["data_verdict"]["verdict"], "warning",
        "{}",
        v["data_verdict"]
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
