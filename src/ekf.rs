//! The extended Kalman filter over any configuration (docs/model.md §Estimator).
//!
//! One filter period: [`Filter::predict`] propagates the state by one RK4
//! step over the commanded motion of the period; [`Filter::update`] then
//! processes the period's measurement (the mean accelerometer output over
//! the period and, in M2, the gimbal angles at its end) together with the
//! covariance's time update. The covariance is kept as a U-D factor
//! ([`crate::factor`]): Bierman's scalar updates of the decorrelated,
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
//! bound. Measurements of every remedy: README, "The estimator, and the cold
//! start" (`host-sim remedies`).
//!
//! **Correlated noise.** The gyro noise of a period moves the attitude
//! during the same period whose mean the accelerometers report, so it is
//! both process and measurement noise; the factored update decorrelates
//! the two ([`Filter::update`]).

use core::any::Any;
use core::marker::PhantomData;

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector3};

use crate::command::{CommandFrame, Period, PeriodIn};
use crate::factor::{AttitudeNoise, Ud};
use crate::geometry::wrap_angle;
use crate::models::{
    Environment, Installation, InstallationMatrices, Layout, Model, PeriodPropagation, ATT,
};
use crate::precision::{scalar_to_f64, to_f64, to_t};
use crate::second_order::AccelCovariance;

/// Errors of the estimator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// An input (increment, period, measurement, option) is NaN or infinite.
    NonFiniteInput,
    /// The period is not strictly positive.
    InvalidPeriod,
    /// The configuration observes gimbal angles but none were given.
    MissingGimbal,
    /// The Euler-angle attitude reached gimbal lock (`β = ±90°`).
    GimbalLock,
    /// The innovation covariance `S` is not positive definite.
    InnovationNotPositiveDefinite,
    /// The state covariance `P` lost positive definiteness.
    CovarianceNotPositiveDefinite,
    /// The propagated or updated state is not finite.
    NonFiniteState,
    /// The innovation failed the NIS gate; the state was left untouched.
    Gated,
    /// `update` was called without a preceding `predict`.
    NoPrediction,
    /// The options ask for a branch this build leaves out: the second-order
    /// dynamics or the iterated update without the cargo feature
    /// `research-options` (a lean firmware image; [`Options::is_built`]).
    UnsupportedOption,
}

impl core::fmt::Display for Error {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Error::NonFiniteInput => "input is not finite",
            Error::InvalidPeriod => "period is not strictly positive",
            Error::MissingGimbal => "configuration observes gimbal angles but none were given",
            Error::GimbalLock => "attitude reached gimbal lock (beta = +-90 deg)",
            Error::InnovationNotPositiveDefinite => {
                "innovation covariance is not positive definite"
            }
            Error::CovarianceNotPositiveDefinite => "state covariance is not positive definite",
            Error::NonFiniteState => "state is not finite",
            Error::Gated => "innovation rejected by the NIS gate",
            Error::NoPrediction => "update without a preceding predict",
            Error::UnsupportedOption => {
                "option not in this build (second-order dynamics or iterated update: cargo feature research-options)"
            }
        })
    }
}

impl core::error::Error for Error {}

/// Cold-start remedies and gating.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Options {
    /// Add the second-order terms of the accelerometer measurement to the
    /// innovation covariance (the chosen cold-start remedy).
    pub second_order_covariance: bool,
    /// Add the second-order mean `½ tr(∇²h_a P)` to the predicted measurement.
    pub second_order_mean: bool,
    /// Add the second-order terms of the attitude dynamics to the process noise.
    pub second_order_dynamics: bool,
    /// Iterated-EKF relinearisations per update (0 = plain EKF).
    pub iterations: u8,
    /// Iterate only the first this many updates.
    pub iterate_updates: u32,
    /// Reject an update whose NIS exceeds this value (0 = no gate): the
    /// period is then predicted only. The default, [`DEFAULT_NIS_GATE`],
    /// refuses fewer than 1e-4 of clean updates of any configuration.
    pub nis_gate: f64,
}

/// After this many consecutive gated updates the next one is accepted
/// whatever its NIS. Outliers come alone, while a run of large innovations
/// means the estimate itself is off (pass 1 from a cold start can be
/// overconfident where the path turns onto a new axis, with NIS in the
/// hundreds for tens of periods): gating them all would lock the filter out
/// of its own correction. Once an update above the gate has been accepted,
/// the gate stays open until an update falls below it again, so such a
/// stretch costs at most this many samples.
pub const MAX_GATED_RUN: u32 = 2;

/// The default NIS gate: 30. A clean update's NIS is χ² with `Z` degrees of
/// freedom (3 or 6), which exceeds 30 with probability 1.4e-6 (Z = 3) or
/// 3.9e-5 (Z = 6); a 100σ accelerometer outlier has a NIS near 1e4.
pub const DEFAULT_NIS_GATE: f64 = 30.0;

impl Default for Options {
    fn default() -> Self {
        Self {
            second_order_covariance: true,
            second_order_mean: false,
            second_order_dynamics: false,
            iterations: 0,
            iterate_updates: 0,
            nis_gate: DEFAULT_NIS_GATE,
        }
    }
}

/// Whether this build holds the research options (the cargo feature
/// `research-options`, on by default): the second-order dynamics and the
/// iterated update. Without it their code is left out of the image and a
/// filter that asks for them is refused ([`Error::UnsupportedOption`]).
pub const RESEARCH_OPTIONS: bool = cfg!(feature = "research-options");

impl Options {
    /// Whether this build can run these options ([`RESEARCH_OPTIONS`]):
    /// the defaults, the plain EKF and the second-order mean always; the
    /// second-order dynamics and the iterated update only with the cargo
    /// feature `research-options`.
    pub const fn is_built(&self) -> bool {
        RESEARCH_OPTIONS
            || !(self.second_order_dynamics || (self.iterations > 0 && self.iterate_updates > 0))
    }

    /// A plain EKF (no cold-start remedy), for comparison.
    pub const fn plain() -> Self {
        Self {
            second_order_covariance: false,
            second_order_mean: false,
            second_order_dynamics: false,
            iterations: 0,
            iterate_updates: 0,
            nis_gate: 0.0,
        }
    }
}

/// Noise levels and environment of a filter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterConfig<T: RealField + Copy> {
    /// Earth rate and gravity, in double precision whatever `T` (they drive
    /// the nominal trajectory, see [`Filter`]).
    pub env: Environment<f64>,
    /// Accelerometer noise of the period mean, 1σ per axis (g).
    pub sigma_accel: T,
    /// Gyro white rate noise, constant over a period, 1σ per axis (rad/s).
    pub sigma_gyro: T,
    /// Gimbal-angle noise, 1σ per angle (rad).
    pub sigma_gimbal: T,
    /// Cold-start remedy and gate.
    pub options: Options,
}

impl FilterConfig<f64> {
    /// The same settings for a filter of precision `T`: the noise levels
    /// in `T`, the environment (always f64) and the options as they are.
    pub fn to_precision<T: RealField + Copy>(&self) -> FilterConfig<T> {
        FilterConfig {
            env: self.env,
            sigma_accel: nalgebra::convert(self.sigma_accel),
            sigma_gyro: nalgebra::convert(self.sigma_gyro),
            sigma_gimbal: nalgebra::convert(self.sigma_gimbal),
            options: self.options,
        }
    }
}

/// The measurement of one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation<T: RealField + Copy> {
    /// Mean accelerometer output over the period (g, instrument axes).
    pub accel_mean: Vector3<T>,
    /// Gimbal angles `(α, β, γ)` at the end of the period (rad); required by M2.
    pub gimbal: Option<Vector3<T>>,
}

/// Innovation of one update.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Innovation<T: RealField + Copy, const Z: usize> {
    /// `ν = z − h(x̂)`, gimbal components wrapped into (−π, π] (rad; g).
    pub nu: SVector<T, Z>,
    /// Its covariance `S` (including the second-order terms when enabled).
    pub s: SMatrix<T, Z, Z>,
    /// Normalised innovation squared `νᵀ S⁻¹ ν`.
    pub nis: T,
}

/// The period's gyro noise as both process and measurement noise: with unit
/// noise `u` (3), `x_{k+1} = f(x_k) + G u` and `z = h(x_{k+1}) + D u + v`.
/// The mean accelerometer output of a period sees the noise of that same
/// period (≈ half of it, `D ≈ −½ H G`), so the two are correlated:
/// `C = G Dᵀ` enters the update (decorrelated there).
struct Noise<T: RealField + Copy, const N: usize, const Z: usize> {
    g: SMatrix<T, N, 3>,
    d: SMatrix<T, Z, 3>,
}

struct Measured<T: RealField + Copy, const N: usize, const Z: usize> {
    /// The predicted measurement (f64: it must resolve 1e-7 g of 1 g).
    z: SVector<f64, Z>,
    /// Its Jacobian, in the filter's precision (where it was computed).
    h: SMatrix<T, Z, N>,
    noise: Noise<T, N, Z>,
}

impl<T: RealField + Copy, const N: usize, const Z: usize> Measured<T, N, Z> {
    fn zeros() -> Self {
        Self {
            z: SVector::zeros(),
            h: SMatrix::zeros(),
            noise: Noise {
                g: SMatrix::zeros(),
                d: SMatrix::zeros(),
            },
        }
    }
}

