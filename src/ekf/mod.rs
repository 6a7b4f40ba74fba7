//! The extended Kalman filter over any configuration (docs/model.md §Estimator).
//!
//! One filter period: [`Filter::predict`] propagates the state by one RK4
//! step over the commanded motion of the period; [`Filter::update`] then
//! processes the period's measurement (the mean accelerometer output over
//! the period and, in M2, the gimbal angles at its end) together with the
//! covariance's time update. The covariance is kept as a U-D factor
//! (module `factor`, private): Bierman's scalar updates of the decorrelated,
//! whitened measurement, and the structured time update (the parameters
//! are constant, so only the three attitude rows of `Φ` differ from the
//! identity). The state, the nominal and every model evaluation are `f64`;
//! the factor and the gains are in the filter's precision `T` (see
//! [`Filter`]).
//!
//! **Cold start.** The accelerometers resolve 1e-6 g while the initial
//! errors are ≈ 0.3° (5e-3 rad): the measurement's second-order terms
//! (≈ θ² ≈ 3e-5 g) are thirty times the noise. A plain EKF lets the first
//! updates collapse `P` to the noise level while the linearisation point is
//! still wrong, locks that error in and ends inconsistent. The remedy chosen
//! here (see [`Options`]) adds the second-order terms of the measurement to
//! the innovation covariance, `S = H P Hᵀ + R + ½ [tr(∇²h_a P ∇²h_b P)]_ab`
//! (the Gaussian second-order filter): while `P` is large the update is
//! weighted down by the linearisation error it would commit, and the term
//! vanishes on its own (as `P²`) once the filter has converged.
//!
//! That first pass never diverges, but weakly observable directions (λy in
//! M2-ps, seen only through the Earth rate) keep moving the linearisation
//! point of the well-determined ones, and the filter can end many σ off.
//! The estimator of record therefore runs further passes over the same data:
//! [`Filter::set_nominal`] turns the filter into a Kalman filter linearised
//! about a nominal trajectory (the previous pass's final estimate integrated
//! back to the start; repeated until the estimate stops moving), whose
//! covariance is then the posterior Cramér–Rao bound. The same mode with the true initial state as nominal computes that
//! bound. Measurements of every remedy: docs/estimator.md, "The cold start"
//! (`host-sim remedies`).
//!
//! **Correlated noise.** The gyro noise of a period moves the attitude
//! during the same period whose mean the accelerometers report, so it is
//! both process and measurement noise; the factored update decorrelates
//! the two ([`Filter::update`]).
//!
//! **Files.** One concern a file, the [`Filter`]'s `impl` split over them:
//! `error`, `options` (settings), `observation` (a period's measurement and
//! innovation), `construct` ([`Filter::new`], [`Filter::restart`]), `parts`
//! (checkpoint and restore), `accessors`, `reacquire` (after a gap),
//! `predict`, `pending` (the deferred time update), `measure` (the
//! measurement model), `update/` (the update variants: extended, iterated,
//! linearised), `whiten` and `factored` (the factored update), `step`;
//! `cache` (the installation matrices), `factor` (the U-D factor),
//! `order` (the order of the states in the factor),
//! `wander` (the errors that wander, moved at the end of each period) and
//! `second_order/` (the analytic Hessian of the accelerometer output).

mod accessors;
mod cache;
mod construct;
mod error;
mod factor;
mod factored;
mod measure;
mod observation;
mod options;
mod order;
mod parts;
mod pending;
mod predict;
mod reacquire;
mod rollback;
mod scratch;
mod second_order;
mod step;
mod update;
mod wander;
mod whiten;

pub use error::Error;
pub use observation::{Innovation, Observation};
pub use options::{
    FilterConfig, Options, DEFAULT_NIS_GATE, GRAVITY_RANGE, MAX_EARTH_RATE, MAX_GATED_RUN,
    RESEARCH_OPTIONS,
};
pub use order::factor_state;
pub use parts::Parts;
pub use second_order::{AccelCovariance, AccelSecondOrder, Elements};

