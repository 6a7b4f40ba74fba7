//! Observability of a configuration along a rolling path (docs/model.md
//! §Observability; what the paper proves by hand, computed).
//!
//! [`Observability`] follows the *true* trajectory of a configuration (the
//! model integrated without noise from the true initial state along the
//! commanded path) and accumulates, period by period:
//!
//! - the **information matrix** of the initial state,
//!   `J = Σ_k Φ(k,0)ᵀ H_kᵀ R⁻¹ H_k Φ(k,0)`, where `Φ(k,0)` is the transition
//!   of the linearised model from `t_0` to `t_k` and `H_k` the Jacobian of the
//!   period-`k` measurement with respect to the state at `t_k`; `R` holds the
//!   measurement noise only (accelerometer σ², gimbal σ²), so `J` is the
//!   deterministic observability Gramian weighted by the noise. Its null
//!   space is the set of initial-state changes that leave every noise-free
//!   measurement unchanged to first order: the structurally unobservable
//!   combinations;
//! - the **posterior Cramér–Rao bound**: the covariance recursion of the
//!   Kalman filter linearised about the true trajectory, with the prior and
//!   the process noise (the gyro noise, correlated with the accelerometer
//!   measurement of the same period). Its square-rooted diagonal is
//!   `σ_CRLB`; `σ_CRLB / σ_prior ≪ 1` says *how well* a parameter is
//!   observable, which the rank alone does not.
//!
//! A period without a measurement (a lost sample the calibrator bridged,
//! [`Observability::predict`], or a [`LogRecord`] without observation via
//! [`Observability::record`]) moves the true state and the bound along the
//! commanded motion and adds nothing to `J`: the bound of the samples
//! actually received. This is the one computation of the bound: `host-sim`'s
//! σ_CRLB columns (`run`, `record --truth`, `calibrate --truth`) and the
//! observability report all come from it. [`Bound`]
//! ([`Observability::bound_only`]) runs the same bound without
//! accumulating `Φ(k,0)` and `J`, for a search that needs `σ_CRLB` only
//! (`host-sim design`).
//!
//! [`Observability::analyse`] decomposes `J` (scaled by the prior,
//! `J̃ = S J S`, `S = diag(σ_prior)`, so that its eigenvalues are the
//! information relative to the prior) with a symmetric eigen-decomposition.
//! An eigenvalue counts towards the rank when it exceeds
//! `rel_tol · λ_max` ([`RANK_TOLERANCE`] by default). The null-space basis
//! is returned in reduced row-echelon form (each basis vector has a leading
//! state that appears in no other vector), normalised to unit length, with
//! coefficients below [`COEF_THRESHOLD`] set to zero: this makes the
//! combinations readable, e.g. `0.577 psi_x + 0.577 thgC_x + 0.577 thaC_x`
//! (the ps-frame gauge: the cube frame cannot be told from the accelerometer
//! frame, docs/model.md §Configurations).
//!
//! A state is *structurally unobservable* when it takes part in the null
//! space (the norm of its unit vector's projection on the null space exceeds
//! [`COEF_THRESHOLD`]), and *observable in practice* when in addition
//! `σ_CRLB / σ_prior <` [`PRACTICAL_RATIO`]. States that share one null
//! direction come out with ratios below 1 (0.58 for a three-way tie), so the
//! structural verdict is read from the null space, never from the ratio.

use nalgebra::{RealField, SMatrix, SVector};

use crate::ekf::{Error, Filter, FilterConfig, Options};
use crate::estimator::LogRecord;
use crate::models::{ConfigId, Group, Layout, Model, PeriodPropagation, StateInfo};

/// Default relative tolerance of the numerical rank: an eigenvalue of the
/// prior-scaled information matrix counts when it exceeds `1e-12 · λ_max`.
///
/// On the paper's scenario the weakest observable direction sits at
/// `6e-6 · λ_max` (2e-5 for the azimuth seen through the Earth rate), while
/// the structurally null directions come out at `≤ 1.3e-14 · λ_max` (the
/// round-off of the sum over 5400 periods and of the eigen-solver): the
/// tolerance lies in the gap, six decades below the one side and two above
/// the other. `host-sim observability --json` prints every eigenvalue.
pub const RANK_TOLERANCE: f64 = 1e-12;

