//! The figures of a `Configure` ([`CalibratorConfig`]) that come from a data
//! sheet, and the bounds a calibrator accepts them within
//! ([`ConfigField`], [`FieldBounds`]): a figure that is not finite, is
//! negative, or lies outside its bounds is refused with the field named
//! ([`RefusalReason::InvalidField`](super::RefusalReason::InvalidField);
//! docs/wire.md §Refused). The one place these figures are checked:
//! [`CalibratorConfig::invalid_field`] for a whole `Configure`,
//! [`InstrumentPrior::invalid_field`] and
//! [`Wander::invalid_field`](crate::models::Wander::invalid_field) for
//! their parts (the filter refuses a [`Wander`] outside these bounds too).
//!
//! [`ConfigField`] gives the bounds and why they are these.

use nalgebra::RealField;
use serde::{Deserialize, Serialize};

use super::{CalibratorConfig, InstrumentPrior};
use crate::models::Wander;

/// 1 °/h in rad/s.
const DEG_H: f64 = core::f64::consts::PI / 180.0 / 3600.0;

/// A data-sheet figure of a `Configure` ([`CalibratorConfig`]): what a
/// refusal names ([`RefusalReason::InvalidField`](super::RefusalReason::InvalidField)).
/// On the wire its postcard index is its declaration index (docs/wire.md
/// §Refused), so variants are only ever appended. [`core::fmt::Display`]
/// writes the field's path in the message (`wander.gyro_markov_sigma`).
///
/// # Bounds
///
/// The upper bounds are physical: a figure beyond one is no instrument a
/// platform of this kind carries, most likely a unit slip (µg given as g,
/// °/h as rad/s), and would take the filter outside the small-error model
/// it linearises:
///
/// - gyro drifts (the white rate noise, the constant drift's and `D_g`'s
///   prior σ, the bias instability, the warm-up): at most 1 000 °/h
///   (4.848e-3 rad/s), 10⁵ times a navigation-grade gyro's 0.01 °/h bias
///   instability and 67 Earth rates: the gyrocompassing this calibrator
///   relies on sees the Earth rate, and a drift wandering by 67 of it is not
///   a gyro that can be aligned; the rate random walk at most 1 000 °/h/√h
///   (8.08e-5 rad/s per √s);
/// - accelerometer biases (the bias's prior σ, the bias instability, the
///   warm-up) and the period mean's noise: at most 0.1 g. A bias `b` reads as
///   a tilt of `b/g` rad, so 0.1 g is a 5.7° tilt, where the small-angle
///   model of the tilt leaves out `θ²/2` = 0.5 %; 10⁵ times a
///   navigation-grade accelerometer's bias instability (a few µg). The
///   acceleration random walk at most 0.1 g/√h (1.667e-3 g per √s);
/// - scale-factor errors `kg`, `ka`: at most 0.1 (10 %, 10⁵ ppm), where the
///   first-order scale-factor model has lost its second order's 1 %;
/// - the second-order coefficient `k2`: at most 1e-2 g/g² (10⁴ µg/g²),
///   ten times the largest a MEMS accelerometer's data sheet gives
///   (~1 000 µg/g²) and 10³ times a navigation-grade one's (10–30 µg/g²);
/// - gimbal-angle noise: at most 0.1 rad (5.7°);
/// - correlation and warm-up times: at most 10⁷ s (about 116 days; a
///   process that does not decorrelate in months is a constant and a random
///   walk over any log) and at least 1e-3 s (a process that forgets its
///   value within a thousandth of a 1 s period is white noise, not a bias).
///
/// The lower bounds keep a figure that is not zero representable: every σ
/// not zero is at least 1e-15 (rad/s, rad/s per √s, rad/s per g) or 1e-12
/// (g, g per √s, rad, dimensionless), so that its square is a normal number
/// even in `f32` (an f32 build) — 10⁻⁷ of the smallest figure any data sheet
/// gives. Zero means "not modelled" (a noise, prior or wandering term left
/// out) wherever the model allows it: not for the accelerometer noise, nor
/// the gimbal noise of a configuration that measures gimbal angles.
///
/// The installation prior `prior_sigma_rad`, the environment and the
/// options are not data-sheet figures: the filter checks them
/// ([`RefusalReason::Filter`](super::RefusalReason::Filter)).
///
/// # Examples
///
/// ```
/// use rollcal::models::ConfigId;
/// use rollcal::wire::{CalibratorConfig, ConfigField};
///
/// let mut c = CalibratorConfig::paper(ConfigId::M1Pa);
/// assert_eq!(c.invalid_field(), None);
/// // A k2 prior of 1 g/g² (µg/g² taken for g/g²).
/// c.instrument_prior.k2 = 1.0;
/// assert_eq!(c.invalid_field(), Some(ConfigField::PriorK2));
/// assert_eq!(ConfigField::PriorK2.to_string(), "instrument_prior.k2");
/// let b = ConfigField::PriorK2.bounds();
/// assert_eq!((b.max, b.unit), (1e-2, "g/g²"));
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ConfigField {
    /// `sigma_accel_g`: the accelerometer noise of the period mean (g).
    SigmaAccel,
    /// `sigma_gyro_rad_s`: the gyro white rate noise (rad/s).
    SigmaGyro,
    /// `sigma_gimbal_rad`: the gimbal-angle noise (rad).
    SigmaGimbal,
    /// `instrument_prior.dg_rad_s`: prior σ of the constant drift (rad/s).
    PriorDg,
    /// `instrument_prior.d_g_rad_s_g`: prior σ of the g-sensitive drift
    /// (rad/s per g).
    PriorDG,
    /// `instrument_prior.kg`: prior σ of the torquer scale-factor error (1).
    PriorKg,
    /// `instrument_prior.ba_g`: prior σ of the accelerometer bias (g).
    PriorBa,
    /// `instrument_prior.ka`: prior σ of the accelerometer scale-factor
    /// error (1).
    PriorKa,
    /// `instrument_prior.k2`: prior σ of the accelerometer second-order
    /// coefficient (g/g²).
    PriorK2,
    /// `wander.gyro_markov_sigma`: gyro bias instability (rad/s).
    GyroMarkovSigma,
    /// `wander.gyro_markov_tau_s`: its correlation time (s).
    GyroMarkovTau,
    /// `wander.gyro_random_walk`: gyro rate random walk (rad/s per √s).
    GyroRandomWalk,
    /// `wander.accel_markov_sigma`: accelerometer bias instability (g).
    AccelMarkovSigma,
    /// `wander.accel_markov_tau_s`: its correlation time (s).
    AccelMarkovTau,
    /// `wander.accel_random_walk`: acceleration random walk (g per √s).
    AccelRandomWalk,
    /// `wander.gyro_warmup_sigma`: σ of the drift's warm-up amplitude
    /// (rad/s).
    GyroWarmupSigma,
    /// `wander.accel_warmup_sigma`: σ of the bias's warm-up amplitude (g).
    AccelWarmupSigma,
    /// `wander.warmup_tau_s`: the warm-up's time constant (s).
    WarmupTau,
}

