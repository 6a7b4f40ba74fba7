//! Runs `COUNT` filter periods (or dense reference periods) and nothing
//! else, for counting the host's instructions per period with callgrind:
//! `tools/host-instructions.sh` runs it for two counts and prints the
//! difference per period (BENCHMARKS.md, "Host time per period").
//!
//! `cargo run --release --example period_instructions -- WHAT COUNT`,
//! `WHAT` one of `dense/18x6`, `dense/12x3` (the criterion group's
//! reference, `benches/dense`), `m2ps/linearised`, `m1pa/linearised` (the
//! linearised pass about the zero state over the recorded paper stream,
//! without the NIS gate, as the criterion group times it), `COUNT` ≤ 5400
//! for the filters.

use std::hint::black_box;
use std::process::ExitCode;

use nalgebra::SVector;
use rollcal::models::{M1Pa, M2Ps, Model};
use rollcal::{Filter, Options};

#[path = "../benches/dense/mod.rs"]
mod dense;
#[path = "../tests/it/support/mod.rs"]
mod support;

fn dense_periods<const N: usize, const Z: usize>(count: usize) -> Result<(), String> {
    let (phi, p, q, h, r) = dense::inputs::<N, Z>();
    for _ in 0..count {
        black_box(dense::period(
            black_box(&phi),
            black_box(&p),
            black_box(&q),
            black_box(&h),
            black_box(&r),
        ));
    }
    Ok(())
}

fn filter_periods<M: Model<N, Z>, const N: usize, const Z: usize>(
    count: usize,
) -> Result<(), String> {
    let (settings, stream) = support::paper_stream();
    let options = Options {
        nis_gate: 0.0,
        ..Options::default()
    };
    let cfg = support::filter_config(&settings, options);
    let sigma0 = SVector::<f64, N>::repeat(settings.prior_sigma_rad);
    let mut f = Filter::<f64, M, N, Z>::new(cfg, SVector::zeros(), sigma0)
        .map_err(|e| format!("filter: {e}"))?;
    f.set_nominal(Some(SVector::zeros()));
    for s in stream.iter().take(count) {
        let (dt, dtheta) = support::period(s);
        let r = f.step(black_box(&dtheta), dt, black_box(&support::observation(s)));
        black_box(r).map_err(|e| format!("period {}: {e}", s.seq))?;
    }
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let count = args.get(1).and_then(|c| c.parse().ok());
    let run = match (args.first().map(String::as_str), count) {
        (Some("dense/18x6"), Some(n)) => dense_periods::<18, 6>(n),
        (Some("dense/12x3"), Some(n)) => dense_periods::<12, 3>(n),
        (Some("m2ps/linearised"), Some(n)) => filter_periods::<M2Ps, 18, 6>(n),
        (Some("m1pa/linearised"), Some(n)) => filter_periods::<M1Pa, 12, 3>(n),
        _ => {
            eprintln!(
                "usage: period_instructions dense/18x6|dense/12x3|m2ps/linearised|m1pa/linearised COUNT"
            );
            return ExitCode::from(2);
        }
    };
    match run {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("period_instructions: {e}");
            ExitCode::FAILURE
        }
    }
}
