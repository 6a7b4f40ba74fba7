//! The schema of the protocol (docs/wire.md): every [`Message`] and what it
//! carries: a [`Sample`] per period (platform → calibrator), the
//! [`CalibratorConfig`] that starts a run, the running [`Estimate`] and the
//! [`Checkpoint`] (calibrator → host), with the calibrator's bookkeeping
//! ([`Progress`], [`RejectCounts`]). The postcard encoding follows the
//! declaration order of fields and variants: nothing here may be reordered.

use heapless::Vec;
use serde::{Deserialize, Serialize};

use crate::ekf::Options;
use crate::models::{ConfigId, ErrorModel, Wander};

/// Largest state dimension of the models this build holds: the largest
/// [`ConfigId::layout_with`] over its configurations (cargo features
/// `m1-pa` … `m4-ps`) and error models (`installation-model`,
/// `full-model`). 54 with the default features (the full M2-ps and M3-ps
/// models); 48 in an image of the full M1-pa model alone, 18 in one of the
/// installation M2-ps model, 12 of the installation M1-pa model. It sizes
/// the messages' vectors only: the bytes of a message do not depend on it
/// (postcard writes a vector's length before its items).
///
/// # Examples
///
/// ```
/// use rollcal::models::{ConfigId, ErrorModel};
/// // The default features hold every configuration in both models.
/// assert_eq!(rollcal::wire::MAX_STATES, ConfigId::M2Ps.layout_with(ErrorModel::Full).n());
/// ```
pub const MAX_STATES: usize = max_built_states();

/// [`MAX_STATES`], computed from the build's features.
const fn max_built_states() -> usize {
    let mut n = 0;
    let mut rest: &[ConfigId] = &ConfigId::ALL;
    while let [c, tail @ ..] = rest {
        if c.is_built() {
            if cfg!(feature = "installation-model") {
                let k = c.layout_with(ErrorModel::Installation).n();
                n = if k > n { k } else { n };
            }
            if cfg!(feature = "full-model") {
                let k = c.layout_with(ErrorModel::Full).n();
                n = if k > n { k } else { n };
            }
        }
        rest = tail;
    }
    n
}

/// Capacity of a row-major covariance of [`MAX_STATES`] states
/// ([`crate::session::Covariance`]).
pub const MAX_COVARIANCE: usize = MAX_STATES * MAX_STATES;

/// Capacity of [`Checkpoint::factor`]: the upper triangle, diagonal
/// included, of an `N×N` factor of [`MAX_STATES`] states,
/// `N (N + 1) / 2` values (1 485 for 54 states, 171 for 18).
pub const MAX_FACTOR: usize = factor_len(MAX_STATES);

/// Values in the upper triangle, diagonal included, of an `n×n` matrix:
/// `n (n + 1) / 2` (the length of [`Checkpoint::factor`] of a model of `n`
/// states).
///
/// # Examples
///
/// ```
/// assert_eq!(rollcal::wire::factor_len(12), 78);
/// assert_eq!(rollcal::wire::factor_len(54), 1485);
/// ```
pub const fn factor_len(n: usize) -> usize {
    n * (n + 1) / 2
}

/// Where entry `(r, c)`, `r ≤ c < n`, of an `n×n` upper triangle stored
/// row by row ([`Checkpoint::factor`]) is: row `r` starts after the
/// `n − k` entries of each row `k < r`, on its diagonal.
///
/// # Examples
///
/// ```
/// use rollcal::wire::{factor_index, factor_len};
///
/// assert_eq!(factor_index(3, 0, 0), 0);
/// assert_eq!(factor_index(3, 1, 1), 3); // row 1 starts after the 3 of row 0
/// assert_eq!(factor_index(3, 2, 2), factor_len(3) - 1);
/// ```
pub const fn factor_index(n: usize, r: usize, c: usize) -> usize {
    r * n - r * r.saturating_sub(1) / 2 + (c - r)
}