use core::marker::PhantomData;

use nalgebra::{RealField, SMatrix, SVector};

use crate::command::CommandFrame;
use crate::models::{Environment, Layout, Model};
use crate::precision::{to_f64, to_t};
use cache::MatricesCache;
use factor::Ud;
use pending::PendingSlot;
use scratch::Scratch;

/// The estimator of configuration `M` with `N` states and `Z` measurement
/// components per period, its covariance arithmetic in precision `T`.
///
/// **Precision.** The state estimate, the nominal, the computed frame and
/// every evaluation of the measurement model (predicted measurement, the
/// residual `z − h(x)`) are `f64` whatever `T`: the accelerometers resolve
/// 1e-6 g of a 1 g signal and the path turns the frame by 5 400 increments,
/// where f32's rounding (6e-8 per operation) would be a third of the noise
/// and a drift of the computed frame. The covariance factor, the Jacobians
/// and the gains — the `O(N²)` bulk of a period, whose values need only a
/// few digits — are in `T`. So are the linear terms of the small
/// deviations from the linearisation point (`H δ`, `Φ δ`) and the
/// attitude's increments over a period, added to the f64 attitude
/// (≈ 1.7e-3 rad on the paper's path, exact to ≈ 5e-10 rad in f32, three
/// orders under the gyro noise of a period;
/// [`Layout::propagate_into_jacobians_in`](crate::models::Layout::propagate_into_jacobians_in)),
/// and the small parts of the computed frame's period and of the
/// predicted measurement, each formed without the large quantity it is
/// added to in f64
/// ([`CommandFrame::period_in`](crate::command::CommandFrame::period_in),
/// [`Layout::mean_accel_output`](crate::models::Layout::mean_accel_output)).
/// The attitude's rate in `T` keeps the commanded rate out of its small
/// parts and the RK4 sum is divided by 6: in f32 a rounding of the
/// commanded rotation that every period repeats (`G`'s diagonal, 1/6) is a
/// torquer scale factor
/// ([`Layout::attitude_rate`](crate::models::Layout::attitude_rate)).
#[derive(Clone, Debug, PartialEq)]
pub struct Filter<T: RealField + Copy, M, const N: usize, const Z: usize> {
    x: SVector<f64, N>,
    /// The covariance of `x` — at the start of the pending period while a
    /// prediction is pending (its time update is applied with the
    /// measurement, [`Filter::update`]).
    ud: Ud<T, N>,
    command: CommandFrame<f64>,
    config: FilterConfig<T>,
    pending: PendingSlot<T, N>,
    reference: Option<SVector<f64, N>>,
    updates: u32,
    gated_run: u32,
    gate_open: bool,
    /// The installation matrices of the last linearisation point's
    /// parameters (constant over a linearised pass and shared by the
    /// prediction and the update of a period of pass 1).
    matrices: MatricesCache<T>,
    /// `config.env` rounded to `T` (for the Jacobians and the attitude's
    /// increments), rounded once with the configuration, not every period.
    env_t: Environment<T>,
    /// The update's working memory (`scratch`: not state, not compared).
    scratch: Scratch<T, N, Z>,
    _model: PhantomData<M>,
}

