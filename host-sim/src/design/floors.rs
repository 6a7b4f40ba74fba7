//! The floors of the targets: the floor the errors that wander leave on
//! the persistent part of a drift or a bias (computed once, by
//! [`crate::analysis::floor::scenario_floors`], as `host-sim observability
//! --errors full` shows it), laid on the target states, and the targets
//! below their floor set apart ([`split_below_floor`]): no path of any
//! length reaches them, so the search does not look for one.

use rollcal::models::{ConfigId, ErrorModel, Group};

use crate::analysis::floor::{scenario_floors, Floor};
use crate::sim::scenario::Scenario;

/// The floor of one state: the state of a wandering term (`dg_x`, `ba_y`,
/// …) and the floor of its term.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct StateFloor {
    /// State index.
    pub state: usize,
    /// The floor of its term (internal units): [`Floor::limit`] is the
    /// smallest σ any path of any length reaches, [`Floor::flat_after_s`]
    /// the log length past which rolling longer does not help.
    pub floor: Floor,
}

/// A target below its floor: out of reach of every path of any length.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BelowFloor {
    /// State index.
    pub state: usize,
    /// Target σ (internal units).
    pub target: f64,
    /// The floor of its term (internal units).
    pub floor: Floor,
}

/// The floor of every state of `id` under `errors` that a wandering term
/// of `s` leaves one on (the full model's `dg` and `ba` states when the
/// scenario's `[instruments.wander]` sets a wander); empty otherwise. The
/// floor is [`scenario_floors`]'s, unchanged.
pub fn state_floors(id: ConfigId, errors: ErrorModel, s: &Scenario) -> Vec<StateFloor> {
    if errors != ErrorModel::Full {
        return Vec::new();
    }
    let floors = scenario_floors(s);
    id.states_with(errors)
        .iter()
        .enumerate()
        .filter_map(|(i, st)| {
            floors
                .iter()
                .find(|(g, _, _)| Group::from_name(g) == Some(st.group))
                .map(|(_, _, f)| StateFloor {
                    state: i,
                    floor: *f,
                })
        })
        .collect()
}

/// The floor of state `i` in `floors`, if it has one.
pub fn floor_of(floors: &[StateFloor], i: usize) -> Option<Floor> {
    floors.iter().find(|f| f.state == i).map(|f| f.floor)
}

/// `targets` split into those a path may reach and those below their
/// state's floor (`target < floor.limit`: the floor is approached from
/// above and never passed, so no path of any length meets them).
pub fn split_below_floor(
    targets: Vec<(usize, f64)>,
    floors: &[StateFloor],
) -> (Vec<(usize, f64)>, Vec<BelowFloor>) {
    let mut reachable = Vec::new();
    let mut below = Vec::new();
    for (i, t) in targets {
        match floor_of(floors, i) {
            Some(floor) if t < floor.limit => below.push(BelowFloor {
                state: i,
                target: t,
                floor,
            }),
            _ => reachable.push((i, t)),
        }
    }
    (reachable, below)
}
