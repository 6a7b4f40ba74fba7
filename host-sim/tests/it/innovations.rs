//! The innovations of the last pass that the reports and the no-truth
//! checks use: on a simulated paper run the whitened innovations are
//! independent unit-variance components, and the path's four segments are
//! recovered from the commanded increments alone.

use host_sim::analysis::runner::{run_filter, Estimator};
use host_sim::sim::scenario::Scenario;
use host_sim::sim::truth::{simulate, SimOptions};
use rollcal::models::ConfigId;

#[test]
fn whitened_innovations_are_unit_and_segments_are_the_papers() {
    let scenario = Scenario::paper();
    let sim = simulate(
        &scenario,
        SimOptions {
            seed: 3,
            noise: true,
            earth_rate: true,
        },
    );
    for (id, z) in [(ConfigId::M1Pa, 3), (ConfigId::M2Ps, 6)] {
        let r = run_filter(id, &scenario, &sim, true, Estimator::default(), None, false).unwrap();
        let seg: Vec<_> = r.segments.iter().map(|s| (s.first, s.end)).collect();
        assert_eq!(
            seg,
            [(0, 1800), (1800, 2700), (2700, 4500), (4500, 5400)],
            "{id}"
        );
        assert_eq!(r.updates.len(), r.nis.len(), "{id}");
        assert!(r.updates.len() >= 5390, "{id}: {} updates", r.updates.len());
        for c in 0..z {
            let w: Vec<f64> = r.updates.iter().map(|u| u.white[c]).collect();
            let n = w.len() as f64;
            let mean = w.iter().sum::<f64>() / n;
            let var = w.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
            // 5 400 unit normals: mean within 4/√n = 0.054, variance within
            // 4·√(2/n) = 0.077 of 1.
            assert!(mean.abs() < 0.054, "{id} component {c}: mean {mean}");
            assert!(
                (var - 1.0).abs() < 0.077,
                "{id} component {c}: variance {var}"
            );
        }
        for u in &r.updates {
            let nis: f64 = u.white.iter().map(|v| v * v).sum();
            assert!(
                (nis - u.nis).abs() <= 1e-6 * u.nis.max(1.0),
                "{id}: {nis} vs {}",
                u.nis
            );
        }
    }
}