/// One filter period as measured by the platform (docs/wire.md). `f32` fields:
/// f32 spacing is 1.2e-7 g at 1 g (the accelerometer noise is 1e-6 g) and
/// 0.05″ at π rad (the gimbal noise is 10″).
///
/// # Examples
///
/// A sample of a platform at rest, level, and its round trip through a
/// frame:
///
/// ```
/// use rollcal::wire::{decode_frame, encode, Message, Sample, MAX_FRAME_LEN};
///
/// let sample = Sample {
///     seq: 42,
///     t_us: 42_000_000,
///     dt: 1.0,
///     dtheta_cmd: [0.0; 3],
///     c_cn_quat: [1.0, 0.0, 0.0, 0.0], // C^c_n = I
///     accel_mean: [0.0, 1.0, 0.0],     // 1 g up (North–Up–East)
///     gimbal: None,                    // M2-ps only
/// };
/// let mut buf = [0u8; MAX_FRAME_LEN];
/// let n = encode(&Message::Sample(sample), &mut buf).unwrap();
/// assert_eq!(decode_frame(&mut buf[..n - 1]), Ok(Message::Sample(sample)));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Sequence number, +1 per period (the first sample may start anywhere).
    pub seq: u32,
    /// Time at the end of the period (µs, any fixed origin). An integer:
    /// f32 seconds would resolve only 0.5 ms after 1.5 h.
    pub t_us: u64,
    /// Period length `T` (s).
    pub dt: f32,
    /// Commanded angle increment `Δθc = ∫ωc dt` over the period (rad, c
    /// frame). `f64`: its rounding is not noise but a bias that lasts a
    /// whole path segment (the Earth rate's share of an increment is
    /// ~4e-8 rad and changes slowly): in `f32` it moved the M1-pa answer by
    /// 0.11σ.
    pub dtheta_cmd: [f64; 3],
    /// The computed frame at the end of the period, `C^c_n(t_k)`, as the unit
    /// quaternion `[w, x, y, z]` of its rotation vector θ (`C^c_n = R(θ)`,
    /// [`crate::geometry::quaternion_from_dcm`]). It makes the commanded
    /// motion across lost samples known (see [`crate::calibrator`], "Lost
    /// data"); f32 resolves it to 6e-8 rad (0.012″).
    pub c_cn_quat: [f32; 4],
    /// Mean accelerometer output over the period (g, instrument axes).
    pub accel_mean: [f32; 3],
    /// Gimbal angles `(α, β, γ)` at the end of the period (rad); required by
    /// M2-ps, ignored by the other configurations.
    pub gimbal: Option<[f32; 3]>,
}

/// Validation limits of the calibrator (see [`crate::calibrator`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Limits {
    /// Expected period `T` (s).
    pub period_s: f64,
    /// Accepted deviation of `dt` from `period_s`, and of the timestamp
    /// difference from `dt` per elapsed period (s).
    pub period_tolerance_s: f64,
    /// Largest accepted |component| of the mean specific force (g).
    pub max_accel_g: f64,
    /// Largest accepted |component| of the commanded increment (rad).
    pub max_increment_rad: f64,
    /// Largest accepted |gimbal angle| (rad).
    pub max_gimbal_rad: f64,
    /// Longest gap (missing periods) across which the calibrator searches
    /// for the commanded motion (the last path rate, then one switch to the
    /// new sample's path rate at any period boundary of the gap). A longer
    /// gap, or one whose motion is not found, re-acquires the attitude.
    pub max_bridge: u32,
    /// The motion across a gap is accepted as found when it carries the
    /// computed frame to the sample's reported `C^c_n` within this angle
    /// (rad); also the accepted norm error of the reported quaternion.
    pub frame_tolerance_rad: f64,
}

