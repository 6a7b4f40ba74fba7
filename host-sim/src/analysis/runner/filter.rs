//! The object-safe view of a filter of any configuration and precision,
//! and the precision of its covariance arithmetic.

use nalgebra::RealField;
use rollcal::ekf::{self, Filter};
use rollcal::models::Model;

use super::config::observation_t;
use crate::sim::truth::PeriodSample;

/// Object-safe view of a filter of any configuration and precision
/// (values reported in f64).
pub trait DynFilter: Send {
    /// One period.
    fn step(&mut self, s: &PeriodSample) -> Result<f64, ekf::Error>;
    /// Estimate (rad).
    fn state(&self) -> Vec<f64>;
    /// σ (rad).
    fn sigma(&self) -> Vec<f64>;
    /// Covariance, row-major (rad²).
    fn covariance(&self) -> Vec<f64>;
}

/// A value of precision `T` in f64 (exact for f32).
pub(super) fn f64_of<T: RealField + Copy>(v: T) -> f64 {
    v.to_subset().unwrap_or(f64::NAN)
}

impl<T: RealField + Copy + Send, M: Model<N, Z> + Send, const N: usize, const Z: usize> DynFilter
    for Filter<T, M, N, Z>
{
    fn step(&mut self, s: &PeriodSample) -> Result<f64, ekf::Error> {
        let obs = observation_t::<T>(s);
        Filter::step(self, &s.dtheta_cmd, s.dt, &obs).map(|i| f64_of(i.nis))
    }
    fn state(&self) -> Vec<f64> {
        Filter::state(self).iter().copied().collect()
    }
    fn sigma(&self) -> Vec<f64> {
        Filter::sigma(self).iter().map(|v| f64_of(*v)).collect()
    }
    fn covariance(&self) -> Vec<f64> {
        Filter::covariance(self)
            .transpose()
            .iter()
            .map(|v| f64_of(*v))
            .collect()
    }
}

/// The precision of the filter's covariance arithmetic (its state, nominal
/// and residuals are f64 in both, see [`rollcal::ekf::Filter`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Precision {
    /// Double precision (the host's default).
    #[default]
    F64,
    /// Single precision, as on an FPU without f64 (Cortex-M4F).
    F32,
}

impl Precision {
    /// `"f64"` or `"f32"`.
    pub const fn as_str(self) -> &'static str {
        match self {
            Precision::F64 => "f64",
            Precision::F32 => "f32",
        }
    }
}