/// The bounds of a [`ConfigField`] (in its unit; see the
/// [`ConfigField`] for why these).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldBounds {
    /// The smallest value accepted other than zero.
    pub min: f64,
    /// The largest value accepted.
    pub max: f64,
    /// Whether zero is accepted ("not modelled"). Not for a correlation or
    /// warm-up time; but a time whose σ is zero is not read, and only
    /// finite and not negative is asked of it.
    pub zero: bool,
    /// The unit (`"rad/s"`, `"g"`, …; `""` for a scale factor).
    pub unit: &'static str,
}

impl ConfigField {
    /// Every field, in declaration (wire index) order.
    pub const ALL: [ConfigField; 18] = [
        ConfigField::SigmaAccel,
        ConfigField::SigmaGyro,
        ConfigField::SigmaGimbal,
        ConfigField::PriorDg,
        ConfigField::PriorDG,
        ConfigField::PriorKg,
        ConfigField::PriorBa,
        ConfigField::PriorKa,
        ConfigField::PriorK2,
        ConfigField::GyroMarkovSigma,
        ConfigField::GyroMarkovTau,
        ConfigField::GyroRandomWalk,
        ConfigField::AccelMarkovSigma,
        ConfigField::AccelMarkovTau,
        ConfigField::AccelRandomWalk,
        ConfigField::GyroWarmupSigma,
        ConfigField::AccelWarmupSigma,
        ConfigField::WarmupTau,
    ];