impl Default for Limits {
    /// 1 s period ± 1 ms, |f| ≤ 2 g, |Δθc| ≤ 0.1 rad, |θA| ≤ 2π, the motion
    /// across gaps of up to 7200 periods searched, frame tolerance 1e-5 rad
    /// (2″).
    fn default() -> Self {
        Self {
            period_s: 1.0,
            period_tolerance_s: 1e-3,
            max_accel_g: 2.0,
            max_increment_rad: 0.1,
            max_gimbal_rad: 2.0 * core::f64::consts::PI,
            max_bridge: 7200,
            frame_tolerance_rad: 1e-5,
        }
    }
}

/// Everything a calibrator needs to start: configuration, noise levels,
/// environment, prior, validation limits and estimate cadence. Sent as the
/// `Configure` control message; all scalars `f64` so one message serves the
/// f32 and f64 builds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibratorConfig {
    /// Which estimator to run.
    pub config: ConfigId,
    /// Accelerometer noise of the period mean, 1σ per axis (g).
    pub sigma_accel_g: f64,
    /// Gyro white rate noise, 1σ per axis (rad/s).
    pub sigma_gyro_rad_s: f64,
    /// Gimbal-angle noise, 1σ per angle (rad).
    pub sigma_gimbal_rad: f64,
    /// Earth rate `ω^n_ie` (rad/s, North–Up–East).
    pub earth_rate_n: [f64; 3],
    /// Specific force at rest `f^n` (g, North–Up–East), normally `[0, 1, 0]`.
    pub gravity_n: [f64; 3],
    /// Prior σ of every state (rad); the initial estimate is zero.
    pub prior_sigma_rad: f64,
    /// Filter options (cold-start remedy, gate).
    pub options: Options,
    /// Validation limits.
    pub limits: Limits,
    /// Emit an [`Estimate`] every this many accepted samples (0 = never;
    /// [`crate::calibrator::Calibrator::estimate`] is always available).
    pub estimate_every: u32,
    /// Which errors the filter estimates: the installation errors alone, or
    /// followed by the instruments' own ([`ErrorModel::Full`], 36 more
    /// states; needs the `full-model` feature).
    pub errors: ErrorModel,
    /// Prior σ of the instrument errors (used by [`ErrorModel::Full`]).
    pub instrument_prior: InstrumentPrior,
    /// The instruments' errors that wander (used by [`ErrorModel::Full`];
    /// [`Wander::none`] for constant errors; docs/model.md §Errors that
    /// wander), in internal units: rad/s, s, rad/s per √s, g, s, g per √s.
    pub wander: Wander<f64>,
}

/// Prior σ of the instrument errors of the full model (docs/model.md
/// §Instrument errors), one per group, in the filter's internal units; the
/// initial estimate is zero. A zero σ: the model does not estimate that
/// term (it stays zero). [`Default`] is docs/model.md §The instrumented
/// scenario's: 1 °/h, 1 °/h/g, 2 000 ppm, 1 000 µg, 1 000 ppm, 100 µg/g².
///
/// # Examples
///
/// ```
/// use rollcal::models::Wander;
/// use rollcal::wire::InstrumentPrior;
///
/// let p = InstrumentPrior::default();
/// assert_eq!(p.ba_g, 1e-3); // 1 000 µg
/// let sigma = p.sigma(&Wander::none());
/// assert_eq!(sigma.len(), 36);
/// assert_eq!(sigma[15], 1e-3); // ba_x, after dg (3), D_g (9), kg (3)
/// assert_eq!(sigma[21], 1e-4); // k2_x: 100 µg/g²
/// // The Gauss–Markov parts' prior is their stationary σ, the warm-up's
/// // its amplitude's σ (none here).
/// assert_eq!(sigma[24..], [0.0; 12]);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct InstrumentPrior {
    /// σ of each constant gyro drift `dg` (rad/s).
    pub dg_rad_s: f64,
    /// σ of each entry of the g-sensitive drift `D_g` (rad/s per g).
    pub d_g_rad_s_g: f64,
    /// σ of each torquer scale-factor error `kg` (dimensionless).
    pub kg: f64,
    /// σ of each accelerometer bias `ba` (g).
    pub ba_g: f64,
    /// σ of each accelerometer scale-factor error `ka` (dimensionless).
    pub ka: f64,
    /// σ of each accelerometer second-order coefficient `k2` (g per g²).
    pub k2: f64,
}