/// Coefficients of a normalised null-space vector below this magnitude are
/// dropped (set to zero), and a state takes part in the null space when its
/// projection on it exceeds this.
pub const COEF_THRESHOLD: f64 = 1e-6;

/// A parameter is observable in practice when `σ_CRLB / σ_prior` is below
/// this (docs/model.md §Observability).
pub const PRACTICAL_RATIO: f64 = 0.01;

/// Eigen-decomposition of the prior-scaled information matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spectrum<T: RealField + Copy, const N: usize> {
    /// Eigenvalues of `J̃ = S J S` (dimensionless: information relative to
    /// the prior), in decreasing order.
    pub eigenvalues: SVector<T, N>,
    /// Unit eigenvectors (columns), in the order of `eigenvalues`, in the
    /// scaled coordinates `x̃ = S⁻¹ x` (equal to the state's for a uniform
    /// prior).
    pub eigenvectors: SMatrix<T, N, N>,
    /// The relative tolerance used for the rank.
    pub rel_tol: T,
    /// Numerical rank: the eigenvalues above `rel_tol · λ_max`.
    pub rank: usize,
}

impl<T: RealField + Copy, const N: usize> Spectrum<T, N> {
    /// Dimension of the null space, `N − rank`.
    pub fn nullity(&self) -> usize {
        N.saturating_sub(self.rank)
    }

    /// Per state, the norm of the projection of its unit vector on the null
    /// space (0: fully observable direction, 1: entirely unobservable).
    pub fn participation(&self) -> SVector<T, N> {
        let mut out = SVector::<T, N>::zeros();
        for col in self.eigenvectors.column_iter().skip(self.rank) {
            for (o, v) in out.iter_mut().zip(col.iter()) {
                *o += *v * *v;
            }
        }
        out.map(|v| v.sqrt())
    }

    /// Whether state `i` takes part in the null space (structurally
    /// unobservable); `false` for an out-of-range index.
    pub fn in_null_space(&self, i: usize) -> bool {
        let thr: T = nalgebra::convert(COEF_THRESHOLD);
        self.participation().get(i).is_some_and(|p| *p > thr)
    }

    /// A canonical basis of the null space: the first [`Spectrum::nullity`]
    /// columns of the returned matrix (the rest are zero). It is the reduced
    /// row-echelon form of the null-space eigenvectors (complete pivoting:
    /// each vector has a pivot state, with the largest available
    /// coefficient, that no other vector contains; vectors ordered by their
    /// pivot state), each vector then
    /// normalised to unit length with its leading coefficient positive and
    /// coefficients below [`COEF_THRESHOLD`] set to zero.
    pub fn null_space_basis(&self) -> SMatrix<T, N, N> {
        let k = self.nullity();
        // Rows of `b` are the null-space vectors.
        let mut b = SMatrix::<T, N, N>::zeros();
        for (r, col) in self.eigenvectors.column_iter().skip(self.rank).enumerate() {
            if let Some(mut row) = b.row_iter_mut().nth(r) {
                row.copy_from(&col.transpose());
            }
        }
        // Gauss–Jordan elimination with complete pivoting on the first k
        // rows: each step takes the largest remaining entry as pivot, so
        // that a tiny coefficient never becomes a pivot (which would mix
        // the combinations with large multiples of each other).
        let mut pivot_cols = [usize::MAX; N];
        for step in 0..k {
            let mut best = (step, 0, T::zero());
            for r in step..k {
                for c in 0..N {
                    let v = b.get((r, c)).map_or(T::zero(), |v| v.abs());
                    if v > best.2 {
                        best = (r, c, v);
                    }
                }
            }
            let (br, c, val) = best;
            if val <= T::zero() {
                break;
            }
            b.swap_rows(step, br);
            let p = b.get((step, c)).copied().unwrap_or(T::one());
            let scaled = b.row(step) / p;
            b.set_row(step, &scaled);
            for r in 0..k {
                if r != step {
                    let f = b.get((r, c)).copied().unwrap_or(T::zero());
                    if f != T::zero() {
                        let new = b.row(r) - scaled * f;
                        b.set_row(r, &new);
                    }
                }
            }
            if let Some(pc) = pivot_cols.get_mut(step) {
                *pc = c;
            }
        }
        // Order the vectors by their pivot state.
        let mut order = [0usize; N];
        for (i, o) in order.iter_mut().enumerate() {
            *o = i;
        }
        if let Some(head) = order.get_mut(..k) {
            head.sort_unstable_by_key(|&r| pivot_cols.get(r).copied().unwrap_or(usize::MAX));
        }
        let mut sorted = SMatrix::<T, N, N>::zeros();
        for (dst, &src) in order.iter().enumerate().take(k) {
            sorted.set_row(dst, &b.row(src));
        }
        let b = sorted;
        let thr: T = nalgebra::convert(COEF_THRESHOLD);
        let mut out = SMatrix::<T, N, N>::zeros();
        for r in 0..k {
            let mut v = b.row(r).transpose();
            let norm = v.norm();
            if norm > T::zero() {
                v /= norm;
            }
            let lead = v.iter().copied().find(|c| c.abs() > thr);
            if lead.is_some_and(|l| l < T::zero()) {
                v = -v;
            }
            for c in v.iter_mut() {
                if c.abs() <= thr {
                    *c = T::zero();
                }
            }
            out.set_column(r, &v);
        }
        out
    }
}