    /// The field's path in [`CalibratorConfig`] (`"wander.warmup_tau_s"`).
    pub const fn as_str(self) -> &'static str {
        match self {
            ConfigField::SigmaAccel => "sigma_accel_g",
            ConfigField::SigmaGyro => "sigma_gyro_rad_s",
            ConfigField::SigmaGimbal => "sigma_gimbal_rad",
            ConfigField::PriorDg => "instrument_prior.dg_rad_s",
            ConfigField::PriorDG => "instrument_prior.d_g_rad_s_g",
            ConfigField::PriorKg => "instrument_prior.kg",
            ConfigField::PriorBa => "instrument_prior.ba_g",
            ConfigField::PriorKa => "instrument_prior.ka",
            ConfigField::PriorK2 => "instrument_prior.k2",
            ConfigField::GyroMarkovSigma => "wander.gyro_markov_sigma",
            ConfigField::GyroMarkovTau => "wander.gyro_markov_tau_s",
            ConfigField::GyroRandomWalk => "wander.gyro_random_walk",
            ConfigField::AccelMarkovSigma => "wander.accel_markov_sigma",
            ConfigField::AccelMarkovTau => "wander.accel_markov_tau_s",
            ConfigField::AccelRandomWalk => "wander.accel_random_walk",
            ConfigField::GyroWarmupSigma => "wander.gyro_warmup_sigma",
            ConfigField::AccelWarmupSigma => "wander.accel_warmup_sigma",
            ConfigField::WarmupTau => "wander.warmup_tau_s",
        }
    }

    /// The bounds the field is accepted within (see [`ConfigField`] §Bounds).
    pub const fn bounds(self) -> FieldBounds {
        const fn b(min: f64, max: f64, zero: bool, unit: &'static str) -> FieldBounds {
            FieldBounds {
                min,
                max,
                zero,
                unit,
            }
        }
        const GYRO: f64 = 1e3 * DEG_H;
        const TAU: FieldBounds = b(1e-3, 1e7, false, "s");
        match self {
            ConfigField::SigmaAccel => b(1e-12, 0.1, false, "g"),
            ConfigField::SigmaGyro => b(1e-15, GYRO, true, "rad/s"),
            ConfigField::SigmaGimbal => b(1e-12, 0.1, true, "rad"),
            ConfigField::PriorDg | ConfigField::GyroMarkovSigma | ConfigField::GyroWarmupSigma => {
                b(1e-15, GYRO, true, "rad/s")
            }
            ConfigField::PriorDG => b(1e-15, GYRO, true, "rad/s/g"),
            ConfigField::PriorKg | ConfigField::PriorKa => b(1e-12, 0.1, true, ""),
            ConfigField::PriorBa
            | ConfigField::AccelMarkovSigma
            | ConfigField::AccelWarmupSigma => b(1e-12, 0.1, true, "g"),
            ConfigField::PriorK2 => b(1e-12, 1e-2, true, "g/g²"),
            ConfigField::GyroRandomWalk => b(1e-15, GYRO / 60.0, true, "rad/s/√s"),
            ConfigField::AccelRandomWalk => b(1e-12, 0.1 / 60.0, true, "g/√s"),
            ConfigField::GyroMarkovTau | ConfigField::AccelMarkovTau | ConfigField::WarmupTau => {
                TAU
            }
        }
    }

    /// The field's value in `c`.
    pub fn value(self, c: &CalibratorConfig) -> f64 {
        let mut c = *c;
        *self.value_mut(&mut c)
    }

    /// The field in `c`, to change.
    pub fn value_mut(self, c: &mut CalibratorConfig) -> &mut f64 {
        let (p, w) = (&mut c.instrument_prior, &mut c.wander);
        match self {
            ConfigField::SigmaAccel => &mut c.sigma_accel_g,
            ConfigField::SigmaGyro => &mut c.sigma_gyro_rad_s,
            ConfigField::SigmaGimbal => &mut c.sigma_gimbal_rad,
            ConfigField::PriorDg => &mut p.dg_rad_s,
            ConfigField::PriorDG => &mut p.d_g_rad_s_g,
            ConfigField::PriorKg => &mut p.kg,
            ConfigField::PriorBa => &mut p.ba_g,
            ConfigField::PriorKa => &mut p.ka,
            ConfigField::PriorK2 => &mut p.k2,
            ConfigField::GyroMarkovSigma => &mut w.gyro_markov_sigma,
            ConfigField::GyroMarkovTau => &mut w.gyro_markov_tau_s,
            ConfigField::GyroRandomWalk => &mut w.gyro_random_walk,
            ConfigField::AccelMarkovSigma => &mut w.accel_markov_sigma,
            ConfigField::AccelMarkovTau => &mut w.accel_markov_tau_s,
            ConfigField::AccelRandomWalk => &mut w.accel_random_walk,
            ConfigField::GyroWarmupSigma => &mut w.gyro_warmup_sigma,
            ConfigField::AccelWarmupSigma => &mut w.accel_warmup_sigma,
            ConfigField::WarmupTau => &mut w.warmup_tau_s,
        }
    }

    /// Whether `v` (in precision `T`) is accepted for this field: finite,
    /// not negative, and zero (where [`FieldBounds::zero`] allows it) or
    /// within the bounds. `used`: for a time, whether its σ is not zero
    /// (an unused time need only be finite and not negative); `true` for
    /// every other field.
    pub(crate) fn accepts<T: RealField + Copy>(self, v: T, used: bool) -> bool {
        let b = self.bounds();
        if !(v.is_finite() && v >= T::zero()) {
            return false;
        }
        if !used {
            return true;
        }
        if v == T::zero() {
            return b.zero;
        }
        v >= nalgebra::convert(b.min) && v <= nalgebra::convert(b.max)
    }
}