impl Default for InstrumentPrior {
    fn default() -> Self {
        let deg_h = core::f64::consts::PI / 180.0 / 3600.0;
        Self {
            dg_rad_s: deg_h,
            d_g_rad_s_g: deg_h,
            kg: 2e-3,
            ba_g: 1e-3,
            ka: 1e-3,
            k2: 1e-4,
        }
    }
}

/// The number of instrument states of the full model
/// ([`ErrorModel::extra_states`]): 24 terms, 6 Gauss–Markov parts and 6
/// warm-up transients.
pub const INSTRUMENT_STATES: usize = ErrorModel::Full.extra_states();

impl InstrumentPrior {
    /// The prior σ of the full model's 36 instrument states in state order
    /// `[dg (3), D_g (9, row-major), kg (3), ba (3), ka (3), k2 (3), δ_g (3),
    /// δ_a (3), w_g (3), w_a (3)]` (internal units); the Gauss–Markov parts
    /// `δ_g`, `δ_a` start in their stationary distribution and the warm-up
    /// `w_g`, `w_a` with its amplitude's σ, both of `wander`.
    pub fn sigma(&self, wander: &Wander<f64>) -> [f64; INSTRUMENT_STATES] {
        core::array::from_fn(|i| match i {
            0..=2 => self.dg_rad_s,
            3..=11 => self.d_g_rad_s_g,
            12..=14 => self.kg,
            15..=17 => self.ba_g,
            18..=20 => self.ka,
            21..=23 => self.k2,
            24..=26 => wander.gyro_markov_sigma,
            27..=29 => wander.accel_markov_sigma,
            30..=32 => wander.gyro_warmup_sigma,
            _ => wander.accel_warmup_sigma,
        })
    }

    /// Every σ finite, zero or positive, and within its bounds: no
    /// [`InstrumentPrior::invalid_field`].
    pub fn is_valid(&self) -> bool {
        self.invalid_field().is_none()
    }
}

impl CalibratorConfig {
    /// The paper's settings (docs/model.md §The paper's scenario) for configuration `config`: noise
    /// 1e-6 g, 0.1°/h, 10″; latitude 34.25° with Earth rate; prior 1°;
    /// default options and limits; an estimate every 60 samples; the
    /// installation model (the default instrument prior and no wandering
    /// errors, unused by it).
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::wire::{CalibratorConfig, Limits};
    /// use rollcal::ConfigId;
    ///
    /// let config = CalibratorConfig {
    ///     sigma_accel_g: 2e-6,
    ///     limits: Limits { period_s: 0.5, ..Limits::default() },
    ///     ..CalibratorConfig::paper(ConfigId::M2Ps)
    /// };
    /// assert_eq!(config.config, ConfigId::M2Ps);
    /// assert_eq!(config.gravity_n, [0.0, 1.0, 0.0]);
    /// assert_eq!(config.prior_sigma_rad, std::f64::consts::PI / 180.0); // 1°
    /// assert_eq!(config.estimate_every, 60);
    /// ```
    pub fn paper(config: ConfigId) -> Self {
        let deg = core::f64::consts::PI / 180.0;
        let e = crate::geometry::earth_rate_n(crate::geometry::EARTH_RATE, 34.25 * deg);
        Self {
            config,
            sigma_accel_g: 1e-6,
            sigma_gyro_rad_s: 0.1 * deg / 3600.0,
            sigma_gimbal_rad: 10.0 * deg / 3600.0,
            earth_rate_n: [e.x, e.y, e.z],
            gravity_n: [0.0, 1.0, 0.0],
            prior_sigma_rad: deg,
            options: Options::default(),
            limits: Limits::default(),
            estimate_every: 60,
            errors: ErrorModel::Installation,
            instrument_prior: InstrumentPrior::default(),
            wander: Wander::none(),
        }
    }
}