/// Whether the paper expects state `name` of group `group` to converge in
/// configuration `id` (docs/model.md §Configurations): the
/// non-orthogonalities `θgT`, `θaT` in every configuration; the axis
/// rotations `θgC`, `θaC` in M1-pa, M2-ps, M3-pa and M4-pa; of the mounting
/// angles `λ`, `lam_x` and `lam_z` in M2-ps; never the attitude. The one
/// home of this fact: host-sim's verdicts and summaries read it.
///
/// # Examples
///
/// ```
/// use rollcal::models::{ConfigId, Group};
/// use rollcal::observability::expected_observable;
///
/// assert!(expected_observable(ConfigId::M1Ps, "thgT_1", Group::ThetaGT));
/// assert!(!expected_observable(ConfigId::M1Ps, "thgC_x", Group::ThetaGC));
/// assert!(expected_observable(ConfigId::M2Ps, "lam_z", Group::Lambda));
/// assert!(!expected_observable(ConfigId::M2Ps, "lam_y", Group::Lambda));
/// // Over a configuration's state table:
/// let expected = ConfigId::M2Ps
///     .states()
///     .iter()
///     .filter(|s| expected_observable(ConfigId::M2Ps, s.name, s.group))
///     .count();
/// assert_eq!(expected, 14);
/// ```
pub fn expected_observable(id: ConfigId, name: &str, group: Group) -> bool {
    use ConfigId::*;
    match group {
        Group::ThetaGT | Group::ThetaAT => true,
        Group::ThetaGC | Group::ThetaAC => matches!(id, M1Pa | M2Ps | M3Pa | M4Pa),
        Group::Lambda => id == M2Ps && (name == "lam_x" || name == "lam_z"),
        Group::Attitude => false,
        // The paper takes the instruments' own errors as calibrated: it
        // has no verdict on them (the analysis gives one,
        // docs/observability.md).
        Group::GyroDrift
        | Group::GyroGDrift
        | Group::GyroScale
        | Group::AccelBias
        | Group::AccelScale
        | Group::AccelSecondOrder
        | Group::GyroMarkov
        | Group::AccelMarkov
        | Group::GyroWarmup
        | Group::AccelWarmup => false,
    }
}

