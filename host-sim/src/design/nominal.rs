//! Designing for one's own platform: a platform file (`--platform`, the
//! file `calibrate` reads: site, noise, period, prior, no truth) as the
//! reference scenario of a design, at nominal values ([`nominal_scenario`]).
//!
//! The bound is linearised along a trajectory, so it needs values of the
//! installation errors, the initial attitude and the instrument terms. A
//! platform before its calibration has none: the nominal values stand in,
//! zero installation errors, the path starting aligned with n (gimbal
//! angles zero) and zero instrument terms. The bound depends on them only
//! to second order (they move the Jacobians by their own size, a few
//! tenths of a degree against the path's rotations of tens to hundreds of
//! degrees; docs/path-design.md, "Your own platform", measures it).

use crate::sim::scenario::{Instruments, Platform, Scenario, Timing, Truth};

use super::DesignError;

/// Truth steps per filter period of a nominal scenario: the paper's 0.01 s
/// of 1 s (the design's final check simulates the path; an even number,
/// as the truth simulator's Simpson mean needs).
pub const TRUTH_STEPS_PER_PERIOD: f64 = 100.0;

/// The zero installation errors and initial gimbal angles.
fn nominal_truth() -> Truth {
    Truth {
        theta_a_t_deg: [0.0; 3],
        theta_a_c_deg: [0.0; 3],
        theta_g_t_deg: [0.0; 3],
        theta_g_c_deg: [0.0; 3],
        lambda_deg: [0.0; 3],
        gimbal0_deg: [0.0; 3],
    }
}

/// A platform file as the reference scenario of a design: its site, noise,
/// period and prior, the instruments' prior and errors that wander (the
/// full model's wander states and the floors they leave), the nominal
/// values (zero installation errors, initial gimbal angles and instrument
/// terms, no warm-up) and its `[[path]]` as the reference path, or the
/// paper's when it has none (then also the paper's duration; returned
/// `true`). The duration is the file's `timing.duration_s`, else the
/// path's.
pub fn nominal_scenario(p: &Platform) -> Result<(Scenario, bool), DesignError> {
    let paper = Scenario::paper();
    let paper_path = p.path.is_empty();
    let path = if paper_path {
        paper.path.clone()
    } else {
        p.path.clone()
    };
    let path_s: f64 = path.iter().map(|s| s.duration_s()).sum();
    let period_s = p.timing.period_s;
    let duration_s = p.timing.duration_s.unwrap_or(path_s).max(path_s);
    let s = Scenario {
        name: if p.name.is_empty() {
            "platform".into()
        } else {
            p.name.clone()
        },
        truth: nominal_truth(),
        site: p.site.clone(),
        path,
        noise: p.noise.clone(),
        timing: Timing {
            period_s,
            truth_step_s: period_s / TRUTH_STEPS_PER_PERIOD,
            duration_s,
        },
        prior: p.prior.clone(),
        instruments: Instruments {
            prior: p.instruments.prior.clone(),
            wander: p.instruments.wander.clone(),
            ..Instruments::default()
        },
    };
    s.validate().map_err(|e| {
        DesignError::Scenario(format!(
            "the platform file as a reference scenario{}: {e}",
            if paper_path {
                " (with the paper's path: it has no [[path]])"
            } else {
                ""
            }
        ))
    })?;
    Ok((s, paper_path))
}
