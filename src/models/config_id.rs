//! The seven configurations by name (docs/model.md §Configurations): [`ConfigId`], its identifiers (`"M1-pa"` … `"M4-ps"`), their
//! parsing ([`ConfigId::parse`], [`FromStr`](core::str::FromStr) with
//! [`ParseConfigIdError`]), which of them this build holds, and the
//! composition ([`Layout`]) of each.

use core::fmt;

use super::error_model::ErrorModel;
use super::layout::{AttitudeKind, Layout, PlatformFrame};

/// The seven configurations of docs/model.md §Configurations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize)]
pub enum ConfigId {
    /// Misalignment dynamics, accelerometer observations, pa frame (12 states).
    M1Pa,
    /// Misalignment dynamics, accelerometer observations, ps frame (15 states).
    M1Ps,
    /// Gimbal-angle dynamics, gimbal + accelerometer observations, ps (18 states).
    M2Ps,
    /// Gimbal-angle dynamics, accelerometer observations, pa (15 states).
    M3Pa,
    /// Gimbal-angle dynamics, accelerometer observations, ps (18 states).
    M3Ps,
    /// Attitude-angle dynamics, accelerometer observations, pa (12 states).
    M4Pa,
    /// Attitude-angle dynamics, accelerometer observations, ps (15 states).
    M4Ps,
}

impl ConfigId {
    /// All seven, in the order of docs/model.md §Configurations.
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::ConfigId;
    ///
    /// let names: Vec<&str> = ConfigId::ALL.iter().map(|c| c.as_str()).collect();
    /// assert_eq!(names, ["M1-pa", "M1-ps", "M2-ps", "M3-pa", "M3-ps", "M4-pa", "M4-ps"]);
    /// ```
    pub const ALL: [ConfigId; 7] = [
        ConfigId::M1Pa,
        ConfigId::M1Ps,
        ConfigId::M2Ps,
        ConfigId::M3Pa,
        ConfigId::M3Ps,
        ConfigId::M4Pa,
        ConfigId::M4Ps,
    ];

    /// Whether this build holds the configuration: its cargo feature
    /// (`m1-pa` … `m4-ps`, all seven by default) is on. `Session` refuses a
    /// `Configure` for one that is not, and [`with_built_config!`] takes its
    /// fallback.
    ///
    /// [`with_built_config!`]: crate::with_built_config
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::ConfigId;
    ///
    /// // The default features (`all-configs`) build all seven.
    /// assert!(ConfigId::ALL.iter().all(|c| c.is_built()));
    /// assert_eq!(ConfigId::first_built(), ConfigId::M1Pa);
    /// ```
    pub const fn is_built(self) -> bool {
        match self {
            ConfigId::M1Pa => cfg!(feature = "m1-pa"),
            ConfigId::M1Ps => cfg!(feature = "m1-ps"),
            ConfigId::M2Ps => cfg!(feature = "m2-ps"),
            ConfigId::M3Pa => cfg!(feature = "m3-pa"),
            ConfigId::M3Ps => cfg!(feature = "m3-ps"),
            ConfigId::M4Pa => cfg!(feature = "m4-pa"),
            ConfigId::M4Ps => cfg!(feature = "m4-ps"),
        }
    }

    /// The first configuration of this build, in the order of docs/model.md
    /// §Configurations (the one a
    /// one-configuration build runs).
    pub const fn first_built() -> ConfigId {
        use ConfigId::*;
        // A build without any configuration does not compile: M4-ps is then
        // the only one left.
        match () {
            () if M1Pa.is_built() => M1Pa,
            () if M1Ps.is_built() => M1Ps,
            () if M2Ps.is_built() => M2Ps,
            () if M3Pa.is_built() => M3Pa,
            () if M3Ps.is_built() => M3Ps,
            () if M4Pa.is_built() => M4Pa,
            () => M4Ps,
        }
    }