/// [`expected_observable`] of a state of `id`'s table
/// ([`ConfigId::states`]).
///
/// # Examples
///
/// ```
/// use rollcal::models::ConfigId;
/// use rollcal::observability::expected_observable_state;
///
/// let states = ConfigId::M1Pa.states();
/// // M1-pa: attitude (3) not expected; θgC^pa, θgT, θaT (9) expected.
/// let n = states.iter().filter(|s| expected_observable_state(ConfigId::M1Pa, s)).count();
/// assert_eq!((states.len(), n), (12, 9));
/// ```
pub fn expected_observable_state(id: ConfigId, state: &StateInfo) -> bool {
    expected_observable(id, state.name, state.group)
}

/// Information matrix and posterior Cramér–Rao bound of configuration `M`
/// along the true trajectory, accumulated one filter period at a time.
///
/// `FULL = false` ([`Bound`], built by [`Observability::bound_only`])
/// advances the bound only: the true state and the bound's recursion are
/// the same code as in the full mode (the bound comes out bit-identical,
/// `host-sim/tests/it/design.rs`), but `Φ(k,0)` and `J` are not accumulated,
/// so [`Observability::transition`], [`Observability::information`] and
/// [`Observability::analyse`] exist only for `FULL = true`. It is what a
/// search over candidate paths that only needs `σ_CRLB` runs.
///
/// # Examples
///
/// M1-pa along a short path: 90° about the x axis, then 90° about z, at
/// 1°/s (the commanded increments from the computed frame, as the platform
/// computer forms them).
///
/// ```
/// use nalgebra::{SVector, Vector3};
/// use rollcal::command::CommandFrame;
/// use rollcal::ekf::FilterConfig;
/// use rollcal::models::{ConfigId, M1Pa};
/// use rollcal::observability::{Observability, RANK_TOLERANCE};
/// use rollcal::wire::CalibratorConfig;
///
/// let settings = CalibratorConfig::paper(ConfigId::M1Pa);
/// let config = FilterConfig::<f64>::from(&settings);
/// let sigma_prior = SVector::<f64, 12>::repeat(settings.prior_sigma_rad);
/// let mut obs = Observability::<f64, M1Pa, 12, 3>::new(config, SVector::zeros(), sigma_prior)?;
/// let mut frame = CommandFrame::aligned(config.env.earth_rate_n);
/// let rate = 1f64.to_radians();
/// for axis in [Vector3::x(), Vector3::z()] {
///     let u = axis * rate;
///     for _ in 0..90 {
///         obs.step(&frame.increment(&u, 1.0), 1.0)?;
///         frame.c_cn = frame.after(&u, 1.0, 1);
///     }
/// }
/// assert_eq!(obs.periods(), 180);
/// // The information matrix J of the initial state and its spectrum.
/// let spectrum = obs.analyse(RANK_TOLERANCE)?;
/// assert_eq!(spectrum.rank + spectrum.nullity(), 12);
/// assert!(obs.information()[(0, 0)] >= 0.0);
/// // σ_CRLB: no state is known worse than its prior.
/// let ratio = obs.ratio();
/// assert!(ratio.iter().all(|r| *r <= 1.0 + 1e-12));
/// for (state, r) in ConfigId::M1Pa.states().iter().zip(ratio.iter()) {
///     println!("{:8} σ_CRLB/σ_prior = {r:.2e}", state.name);
/// }
/// # Ok::<(), rollcal::ekf::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct Observability<
    T: RealField + Copy,
    M,
    const N: usize,
    const Z: usize,
    const FULL: bool = true,
> {
    /// The Kalman filter linearised about the true trajectory: its
    /// covariance is the posterior Cramér–Rao bound, its nominal the true
    /// (noise-free model) state, its computed frame the commanded one.
    crlb: Filter<T, M, N, Z>,
    /// The true state at the current time (rad; the filter's nominal, in
    /// double precision).
    x_true: SVector<f64, N>,
    /// `Φ(k,0)` (`FULL` only; the identity otherwise).
    phi: SMatrix<T, N, N>,
    /// `J` (rad⁻²; `FULL` only, zero otherwise).
    info: SMatrix<T, N, N>,
    sigma_prior: SVector<T, N>,
    periods: u32,
}