/// Counts of rejected samples by reason (see
/// [`crate::calibrator::RejectReason`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RejectCounts {
    /// A field is NaN or infinite.
    pub non_finite: u32,
    /// `dt` outside the expected period ± tolerance.
    pub period: u32,
    /// |specific force| component above the limit.
    pub accel_range: u32,
    /// |commanded increment| component above the limit.
    pub increment_range: u32,
    /// |gimbal angle| above the limit.
    pub gimbal_range: u32,
    /// No gimbal angles for a configuration that observes them.
    pub missing_gimbal: u32,
    /// Same sequence number as the last accepted sample.
    pub duplicate: u32,
    /// Sequence number below the last accepted one.
    pub out_of_order: u32,
    /// Timestamp not after the last accepted one.
    pub time_backwards: u32,
    /// Timestamp difference disagrees with `dt` × elapsed periods (a clock
    /// step is re-anchored once the next sample confirms it).
    pub time_mismatch: u32,
    /// The computed-frame quaternion is not a unit quaternion.
    pub frame_attitude: u32,
    /// The filter refused the period (state left untouched).
    pub filter: u32,
}

impl RejectCounts {
    /// Total of all reasons.
    pub fn total(&self) -> u32 {
        [
            self.non_finite,
            self.period,
            self.accel_range,
            self.increment_range,
            self.gimbal_range,
            self.missing_gimbal,
            self.duplicate,
            self.out_of_order,
            self.time_backwards,
            self.time_mismatch,
            self.frame_attitude,
            self.filter,
        ]
        .iter()
        .fold(0u32, |a, b| a.saturating_add(*b))
    }
}

/// Calibrator bookkeeping (part of [`Checkpoint`] and [`Estimate`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// Sequence number of the last accepted sample.
    pub last_seq: Option<u32>,
    /// Timestamp of the last accepted sample (µs).
    pub last_t_us: Option<u64>,
    /// Commanded increment of the last accepted sample (rad, c frame), for
    /// finding the motion across a gap.
    pub last_increment: [f64; 3],
    /// A sample whose timestamp disagreed with the last accepted one:
    /// `(seq, t_us)`. If the next sample's timestamp agrees with it, the
    /// clock stepped and the time is re-anchored there.
    pub clock_candidate: Option<(u32, u64)>,
    /// NIS of the last update (NaN before the first).
    pub last_nis: f64,
    /// Samples accepted.
    pub accepted: u32,
    /// Missing periods bridged by prediction without measurement, along the
    /// commanded motion found across the gap.
    pub bridged: u32,
    /// Gaps across which the motion was not found: the computed frame was
    /// set from the reported `C^c_n` and the attitude states re-acquired
    /// (their covariance re-opened to the prior, the parameters' kept).
    pub reacquired: u32,
    /// Missing periods of those gaps (predicted along the shortest rotation).
    pub reacquired_periods: u32,
    /// Clock steps re-anchored.
    pub clock_steps: u32,
    /// Records appended to the sample log (measured samples and bridged
    /// periods), for the final passes.
    pub logged: u32,
    /// Why the log no longer holds the whole run (then [`Message::Finish`]
    /// can only answer with pass 1); `None` while it does.
    pub log_incomplete: Option<SinglePassReason>,
    /// Accepted samples whose update failed the NIS gate (predicted only).
    pub gated: u32,
    /// Accepted samples since the last emitted estimate.
    pub since_estimate: u32,
    /// Rejected samples by reason.
    pub rejects: RejectCounts,
}

