//! The extended Kalman filter over any configuration (SPEC §6).
//!
//! One filter period: [`Filter::predict`] propagates the state by one RK4
//! step over the commanded motion of the period and the covariance with the
//! structured transition (the parameters are constant, so only the three
//! attitude rows of `Φ` differ from the identity); [`Filter::update`] then
//! processes the period's measurement: the mean accelerometer output over the
//! period and, in M2, the gimbal angles at its end. The covariance update is
//! in Joseph form and `P` is kept symmetric.
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
//! both process and measurement noise; the gain and the Joseph form carry
//! their cross-covariance.

use core::marker::PhantomData;

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector3};

use crate::command::{CommandFrame, Period};
use crate::geometry::wrap_angle;
use crate::models::{Environment, Layout, Model, PeriodPropagation, ATT};

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

impl Options {
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
    /// Earth rate and gravity.
    pub env: Environment<T>,
    /// Accelerometer noise of the period mean, 1σ per axis (g).
    pub sigma_accel: T,
    /// Gyro white rate noise, constant over a period, 1σ per axis (rad/s).
    pub sigma_gyro: T,
    /// Gimbal-angle noise, 1σ per angle (rad).
    pub sigma_gimbal: T,
    /// Cold-start remedy and gate.
    pub options: Options,
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
/// `C = G Dᵀ` enters the gain and the Joseph form.
struct Noise<T: RealField + Copy, const N: usize, const Z: usize> {
    g: SMatrix<T, N, 3>,
    d: SMatrix<T, Z, 3>,
}

struct Measured<T: RealField + Copy, const N: usize, const Z: usize> {
    z: SVector<T, Z>,
    h: SMatrix<T, Z, N>,
    noise: Noise<T, N, Z>,
}

/// One Kalman gain with correlated noise.
struct Gain<T: RealField + Copy, const N: usize, const Z: usize> {
    k: SMatrix<T, N, Z>,
    s: SMatrix<T, Z, Z>,
    r_eff: SMatrix<T, Z, Z>,
    c: SMatrix<T, N, Z>,
    nis: T,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Pending<T: RealField + Copy, const N: usize> {
    period: Period<T>,
    prop: PeriodPropagation<T, N>,
}

/// The estimator of configuration `M` with `N` states and `Z` measurement
/// components per period.
#[derive(Clone, Debug, PartialEq)]
pub struct Filter<T: RealField + Copy, M, const N: usize, const Z: usize> {
    x: SVector<T, N>,
    p: SMatrix<T, N, N>,
    command: CommandFrame<T>,
    config: FilterConfig<T>,
    pending: Option<Pending<T, N>>,
    reference: Option<SVector<T, N>>,
    updates: u32,
    gated_run: u32,
    gate_open: bool,
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

/// `(½ tr(∇²g_a P), ½ tr(∇²g_a P ∇²g_b P))` of a 3-vector function `g`
/// whose Jacobian is `jac`, by central differences of `jac` along the
/// error-state directions `j` with `relevant(j)`.
fn hessian_terms<T: RealField + Copy, const N: usize>(
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

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    const LAYOUT: Layout = M::LAYOUT;
    const SIZES_AGREE: () = assert!(M::LAYOUT.n() == N && M::LAYOUT.z() == Z);

    /// A filter with initial estimate `x0` (rad) and prior standard
    /// deviations `sigma0` (rad), the computed frame aligned with n.
    pub fn new(
        config: FilterConfig<T>,
        x0: SVector<T, N>,
        sigma0: SVector<T, N>,
    ) -> Result<Self, Error> {
        #[allow(clippy::let_unit_value)]
        let () = Self::SIZES_AGREE;
        let inputs = [config.sigma_accel, config.sigma_gyro, config.sigma_gimbal];
        if !all_finite(x0.iter().chain(sigma0.iter()).copied().chain(inputs))
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
        if sigma0.iter().any(|s| *s <= T::zero()) || config.sigma_accel <= T::zero() {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        // A finite prior σ whose variance overflows (σ > 1.3e154 in f64,
        // 1.8e19 in f32) would give an infinite covariance, from which no
        // checkpoint of the filter could be restored (`from_parts`).
        let variance = sigma0.component_mul(&sigma0);
        if !all_finite(variance.iter().copied()) {
            return Err(Error::NonFiniteInput);
        }
        if Self::LAYOUT.gimbal_obs && config.sigma_gimbal <= T::zero() {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        Ok(Self {
            x: x0,
            p: SMatrix::from_diagonal(&variance),
            command: CommandFrame::aligned(config.env.earth_rate_n),
            config,
            pending: None,
            reference: None,
            updates: 0,
            gated_run: 0,
            gate_open: false,
            _model: PhantomData,
        })
    }

    /// Rebuilds a filter between two periods from its parts, as saved by a
    /// checkpoint ([`crate::calibrator::Calibrator::checkpoint`]): state `x`
    /// (rad), covariance `p` (rad², used as given, so a restored filter
    /// continues bit-identically), computed frame `c_cn` (`C^c_n`), nominal
    /// of the linearised mode, the update counter and the state of the NIS
    /// gate ([`Filter::gate_state`]). The Earth rate of the computed frame is
    /// the one of `config`.
    pub fn from_parts(
        config: FilterConfig<T>,
        x: SVector<T, N>,
        p: SMatrix<T, N, N>,
        c_cn: Matrix3<T>,
        nominal: Option<SVector<T, N>>,
        updates: u32,
        gate_state: (u32, bool),
    ) -> Result<Self, Error> {
        let mut f = Self::new(config, SVector::zeros(), SVector::repeat(T::one()))?;
        let nominal_values = nominal.iter().flat_map(|v| v.iter().copied());
        if !all_finite(
            x.iter()
                .chain(p.iter())
                .chain(c_cn.iter())
                .copied()
                .chain(nominal_values),
        ) {
            return Err(Error::NonFiniteInput);
        }
        if p.diagonal().iter().any(|v| *v <= T::zero()) {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        f.x = x;
        f.p = p;
        f.command.c_cn = c_cn;
        f.reference = nominal;
        f.updates = updates;
        (f.gated_run, f.gate_open) = gate_state;
        Ok(f)
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
    pub fn set_nominal(&mut self, x_nominal: Option<SVector<T, N>>) {
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
    pub fn reacquire_attitude(&mut self, c_cn: &Matrix3<T>, sigma: T) -> Result<(), Error> {
        if !all_finite(c_cn.iter().copied().chain([sigma])) {
            return Err(Error::NonFiniteInput);
        }
        if sigma <= T::zero() {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        let zeros = SMatrix::<T, 3, N>::zeros();
        self.p.fixed_rows_mut::<3>(ATT).copy_from(&zeros);
        self.p
            .fixed_columns_mut::<3>(ATT)
            .copy_from(&zeros.transpose());
        self.p
            .fixed_view_mut::<3, 3>(ATT, ATT)
            .copy_from(&(Matrix3::identity() * (sigma * sigma)));
        self.command.c_cn = *c_cn;
        if let Some(nominal) = self.reference.as_mut() {
            let att = self.x.fixed_rows::<3>(ATT).clone_owned();
            nominal.fixed_rows_mut::<3>(ATT).copy_from(&att);
        }
        self.pending = None;
        Ok(())
    }

    /// The nominal state at the current time, in linearised mode.
    pub fn nominal(&self) -> Option<&SVector<T, N>> {
        self.reference.as_ref()
    }

    /// The state estimate (rad), in the configuration's state order.
    pub fn state(&self) -> &SVector<T, N> {
        &self.x
    }

    /// The state covariance `P` (rad²).
    pub fn covariance(&self) -> &SMatrix<T, N, N> {
        &self.p
    }

    /// Per-state standard deviations `√P_ii` (rad).
    pub fn sigma(&self) -> SVector<T, N> {
        self.p.diagonal().map(|v| v.max(T::zero()).sqrt())
    }

    /// The filter's settings.
    pub fn config(&self) -> &FilterConfig<T> {
        &self.config
    }

    /// The computed frame the filter integrates from the commands.
    pub fn command_frame(&self) -> &CommandFrame<T> {
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

    /// Propagates the state and covariance over one period of length `dt`
    /// (s) with commanded angle increment `dtheta_c` (rad, c frame).
    /// On error the filter is left untouched.
    pub fn predict(&mut self, dtheta_c: &Vector3<T>, dt: T) -> Result<(), Error> {
        if !all_finite(dtheta_c.iter().copied().chain([dt])) {
            return Err(Error::NonFiniteInput);
        }
        if dt <= T::zero() {
            return Err(Error::InvalidPeriod);
        }
        let layout = Self::LAYOUT;
        let period = self.command.period(dtheta_c, dt);
        // The linearisation point: the estimate (EKF) or the nominal.
        let x_lin = self.reference.unwrap_or(self.x);
        let prop: PeriodPropagation<T, N> = layout
            .propagate(
                &self.config.env,
                &layout.matrices(&x_lin),
                &layout.attitude(&x_lin),
                &period,
            )
            .ok_or(Error::GimbalLock)?;
        let lin_prop = prop;
        // P ← Φ P Φᵀ + Q, touching only the attitude rows and columns.
        let a = &lin_prop.phi_att;
        let ap = a * self.p;
        let aaa = ap * a.transpose();
        let q_scale = self.config.sigma_gyro * dt;
        let b = lin_prop.noise_map * q_scale;
        let mut q = b * b.transpose();
        if self.config.options.second_order_dynamics {
            // Linearisation error of the period map x_{k+1} ≈ x_k + f(x_mid) T.
            let env = &self.config.env;
            let [_, wm, _] = period.omega_c;
            let [_, att_mid, _] = prop.att;
            let mut x_mid = self.x;
            x_mid.fixed_rows_mut::<3>(ATT).copy_from(&att_mid);
            let relevant =
                |j: usize| j < 9 || layout.lam().is_some_and(|i| (i..i + 3).contains(&j));
            let (_, q2) = hessian_terms(&x_mid, &self.p, relevant, |xp| {
                layout.attitude_rate_jacobian(env, &layout.matrices(xp), &layout.attitude(xp), &wm)
            })
            .ok_or(Error::GimbalLock)?;
            q += q2 * (dt * dt);
        }
        let mut p = self.p;
        p.fixed_rows_mut::<3>(ATT).copy_from(&ap);
        p.fixed_columns_mut::<3>(ATT).copy_from(&ap.transpose());
        p.fixed_view_mut::<3, 3>(ATT, ATT).copy_from(&(aaa + q));
        if !all_finite(p.iter().copied()) {
            return Err(Error::NonFiniteState);
        }
        let [_, _, att1] = prop.att;
        let mut x_lin_end = x_lin;
        x_lin_end.fixed_rows_mut::<3>(ATT).copy_from(&att1);
        let x_new = match self.reference {
            // x̂_{k+1} = x_nom,k+1 ⊞ Φ (x̂_k ⊟ x_nom,k).
            Some(_) => {
                let mut delta = layout.difference(&self.x, &x_lin);
                let d_att = prop.phi_att * delta;
                delta.fixed_rows_mut::<3>(ATT).copy_from(&d_att);
                self.reference = Some(x_lin_end);
                x_lin_end + delta
            }
            None => x_lin_end,
        };
        if !all_finite(x_new.iter().copied()) {
            return Err(Error::NonFiniteState);
        }
        self.x = x_new;
        self.p = p;
        self.command.advance(&period);
        self.pending = Some(Pending { period, prop });
        Ok(())
    }

    /// Predicted measurement, its Jacobian (w.r.t. the state at the end of
    /// the period) for the state `x` whose period trajectory is `prop`, and
    /// the measurement's share of the period's process noise (see [`Noise`]).
    fn measure(&self, x: &SVector<T, N>, pending: &Pending<T, N>) -> Measured<T, N, Z> {
        let layout = Self::LAYOUT;
        let m = layout.matrices(x);
        let (za, ha, da) = layout.mean_accel(&self.config.env, &m, &pending.prop, &pending.period);
        let mut z = SVector::<T, Z>::zeros();
        let mut h = SMatrix::<T, Z, N>::zeros();
        let accel_row = if layout.gimbal_obs {
            let att = layout.attitude(x);
            z.fixed_rows_mut::<3>(0).copy_from(&att);
            h.fixed_view_mut::<3, 3>(0, ATT)
                .copy_from(&Matrix3::identity());
            3
        } else {
            0
        };
        z.fixed_rows_mut::<3>(accel_row).copy_from(&za);
        h.fixed_rows_mut::<3>(accel_row).copy_from(&ha);
        // Unit-variance noise w = σ_g u: x_{k+1} gets G u, z gets D u.
        let sigma_g = self.config.sigma_gyro;
        let mut g = SMatrix::<T, N, 3>::zeros();
        g.fixed_rows_mut::<3>(ATT)
            .copy_from(&(pending.prop.noise_map * (sigma_g * pending.period.dt)));
        let mut d = SMatrix::<T, Z, 3>::zeros();
        d.fixed_rows_mut::<3>(accel_row).copy_from(&(da * sigma_g));
        Measured {
            z,
            h,
            noise: Noise { g, d },
        }
    }

    /// The trajectory over the pending period that ends at state `x`
    /// (integrated backwards), for relinearisation.
    fn retrace(&self, x: &SVector<T, N>, pending: &Pending<T, N>) -> Result<Pending<T, N>, Error> {
        let layout = Self::LAYOUT;
        let pr = &pending.period;
        let reversed = pr.reversed();
        let m = layout.matrices(x);
        let back: PeriodPropagation<T, N> = layout
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
        Ok(Pending { period: *pr, prop })
    }

    /// Second-order terms of the accelerometer rows: returns
    /// (`½ tr(∇²h_a P)`, `½ tr(∇²h_a P ∇²h_b P)`), by central differences of
    /// the instantaneous accelerometer Jacobian at the end of the period.
    fn second_order(&self, x: &SVector<T, N>, pending: &Pending<T, N>) -> (Vector3<T>, Matrix3<T>) {
        let layout = Self::LAYOUT;
        let env = &self.config.env;
        let [_, _, c_end] = pending.period.c_cn;
        let relevant = |j: usize| {
            j < 3
                || layout.ac().is_some_and(|i| (i..i + 3).contains(&j))
                || (layout.at()..layout.at() + 3).contains(&j)
                || layout.lam().is_some_and(|i| (i..i + 3).contains(&j))
        };
        hessian_terms(x, &self.p, relevant, |xp| {
            Some(layout.accel_jacobian(env, &layout.matrices(xp), &layout.attitude(xp), &c_end))
        })
        .unwrap_or((Vector3::zeros(), Matrix3::zeros()))
    }

    /// Processes the measurement of the period that [`Filter::predict`] just
    /// propagated over. On error (other than a singular covariance after the
    /// update) the state and covariance are left untouched.
    pub fn update(&mut self, obs: &Observation<T>) -> Result<Innovation<T, Z>, Error> {
        let layout = Self::LAYOUT;
        let pending = self.pending.ok_or(Error::NoPrediction)?;
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
        let mut z = SVector::<T, Z>::zeros();
        let mut r = SVector::<T, Z>::zeros();
        let sa2 = self.config.sigma_accel * self.config.sigma_accel;
        let accel_row = if let Some(g) = gimbal {
            z.fixed_rows_mut::<3>(0).copy_from(&g);
            let sg2 = self.config.sigma_gimbal * self.config.sigma_gimbal;
            r.fixed_rows_mut::<3>(0).fill(sg2);
            3
        } else {
            0
        };
        z.fixed_rows_mut::<3>(accel_row).copy_from(&obs.accel_mean);
        r.fixed_rows_mut::<3>(accel_row).fill(sa2);
        let r = SMatrix::<T, Z, Z>::from_diagonal(&r);

        if let Some(x_nom) = self.reference {
            return self.update_linearised(&x_nom, &pending, &z, &r, accel_row);
        }
        let opts = self.config.options;
        let (mean2, cov2) = if opts.second_order_covariance || opts.second_order_mean {
            self.second_order(&self.x, &pending)
        } else {
            (Vector3::zeros(), Matrix3::zeros())
        };
        let x_prior = self.x;
        let iterations = if self.updates < opts.iterate_updates {
            opts.iterations
        } else {
            0
        };
        let mut x_lin = x_prior;
        let mut lin = pending;
        let mut result = None;
        for it in 0..=iterations {
            if it > 0 {
                lin = self.retrace(&x_lin, &pending)?;
            }
            let Measured { z: zp, h, noise } = self.measure(&x_lin, &lin);
            let mut nu = z - zp;
            // IEKF: ν = z − h(x_i) − H (x̂ − x_i).
            nu -= h * layout.difference(&x_prior, &x_lin);
            if opts.second_order_mean {
                let mut acc = nu.fixed_rows_mut::<3>(accel_row);
                acc -= mean2;
            }
            if layout.gimbal_obs {
                for v in nu.iter_mut().take(3) {
                    *v = wrap_angle(*v);
                }
            }
            let mut extra = SMatrix::<T, Z, Z>::zeros();
            if opts.second_order_covariance {
                let mut blk = extra.fixed_view_mut::<3, 3>(accel_row, accel_row);
                blk += cov2;
            }
            let gain = self.gain(&h, &nu, &r, &noise, &extra)?;
            x_lin = x_prior + gain.k * nu;
            result = Some((gain, h, nu));
        }
        let (gain, h, nu) = result.ok_or(Error::NoPrediction)?;
        self.commit(x_lin, &gain, &h, nu)
    }

    /// The update of the linearised filter about the nominal `x_nom`.
    fn update_linearised(
        &mut self,
        x_nom: &SVector<T, N>,
        pending: &Pending<T, N>,
        z: &SVector<T, Z>,
        r: &SMatrix<T, Z, Z>,
        accel_row: usize,
    ) -> Result<Innovation<T, Z>, Error> {
        let layout = Self::LAYOUT;
        let Measured { z: z_nom, h, noise } = self.measure(x_nom, pending);
        let delta = layout.difference(&self.x, x_nom);
        let mut nu = z - z_nom - h * delta;
        if layout.gimbal_obs {
            for v in nu.iter_mut().take(accel_row) {
                *v = wrap_angle(*v);
            }
        }
        let gain = self.gain(&h, &nu, r, &noise, &SMatrix::zeros())?;
        let x_new = x_nom + delta + gain.k * nu;
        self.commit(x_new, &gain, &h, nu)
    }

    /// Gain with measurement noise `R + D Dᵀ + extra` correlated with the
    /// process noise by `C = G Dᵀ`: `S = H P Hᵀ + H C + Cᵀ Hᵀ + R_eff`,
    /// `K = (P Hᵀ + C) S⁻¹`.
    fn gain(
        &self,
        h: &SMatrix<T, Z, N>,
        nu: &SVector<T, Z>,
        r: &SMatrix<T, Z, Z>,
        noise: &Noise<T, N, Z>,
        extra: &SMatrix<T, Z, Z>,
    ) -> Result<Gain<T, N, Z>, Error> {
        let c = noise.g * noise.d.transpose();
        let r_eff = r + noise.d * noise.d.transpose() + extra;
        let ph = self.p * h.transpose() + c;
        let mut s = h * ph + h * c + r_eff;
        s = (s + s.transpose()) * nalgebra::convert::<f64, T>(0.5);
        let chol = s.cholesky().ok_or(Error::InnovationNotPositiveDefinite)?;
        let k = chol.solve(&ph.transpose()).transpose();
        let nis = nu.dot(&chol.solve(nu));
        Ok(Gain {
            k,
            s,
            r_eff,
            c,
            nis,
        })
    }

    /// Gate, Joseph-form covariance update, and state commit.
    fn commit(
        &mut self,
        x_new: SVector<T, N>,
        gain: &Gain<T, N, Z>,
        h: &SMatrix<T, Z, N>,
        nu: SVector<T, Z>,
    ) -> Result<Innovation<T, Z>, Error> {
        let innovation = Innovation {
            nu,
            s: gain.s,
            nis: gain.nis,
        };
        let (k, r, c) = (&gain.k, &gain.r_eff, &gain.c);
        let layout = Self::LAYOUT;
        if !all_finite(x_new.iter().copied()) || !innovation.nis.is_finite() {
            return Err(Error::NonFiniteState);
        }
        let gate = self.config.options.nis_gate;
        let above = gate > 0.0 && innovation.nis > nalgebra::convert(gate);
        if above && !self.gate_open && self.gated_run < MAX_GATED_RUN {
            self.gated_run += 1;
            self.pending = None;
            return Err(Error::Gated);
        }
        // Joseph form with correlated noise:
        // P = (I − K H) P (I − K H)ᵀ + K R Kᵀ − (I − K H) C Kᵀ − K Cᵀ (I − K H)ᵀ.
        let ikh = SMatrix::<T, N, N>::identity() - k * h;
        let ick = ikh * c * k.transpose();
        let mut p = ikh * self.p * ikh.transpose() + k * r * k.transpose() - ick - ick.transpose();
        p = (p + p.transpose()) * nalgebra::convert::<f64, T>(0.5);
        if p.diagonal().iter().any(|v| *v <= T::zero()) || !all_finite(p.iter().copied()) {
            return Err(Error::CovarianceNotPositiveDefinite);
        }
        // Keep the Euler attitude angles in (−π, π]; P is unchanged by 2π shifts.
        let mut x = x_new;
        if layout.attitude != crate::models::AttitudeKind::Misalignment {
            for v in x.iter_mut().take(3) {
                *v = wrap_angle(*v);
            }
        }
        self.x = x;
        self.p = p;
        self.pending = None;
        self.updates = self.updates.saturating_add(1);
        self.gated_run = 0;
        self.gate_open = above;
        Ok(innovation)
    }

    /// One filter period: [`Filter::predict`] then [`Filter::update`].
    pub fn step(
        &mut self,
        dtheta_c: &Vector3<T>,
        dt: T,
        obs: &Observation<T>,
    ) -> Result<Innovation<T, Z>, Error> {
        let saved = (self.x, self.p, self.command, self.reference);
        self.predict(dtheta_c, dt)?;
        match self.update(obs) {
            Ok(i) => Ok(i),
            Err(Error::Gated) => Err(Error::Gated),
            Err(e) => {
                (self.x, self.p, self.command, self.reference) = saved;
                self.pending = None;
                Err(e)
            }
        }
    }

    /// Measurement function and Jacobian at an arbitrary end-of-period state,
    /// for tests and the observability analysis: returns `(h(x), H)` for the
    /// period that [`Filter::predict`] last propagated over.
    pub fn measurement_at(
        &self,
        x: &SVector<T, N>,
    ) -> Result<(SVector<T, Z>, SMatrix<T, Z, N>), Error> {
        let pending = self.pending.ok_or(Error::NoPrediction)?;
        let lin = self.retrace(x, &pending)?;
        let m = self.measure(x, &lin);
        Ok((m.z, m.h))
    }
}