/// The bound-only [`Observability`]: `σ_CRLB` without `Φ(k,0)` and `J`.
pub type Bound<T, M, const N: usize, const Z: usize> = Observability<T, M, N, Z, false>;

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize>
    Observability<T, M, N, Z, true>
{
    /// Starts at the true initial state `x_true0` (rad) with prior σ
    /// `sigma_prior` (rad) of every state. The filter options of `config`
    /// are ignored: the bound is the plain linearised recursion.
    pub fn new(
        config: FilterConfig<T>,
        x_true0: SVector<f64, N>,
        sigma_prior: SVector<T, N>,
    ) -> Result<Self, Error> {
        Self::start(config, x_true0, sigma_prior)
    }

    /// The transition `Φ(k,0)` of the linearised model from the initial
    /// time to the current one (the state at `t_k` moves by `Φ(k,0) δx_0`
    /// when the initial state moves by `δx_0`).
    pub fn transition(&self) -> &SMatrix<T, N, N> {
        &self.phi
    }

    /// The information matrix `J` of the initial state (rad⁻²).
    pub fn information(&self) -> &SMatrix<T, N, N> {
        &self.info
    }

    /// Eigen-decomposition of the prior-scaled information matrix with the
    /// relative rank tolerance `rel_tol` (see [`RANK_TOLERANCE`]).
    pub fn analyse(&self, rel_tol: T) -> Result<Spectrum<T, N>, Error> {
        let s = SMatrix::<T, N, N>::from_diagonal(&self.sigma_prior);
        let mut j = s * self.info * s;
        j = (j + j.transpose()) * nalgebra::convert::<f64, T>(0.5);
        let (values, vectors) = jacobi_eigen(j).ok_or(Error::NonFiniteState)?;
        // Sort by decreasing eigenvalue.
        let mut order = [0usize; N];
        for (i, o) in order.iter_mut().enumerate() {
            *o = i;
        }
        let val = |i: usize| values.get(i).copied().unwrap_or(T::zero());
        order.sort_unstable_by(|&a, &b| {
            val(b)
                .partial_cmp(&val(a))
                .unwrap_or(core::cmp::Ordering::Equal)
        });
        let mut eigenvalues = SVector::<T, N>::zeros();
        let mut eigenvectors = SMatrix::<T, N, N>::zeros();
        for (dst, &src) in order.iter().enumerate() {
            if let Some(v) = eigenvalues.get_mut(dst) {
                *v = val(src);
            }
            if let Some(col) = vectors.column_iter().nth(src) {
                eigenvectors.set_column(dst, &col);
            }
        }
        let max = eigenvalues.get(0).copied().unwrap_or(T::zero());
        let rank = eigenvalues
            .iter()
            .filter(|v| **v > rel_tol * max && max > T::zero())
            .count();
        Ok(Spectrum {
            eigenvalues,
            eigenvectors,
            rel_tol,
            rank,
        })
    }
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize>
    Observability<T, M, N, Z, false>
{
    /// [`Observability::new`] for the bound only ([`Bound`]): the same
    /// start, and every period updates the bound and the true state but not
    /// `Φ(k,0)` and `J`.
    pub fn bound_only(
        config: FilterConfig<T>,
        x_true0: SVector<f64, N>,
        sigma_prior: SVector<T, N>,
    ) -> Result<Self, Error> {
        Self::start(config, x_true0, sigma_prior)
    }
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize, const FULL: bool>
    Observability<T, M, N, Z, FULL>
{
    const LAYOUT: Layout = M::LAYOUT;

    fn start(
        config: FilterConfig<T>,
        x_true0: SVector<f64, N>,
        sigma_prior: SVector<T, N>,
    ) -> Result<Self, Error> {
        let config = FilterConfig {
            options: Options::plain(),
            ..config
        };
        let mut crlb = Filter::new(config, x_true0, sigma_prior)?;
        crlb.set_nominal(Some(x_true0));
        Ok(Self {
            crlb,
            x_true: x_true0,
            phi: SMatrix::identity(),
            info: SMatrix::zeros(),
            sigma_prior,
            periods: 0,
        })
    }

    /// Sets the computed frame `C^c_n` at the start of the first period to
    /// `c_cn` (the path's start, `C^c_n = I`, otherwise), for a log that
    /// starts elsewhere on its path ([`crate::estimator::LogStart`]); the
    /// true initial state given to [`Observability::new`] is then the one
    /// at that start. Call it before the first period. On error nothing
    /// changes.
    pub fn start_at(&mut self, c_cn: &nalgebra::Matrix3<f64>) -> Result<(), Error> {
        self.crlb.start_at(c_cn)
    }

    /// One filter period of length `dt` (s) with commanded angle increment
    /// `dtheta_c` (rad, c frame) and a measurement: propagates the true
    /// state and the bound, adds the period's measurement to `J` (`FULL`)
    /// and updates the bound with it. On error nothing changes.
    pub fn step(&mut self, dtheta_c: &nalgebra::Vector3<f64>, dt: f64) -> Result<(), Error> {
        self.period(dtheta_c, dt, true)
    }

    /// One filter period without a measurement (e.g. a sample lost and
    /// bridged along the commanded motion): the true state, `Φ(k,0)`
    /// (`FULL`) and the bound are propagated (the bound grows by the process
    /// noise), `J` gains nothing. On error nothing changes.
    pub fn predict(&mut self, dtheta_c: &nalgebra::Vector3<f64>, dt: f64) -> Result<(), Error> {
        self.period(dtheta_c, dt, false)
    }

    /// One logged period: [`Observability::step`] for a record with a
    /// measurement, [`Observability::predict`] for one without. Only the
    /// record's period and increment are used (the bound's measurements are
    /// the noise-free ones of the true trajectory; the covariance of the
    /// linearised filter does not depend on their values).
    pub fn record(&mut self, r: &LogRecord<T>) -> Result<(), Error> {
        self.period(&r.dtheta_cmd, r.dt, r.observation.is_some())
    }

    fn period(
        &mut self,
        dtheta_c: &nalgebra::Vector3<f64>,
        dt: f64,
        measured: bool,
    ) -> Result<(), Error> {
        if !dtheta_c.iter().chain([dt].iter()).all(|v| v.is_finite()) {
            return Err(Error::NonFiniteInput);
        }
        if dt <= 0.0 {
            return Err(Error::InvalidPeriod);
        }
        // Φ(k,0) and J only in the full mode (the bound-only mode neither
        // computes nor copies them).
        let accumulated = if FULL {
            Some(self.accumulated(dtheta_c, dt, measured)?)
        } else {
            None
        };
        // The bound: the linearised filter fed the noise-free measurement of
        // its nominal, the true trajectory (the filter is left untouched on
        // error). The one recursion of both modes.
        if measured {
            self.crlb.step_noise_free(dtheta_c, dt)?;
        } else {
            self.crlb.predict(dtheta_c, dt)?;
        }
        if let Some(x) = self.crlb.nominal() {
            self.x_true = *x;
        }
        if let Some((phi, info)) = accumulated {
            self.phi = phi;
            self.info = info;
        }
        self.periods = self.periods.saturating_add(1);
        Ok(())
    }

    /// `Φ(k+1,0)` and `J` with the period's measurement (if `measured`),
    /// from the propagation of the true state over the period.
    fn accumulated(
        &self,
        dtheta_c: &nalgebra::Vector3<f64>,
        dt: f64,
        measured: bool,
    ) -> Result<(SMatrix<T, N, N>, SMatrix<T, N, N>), Error> {
        let layout = Self::LAYOUT;
        let env = self.crlb.config().env;
        let period = self.crlb.command_frame().period(dtheta_c, dt);
        let m = layout.matrices(&self.x_true);
        let prop: PeriodPropagation<f64, N> = layout
            .propagate(&env, &m, &layout.attitude(&self.x_true), &period)
            .ok_or(Error::GimbalLock)?;

        // Φ_k: identity with the attitude rows from the propagation; the
        // period's measurement sees the state before the end-of-period
        // decay of the Gauss–Markov states (docs/model.md §Errors that
        // wander), which Φ(k+1,0) then takes (`decayed`).
        let mut phi_k = SMatrix::<T, N, N>::identity();
        phi_k
            .fixed_rows_mut::<3>(crate::models::ATT)
            .copy_from(&prop.phi_att.map(nalgebra::convert::<f64, T>));
        let phi = phi_k * self.phi;
        if !phi.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFiniteState);
        }
        let step = self.crlb.config().wander.step(dt);
        let decayed = |mut phi: SMatrix<T, N, N>| {
            let rows = [
                (layout.dg_gm(), step.gyro_phi),
                (layout.ba_gm(), step.accel_phi),
                (layout.dg_wu(), step.warmup_phi),
                (layout.ba_wu(), step.warmup_phi),
            ];
            for (first, s) in rows {
                for r in first.into_iter().flat_map(|i| i..i + 3) {
                    if let Some(mut row) = phi.row_iter_mut().nth(r) {
                        row *= s;
                    }
                }
            }
            phi
        };
        if !measured {
            return Ok((decayed(phi), self.info));
        }
        let mut h_accel = SMatrix::<f64, 3, N>::zeros();
        layout.mean_accel(&env, &m, &prop, &period, &mut h_accel);
        // H_k Φ(k,0) and R⁻¹ (diagonal).
        let cfg = self.crlb.config();
        let mut h = SMatrix::<T, Z, N>::zeros();
        let mut r_inv = SVector::<T, Z>::zeros();
        let accel_row = if layout.gimbal_obs {
            h.fixed_view_mut::<3, 3>(0, crate::models::ATT)
                .copy_from(&nalgebra::Matrix3::identity());
            r_inv
                .fixed_rows_mut::<3>(0)
                .fill(T::one() / (cfg.sigma_gimbal * cfg.sigma_gimbal));
            3
        } else {
            0
        };
        h.fixed_rows_mut::<3>(accel_row)
            .copy_from(&h_accel.map(nalgebra::convert::<f64, T>));
        r_inv
            .fixed_rows_mut::<3>(accel_row)
            .fill(T::one() / (cfg.sigma_accel * cfg.sigma_accel));
        let hphi = h * phi;
        let weighted = SMatrix::<T, Z, Z>::from_diagonal(&r_inv) * hphi;
        let info = self.info + hphi.transpose() * weighted;
        if !info.iter().all(|v| v.is_finite()) {
            return Err(Error::NonFiniteState);
        }
        Ok((decayed(phi), info))
    }

    /// Periods processed (measured or predicted only).
    pub fn periods(&self) -> u32 {
        self.periods
    }

    /// The true (noise-free model) state at the current time (rad).
    pub fn true_state(&self) -> &SVector<f64, N> {
        &self.x_true
    }

    /// Posterior Cramér–Rao covariance at the current time (rad²).
    pub fn crlb_covariance(&self) -> SMatrix<T, N, N> {
        self.crlb.covariance()
    }

    /// Posterior Cramér–Rao σ of every state at the current time (rad).
    pub fn crlb_sigma(&self) -> SVector<T, N> {
        self.crlb.sigma()
    }

    /// The degree of observability `σ_CRLB / σ_prior` of every state.
    pub fn ratio(&self) -> SVector<T, N> {
        self.crlb.sigma().component_div(&self.sigma_prior)
    }
}