impl Default for Progress {
    fn default() -> Self {
        Self {
            last_seq: None,
            last_t_us: None,
            last_increment: [0.0; 3],
            clock_candidate: None,
            last_nis: f64::NAN,
            accepted: 0,
            bridged: 0,
            reacquired: 0,
            reacquired_periods: 0,
            clock_steps: 0,
            logged: 0,
            log_incomplete: None,
            gated: 0,
            since_estimate: 0,
            rejects: RejectCounts::default(),
        }
    }
}

/// Why a final answer is pass 1 only, not the estimator of record over the
/// whole run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SinglePassReason {
    /// The calibrator was fed without a sample log.
    NoLog,
    /// The sample log filled up.
    LogFull,
    /// The sample log's storage failed.
    LogStorage,
    /// The log holds a different number of records than the calibrator
    /// appended (e.g. after a restore without the matching log).
    LogMismatch,
    /// A gap's motion was not found and the attitude was re-acquired: the
    /// later passes cannot yet linearise across it.
    Reacquired,
    /// A period whose gap had been bridged was then refused by the filter.
    FilterFailed,
    /// The multi-pass estimator refused the log (an empty log, or the
    /// back-propagation hit gimbal lock).
    Estimator,
    /// The sample log could not encode a record (e.g. a
    /// [`crate::estimator::PackedLog`] whose command table is full).
    LogUnrepresentable,
}

impl core::fmt::Display for SinglePassReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            SinglePassReason::NoLog => "no sample log",
            SinglePassReason::LogFull => "the sample log is full",
            SinglePassReason::LogStorage => "the sample log's storage failed",
            SinglePassReason::LogMismatch => "the sample log does not match the calibrator",
            SinglePassReason::Reacquired => "the attitude was re-acquired after a gap",
            SinglePassReason::FilterFailed => "the filter refused a period after a bridged gap",
            SinglePassReason::Estimator => "the multi-pass estimator refused the log",
            SinglePassReason::LogUnrepresentable => "the sample log could not encode a record",
        })
    }
}

/// What an [`Estimate`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EstimateKind {
    /// The running estimate of pass 1, while samples arrive.
    Running,
    /// The answer of record: the multi-pass estimator over the whole logged
    /// run, after `passes` passes (`converged`: the last moved < 0.1σ).
    Final {
        /// Passes run.
        passes: u8,
        /// The last pass moved no state by more than the tolerance.
        converged: bool,
    },
    /// The final answer, but pass 1 only (the running estimate at the end of
    /// the stream), because of `reason`; `logged` records were in the log.
    SinglePass {
        /// Why the later passes could not run.
        reason: SinglePassReason,
        /// Records in the log.
        logged: u32,
    },
}

/// The running estimate (docs/wire.md). `f64` even from an f32 build (exact), so
/// that an f64 firmware build can be compared with the host to 1e-9 rad.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Estimate {
    /// The configuration; the states are in its order
    /// ([`ConfigId::states_with`] of `config` and `errors`).
    pub config: ConfigId,
    /// The error model: the installation states alone, or followed by the
    /// 21 instrument errors (internal units: rad/s, rad/s per g, 1, g, 1).
    pub errors: ErrorModel,
    /// Sequence number of the last accepted sample (0 before any).
    pub seq: u32,
    /// Filter updates processed.
    pub updates: u32,
    /// Estimated states (rad; the instrument errors in internal units).
    pub state: Vec<f64, MAX_STATES>,
    /// Their σ, `√P_ii` (the states' units).
    pub sigma: Vec<f64, MAX_STATES>,
    /// Calibrator bookkeeping: last NIS, accepted, bridged, re-acquired,
    /// rejected by reason.
    pub progress: Progress,
    /// Frames the receiver's decoder rejected so far (as told to the
    /// calibrator by [`crate::calibrator::Calibrator::set_frame_errors`]).
    pub frame_errors: u32,
    /// A running estimate, or the final answer (and how it was reached).
    pub kind: EstimateKind,
}