impl core::fmt::Display for ConfigField {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl core::fmt::Display for FieldBounds {
    /// `"0 or 1e-15..4.848e-3 rad/s"`, `"1e-12..0.1 g"` (each bound as
    /// written where that is short, else to four significant digits).
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        /// `v` as `{}` between 1e-3 and 1e6 where that is short (`0.01`),
        /// else as `{:e}` where that is short (`1e-15`), else to four
        /// significant digits (`4.848e-3`).
        fn short(f: &mut core::fmt::Formatter<'_>, v: f64) -> core::fmt::Result {
            use core::fmt::Write;
            let mut s = heapless::String::<40>::new();
            if (1e-3..1e6).contains(&v) && write!(s, "{v}").is_ok() && s.len() <= 8 {
                return f.write_str(&s);
            }
            s.clear();
            if write!(s, "{v:e}").is_ok() && s.len() <= 8 {
                f.write_str(&s)
            } else {
                write!(f, "{v:.3e}")
            }
        }
        if self.zero {
            f.write_str("0 or ")?;
        }
        short(f, self.min)?;
        f.write_str("..")?;
        short(f, self.max)?;
        if !self.unit.is_empty() {
            write!(f, " {}", self.unit)?;
        }
        Ok(())
    }
}

impl<T: RealField + Copy> Wander<T> {
    /// The first figure that is not accepted (see [`ConfigField::bounds`]
    /// and the [`wire::field`](crate::wire) bounds): not finite, negative,
    /// or not zero and outside its bounds; a correlation or warm-up time
    /// outside its bounds where its σ is not zero. `None`: every figure is
    /// valid.
    pub fn invalid_field(&self) -> Option<ConfigField> {
        let gyro = self.gyro_markov_sigma != T::zero();
        let accel = self.accel_markov_sigma != T::zero();
        let warmup = self.has_warmup();
        [
            (ConfigField::GyroMarkovSigma, self.gyro_markov_sigma, true),
            (ConfigField::GyroMarkovTau, self.gyro_markov_tau_s, gyro),
            (ConfigField::GyroRandomWalk, self.gyro_random_walk, true),
            (ConfigField::AccelMarkovSigma, self.accel_markov_sigma, true),
            (ConfigField::AccelMarkovTau, self.accel_markov_tau_s, accel),
            (ConfigField::AccelRandomWalk, self.accel_random_walk, true),
            (ConfigField::GyroWarmupSigma, self.gyro_warmup_sigma, true),
            (ConfigField::AccelWarmupSigma, self.accel_warmup_sigma, true),
            (ConfigField::WarmupTau, self.warmup_tau_s, warmup),
        ]
        .into_iter()
        .find(|(field, v, used)| !field.accepts(*v, *used))
        .map(|(field, _, _)| field)
    }
}

impl InstrumentPrior {
    /// The first σ that is not accepted (not finite, negative, or not zero
    /// and outside its bounds: [`ConfigField::bounds`]), or `None`.
    pub fn invalid_field(&self) -> Option<ConfigField> {
        [
            (ConfigField::PriorDg, self.dg_rad_s),
            (ConfigField::PriorDG, self.d_g_rad_s_g),
            (ConfigField::PriorKg, self.kg),
            (ConfigField::PriorBa, self.ba_g),
            (ConfigField::PriorKa, self.ka),
            (ConfigField::PriorK2, self.k2),
        ]
        .into_iter()
        .find(|(field, v)| !field.accepts(*v, true))
        .map(|(field, _)| field)
    }
}

impl CalibratorConfig {
    /// The first data-sheet figure that is not accepted (see the
    /// bounds of [`ConfigField`]): the noise levels (the gimbal noise may not be
    /// zero where the configuration measures gimbal angles), the
    /// instrument prior and the wandering errors — checked whatever the
    /// error model, since a value that is not a number is an error even
    /// where it is not used. `None`: all valid. A calibrator refuses a
    /// `Configure` with such a field
    /// ([`calibrator::Error::InvalidField`](crate::calibrator::Error::InvalidField)).
    pub fn invalid_field(&self) -> Option<ConfigField> {
        let gimbal_measured = self.config.layout().gimbal_obs;
        [
            (ConfigField::SigmaAccel, self.sigma_accel_g),
            (ConfigField::SigmaGyro, self.sigma_gyro_rad_s),
            (ConfigField::SigmaGimbal, self.sigma_gimbal_rad),
        ]
        .into_iter()
        .find(|(field, v)| {
            let needed = *field == ConfigField::SigmaGimbal && gimbal_measured && *v == 0.0;
            needed || !field.accepts(*v, true)
        })
        .map(|(field, _)| field)
        .or_else(|| self.instrument_prior.invalid_field())
        .or_else(|| self.wander.invalid_field())
    }
}