/// The factored update's inputs ([`Filter::whiten`]), all formed and
/// checked before the factor is touched ([`Filter::apply_whitened`]).
/// The whitened rows `L⁻¹ H Φ` (`L = chol(R_e)`) take the place of the
/// measurement's `H`.
struct Whitened<T: RealField + Copy, const N: usize, const Z: usize> {
    /// The whitened innovation `L⁻¹ ν`.
    nu_w: SVector<T, Z>,
    /// The decorrelation gain times `L`, `J L` (attitude rows).
    j_l: SMatrix<T, 3, Z>,
    /// The decorrelated transition `Φ − J H Φ` (attitude rows).
    phi_dec: SMatrix<T, 3, N>,
    /// The decorrelated process noise `G Gᵀ − J R_e Jᵀ` (rad²), factored.
    q: AttitudeNoise<T>,
    /// `ν` and `S` as reported (`nis` is the update's).
    innovation: Innovation<T, Z>,
}

impl<T: RealField + Copy, const N: usize, const Z: usize> Whitened<T, N, Z> {
    fn zeros() -> Self {
        Self {
            nu_w: SVector::zeros(),
            j_l: SMatrix::zeros(),
            phi_dec: SMatrix::zeros(),
            q: AttitudeNoise::zero(),
            innovation: Innovation {
                nu: SVector::zeros(),
                s: SMatrix::zeros(),
                nis: T::zero(),
            },
        }
    }
}

/// The NIS gate's verdict on an update ([`Filter::whiten`]).
enum Gate {
    /// The update goes ahead.
    Pass,
    /// Refused: the period gets its time update only.
    Refuse,
}

/// One Kalman gain with correlated noise, dense (the iterated filter's
/// intermediate relinearisation points only).
struct Gain<T: RealField + Copy, const N: usize, const Z: usize> {
    k: SMatrix<T, N, Z>,
}

/// A period the state has been propagated over whose covariance time
/// update is still to be applied (with the period's measurement, or alone).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pending<T: RealField + Copy, const N: usize> {
    period: Period<f64>,
    /// The same period in `T` (each value rounded once,
    /// [`CommandFrame::period_in_into`](crate::command::CommandFrame::period_in_into)):
    /// what the Jacobians and the attitude's increments read, and the
    /// frame's turn within it (M1's specific force).
    period_t: PeriodIn<T>,
    /// The attitude at the period's three nodes (rad).
    att: [Vector3<f64>; 3],
    /// The same nodes rounded to `T`, with the period's transition rows,
    /// `F` and noise map, computed in `T`.
    prop: PeriodPropagation<T, N>,
    /// Second-order process noise of the attitude (rad², zero unless
    /// [`Options::second_order_dynamics`]).
    q_extra: Matrix3<T>,
}

impl<T: RealField + Copy, const N: usize> Pending<T, N> {
    /// An all-zero period (the content of an empty slot).
    fn zeros() -> Self {
        Self {
            period: Period::zeros(),
            period_t: PeriodIn::zeros(),
            att: [Vector3::zeros(); 3],
            prop: PeriodPropagation::zeros(),
            q_extra: Matrix3::zeros(),
        }
    }
}

/// The filter's storage of the pending period. It stays in place from
/// period to period ([`Filter::predict`] propagates straight into it: no
/// copy of the ≈ 1.8 KB period on the hot path); `valid` says whether it
/// holds one. Two slots compare equal when neither holds a period or both
/// hold equal ones.
#[derive(Clone, Copy, Debug)]
struct PendingSlot<T: RealField + Copy, const N: usize> {
    value: Pending<T, N>,
    valid: bool,
}

impl<T: RealField + Copy, const N: usize> PartialEq for PendingSlot<T, N> {
    fn eq(&self, other: &Self) -> bool {
        self.get() == other.get()
    }
}

impl<T: RealField + Copy, const N: usize> PendingSlot<T, N> {
    fn empty() -> Self {
        Self {
            value: Pending::zeros(),
            valid: false,
        }
    }

    /// The pending period, if any.
    fn get(&self) -> Option<&Pending<T, N>> {
        self.valid.then_some(&self.value)
    }

    /// No period pending (the storage is kept).
    fn clear(&mut self) {
        self.valid = false;
    }
}

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
    _model: PhantomData<M>,
}

/// The parts of a filter between two periods, as a checkpoint saves them
/// ([`Filter::set_parts`], [`Filter::from_parts`]).
#[derive(Clone, Copy, Debug)]
pub struct Parts<'a, const N: usize> {
    /// State (rad; the configuration's state order).
    pub x: &'a SVector<f64, N>,
    /// The packed U-D factor of the covariance (rad², [`Filter::factor`]),
    /// its `N·N` entries row by row in f64 (rounded to `T`); the part below
    /// the diagonal is ignored.
    pub factor: &'a [f64],
    /// The computed frame `C^c_n` at the start of the next period.
    pub c_cn: &'a Matrix3<f64>,
    /// The nominal of the linearised mode (rad), `None` for the extended
    /// filter.
    pub nominal: Option<&'a SVector<f64, N>>,
    /// Updates applied so far.
    pub updates: u32,
    /// The NIS gate's state ([`Filter::gate_state`]).
    pub gate_state: (u32, bool),
}

/// The installation matrices of one parameter value as the filter uses
/// them: all of them in `T` (the Jacobians' and the attitude increments',
/// and for `T = f64` everything's; computed in `T` from the parameters
/// rounded to `T`), `A` and `C^r_n` in f64 (the single-precision filter's
/// f64 value of the mean specific force, [`Layout::mean_accel_output`]).
/// Computed once per parameter value, not once per use (on the M4F the
/// linearised period fell by 11 k instructions); in `T`, not rounded from
/// f64, so that pass 1, whose parameters move every period, emulates no
/// f64 trigonometry and rounding it does not need (the M4F's pass-1
/// period fell from 79 k to 60 k instructions for M1-pa, 166 k to 144 k
/// for M2-ps).
///
/// As the filter's cache, a pure function of the parameters it holds: not
/// part of the filter's value (every cache equals every other, so two
/// filters with equal state, factor and history compare equal whatever they
/// last evaluated).
#[derive(Copy, Debug)]
struct MatricesCache<T: RealField + Copy> {
    /// The parameters (rad) they are the matrices of.
    params: Installation<f64>,
    /// `A` in f64.
    a: Matrix3<f64>,
    /// `C^r_n` in f64.
    c_rn: Matrix3<f64>,
    /// The matrices in `T`.
    m: InstallationMatrices<T>,
}

// A copy (the derived `Clone` of a generic struct clones field by field, and
// the filter's `clone` then went through an out-of-line copy with a 4.4 KB
// frame on the M7).
impl<T: RealField + Copy> Clone for MatricesCache<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T: RealField + Copy> PartialEq for MatricesCache<T> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl<T: RealField + Copy> MatricesCache<T> {
    /// The matrices of `params` (rad) as the filter uses them, the same
    /// as [`MatricesCache::fill`] makes them. Out of line: the matrices'
    /// temporaries are not in the frame of the caller, which builds a
    /// calibrator in place (firmware stack).
    #[inline(never)]
    fn new(params: Installation<f64>) -> Self {
        let (a, c_rn) = InstallationMatrices::accel_and_base(&params);
        Self {
            params,
            a,
            c_rn,
            m: Self::in_t(&params),
        }
    }

    /// The matrices in `T` of `params` (rad): computed in `T` from the
    /// parameters rounded to `T` (the Jacobians' and the attitude
    /// increments' few digits; for `T = f64`, `InstallationMatrices::new`
    /// of `params` itself).
    fn in_t(params: &Installation<f64>) -> InstallationMatrices<T> {
        InstallationMatrices::new(Installation {
            theta_g_c: to_t(&params.theta_g_c),
            theta_g_t: to_t(&params.theta_g_t),
            theta_a_c: to_t(&params.theta_a_c),
            theta_a_t: to_t(&params.theta_a_t),
            lambda: to_t(&params.lambda),
        })
    }

    /// Makes the cache hold the matrices of the parameters of `x`. The
    /// parameters are compared bit for bit (a `−0` for a `0` recomputes the
    /// same matrices; a NaN keeps the NaN matrices it gave): integer
    /// comparisons, where an f64 comparison is a library call on an FPU
    /// without double precision.
    fn refresh<const N: usize>(&mut self, layout: &Layout, x: &SVector<f64, N>) {
        let params = layout.installation(x);
        let bits = |p: &Installation<f64>| {
            [p.theta_g_c, p.theta_g_t, p.theta_a_c, p.theta_a_t, p.lambda]
                .map(|v| v.map(f64::to_bits))
        };
        if bits(&params) != bits(&self.params) {
            self.fill(params);
        }
    }

    /// Makes the cache hold the matrices of `params` (rad), in place: the
    /// f64 filter's are built straight into their slot. Out of line: the
    /// matrices' temporaries are in no frame of the filter's step.
    #[inline(never)]
    fn fill(&mut self, params: Installation<f64>) {
        if let Some(m) = (&mut self.m as &mut dyn Any).downcast_mut::<InstallationMatrices<f64>>() {
            *m = InstallationMatrices::new(params);
            (self.a, self.c_rn) = (m.a, m.c_rn);
        } else {
            self.m = Self::in_t(&params);
            (self.a, self.c_rn) = InstallationMatrices::accel_and_base(&params);
        }
        self.params = params;
    }