/// Everything a calibrator needs to continue bit-identically after a reset.
/// Scalars are `f64` (an f32 value round-trips exactly).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Checkpoint {
    /// The configuration.
    pub config: ConfigId,
    /// The error model.
    pub errors: ErrorModel,
    /// State `x` (rad).
    pub state: Vec<f64, MAX_STATES>,
    /// The packed U-D factor of the covariance `P = U D Uᵀ` (rad²), its
    /// upper triangle row by row ([`factor_len`]`(N)` values): row `r` is
    /// `D_r`, then `U_{r,r+1} … U_{r,N-1}` (the unit upper triangular
    /// `U`'s strict upper triangle; the zeros below the diagonal are not
    /// sent; [`crate::ekf::Filter::factor`]).
    pub factor: Vec<f64, MAX_FACTOR>,
    /// Nominal state of a linearised filter (rad), if any.
    pub nominal: Option<Vec<f64, MAX_STATES>>,
    /// `C^c_n` of the computed frame, row-major.
    pub c_cn: [f64; 9],
    /// Filter updates processed.
    pub updates: u32,
    /// Consecutive updates refused by the NIS gate just before the
    /// checkpoint ([`crate::ekf::Filter::gate_state`]).
    pub gated_run: u32,
    /// The NIS gate is held open (the last accepted update was above it).
    pub gate_open: bool,
    /// Calibrator bookkeeping.
    pub progress: Progress,
}

impl Checkpoint {
    /// A checkpoint of no states (M1-pa's configuration, zeros): the value
    /// [`crate::calibrator::Calibrator::checkpoint_into`] writes over. Its
    /// vectors are empty, so building it writes a few hundred bytes, not
    /// the vectors' capacity.
    pub fn empty() -> Self {
        Self {
            config: ConfigId::M1Pa,
            errors: ErrorModel::Installation,
            state: Vec::new(),
            factor: Vec::new(),
            nominal: None,
            c_cn: [0.0; 9],
            updates: 0,
            gated_run: 0,
            gate_open: false,
            progress: Progress::default(),
        }
    }
}

/// Every message of the protocol. The postcard tag is the variant's index
/// (a varint): `Sample` 0, `Estimate` 1, `Checkpoint` 2, `Configure` 3,
/// `Reset` 4, `CheckpointRequest` 5, `EstimateRequest` 6, `Finish` 7,
/// `Refused` 8. New variants are only ever appended.
// A large variant is the price of no heap (a Checkpoint is ~3 KB, ~12.5 KB
// with the `full-model` feature).
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Message {
    /// Platform → calibrator: one period's measurement.
    Sample(Sample),
    /// Calibrator → host: the running estimate.
    Estimate(Estimate),
    /// Calibrator → host: a checkpoint; host → calibrator: restore from it.
    Checkpoint(Checkpoint),
    /// Host → calibrator: (re)configure and restart from the prior.
    Configure(CalibratorConfig),
    /// Host → calibrator: restart from the prior with the current settings.
    Reset,
    /// Host → calibrator: reply with a `Checkpoint`.
    CheckpointRequest,
    /// Host → calibrator: reply with an `Estimate` now.
    EstimateRequest,
    /// Host → calibrator: the run is over; run the final passes over the
    /// sample log and reply with the final `Estimate`.
    Finish,
    /// Calibrator → host: a message the calibrator could not act on, and
    /// why; the calibrator is as it was before the message (a refused
    /// `Configure` or restore changes nothing). Appended in version 6.
    Refused(Refusal),
}