/// Eigenvalues and unit eigenvectors (columns) of the symmetric matrix `a`
/// by cyclic Jacobi rotations, swept until the off-diagonal part is below
/// `1e-15 ×` the Frobenius norm (Jacobi keeps small eigenvalues accurate
/// relative to the norm, which the rank decision needs). `None` on
/// non-finite input or if 100 sweeps do not converge.
pub fn jacobi_eigen<T: RealField + Copy, const N: usize>(
    mut a: SMatrix<T, N, N>,
) -> Option<(SVector<T, N>, SMatrix<T, N, N>)> {
    if !a.iter().all(|v| v.is_finite()) {
        return None;
    }
    let mut v = SMatrix::<T, N, N>::identity();
    let norm = a.norm();
    let tol = norm * nalgebra::convert::<f64, T>(1e-15);
    let two: T = nalgebra::convert(2.0);
    let at = |m: &SMatrix<T, N, N>, i: usize, j: usize| m.get((i, j)).copied().unwrap_or(T::zero());
    for _sweep in 0..100 {
        let mut off = T::zero();
        for i in 0..N {
            for j in 0..N {
                if i != j {
                    off += at(&a, i, j) * at(&a, i, j);
                }
            }
        }
        if off.sqrt() <= tol {
            return Some((a.diagonal(), v));
        }
        for p in 0..N {
            for q in (p + 1)..N {
                let apq = at(&a, p, q);
                if apq == T::zero() {
                    continue;
                }
                let app = at(&a, p, p);
                let aqq = at(&a, q, q);
                // Rotation angle: tan 2φ = 2 a_pq / (a_qq − a_pp).
                let theta = (aqq - app) / (two * apq);
                let sign = if theta >= T::zero() {
                    T::one()
                } else {
                    -T::one()
                };
                let t = sign / (theta.abs() + (theta * theta + T::one()).sqrt());
                let c = T::one() / (t * t + T::one()).sqrt();
                let s = t * c;
                // A ← Jᵀ A J with J the rotation in the (p, q) plane.
                for k in 0..N {
                    let akp = at(&a, k, p);
                    let akq = at(&a, k, q);
                    if let Some(x) = a.get_mut((k, p)) {
                        *x = c * akp - s * akq;
                    }
                    if let Some(x) = a.get_mut((k, q)) {
                        *x = s * akp + c * akq;
                    }
                }
                for k in 0..N {
                    let apk = at(&a, p, k);
                    let aqk = at(&a, q, k);
                    if let Some(x) = a.get_mut((p, k)) {
                        *x = c * apk - s * aqk;
                    }
                    if let Some(x) = a.get_mut((q, k)) {
                        *x = s * apk + c * aqk;
                    }
                }
                for k in 0..N {
                    let vkp = at(&v, k, p);
                    let vkq = at(&v, k, q);
                    if let Some(x) = v.get_mut((k, p)) {
                        *x = c * vkp - s * vkq;
                    }
                    if let Some(x) = v.get_mut((k, q)) {
                        *x = s * vkp + c * vkq;
                    }
                }
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The states each configuration is expected to converge
    /// (docs/model.md §Configurations): the non-orthogonalities always;
    /// the axis rotations in M1-pa, M2-ps, M3-pa, M4-pa; `lam_x`, `lam_z`
    /// in M2-ps; never the attitude.
    #[test]
    fn expected_observable_matches_the_configurations_table() {
        use ConfigId::*;
        let rotations = |id| matches!(id, M1Pa | M2Ps | M3Pa | M4Pa);
        for id in ConfigId::ALL {
            let (mut n, mut expected) = (0, 0);
            for s in id.states() {
                let want = match s.group {
                    Group::Attitude
                    | Group::GyroDrift
                    | Group::GyroGDrift
                    | Group::GyroScale
                    | Group::AccelBias
                    | Group::AccelScale
                    | Group::AccelSecondOrder
                    | Group::GyroMarkov
                    | Group::AccelMarkov
                    | Group::GyroWarmup
                    | Group::AccelWarmup => false,
                    Group::ThetaGT | Group::ThetaAT => true,
                    Group::ThetaGC | Group::ThetaAC => rotations(id),
                    Group::Lambda => id == M2Ps && s.name != "lam_y",
                };
                assert_eq!(
                    expected_observable_state(id, s),
                    want,
                    "{} {}",
                    id.as_str(),
                    s.name
                );
                n += 1;
                expected += usize::from(want);
            }
            let count = match id {
                M1Pa | M3Pa | M4Pa => 9,
                M2Ps => 14,
                M1Ps | M3Ps | M4Ps => 6,
            };
            assert_eq!((n, expected), (id.layout().n(), count), "{}", id.as_str());
        }
        // M3-ps shares M2-ps's states but observes no mounting angle.
        assert!(expected_observable(M2Ps, "lam_z", Group::Lambda));
        assert!(!expected_observable(M3Ps, "lam_z", Group::Lambda));
    }
}