    /// The identifier (docs/model.md §Configurations), e.g. `"M2-ps"`; also
    /// its [`Display`](fmt::Display).
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::ConfigId;
    ///
    /// assert_eq!(ConfigId::M2Ps.as_str(), "M2-ps");
    /// assert_eq!(ConfigId::M4Pa.to_string(), "M4-pa");
    /// ```
    pub const fn as_str(self) -> &'static str {
        match self {
            ConfigId::M1Pa => "M1-pa",
            ConfigId::M1Ps => "M1-ps",
            ConfigId::M2Ps => "M2-ps",
            ConfigId::M3Pa => "M3-pa",
            ConfigId::M3Ps => "M3-ps",
            ConfigId::M4Pa => "M4-pa",
            ConfigId::M4Ps => "M4-ps",
        }
    }

    /// Parses an identifier (docs/model.md §Configurations), case-insensitively (`m2-ps` = `M2-ps`).
    /// [`str::parse`] does the same with an error that says what was
    /// expected ([`ParseConfigIdError`]).
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::ConfigId;
    ///
    /// assert_eq!(ConfigId::parse("m2-PS"), Some(ConfigId::M2Ps));
    /// assert_eq!(ConfigId::parse("M5-pa"), None);
    /// ```
    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|c| c.as_str().eq_ignore_ascii_case(s))
    }

    /// The configuration's composition.
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::models::{AttitudeKind, PlatformFrame};
    /// use rollcal::ConfigId;
    ///
    /// let layout = ConfigId::M2Ps.layout();
    /// assert_eq!(layout.attitude, AttitudeKind::Gimbal);
    /// assert_eq!(layout.frame, PlatformFrame::Ps);
    /// assert!(layout.base && layout.gimbal_obs);
    /// // 18 states: θA, θgC, θgT, θaC, θaT, λ; 6 measurements per period.
    /// assert_eq!((layout.n(), layout.z()), (18, 6));
    /// assert_eq!((layout.ac(), layout.at(), layout.lam()), (Some(9), 12, Some(15)));
    /// ```
    pub const fn layout(self) -> Layout {
        use AttitudeKind::*;
        use PlatformFrame::*;
        let (attitude, frame, base, gimbal_obs) = match self {
            ConfigId::M1Pa => (Misalignment, Pa, false, false),
            ConfigId::M1Ps => (Misalignment, Ps, false, false),
            ConfigId::M2Ps => (Gimbal, Ps, true, true),
            ConfigId::M3Pa => (Gimbal, Pa, true, false),
            ConfigId::M3Ps => (Gimbal, Ps, true, false),
            ConfigId::M4Pa => (Attitude, Pa, false, false),
            ConfigId::M4Ps => (Attitude, Ps, false, false),
        };
        Layout {
            attitude,
            frame,
            base,
            gimbal_obs,
            errors: ErrorModel::Installation,
        }
    }

    /// The configuration's composition with the error model `errors`
    /// ([`ConfigId::layout`] is the installation-only one).
    ///
    /// # Examples
    ///
    /// ```
    /// use rollcal::models::ErrorModel;
    /// use rollcal::ConfigId;
    ///
    /// let full = ConfigId::M4Ps.layout_with(ErrorModel::Full);
    /// assert_eq!((full.n(), full.z(), full.instruments()), (51, 3, Some(15)));
    /// assert_eq!(ConfigId::M4Ps.layout_with(ErrorModel::Installation), ConfigId::M4Ps.layout());
    /// ```
    pub const fn layout_with(self, errors: ErrorModel) -> Layout {
        self.layout().with_errors(errors)
    }
}

impl core::fmt::Display for ConfigId {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Capacity (bytes) of the offending input a [`ParseConfigIdError`] keeps.
const INPUT_CAPACITY: usize = 64;

/// Marks an input cut to [`ParseConfigIdError::INPUT_CAPACITY`].
const ELLIPSIS: char = '…';

/// The error of parsing a [`ConfigId`] with [`str::parse`]: the text names
/// none of the seven configurations. Its [`Display`](fmt::Display) says
/// which text and lists the identifiers:
/// `unknown configuration 'M5-pa' (expected one of M1-pa, M1-ps, M2-ps,
/// M3-pa, M3-ps, M4-pa, M4-ps)`.
///
/// No heap: it keeps the text in a fixed buffer of
/// [`INPUT_CAPACITY`](ParseConfigIdError::INPUT_CAPACITY) bytes; a longer
/// text is cut at a character boundary and ends with `…`.
///
/// # Examples
///
/// ```
/// use rollcal::models::ParseConfigIdError;
/// use rollcal::ConfigId;
///
/// let id: ConfigId = "m1-pa".parse().unwrap();
/// assert_eq!(id, ConfigId::M1Pa);
///
/// let err: ParseConfigIdError = "M5-pa".parse::<ConfigId>().unwrap_err();
/// assert_eq!(err.input(), "M5-pa");
/// assert_eq!(
///     err.to_string(),
///     "unknown configuration 'M5-pa' (expected one of M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps)"
/// );
///
/// let long = "x".repeat(100);
/// let err = long.parse::<ConfigId>().unwrap_err();
/// assert!(err.input().ends_with('…'));
/// assert!(err.input().len() <= ParseConfigIdError::INPUT_CAPACITY);
/// ```
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseConfigIdError {
    /// The offending text, cut to the capacity.
    input: heapless::String<INPUT_CAPACITY>,
}

impl ParseConfigIdError {
    /// Bytes of the offending text kept (and shown) at most, the `…` that
    /// marks a cut included.
    pub const INPUT_CAPACITY: usize = INPUT_CAPACITY;