impl Message {
    /// The message's postcard tag (its variant index, docs/wire.md
    /// §Messages): `Sample` 0 … `Finish` 7, `Refused` 8.
    pub const fn tag(&self) -> u8 {
        match self {
            Message::Sample(_) => 0,
            Message::Estimate(_) => 1,
            Message::Checkpoint(_) => 2,
            Message::Configure(_) => 3,
            Message::Reset => 4,
            Message::CheckpointRequest => 5,
            Message::EstimateRequest => 6,
            Message::Finish => 7,
            Message::Refused(_) => 8,
        }
    }
}

/// The calibrator's answer to a message it could not act on
/// ([`Message::Refused`]): which message, and why. The calibrator is left as
/// it was.
///
/// # Examples
///
/// ```
/// use rollcal::wire::{decode_frame, encode, Message, Refusal, RefusalReason, MAX_FRAME_LEN};
///
/// // A Finish before any Configure.
/// let refused = Message::Refused(Refusal {
///     message: Message::Finish.tag(),
///     reason: RefusalReason::NotConfigured,
/// });
/// let mut buf = [0u8; MAX_FRAME_LEN];
/// let n = encode(&refused, &mut buf).unwrap();
/// assert_eq!(n, 10); // 8 bytes of frame for the message's 3 bytes, then the delimiter
/// assert_eq!(decode_frame(&mut buf[..n - 1]), Ok(refused));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Refusal {
    /// The tag of the refused message ([`Message::tag`]: 0 a `Sample`
    /// before any `Configure`, 2 a `Checkpoint` to restore, 3 `Configure`,
    /// 4 `Reset`, 5 `CheckpointRequest`, 6 `EstimateRequest`, 7 `Finish`).
    pub message: u8,
    /// Why it was refused.
    pub reason: RefusalReason,
}

/// Why a message was refused ([`Refusal`]; docs/wire.md §Refused). New
/// reasons are only ever appended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum RefusalReason {
    /// A message that needs a calibrator came before any `Configure`.
    NotConfigured,
    /// A `Configure` or a checkpoint names another configuration than the
    /// one the calibrator (or the session) runs.
    ConfigMismatch {
        /// The configuration run.
        expected: ConfigId,
        /// The one the message names.
        found: ConfigId,
    },
    /// A `Configure` or a checkpoint names another error model than the
    /// calibrator's, or one this build leaves out.
    ErrorModelMismatch {
        /// The calibrator's (or the build's) error model.
        expected: ErrorModel,
        /// The one the message names.
        found: ErrorModel,
    },
    /// A checkpoint's vectors have the wrong lengths for its configuration.
    CheckpointDimension,
    /// A checkpoint's values are not a filter's (a frame that is not a
    /// rotation).
    CheckpointInvalid,
    /// The filter refused the settings or the checkpoint's values
    /// ([`crate::ekf::Error`], its index in docs/wire.md).
    Filter(crate::ekf::Error),
    /// A `Configure`'s data-sheet figure (a noise level, an instrument
    /// prior σ, a wandering error) is not finite, is negative, or is
    /// outside its bounds ([`ConfigField::bounds`](super::ConfigField::bounds)):
    /// the field, named. Appended in version 6 (issue 43).
    InvalidField(super::ConfigField),
}

impl core::fmt::Display for RefusalReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RefusalReason::NotConfigured => f.write_str("no Configure message yet"),
            RefusalReason::ConfigMismatch { expected, found } => write!(
                f,
                "configuration {} where {} runs",
                found.as_str(),
                expected.as_str()
            ),
            RefusalReason::ErrorModelMismatch { expected, found } => write!(
                f,
                "error model {} where the {} model runs",
                found.as_str(),
                expected.as_str()
            ),
            RefusalReason::CheckpointDimension => f.write_str("checkpoint dimensions do not match"),
            RefusalReason::CheckpointInvalid => f.write_str("checkpoint is not a filter's"),
            RefusalReason::Filter(e) => write!(f, "filter: {e}"),
            RefusalReason::InvalidField(field) => write!(
                f,
                "{field} is not finite, negative or outside {}",
                field.bounds()
            ),
        }
    }
}