    /// The matrices in f64 when `T` is f64.
    fn as_f64(&self) -> Option<&InstallationMatrices<f64>> {
        (&self.m as &dyn Any).downcast_ref()
    }
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

/// `(½ tr(∇²g_a P), ½ tr(∇²g_a P ∇²g_b P))` of a 3-vector function `g`
/// whose Jacobian is `jac`, by central differences of `jac` along the
/// error-state directions `j` with `relevant(j)`. Used for the attitude
/// dynamics (`Options::second_order_dynamics`, off by default), and as the
/// reference the analytic accelerometer Hessian is tested against.
pub(crate) fn hessian_terms<T: RealField + Copy, const N: usize>(
    x: &SVector<T, N>,
    p: &SMatrix<T, N, N>,
    relevant: impl Fn(usize) -> bool,
    jac: impl Fn(&SVector<T, N>) -> Option<SMatrix<T, 3, N>>,
) -> Option<(Vector3<T>, Matrix3<T>)> {
    let delta: T = nalgebra::convert(1e-5);
    let two: T = nalgebra::convert(2.0);
    let half: T = nalgebra::convert(0.5);
    let mut hess = [SMatrix::<T, N, N>::zeros(); 3];
    for j in (0..N).filter(|&j| relevant(j)) {
        let mut e = SVector::<T, N>::zeros();
        if let Some(v) = e.get_mut(j) {
            *v = delta;
        }
        let d = (jac(&(x + e))? - jac(&(x - e))?) / (two * delta);
        for (a, hs) in hess.iter_mut().enumerate() {
            if let (Some(mut col), Some(row)) = (hs.column_iter_mut().nth(j), d.row_iter().nth(a)) {
                col.copy_from(&row.transpose());
            }
        }
    }
    let mut mean = Vector3::zeros();
    let mut cov = Matrix3::zeros();
    let mut hp = [SMatrix::<T, N, N>::zeros(); 3];
    for (a, hs) in hess.iter_mut().enumerate() {
        *hs = (*hs + hs.transpose()) * half;
        if let (Some(dst), Some(m)) = (hp.get_mut(a), mean.get_mut(a)) {
            *dst = *hs * p;
            *m = dst.trace() * half;
        }
    }
    for a in 0..3 {
        for b in a..3 {
            if let (Some(ha), Some(hb)) = (hp.get(a), hp.get(b)) {
                // tr(A B) = Σ_ij A_ij B_ji
                let t = ha.component_mul(&hb.transpose()).sum() * half;
                if let Some(v) = cov.get_mut((a, b)) {
                    *v = t;
                }
                if let Some(v) = cov.get_mut((b, a)) {
                    *v = t;
                }
            }
        }
    }
    Some((mean, cov))
}

fn all_finite<T: RealField + Copy>(it: impl IntoIterator<Item = T>) -> bool {
    it.into_iter().all(|v| v.is_finite())
}

/// A period's trajectory and transition in precision `T`.
fn propagation_t<T: RealField + Copy, const N: usize>(
    p: &PeriodPropagation<f64, N>,
) -> PeriodPropagation<T, N> {
    let [a0, am, a1] = p.att;
    PeriodPropagation {
        att: [to_t(&a0), to_t(&am), to_t(&a1)],
        phi_att: to_t(&p.phi_att),
        f_mid: to_t(&p.f_mid),
        f_end: to_t(&p.f_end),
        noise_map: to_t(&p.noise_map),
    }
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

/// `L⁻¹ B` in place of `B` for the lower triangle of `l` (its upper
/// triangle is not read: a Cholesky factor's `l_dirty`). The operations of
/// nalgebra's `solve_lower_triangular_mut`, in the same order (each column:
/// `b_i ← b_i / L_ii`, then `b_k ← b_k − b_i L_ki` below it), so the same
/// bits, without its per-column views: at fixed sizes it unrolls (the M4F's
/// whitening of the `Z × N` rows). `false` (and `b` untouched) if a diagonal
/// element is zero.
fn solve_lower<T: RealField + Copy, const Z: usize, const C: usize>(
    l: &SMatrix<T, Z, Z>,
    b: &mut SMatrix<T, Z, C>,
) -> bool {
    let l = &l.data.0; // l[col][row]
    let diagonal = |(i, l_i): (usize, &[T; Z])| l_i.get(i).copied();
    if !l
        .iter()
        .enumerate()
        .all(|c| diagonal(c).is_some_and(|d| !d.is_zero()))
    {
        return false;
    }
    for col in b.data.0.iter_mut() {
        for (i, l_i) in l.iter().enumerate() {
            let (Some(d), Some((b_i, below))) = (
                diagonal((i, l_i)),
                col.get_mut(i..).and_then(|rest| rest.split_first_mut()),
            ) else {
                continue;
            };
            let coeff = *b_i / d;
            *b_i = coeff;
            for (b_k, l_ki) in below.iter_mut().zip(l_i.iter().skip(i + 1)) {
                *b_k -= coeff * *l_ki;
            }
        }
    }
    true
}

/// The dense gain with measurement noise `R_v + D Dᵀ` correlated with the
/// process noise by `C = G Dᵀ`: `S = H P Hᵀ + H C + Cᵀ Hᵀ + R_eff`,
/// `K = (P Hᵀ + C) S⁻¹`, for the predicted covariance `p`.
fn dense_gain<T: RealField + Copy, const N: usize, const Z: usize>(
    p: &SMatrix<T, N, N>,
    h: &SMatrix<T, Z, N>,
    r: &SMatrix<T, Z, Z>,
    noise: &Noise<T, N, Z>,
) -> Result<Gain<T, N, Z>, Error> {
    let c = noise.g * noise.d.transpose();
    let r_eff = r + noise.d * noise.d.transpose();
    let ph = p * h.transpose() + c;
    let mut s = h * ph + h * c + r_eff;
    s = (s + s.transpose()) * nalgebra::convert::<f64, T>(0.5);
    let chol = s.cholesky().ok_or(Error::InnovationNotPositiveDefinite)?;
    let k = chol.solve(&ph.transpose()).transpose();
    Ok(Gain { k })
}

/// The covariance at the end of a filter's pending period, read by pass 1's
/// second-order terms ([`Filter::second_order`]).
struct PredictedCovariance<'a, T: RealField + Copy, M, const N: usize, const Z: usize> {
    filter: &'a Filter<T, M, N, Z>,
    pending: &'a Pending<T, N>,
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> AccelCovariance<T>
    for PredictedCovariance<'_, T, M, N, Z>
{
    /// Element by element from the factor: no `N×N` matrix, and no copy of
    /// the factor (the time update changes only its first three rows). Out
    /// of line: those rows are in this frame, which has returned before the
    /// Hessians are formed (firmware stack).
    #[inline(never)]
    fn fill<const R: usize>(&self, layout: &Layout, p_r: &mut SMatrix<T, R, R>) {
        let (f, pending) = (self.filter, self.pending);
        let rows = f
            .process_noise(pending)
            .and_then(|q| f.ud.predicted_attitude_rows(&pending.prop.phi_att, &q));
        layout.accel_covariance(
            |i, j| match &rows {
                Some(rows) => f.ud.covariance_entry_with_rows(rows, i, j),
                // As `settled` (the unpropagated factor; predict checks it).
                None => f.ud.covariance_entry(i, j),
            },
            p_r,
        );
    }
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    const LAYOUT: Layout = M::LAYOUT;
    const SIZES_AGREE: () = assert!(M::LAYOUT.n() == N && M::LAYOUT.z() == Z);
    /// The first accelerometer row of the measurement (after the gimbal
    /// angles in M2). A constant, so that the views at it fold at compile
    /// time (a runtime offset keeps nalgebra's bounds assert).
    const ACCEL_ROW: usize = if M::LAYOUT.gimbal_obs { 3 } else { 0 };

    /// A filter with initial estimate `x0` (rad) and prior standard
    /// deviations `sigma0` (rad), the computed frame aligned with n.
    // Not inlined: a caller that holds its filter in its own frame (the
    // firmware's synthetic run) then holds one `Result`, not the
    // constructor's temporaries too.
    #[inline(never)]
    pub fn new(
        config: FilterConfig<T>,
        x0: SVector<f64, N>,
        sigma0: SVector<T, N>,
    ) -> Result<Self, Error> {
        let variance = Self::prior_variance(&config, &x0, &sigma0)?;
        Ok(Self::with_prior_variance(config, x0, &variance))
    }

    /// [`Filter::new`] from the prior variances `variance` that
    /// [`Filter::prior_variance`] returned for `config`, `x0`: it cannot
    /// fail, so a caller can build the filter straight into its place (the
    /// session's calibrator slot) instead of out of a `Result`.
    #[inline(always)]
    pub(crate) fn with_prior_variance(
        config: FilterConfig<T>,
        x0: SVector<f64, N>,
        variance: &SVector<T, N>,
    ) -> Self {
        Self {
            x: x0,
            ud: Ud::diagonal(variance),
            command: CommandFrame::aligned(config.env.earth_rate_n),
            config,
            pending: PendingSlot::empty(),
            reference: None,
            updates: 0,
            gated_run: 0,
            gate_open: false,
            matrices: MatricesCache::new(Self::LAYOUT.installation(&x0)),
            env_t: env_t(&config.env),
            _model: PhantomData,
        }
    }

    /// Makes this filter equal to `Filter::new(config, x0, sigma0)`, in
    /// place (no filter-sized temporary: the estimator's passes restart one
    /// filter, [`crate::estimator::estimate_in`]). On error the filter is
    /// unchanged.
    // Not inlined: once per pass, and its code once per configuration.
    #[inline(never)]
    pub fn restart(
        &mut self,
        config: FilterConfig<T>,
        x0: SVector<f64, N>,
        sigma0: SVector<T, N>,
    ) -> Result<(), Error> {
        let variance = Self::prior_variance(&config, &x0, &sigma0)?;
        if !self.ud.set_diagonal(&variance) {
            return Err(Error::NonFiniteInput);
        }
        self.x = x0;
        self.command = CommandFrame::aligned(config.env.earth_rate_n);
        self.env_t = env_t(&config.env);
        self.config = config;
        self.pending.clear();
        self.reference = None;
        self.updates = 0;
        self.gated_run = 0;
        self.gate_open = false;
        self.matrices.fill(Self::LAYOUT.installation(&x0));
        Ok(())
    }

    /// The prior variances `σ0²` (rad²) of [`Filter::new`] after its
    /// checks of the inputs.
    pub(crate) fn prior_variance(
        config: &FilterConfig<T>,
        x0: &SVector<f64, N>,
        sigma0: &SVector<T, N>,
    ) -> Result<SVector<T, N>, Error> {
        #[allow(clippy::let_unit_value)]
        let () = Self::SIZES_AGREE;
        let inputs = [config.sigma_accel, config.sigma_gyro, config.sigma_gimbal];
        if !all_finite(sigma0.iter().copied().chain(inputs))
            || !all_finite(x0.iter().copied())
            || !all_finite(
                config
                    .env
                    .earth_rate_n
                    .iter()
                    .chain(config.env.gravity_n.iter())
                    .copied(),
            )
            || !config.options.nis_gate.is_finite()
        {
            return Err(Error::NonFiniteInput);
        }
        if !config.options.is_built() {
            return Err(Error::UnsupportedOption);
        }
        if sigma0.iter().any(|s| *s <= T::zero()) || config.sigma_accel <= T::zero() {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        // A finite prior σ whose variance overflows (σ > 1.3e154 in f64,
        // 1.8e19 in f32) would give an infinite covariance, from which no
        // checkpoint of the filter could be restored (`from_parts`).
        let variance = sigma0.component_mul(sigma0);
        // (Also one that underflows to zero: no factor has a zero variance.)
        if !all_finite(variance.iter().copied()) || variance.iter().any(|v| *v <= T::zero()) {
            return Err(Error::NonFiniteInput);
        }
        if Self::LAYOUT.gimbal_obs && config.sigma_gimbal <= T::zero() {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        Ok(variance)
    }

    /// Rebuilds a filter between two periods from its parts, as saved by a
    /// checkpoint ([`crate::calibrator::Calibrator::checkpoint`]): state `x`
    /// (rad), the packed U-D factor of its covariance ([`Filter::factor`],
    /// rad², used as given, so a restored filter continues
    /// bit-identically), computed frame `c_cn` (`C^c_n`), nominal
    /// of the linearised mode, the update counter and the state of the NIS
    /// gate ([`Filter::gate_state`]). The Earth rate of the computed frame is
    /// the one of `config`.
    pub fn from_parts(
        config: FilterConfig<T>,
        x: SVector<f64, N>,
        factor: SMatrix<T, N, N>,
        c_cn: Matrix3<f64>,
        nominal: Option<SVector<f64, N>>,
        updates: u32,
        gate_state: (u32, bool),
    ) -> Result<Self, Error> {
        let mut f = Self::new(config, SVector::zeros(), SVector::repeat(T::one()))?;
        // Exact: every T of the filter is an f64.
        let rows: SMatrix<f64, N, N> = to_f64(&factor.transpose());
        let parts = Parts {
            x: &x,
            factor: rows.as_slice(),
            c_cn: &c_cn,
            nominal: nominal.as_ref(),
            updates,
            gate_state,
        };
        f.set_parts(config, &parts)?;
        Ok(f)
    }

    /// [`Filter::from_parts`] in place, with the factor as its `N·N`
    /// entries in row-major order in f64 (a checkpoint's layout, read where
    /// it is: no `N×N` temporary). Every part is checked before the filter
    /// is touched: on error it is unchanged ([`Error::NonFiniteInput`] also
    /// for a factor that has not `N·N` entries).
    pub fn set_parts(
        &mut self,
        config: FilterConfig<T>,
        parts: &Parts<'_, N>,
    ) -> Result<(), Error> {
        Self::prior_variance(&config, &SVector::zeros(), &SVector::repeat(T::one()))?;
        let nominal_values = parts.nominal.iter().flat_map(|v| v.iter().copied());
        if !all_finite(
            parts
                .x
                .iter()
                .chain(parts.c_cn.iter())
                .copied()
                .chain(nominal_values),
        ) || parts.factor.len() != N * N
            // Finite in T, not only in f64 (an f32 overflow is non-finite).
            || !parts
                .factor
                .iter()
                .all(|v| nalgebra::convert::<f64, T>(*v).is_finite())
        {
            return Err(Error::NonFiniteInput);
        }
        if !self.ud.set_packed_rows(parts.factor) {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        self.x = *parts.x;
        self.command = CommandFrame::aligned(config.env.earth_rate_n);
        self.command.c_cn = *parts.c_cn;
        self.env_t = env_t(&config.env);
        self.config = config;
        self.pending.clear();
        self.reference = parts.nominal.copied();
        self.updates = parts.updates;
        (self.gated_run, self.gate_open) = parts.gate_state;
        self.matrices
            .fill(Self::LAYOUT.installation(&SVector::<f64, N>::zeros()));
        Ok(())
    }

    /// Switches to a linearised Kalman filter about a nominal trajectory
    /// that starts at `x_nominal` (the state at the current time) and follows
    /// the model's own dynamics; `None` returns to the extended filter.
    ///
    /// Jacobians are then evaluated on the nominal trajectory and the
    /// innovation is `z − h(x_nom) − H (x̂ − x_nom)`. This is each later pass
    /// of the multi-pass estimator (the nominal is the previous pass's estimate
    /// propagated back to the start), and, with the true initial state as
    /// nominal, the Riccati recursion of the posterior Cramér–Rao bound.
    pub fn set_nominal(&mut self, x_nominal: Option<SVector<f64, N>>) {
        self.reference = x_nominal;
    }

    /// Re-acquires the attitude after a gap across which the commanded
    /// motion is not known: the computed frame is set to `c_cn` (`C^c_n` at
    /// the start of the next period), and the attitude states' covariance
    /// is re-opened to `sigma` (rad) on each of them with no correlation to
    /// the parameters, whose covariance (their information) is kept. The
    /// attitude estimate is left as it is (the caller predicts it across the
    /// gap). In linearised mode the nominal's attitude follows the estimate,
    /// so the nominal stays a trajectory of the model.
    ///
    /// # Errors
    /// [`Error::NonFiniteInput`] or [`Error::CovarianceNotPositiveDefinite`]
    /// for a non-finite frame or a `sigma` that is not strictly positive; the
    /// filter is then left untouched.
    pub fn reacquire_attitude(&mut self, c_cn: &Matrix3<f64>, sigma: T) -> Result<(), Error> {
        if !all_finite(c_cn.iter().copied()) || !sigma.is_finite() {
            return Err(Error::NonFiniteInput);
        }
        if sigma <= T::zero() {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        // The pending time update moves only the attitude block, which this
        // replaces: it needs no applying.
        self.ud.reset_attitude(sigma * sigma);
        self.command.c_cn = *c_cn;
        if let Some(nominal) = self.reference.as_mut() {
            let att = Self::LAYOUT.attitude(&self.x);
            nominal.fixed_rows_mut::<3>(ATT).copy_from(&att);
        }
        self.pending.clear();
        Ok(())
    }

    /// The nominal state at the current time, in linearised mode.
    pub fn nominal(&self) -> Option<&SVector<f64, N>> {
        self.reference.as_ref()
    }

    /// The state estimate (rad), in the configuration's state order; held
    /// in double precision whatever `T` (see [`Filter`]).
    pub fn state(&self) -> &SVector<f64, N> {
        &self.x
    }

    /// The state covariance `P = U D Uᵀ` (rad²) of [`Filter::state`].
    pub fn covariance(&self) -> SMatrix<T, N, N> {
        match self.pending.get() {
            Some(_) => self.settled().covariance(),
            None => self.ud.covariance(),
        }
    }

    /// Per-state standard deviations `√P_ii` (rad).
    pub fn sigma(&self) -> SVector<T, N> {
        // With a period pending, those of `settled()`, from its new
        // attitude rows (no copy of the factor).
        let rows = self.pending.get().and_then(|p| {
            self.process_noise(p)
                .and_then(|q| self.ud.predicted_attitude_rows(&p.prop.phi_att, &q))
        });
        let variances = match rows {
            Some(rows) => self.ud.variances_with_rows(&rows),
            None => self.ud.variances(),
        };
        variances.map(|v| v.max(T::zero()).sqrt())
    }

    /// The packed U-D factor of the covariance (rad²; `D` on the diagonal,
    /// `U` strictly above, see [`crate::factor`]), as checkpoints carry it.
    /// Between [`Filter::predict`] and [`Filter::update`] it is the factor at
    /// the start of the pending period.
    pub fn factor(&self) -> &SMatrix<T, N, N> {
        self.ud.packed()
    }

    /// The factor with any pending time update applied (the unpropagated
    /// one in the impossible case that it fails: predict checks it).
    fn settled(&self) -> Ud<T, N> {
        self.propagated_factor().unwrap_or(self.ud)
    }

    /// The process noise of a pending period on the attitude (rad²): the
    /// gyro noise's map `B Bᵀ` as it is, factored only with second-order
    /// dynamics' `Q_extra` added. `None` if it is not finite (or, with
    /// `Q_extra`, not positive semi-definite).
    fn process_noise(&self, pending: &Pending<T, N>) -> Option<AttitudeNoise<T>> {
        let b = pending.prop.noise_map
            * (self.config.sigma_gyro * nalgebra::convert::<f64, T>(pending.period.dt));
        if pending.q_extra.iter().all(|v| *v == T::zero()) {
            AttitudeNoise::from_map(&b)
        } else {
            AttitudeNoise::from_covariance(&(b * b.transpose() + pending.q_extra))
        }
    }

    /// Applies the pending period's time update without a measurement, in
    /// place (the pending period stays recorded; callers clear it). On error
    /// the factor is untouched.
    fn settle(&mut self) -> Result<(), Error> {
        if let Some(pending) = self.pending.get() {
            let q = self
                .process_noise(pending)
                .ok_or(Error::CovarianceNotPositiveDefinite)?;
            self.ud
                .predict_attitude(&pending.prop.phi_att, &q)
                .ok_or(Error::CovarianceNotPositiveDefinite)?;
        }
        Ok(())
    }

    /// The factor at the current time: the pending time update applied
    /// without a measurement.
    fn propagated_factor(&self) -> Result<Ud<T, N>, Error> {
        let mut ud = self.ud;
        if let Some(pending) = self.pending.get() {
            let q = self
                .process_noise(pending)
                .ok_or(Error::CovarianceNotPositiveDefinite)?;
            ud.predict_attitude(&pending.prop.phi_att, &q)
                .ok_or(Error::CovarianceNotPositiveDefinite)?;
        }
        Ok(ud)
    }

    /// The filter's settings.
    pub fn config(&self) -> &FilterConfig<T> {
        &self.config
    }

    /// The computed frame the filter integrates from the commands.
    pub fn command_frame(&self) -> &CommandFrame<f64> {
        &self.command
    }

    /// Number of updates processed.
    pub fn updates(&self) -> u32 {
        self.updates
    }

    /// The NIS gate's state: consecutive updates it refused just before now
    /// (at most [`MAX_GATED_RUN`]: the next one is then accepted), and
    /// whether it is held open because the last accepted update was above it.
    pub fn gate_state(&self) -> (u32, bool) {
        (self.gated_run, self.gate_open)
    }

    /// The configuration's layout.
    pub const fn layout(&self) -> Layout {
        Self::LAYOUT
    }

    /// Propagates the state over one period of length `dt` (s) with
    /// commanded angle increment `dtheta_c` (rad, c frame). The covariance's
    /// time update is applied by the [`Filter::update`] that follows (with
    /// the measurement, whose noise it shares), or by the next `predict`.
    ///
    /// On error the filter is left as it was, except that a period
    /// predicted before without its update gets its time update (as the
    /// next `predict` or `step` would apply it): the period is propagated
    /// straight into the filter's pending slot, which that period held.
    pub fn predict(&mut self, dtheta_c: &Vector3<f64>, dt: f64) -> Result<(), Error> {
        if !all_finite(dtheta_c.iter().copied().chain([dt])) {
            return Err(Error::NonFiniteInput);
        }
        if dt <= 0.0 {
            return Err(Error::InvalidPeriod);
        }
        // A period predicted without a measurement: its time update (in
        // place, untouched on error) frees the slot.
        self.settle()?;
        self.pending.clear();
        let layout = Self::LAYOUT;
        // The linearisation point: the estimate (EKF) or the nominal (by
        // reference: no copy of the state).
        let x_lin = self.reference.as_ref().unwrap_or(&self.x);
        self.matrices.refresh(&layout, x_lin);
        let slot = &mut self.pending.value;
        self.command
            .period_in_into::<T>(dtheta_c, dt, &mut slot.period, &mut slot.period_t);
        let att0 = layout.attitude(x_lin);
        // The attitude in f64, its increments over the period and the
        // Jacobians in T (see `Filter`).
        layout
            .propagate_into_jacobians_in(
                &self.env_t,
                &self.matrices.m,
                &att0,
                &slot.period_t.period,
                &mut slot.att,
                &mut slot.prop,
            )
            .ok_or(Error::GimbalLock)?;
        let new = &self.pending.value;
        let q_extra = if RESEARCH_OPTIONS && self.config.options.second_order_dynamics {
            self.second_order_dynamics(&new.period, &new.att)?
        } else {
            Matrix3::<T>::zeros()
        };
        if !all_finite(q_extra.iter().copied()) || !all_finite(new.prop.noise_map.iter().copied()) {
            return Err(Error::NonFiniteState);
        }
        let [_, _, att1] = new.att;
        let x_new = match &self.reference {
            // x̂_{k+1} = x_nom,k+1 ⊞ Φ (x̂_k ⊟ x_nom,k): the parameters
            // x_nom + δ, the attitude att_{k+1} + Φ_att δ (formed in δ's
            // place).
            Some(x_nom) => {
                let mut x = layout.difference(&self.x, x_nom);
                let d_att = linear_term::<T, N, 3>(&new.prop.phi_att, &x);
                for (i, (v, nom)) in x.iter_mut().zip(x_nom.iter()).enumerate() {
                    if i >= ATT + 3 {
                        *v += *nom;
                    }
                }
                x.fixed_rows_mut::<3>(ATT).copy_from(&(att1 + d_att));
                x
            }
            // The estimate with the attitude at the period's end.
            None => {
                let mut x = self.x;
                x.fixed_rows_mut::<3>(ATT).copy_from(&att1);
                x
            }
        };
        if !all_finite(x_new.iter().copied()) {
            return Err(Error::NonFiniteState);
        }
        if let Some(x_nom) = self.reference.as_mut() {
            x_nom.fixed_rows_mut::<3>(ATT).copy_from(&att1);
        }
        self.x = x_new;
        self.command.advance(&self.pending.value.period);
        self.pending.value.q_extra = q_extra;
        self.pending.valid = true;
        Ok(())
    }

    /// The second-order process noise of the attitude over `period`
    /// (rad²; [`Options::second_order_dynamics`]): the linearisation error
    /// of the period map `x_{k+1} ≈ x_k + f(x_mid) T`, from central
    /// differences of the attitude-rate Jacobian. Out of line: its N×N
    /// temporaries stay out of [`Filter::predict`]'s frame.
    #[inline(never)]
    fn second_order_dynamics(
        &self,
        period: &Period<f64>,
        att: &[Vector3<f64>; 3],
    ) -> Result<Matrix3<T>, Error> {
        let layout = Self::LAYOUT;
        let env = &self.config.env;
        let [_, wm, _] = period.omega_c;
        let [_, att_mid, _] = *att;
        let mut x_mid = self.x;
        x_mid.fixed_rows_mut::<3>(ATT).copy_from(&att_mid);
        let relevant = |j: usize| j < 9 || layout.lam().is_some_and(|i| (i..i + 3).contains(&j));
        let p_now = to_f64(&self.propagated_factor()?.covariance());
        let (_, q2) = hessian_terms(&x_mid, &p_now, relevant, |xp| {
            layout.attitude_rate_jacobian(env, &layout.matrices(xp), &layout.attitude(xp), &wm)
        })
        .ok_or(Error::GimbalLock)?;
        Ok(to_t(&(q2 * (period.dt * period.dt))))
    }

    /// Predicted measurement, its Jacobian (w.r.t. the state at the end of
    /// the period) for the state `x` whose period trajectory is `prop`, and
    /// the measurement's share of the period's process noise (see [`Noise`]).
    /// `m` holds the installation matrices of `x`'s parameters: the caller
    /// builds or refreshes them, so that their trigonometry is not nested
    /// below the measurement model's frames on the stack.
    fn measure(
        &self,
        x: &SVector<f64, N>,
        pending: &Pending<T, N>,
        m: &MatricesCache<T>,
    ) -> Measured<T, N, Z> {
        let mut out = Measured::zeros();
        self.measure_into(x, pending, m, &mut out);
        out
    }

    /// [`Filter::measure`] into `out` (every part of it written). Out of
    /// line, into the caller's slot: the model's temporaries are not in the
    /// frame that holds the measurement while the factor is updated
    /// (firmware stack).
    #[inline(never)]
    fn measure_into(
        &self,
        x: &SVector<f64, N>,
        pending: &Pending<T, N>,
        m: &MatricesCache<T>,
        out: &mut Measured<T, N, Z>,
    ) {
        let layout = Self::LAYOUT;
        let env = &self.config.env;
        let as_f64 = (&pending.prop as &dyn Any).downcast_ref::<PeriodPropagation<f64, N>>();
        out.z.fill(0.0);
        out.h.fill(T::zero());
        out.noise.g.fill(T::zero());
        out.noise.d.fill(T::zero());
        let accel_row = Self::ACCEL_ROW;
        let h64 = (&mut out.h as &mut dyn Any).downcast_mut::<SMatrix<f64, Z, N>>();
        let (za, da) = if let (Some(prop), Some(h64), Some(m)) = (as_f64, h64, m.as_f64()) {
            // T = f64: the nodes in `prop` are the f64 ones. The Jacobian
            // is written into its rows of `out.h`.
            let mut ha = h64.fixed_rows_mut::<3>(accel_row);
            layout.mean_accel(env, m, prop, &pending.period, &mut ha)
        } else {
            // The value in f64 (it must resolve 1e-7 g of 1 g), the
            // Jacobians in T (they need a few digits; f64 is emulated on an
            // FPU without it), on the f64 installation matrices rounded.
            let za = layout.mean_accel_output::<T>(
                env,
                &m.a,
                &m.c_rn,
                &pending.att,
                &pending.period,
                &pending.period_t.turn,
            );
            let mut ha = out.h.fixed_rows_mut::<3>(accel_row);
            let (_, da) = layout.mean_accel(
                &self.env_t,
                &m.m,
                &pending.prop,
                &pending.period_t.period,
                &mut ha,
            );
            (za, to_f64(&da))
        };
        if layout.gimbal_obs {
            let att = layout.attitude(x);
            out.z.fixed_rows_mut::<3>(0).copy_from(&att);
            out.h
                .fixed_view_mut::<3, 3>(0, ATT)
                .copy_from(&Matrix3::identity());
        }
        out.z.fixed_rows_mut::<3>(accel_row).copy_from(&za);
        // Unit-variance noise w = σ_g u: x_{k+1} gets G u, z gets D u.
        let sigma_g = scalar_to_f64(self.config.sigma_gyro);
        out.noise.g.fixed_rows_mut::<3>(ATT).copy_from(
            &(pending.prop.noise_map
                * (self.config.sigma_gyro * nalgebra::convert::<f64, T>(pending.period.dt))),
        );
        out.noise
            .d
            .fixed_rows_mut::<3>(accel_row)
            .copy_from(&to_t(&(da * sigma_g)));
    }

    /// The trajectory over the pending period that ends at state `x`
    /// (integrated backwards), for relinearisation.
    fn retrace(
        &self,
        x: &SVector<f64, N>,
        pending: &Pending<T, N>,
    ) -> Result<Pending<T, N>, Error> {
        let layout = Self::LAYOUT;
        let pr = &pending.period;
        let reversed = pr.reversed();
        let m = layout.matrices(x);
        let back: PeriodPropagation<f64, N> = layout
            .propagate(&self.config.env, &m, &layout.attitude(x), &reversed)
            .ok_or(Error::GimbalLock)?;
        let [a1, am, a0] = back.att;
        let prop = PeriodPropagation {
            att: [a0, am, a1],
            phi_att: crate::models::transition_rows(&back.f_mid, pr.dt),
            f_mid: back.f_mid,
            f_end: layout
                .attitude_rate_jacobian(&self.config.env, &m, &layout.attitude(x), &pr.omega_c[2])
                .ok_or(Error::GimbalLock)?,
            noise_map: back.noise_map,
        };
        Ok(Pending {
            period: *pr,
            period_t: pending.period_t,
            att: prop.att,
            prop: propagation_t(&prop),
            q_extra: pending.q_extra,
        })
    }

    /// Second-order terms of the accelerometer rows (out of line: the N×N
    /// covariance it reads stays out of the update's frame): returns
    /// (`½ tr(∇²h_a P)`, `½ tr(∇²h_a P ∇²h_b P)`) of the instantaneous
    /// accelerometer output at the end of the period, from its analytic
    /// Hessian ([`crate::second_order`]).
    #[inline(never)]
    fn second_order(
        &self,
        x: &SVector<f64, N>,
        pending: &Pending<T, N>,
        m: &MatricesCache<T>,
    ) -> (Vector3<f64>, Matrix3<f64>) {
        let layout = Self::LAYOUT;
        // In T: a weighting of the update, needed to a few digits.
        let env = self.env_t;
        let [_, _, c_end] = pending.period.c_cn;
        let c_end: Matrix3<T> = to_t(&c_end);
        let att: Vector3<T> = to_t(&layout.attitude(x));
        let source = PredictedCovariance {
            filter: self,
            pending,
        };
        let terms = layout.accel_second_order_from(&env, &m.m, &att, &c_end, &source);
        (to_f64(&terms.mean), to_f64(&terms.cov))
    }

    /// Processes the measurement of the period that [`Filter::predict`] just
    /// propagated over.
    ///
    /// On error the state is left untouched. So is the covariance, with one
    /// exception: the factor is updated in place (no copy of it on the hot
    /// path), so when the factored update itself fails part-way
    /// ([`Error::CovarianceNotPositiveDefinite`], or
    /// [`Error::NonFiniteState`] for a non-finite result) the factor keeps
    /// the part already applied. Every input of the update is checked
    /// before the factor is touched, so this takes a covariance that has
    /// already lost its numerical positive definiteness; no test reaches it.
    pub fn update(&mut self, obs: &Observation<T>) -> Result<Innovation<T, Z>, Error> {
        let layout = Self::LAYOUT;
        if self.pending.get().is_none() {
            return Err(Error::NoPrediction);
        }
        let gimbal = match (layout.gimbal_obs, obs.gimbal) {
            (true, None) => return Err(Error::MissingGimbal),
            (true, Some(g)) => Some(g),
            (false, _) => None,
        };
        if !all_finite(
            obs.accel_mean
                .iter()
                .chain(gimbal.iter().flat_map(|g| g.iter()))
                .copied(),
        ) {
            return Err(Error::NonFiniteInput);
        }
        let mut z = SVector::<f64, Z>::zeros();
        if let Some(g) = gimbal {
            z.fixed_rows_mut::<3>(0).copy_from(&to_f64(&g));
        }
        z.fixed_rows_mut::<3>(Self::ACCEL_ROW)
            .copy_from(&to_f64(&obs.accel_mean));
        if self.reference.is_some() {
            self.update_linearised(Some(&z))
        } else {
            self.update_extended(&z)
        }
    }

    /// The EKF's update of the pending period (pass 1), with the
    /// cold-start remedies of [`Options`].
    #[inline(never)]
    fn update_extended(&mut self, z: &SVector<f64, Z>) -> Result<Innovation<T, Z>, Error> {
        // The matrices of the linearisation point (the cache holds them
        // since `predict`: it changed only the attitude).
        self.matrices.refresh(&Self::LAYOUT, &self.x);
        let m = &self.matrices;
        let pending = self.pending.get().ok_or(Error::NoPrediction)?;
        let opts = self.config.options;
        let (mean2, cov2) = if opts.second_order_covariance || opts.second_order_mean {
            self.second_order(&self.x, pending, m)
        } else {
            (Vector3::zeros(), Matrix3::zeros())
        };
        let iterations = if RESEARCH_OPTIONS && self.updates < opts.iterate_updates {
            opts.iterations
        } else {
            0
        };
        // Linearised at the iterated filter's relinearisation point (IEKF),
        // else at the prediction; the update itself is always the factored
        // one.
        if iterations > 0 {
            return self.update_iterated(z, &cov2, &mean2, iterations);
        }
        self.update_predicted(z, &cov2, &mean2)
    }

    /// The EKF's measurement noise `R_v`: `R` plus, when enabled, the
    /// second-order covariance `cov2` (g²) of the accelerometer rows.
    fn extended_noise(&self, cov2: &Matrix3<f64>) -> SMatrix<T, Z, Z> {
        let mut r_v = self.measurement_noise();
        if self.config.options.second_order_covariance {
            let mut blk = r_v.fixed_view_mut::<3, 3>(Self::ACCEL_ROW, Self::ACCEL_ROW);
            blk += to_t::<T, 3, 3>(cov2);
        }
        r_v
    }

    /// [`Filter::update_extended`] linearised at the prediction (the
    /// default), with the second-order terms `cov2`, `mean2`. Out of line:
    /// the measurement model, the noise and the whitened update it holds are
    /// not above the second-order terms' frames.
    #[inline(never)]
    fn update_predicted(
        &mut self,
        z: &SVector<f64, Z>,
        cov2: &Matrix3<f64>,
        mean2: &Vector3<f64>,
    ) -> Result<Innovation<T, Z>, Error> {
        let pending = self.pending.get().ok_or(Error::NoPrediction)?;
        // Filled in place (moving its parts would copy them in this frame,
        // which is on the deepest path of a step).
        let mut measured = Measured::zeros();
        let nu = self.innovation_at(z, &self.x, pending, mean2, &self.matrices, &mut measured);
        let r_v = self.extended_noise(cov2);
        self.factored(&mut measured.h, &nu, &r_v, &measured.noise, true, None)
    }

    /// [`Filter::update_extended`] linearised at the iterated EKF's
    /// relinearisation point ([`Filter::iterated_innovation`]). Out of line:
    /// its measurement model stays out of the frame of every update that
    /// does not iterate (the default).
    #[inline(never)]
    fn update_iterated(
        &mut self,
        z: &SVector<f64, Z>,
        cov2: &Matrix3<f64>,
        mean2: &Vector3<f64>,
        iterations: u8,
    ) -> Result<Innovation<T, Z>, Error> {
        let pending = self.pending.get().ok_or(Error::NoPrediction)?;
        let r_v = self.extended_noise(cov2);
        let mut measured = Measured::zeros();
        let nu = self.iterated_innovation(z, pending, &r_v, mean2, iterations, &mut measured)?;
        self.factored(&mut measured.h, &nu, &r_v, &measured.noise, true, None)
    }

    /// The innovation `ν = z − h(x_i) − H (x̂ − x_i)` of the EKF update
    /// linearised at `x_lin` (trajectory `lin`), less the second-order mean
    /// `mean2` when enabled, gimbal components wrapped; with the measurement
    /// model there written into `measured`. `m`: the installation matrices
    /// of `x_lin`.
    fn innovation_at(
        &self,
        z: &SVector<f64, Z>,
        x_lin: &SVector<f64, N>,
        lin: &Pending<T, N>,
        mean2: &Vector3<f64>,
        m: &MatricesCache<T>,
        measured: &mut Measured<T, N, Z>,
    ) -> SVector<f64, Z> {
        let layout = Self::LAYOUT;
        self.measure_into(x_lin, lin, m, measured);
        let mut nu = z - measured.z;
        nu -= linear_term::<T, N, Z>(&measured.h, &layout.difference(&self.x, x_lin));
        if self.config.options.second_order_mean {
            let mut acc = nu.fixed_rows_mut::<3>(Self::ACCEL_ROW);
            acc -= mean2;
        }
        if layout.gimbal_obs {
            for v in nu.iter_mut().take(3) {
                *v = wrap_angle(*v);
            }
        }
        nu
    }

    /// [`Filter::innovation_at`] the iterated EKF's relinearisation point:
    /// `iterations` dense Gauss–Newton steps from the prediction (double
    /// precision, the dense gain), then the period's trajectory retraced
    /// to end there. Out of line: its N×N temporaries and the retraced
    /// period (≈ 1.8 KB) stay out of the frame of every update that does
    /// not iterate (the default).
    #[inline(never)]
    fn iterated_innovation(
        &self,
        z: &SVector<f64, Z>,
        pending: &Pending<T, N>,
        r_v: &SMatrix<T, Z, Z>,
        mean2: &Vector3<f64>,
        iterations: u8,
        measured: &mut Measured<T, N, Z>,
    ) -> Result<SVector<f64, Z>, Error> {
        let p_prior = to_f64(&self.settled().covariance());
        let r_v = to_f64(r_v);
        let mut x_lin = self.x;
        let mut lin = *pending;
        for it in 0..iterations {
            if it > 0 {
                lin = self.retrace(&x_lin, pending)?;
            }
            let m = MatricesCache::new(Self::LAYOUT.installation(&x_lin));
            let nu = self.innovation_at(z, &x_lin, &lin, mean2, &m, measured);
            let noise = Noise {
                g: to_f64(&measured.noise.g),
                d: to_f64(&measured.noise.d),
            };
            let gain = dense_gain(&p_prior, &to_f64(&measured.h), &r_v, &noise)?;
            x_lin = self.x + gain.k * nu;
        }
        let lin = self.retrace(&x_lin, pending)?;
        let m = MatricesCache::new(Self::LAYOUT.installation(&x_lin));
        Ok(self.innovation_at(z, &x_lin, &lin, mean2, &m, measured))
    }

    /// The measurement noise covariance `R` (diagonal: gimbal σ² (rad²) in
    /// M2's first three rows, accelerometer σ² (g²) in the others).
    fn measurement_noise(&self) -> SMatrix<T, Z, Z> {
        let mut r = SVector::<T, Z>::zeros();
        if Self::LAYOUT.gimbal_obs {
            let sg2 = self.config.sigma_gimbal * self.config.sigma_gimbal;
            r.fixed_rows_mut::<3>(0).fill(sg2);
        }
        let sa2 = self.config.sigma_accel * self.config.sigma_accel;
        r.fixed_rows_mut::<3>(Self::ACCEL_ROW).fill(sa2);
        SMatrix::<T, Z, Z>::from_diagonal(&r)
    }

    /// The update of the linearised filter about its nominal `x_nom` with
    /// measurement `z`, or with the nominal's own noise-free measurement
    /// `h(x_nom)` for `None` (then `ν = −H (x̂ − x_nom)`; the covariance
    /// update does not depend on `z`; the update is not gated and `S` is
    /// not computed, see [`Filter::factored`]).
    #[inline(never)]
    fn update_linearised(
        &mut self,
        z: Option<&SVector<f64, Z>>,
    ) -> Result<Innovation<T, Z>, Error> {
        let (Some(pending), Some(x_nom)) = (self.pending.get(), self.reference.as_ref()) else {
            return Err(Error::NoPrediction);
        };
        let layout = Self::LAYOUT;
        // The nominal's matrices (the cache holds them since `predict`).
        self.matrices.refresh(&layout, x_nom);
        // Used in place (moving its parts out would copy them in this frame).
        let mut measured = Measured::zeros();
        self.measure_into(x_nom, pending, &self.matrices, &mut measured);
        let delta = layout.difference(&self.x, x_nom);
        let h_delta = linear_term::<T, N, Z>(&measured.h, &delta);
        let mut nu = match z {
            Some(z) => z - measured.z - h_delta,
            None => -h_delta,
        };
        if layout.gimbal_obs {
            for v in nu.iter_mut().take(Self::ACCEL_ROW) {
                *v = wrap_angle(*v);
            }
        }
        let x_base = x_nom + delta;
        let r = self.measurement_noise();
        self.factored(
            &mut measured.h,
            &nu,
            &r,
            &measured.noise,
            z.is_some(),
            Some(&x_base),
        )
    }

    /// The factored update of one period, measurement and time update
    /// together (docs/model.md §Measurement timing, the gyro noise; Anderson &
    /// Moore, *Optimal Filtering*, §5.5).
    ///
    /// The measurement `z = H x_{k+1} + D u + v` shares the period's gyro
    /// noise `u` with the dynamics `x_{k+1} = Φ x_k + G u`. Written as a
    /// measurement of `x_k`, `z = H Φ x_k + e` with `e = M u + v`,
    /// `M = H G + D`, `R_e = M Mᵀ + R_v`, it is decorrelated from the
    /// dynamics by subtracting `J (z − H Φ x_k − e)`, `J = G Mᵀ R_e⁻¹`:
    /// `x_{k+1} = (Φ − J H Φ) x_k + J z + (G u − J e)`, whose noise is
    /// uncorrelated with `e`, with covariance `G Gᵀ − J R_e Jᵀ`. Whitening
    /// by `L = chol(R_e)` makes the `Z` components independent: Bierman's
    /// scalar updates of the factor at `t_k` take them one at a time, then
    /// the structured time update (`G` and `J` touch only the attitude rows)
    /// brings the factor to `t_{k+1}`. The result equals the dense filter's
    /// `K = (P⁻ Hᵀ + G Dᵀ) S⁻¹` update in exact arithmetic.
    ///
    /// Everything the update reads (the whitened rows, the decorrelation
    /// gain, `S`) is computed and checked before the factor is touched; the
    /// NIS gate is decided from `S` then, so a refused update costs only the
    /// time update. The factor is then updated in place (no copy of it;
    /// see [`Filter::update`] for what a failure part-way leaves). The
    /// reported NIS is that of the scalar updates (equal to `νᵀ S⁻¹ ν` in
    /// exact arithmetic). On success the state becomes `x_base` (`None`:
    /// the estimate itself) plus the correction and the pending period is
    /// cleared.
    ///
    /// `measured`: a real measurement: compute the innovation covariance
    /// `S` for the [`Innovation`] and apply the NIS gate; without it (the
    /// noise-free step of the bound) the result's `s` is `R_e` only (the
    /// update itself never uses `S`) and nothing is gated.
    // Out of line: the whitened update it holds is in no frame above the
    // measurement model's, and the updates' frames are not above the factor's
    // (firmware stack).
    #[inline(never)]
    fn factored(
        &mut self,
        h: &mut SMatrix<T, Z, N>,
        nu_f64: &SVector<f64, Z>,
        r_v: &SMatrix<T, Z, Z>,
        noise: &Noise<T, N, Z>,
        measured: bool,
        x_base: Option<&SVector<f64, N>>,
    ) -> Result<Innovation<T, Z>, Error> {
        let mut w = Whitened::zeros();
        if let Gate::Refuse = self.whiten(h, nu_f64, r_v, noise, measured, &mut w)? {
            // Predicted only: the time update without the measurement.
            self.settle()?;
            self.gated_run += 1;
            self.pending.clear();
            return Err(Error::Gated);
        }
        self.apply_whitened(h, &w, measured, x_base)
    }

    /// The first half of [`Filter::factored`]: the whitened rows `L⁻¹ H Φ`
    /// in place of `h`; the whitened innovation, the decorrelated time
    /// update and `S` into `w`; and the NIS gate's verdict, without touching
    /// the factor. Out of line: its temporaries
    /// (the Choleskys, `R_e`, `M`) are not below the factor's updates.
    #[inline(never)]
    fn whiten(
        &self,
        h: &mut SMatrix<T, Z, N>,
        nu_f64: &SVector<f64, Z>,
        r_v: &SMatrix<T, Z, Z>,
        noise: &Noise<T, N, Z>,
        measured: bool,
        w: &mut Whitened<T, N, Z>,
    ) -> Result<Gate, Error> {
        let half: T = nalgebra::convert(0.5);
        let phi_att = &self.pending.get().ok_or(Error::NoPrediction)?.prop.phi_att;
        let nu: SVector<T, Z> = to_t(nu_f64);
        let g_att: Matrix3<T> = crate::models::attitude_rows(&noise.g);
        let h_att: SMatrix<T, Z, 3> = crate::models::attitude_columns(h);
        // H Φ in T (f64 is emulated on an FPU without it), in place. It
        // becomes the whitened rows in place below.
        crate::models::apply_transition(h, phi_att);
        let m_e = h_att * g_att + noise.d;
        let mut r_e = m_e * m_e.transpose() + r_v;
        r_e = (r_e + r_e.transpose()) * half;
        // S = H Φ P Φᵀ Hᵀ + R_e, for the innovation report and the gate.
        let s = if measured {
            r_e + self.ud.congruence(h)
        } else {
            r_e
        };
        let Some(chol) = r_e.cholesky() else {
            return Err(Error::InnovationNotPositiveDefinite);
        };
        // The factor's lower triangle (the solves read nothing else).
        let l = chol.l_dirty();
        // The triangular solves in place (no Option/Result moves of the
        // Z×N results).
        w.nu_w = nu;
        // J L = G Mᵀ L⁻ᵀ (attitude rows), so J z = (J L) ν_w.
        let mut l_inv_m_g = m_e * g_att.transpose();
        if !(solve_lower(l, &mut w.nu_w) && solve_lower(l, h) && solve_lower(l, &mut l_inv_m_g)) {
            return Err(Error::InnovationNotPositiveDefinite);
        }
        w.j_l = l_inv_m_g.transpose();
        // Time update with Φ' = Φ − J H Φ and Q' = G Gᵀ − J R_e Jᵀ.
        w.phi_dec = phi_att - w.j_l * *h;
        let q = g_att * g_att.transpose() - w.j_l * w.j_l.transpose();
        // Factored here, before the factor is touched: a `Q'` that is not
        // positive semi-definite (garbage noise settings) is refused now,
        // not after the scalar updates have been applied.
        w.q = AttitudeNoise::from_covariance(&((q + q.transpose()) * half))
            .ok_or(Error::CovarianceNotPositiveDefinite)?;
        let gate = self.config.options.nis_gate;
        if measured && gate > 0.0 && !self.gate_open && self.gated_run < MAX_GATED_RUN {
            let Some(chol_s) = s.cholesky() else {
                return Err(Error::InnovationNotPositiveDefinite);
            };
            let mut y = nu;
            if !chol_s.l_dirty().solve_lower_triangular_mut(&mut y) {
                return Err(Error::InnovationNotPositiveDefinite);
            }
            let nis_prior = y.norm_squared();
            if !nis_prior.is_finite() {
                return Err(Error::NonFiniteState);
            }
            if nis_prior > nalgebra::convert(gate) {
                return Ok(Gate::Refuse);
            }
        }
        // The factor is updated in place: check everything it reads first
        // (slice by slice: a chain of iterators costs more than the checks).
        let read = [
            h.as_slice(),
            w.nu_w.as_slice(),
            w.j_l.as_slice(),
            phi_att.as_slice(),
            w.phi_dec.as_slice(),
        ];
        if !read.iter().all(|part| all_finite(part.iter().copied())) {
            return Err(Error::NonFiniteState);
        }
        w.innovation = Innovation {
            nu,
            s,
            nis: T::zero(),
        };
        Ok(Gate::Pass)
    }

    /// The second half of [`Filter::factored`]: Bierman's scalar updates of
    /// the whitened rows `h_w`, the decorrelated time update, the new state.
    #[inline(never)]
    fn apply_whitened(
        &mut self,
        h_w: &SMatrix<T, Z, N>,
        w: &Whitened<T, N, Z>,
        measured: bool,
        x_base: Option<&SVector<f64, N>>,
    ) -> Result<Innovation<T, Z>, Error> {
        let phi_att = &self.pending.get().ok_or(Error::NoPrediction)?.prop.phi_att;
        let mut dx = SVector::<T, N>::zeros();
        let mut nis = T::zero();
        for (row, nu_i) in h_w.row_iter().zip(w.nu_w.iter()) {
            let row = row.transpose();
            let resid = *nu_i - row.dot(&dx);
            let Some(up) = self.ud.update(&row, T::one()) else {
                return Err(Error::CovarianceNotPositiveDefinite);
            };
            nis += resid * resid / up.alpha;
            dx += up.gain * resid;
        }
        self.ud
            .predict_attitude(&w.phi_dec, &w.q)
            .ok_or(Error::CovarianceNotPositiveDefinite)?;
        // x̂_{k+1} − x̂⁻_{k+1} = Φ δ + J (z − H Φ δ) for the correction δ at t_k.
        let d_att = phi_att * dx + w.j_l * (w.nu_w - h_w * dx);
        dx.fixed_rows_mut::<3>(ATT).copy_from(&d_att);
        let x_new = x_base.unwrap_or(&self.x) + to_f64(&dx);
        if !all_finite(x_new.iter().copied()) || !nis.is_finite() {
            return Err(Error::NonFiniteState);
        }
        let gate = self.config.options.nis_gate;
        let above = measured && gate > 0.0 && nis > nalgebra::convert(gate);
        // Keep the Euler attitude angles in (−π, π]; P is unchanged by 2π shifts.
        let mut x = x_new;
        if Self::LAYOUT.attitude != crate::models::AttitudeKind::Misalignment {
            for v in x.iter_mut().take(3) {
                *v = wrap_angle(*v);
            }
        }
        self.x = x;
        self.pending.clear();
        self.updates = self.updates.saturating_add(1);
        self.gated_run = 0;
        self.gate_open = above;
        Ok(Innovation {
            nu: w.innovation.nu,
            s: w.innovation.s,
            nis,
        })
    }

    /// One filter period: [`Filter::predict`] then [`Filter::update`].
    pub fn step(
        &mut self,
        dtheta_c: &Vector3<f64>,
        dt: f64,
        obs: &Observation<T>,
    ) -> Result<Innovation<T, Z>, Error> {
        self.step_with(dtheta_c, dt, Some(obs))
    }

    /// One period of the linearised filter fed the noise-free measurement
    /// of its own nominal, `h(x_nom)`, without the caller computing it: the
    /// posterior Cramér–Rao recursion of
    /// [`crate::observability::Observability`] (its covariance update is
    /// [`Filter::step`]'s, which does not depend on the measured values).
    /// [`Error::NoPrediction`] outside the linearised mode (no nominal).
    /// The innovation is not reported (its covariance `S` is not computed)
    /// and the NIS gate does not apply.
    pub(crate) fn step_noise_free(
        &mut self,
        dtheta_c: &Vector3<f64>,
        dt: f64,
    ) -> Result<(), Error> {
        self.step_with(dtheta_c, dt, None).map(|_| ())
    }

    /// [`Filter::step`] with `obs`, or [`Filter::step_noise_free`] for
    /// `None`. Out of line: one filter step is this function
    /// (`firmware/bench.sh` measures its stack).
    #[inline(never)]
    fn step_with(
        &mut self,
        dtheta_c: &Vector3<f64>,
        dt: f64,
        obs: Option<&Observation<T>>,
    ) -> Result<Innovation<T, Z>, Error> {
        if obs.is_none() && self.reference.is_none() {
            return Err(Error::NoPrediction);
        }
        if self.pending.get().is_some() {
            self.settle()?;
            self.pending.clear();
        }
        // `predict` and `update` leave the factor untouched on error (every
        // input of the in-place update is checked before it is touched; see
        // `update` for the one exception), so only the state is saved: the
        // estimate, the computed frame, and the nominal's attitude (`predict`
        // moves only the attitude of the nominal).
        let layout = Self::LAYOUT;
        let saved = (
            self.x,
            self.command,
            self.reference.as_ref().map(|r| layout.attitude(r)),
        );
        self.predict(dtheta_c, dt)?;
        let updated = match obs {
            Some(obs) => self.update(obs),
            None => self.update_linearised(None),
        };
        match updated {
            Err(e) if e != Error::Gated => {
                let (x, command, nominal_att) = saved;
                self.x = x;
                self.command = command;
                if let (Some(r), Some(att)) = (self.reference.as_mut(), nominal_att) {
                    r.fixed_rows_mut::<3>(ATT).copy_from(&att);
                }
                self.pending.clear();
                Err(e)
            }
            other => other,
        }
    }

    /// Measurement function and Jacobian at an arbitrary end-of-period state,
    /// for tests and the observability analysis: returns `(h(x), H)` for the
    /// period that [`Filter::predict`] last propagated over.
    pub fn measurement_at(
        &self,
        x: &SVector<f64, N>,
    ) -> Result<(SVector<f64, Z>, SMatrix<f64, Z, N>), Error> {
        let pending = self.pending.get().ok_or(Error::NoPrediction)?;
        let lin = self.retrace(x, pending)?;
        let m = self.measure(x, &lin, &MatricesCache::new(Self::LAYOUT.installation(x)));
        Ok((m.z, to_f64(&m.h)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The installation matrices cache holds the same values however it
    /// got them (built for the parameters, or refilled for them after
    /// others): a pure function of the parameters, in f32 and in f64; the
    /// f64 `A` and `C^r_n` are `InstallationMatrices::new`'s.
    #[test]
    fn matrices_cache_is_a_function_of_its_parameters() {
        let v = |a: f64, b: f64, c: f64| Vector3::new(a, b, c);
        let p = Installation {
            theta_g_c: v(1e-3, -2e-3, 0.5e-3),
            theta_g_t: v(3e-4, 1e-4, -2e-4),
            theta_a_c: v(-7e-4, 2e-4, 9e-4),
            theta_a_t: v(1e-4, -3e-4, 5e-4),
            lambda: v(0.3, -1.2, 2.0),
        };
        let q = Installation {
            lambda: v(0.0, 0.0, 0.0),
            ..p
        };
        fn check<T: RealField + Copy>(p: Installation<f64>, q: Installation<f64>) {
            let built = MatricesCache::<T>::new(p);
            let mut refilled = MatricesCache::<T>::new(q);
            refilled.fill(p);
            assert_eq!(built.m, refilled.m);
            assert_eq!((built.a, built.c_rn), (refilled.a, refilled.c_rn));
            let f64_matrices = InstallationMatrices::new(p);
            assert_eq!((built.a, built.c_rn), (f64_matrices.a, f64_matrices.c_rn));
        }
        check::<f32>(p, q);
        check::<f64>(p, q);
    }

    /// `solve_lower` gives nalgebra's `solve_lower_triangular_mut` bit for
    /// bit (the same operations in the same order), reading only the lower
    /// triangle, and refuses a zero on the diagonal with `b` untouched.
    #[test]
    fn solve_lower_is_nalgebras_solve() {
        let a = SMatrix::<f64, 6, 6>::from_fn(|i, j| ((7 * i + 3 * j) % 11) as f64 / 3.0 - 1.4);
        let s = a * a.transpose() + SMatrix::identity() * 0.3;
        let chol = s.cholesky().expect("positive definite");
        let mut l = chol.l();
        let want_l = l;
        // Garbage above the diagonal, as in a Cholesky's `l_dirty`.
        for i in 0..6 {
            for j in i + 1..6 {
                l[(i, j)] = f64::NAN;
            }
        }
        let b = SMatrix::<f64, 6, 18>::from_fn(|i, j| ((5 * i + j) % 13) as f64 * 0.37 - 2.0);
        let mut want = b;
        assert!(want_l.solve_lower_triangular_mut(&mut want));
        let mut got = b;
        assert!(solve_lower(&l, &mut got));
        assert_eq!(got, want);
        let mut f32_got = b.map(|v| v as f32);
        let mut f32_want = f32_got;
        assert!(want_l
            .map(|v| v as f32)
            .solve_lower_triangular_mut(&mut f32_want));
        assert!(solve_lower(&l.map(|v| v as f32), &mut f32_got));
        assert_eq!(f32_got, f32_want);
        l[(3, 3)] = 0.0;
        let mut refused = b;
        assert!(!solve_lower(&l, &mut refused));
        assert_eq!(refused, b);
    }
}