/// M1-pa filter (12 states).
pub type M1PaFilter<T> = Filter<T, crate::models::M1Pa, 12, 3>;
/// M1-ps filter (15 states).
pub type M1PsFilter<T> = Filter<T, crate::models::M1Ps, 15, 3>;
/// M2-ps filter (18 states).
pub type M2PsFilter<T> = Filter<T, crate::models::M2Ps, 18, 6>;
/// M3-pa filter (15 states).
pub type M3PaFilter<T> = Filter<T, crate::models::M3Pa, 15, 3>;
/// M3-ps filter (18 states).
pub type M3PsFilter<T> = Filter<T, crate::models::M3Ps, 18, 3>;
/// M4-pa filter (12 states).
pub type M4PaFilter<T> = Filter<T, crate::models::M4Pa, 12, 3>;
/// M4-ps filter (15 states).
pub type M4PsFilter<T> = Filter<T, crate::models::M4Ps, 15, 3>;
/// M1-pa full-model filter (48 states: installation and instrument errors,
/// docs/model.md §Instrument errors; [`crate::models::M1PaFull`]).
pub type M1PaFullFilter<T> = Filter<T, crate::models::M1PaFull, 48, 3>;
/// M1-ps full-model filter (51 states).
pub type M1PsFullFilter<T> = Filter<T, crate::models::M1PsFull, 51, 3>;
/// M2-ps full-model filter (54 states).
pub type M2PsFullFilter<T> = Filter<T, crate::models::M2PsFull, 54, 6>;
/// M3-pa full-model filter (51 states).
pub type M3PaFullFilter<T> = Filter<T, crate::models::M3PaFull, 51, 3>;
/// M3-ps full-model filter (54 states).
pub type M3PsFullFilter<T> = Filter<T, crate::models::M3PsFull, 54, 3>;
/// M4-pa full-model filter (48 states).
pub type M4PaFullFilter<T> = Filter<T, crate::models::M4PaFull, 48, 3>;
/// M4-ps full-model filter (51 states).
pub type M4PsFullFilter<T> = Filter<T, crate::models::M4PsFull, 51, 3>;

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    const LAYOUT: Layout = M::LAYOUT;
    const SIZES_AGREE: () = assert!(M::LAYOUT.n() == N && M::LAYOUT.z() == Z);
    /// The first accelerometer row of the measurement (after the gimbal
    /// angles in M2). A constant, so that the views at it fold at compile
    /// time (a runtime offset keeps nalgebra's bounds assert).
    const ACCEL_ROW: usize = if M::LAYOUT.gimbal_obs { 3 } else { 0 };
    /// The first state whose variance the factor's updates test for zero
    /// (a term the model does not estimate, held): `N` for a layout
    /// without instrument states, whose states all keep `D > 0` (the
    /// tests compiled out), `0` (every state tested) for one with them.
    const HELD_FROM: usize = if M::LAYOUT.instruments().is_some() {
        0
    } else {
        N
    };
}

fn all_finite<T: RealField + Copy>(it: impl IntoIterator<Item = T>) -> bool {
    it.into_iter().all(|v| v.is_finite())
}

/// The environment in precision `T`.
fn env_t<T: RealField + Copy>(e: &Environment<f64>) -> Environment<T> {
    Environment {
        earth_rate_n: to_t(&e.earth_rate_n),
        gravity_n: to_t(&e.gravity_n),
    }
}

/// `H δ` (g, rad; Z components) in precision `T`, returned in f64: the
/// linear term of the innovation (or `Φ δ` of the linearised prediction),
/// `δ` the small offset of the estimate from the linearisation point. `h`
/// is the model's Jacobian, computed in `T`, so the product needs `T`'s
/// digits only: with entries of `h` of order 1, a `δ` of 1e-4 rad (about
/// σ of the weakest parameter, λy of M2-ps, 27″) gives `|H δ|` ≈ 1e-4 g,
/// whose f32 rounding (≈ 1e-11 g) is five orders under the accelerometer
/// noise (1e-6 g). On an FPU without double precision the f64 product is
/// emulated (the M4F's linearised M2-ps period fell by 12 k instructions,
/// BENCHMARKS.md). The same values as `h * delta` for `T = f64`.
fn linear_term<T: RealField + Copy, const N: usize, const Z: usize>(
    h: &SMatrix<T, Z, N>,
    delta: &SVector<f64, N>,
) -> SVector<f64, Z> {
    to_f64(&(h * to_t::<T, N, 1>(delta)))
}