    /// The error for the text `s`.
    fn new(s: &str) -> Self {
        let mut input = heapless::String::new();
        if input.push_str(s).is_err() {
            input.clear();
            for c in s.chars() {
                if input.len() + c.len_utf8() + ELLIPSIS.len_utf8() > INPUT_CAPACITY
                    || input.push(c).is_err()
                {
                    break;
                }
            }
            // Fits: the loop left room for it.
            if input.push(ELLIPSIS).is_err() {
                input.clear();
            }
        }
        Self { input }
    }

    /// The text that names no configuration, as the message shows it (cut
    /// and ended with `…` when longer than
    /// [`INPUT_CAPACITY`](Self::INPUT_CAPACITY) bytes).
    pub fn input(&self) -> &str {
        &self.input
    }
}

impl fmt::Display for ParseConfigIdError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown configuration '{}' (expected one of ",
            self.input
        )?;
        for (i, id) in ConfigId::ALL.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            f.write_str(id.as_str())?;
        }
        f.write_str(")")
    }
}

impl core::error::Error for ParseConfigIdError {}

#[cfg(feature = "defmt")]
impl defmt::Format for ParseConfigIdError {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(
            f,
            "unknown configuration '{=str}' (expected one of ",
            self.input.as_str()
        );
        for (i, id) in ConfigId::ALL.iter().enumerate() {
            if i > 0 {
                defmt::write!(f, ", ");
            }
            defmt::write!(f, "{=str}", id.as_str());
        }
        defmt::write!(f, ")");
    }
}

impl core::str::FromStr for ConfigId {
    type Err = ParseConfigIdError;

    /// [`ConfigId::parse`], with an error that names the text and the
    /// identifiers expected.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::parse(s).ok_or_else(|| ParseConfigIdError::new(s))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::string::{String, ToString};

    use super::*;

    #[test]
    fn from_str_is_parse() {
        for id in ConfigId::ALL {
            assert_eq!(id.as_str().parse::<ConfigId>(), Ok(id));
            assert_eq!(id.as_str().to_ascii_lowercase().parse::<ConfigId>(), Ok(id));
        }
    }

    #[test]
    fn error_message_is_host_sims() {
        let err = "M2-pa".parse::<ConfigId>().unwrap_err();
        assert_eq!(
            err.to_string(),
            "unknown configuration 'M2-pa' (expected one of M1-pa, M1-ps, M2-ps, M3-pa, M3-ps, M4-pa, M4-ps)"
        );
        assert_eq!("".parse::<ConfigId>().unwrap_err().input(), "");
    }

    #[test]
    fn long_input_is_cut_at_a_char_boundary() {
        let fits: String = "é".repeat(INPUT_CAPACITY / 2);
        assert_eq!(fits.parse::<ConfigId>().unwrap_err().input(), fits);
        let long: String = "é".repeat(INPUT_CAPACITY);
        let err = long.parse::<ConfigId>().unwrap_err();
        let kept = err.input();
        assert!(kept.len() <= INPUT_CAPACITY);
        assert!(kept.ends_with('…'));
        assert!(long.starts_with(kept.trim_end_matches('…')));
        assert_eq!(kept.chars().count(), (INPUT_CAPACITY - 3) / 2 + 1);
    }
}
