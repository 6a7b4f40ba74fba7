//! Which rotations excite which parameters: the share of each target
//! group's information gain contributed by each rotation of a recorded
//! outcome (`host-sim design --explain`).

use rollcal::models::Group;

use super::{Outcome, Pattern, Problem};

/// Information shares: per rotation of the path (in order), per state
/// group, the share of the group's information gain `Σ 1/σ²(end) −
/// 1/σ²(start)` (σ_CRLB, marginal) that the rotation contributed.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Contribution {
    /// The rotation.
    pub rotation: String,
    /// Start and end (s).
    pub t0_s: f64,
    /// End (s).
    pub t1_s: f64,
    /// `(group, share)`.
    pub shares: Vec<(&'static str, f64)>,
}

/// The groups of the targets of `problem`, in state order.
pub fn target_groups(problem: &Problem) -> Vec<Group> {
    let names = problem.config.states_with(problem.errors);
    let mut g: Vec<Group> = Vec::new();
    for &(i, _) in &problem.targets {
        if !g.contains(&names[i].group) {
            g.push(names[i].group);
        }
    }
    g
}

/// Per contiguous rotation of a recorded outcome, the information shares.
pub fn contributions(problem: &Problem, p: &Pattern, o: &Outcome) -> Vec<Contribution> {
    let names = problem.config.states_with(problem.errors);
    let groups = target_groups(problem);
    let info = |s: &[f64], g: Group| -> f64 {
        problem
            .targets
            .iter()
            .filter(|(i, _)| names[*i].group == g)
            .map(|(i, _)| 1.0 / (s[*i] * s[*i]))
            .sum()
    };
    let prior: Vec<f64> = problem.prior.clone();
    let last = o.history.last().map_or(&prior, |h| &h.1);
    let total: Vec<f64> = groups
        .iter()
        .map(|&g| info(last, g) - info(&prior, g))
        .collect();
    let mut out = Vec::new();
    let mut start_sigma = prior.clone();
    let mut t0 = 0.0;
    let mut i = 0;
    while i < o.history.len() {
        let (idx, dwell) = (o.history[i].2, o.history[i].3);
        let mut j = i;
        while j + 1 < o.history.len() && o.history[j + 1].2 == idx && o.history[j + 1].3 == dwell {
            j += 1;
        }
        let (t1, ref end, _, _) = o.history[j];
        let r = &p.rotations[idx];
        let shares = groups
            .iter()
            .zip(&total)
            .map(|(&g, &tot)| (g.as_str(), (info(end, g) - info(&start_sigma, g)) / tot))
            .collect();
        out.push(Contribution {
            rotation: if dwell {
                format!("dwell (after {})", r.axis.name)
            } else {
                format!("{} @{}°/s", r.axis.name, r.rate_deg_s)
            },
            t0_s: t0,
            t1_s: t1,
            shares,
        });
        start_sigma = end.clone();
        t0 = t1;
        i = j + 1;
    }
    out
}
