//! The final answer with its covariance, for a calibrator of any
//! configuration ([`AnyCalibrator::finish_with_covariance`]): what a host
//! reports (the estimate, σ and the full covariance of the estimator of
//! record), without a match over the seven configurations, and without
//! heap (the covariance in a fixed-capacity [`Covariance`]).

use nalgebra::RealField;

use super::AnyCalibrator;
use crate::calibrator::Calibrator;
use crate::estimator::{EstimatorOptions, PassEvent, SampleLog};
use crate::models::Model;
use crate::wire::{Estimate, MAX_COVARIANCE};

/// A covariance of at most [`crate::wire::MAX_STATES`] states, row-major
/// (rad², f64): `n × n` values for a configuration of `n` states.
pub type Covariance = heapless::Vec<f64, MAX_COVARIANCE>;

/// Sees every step of every pass of
/// [`AnyCalibrator::finish_with_covariance`] in the configuration's own
/// types ([`PassEvent`]: the record, the innovation, the filter after the
/// step). `()` sees nothing.
pub trait PassObserver<T: RealField + Copy> {
    /// One step of one pass.
    fn step<M: Model<N, Z>, const N: usize, const Z: usize>(
        &mut self,
        event: &PassEvent<'_, T, M, N, Z>,
    );
}

impl<T: RealField + Copy> PassObserver<T> for () {
    fn step<M: Model<N, Z>, const N: usize, const Z: usize>(
        &mut self,
        _event: &PassEvent<'_, T, M, N, Z>,
    ) {
    }
}

impl<T: RealField + Copy> AnyCalibrator<T> {
    /// The final answer ([`Calibrator::finish`]: the estimator of record
    /// over `log`) and, when the passes ran (an
    /// [`EstimateKind::Final`](crate::wire::EstimateKind::Final) answer),
    /// the final filter's covariance written into `covariance`, row-major
    /// (rad², `n × n` for a configuration of `n` states); `covariance` is
    /// left empty for a single-pass answer. `observer` sees every step of
    /// every pass. The calibrator is unchanged; the passes run in a copy of
    /// its filter on the stack (a firmware uses [`AnyCalibrator::finish`]).
    ///
    /// # Examples
    ///
    /// A platform at rest for 20 periods (M1-pa), then the final answer
    /// with its covariance:
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use rollcal::estimator::{EstimatorOptions, LogRecord, SliceLog};
    /// use rollcal::models::ConfigId;
    /// use rollcal::session::{AnyCalibrator, Covariance};
    /// use rollcal::wire::{CalibratorConfig, Sample};
    ///
    /// let settings = CalibratorConfig::paper(ConfigId::M1Pa);
    /// let mut cal = AnyCalibrator::<f64>::new(settings)?;
    /// let mut records = [LogRecord::predicted(0.0, Vector3::zeros()); 20];
    /// let mut log = SliceLog::new(&mut records);
    /// let e = settings.earth_rate_n; // at rest: the Earth rate alone
    /// for k in 0..20 {
    ///     let s = Sample {
    ///         seq: k,
    ///         t_us: (u64::from(k) + 1) * 1_000_000,
    ///         dt: 1.0,
    ///         dtheta_cmd: e,
    ///         c_cn_quat: [1.0, 0.0, 0.0, 0.0],
    ///         accel_mean: [0.0, 1.0, 0.0],
    ///         gimbal: None,
    ///     };
    ///     cal.push_logged(&s, &mut log).expect("a valid sample");
    /// }
    /// let mut covariance = Covariance::new();
    /// let passes = EstimatorOptions::default();
    /// let estimate = cal.finish_with_covariance(&mut log, &passes, &mut (), &mut covariance);
    /// let n = estimate.state.len();
    /// assert_eq!(n, 12);
    /// assert_eq!(covariance.len(), n * n);
    /// // σ is the square root of the covariance's diagonal.
    /// let sigma_0 = covariance[0].sqrt();
    /// assert!((sigma_0 - estimate.sigma[0]).abs() <= 1e-12 * sigma_0);
    /// # Ok::<(), rollcal::calibrator::Error>(())
    /// ```
    pub fn finish_with_covariance<O: PassObserver<T>>(
        &self,
        log: &mut (dyn SampleLog<T> + '_),
        passes: &EstimatorOptions,
        observer: &mut O,
        covariance: &mut Covariance,
    ) -> Estimate {
        each!(self, c => finish_with_covariance_one(c, log, passes, observer, covariance))
    }
}

/// [`AnyCalibrator::finish_with_covariance`] for one configuration.
fn finish_with_covariance_one<
    T: RealField + Copy,
    M: Model<N, Z> + Clone,
    const N: usize,
    const Z: usize,
    O: PassObserver<T>,
>(
    c: &Calibrator<T, M, N, Z>,
    log: &mut (dyn SampleLog<T> + '_),
    passes: &EstimatorOptions,
    observer: &mut O,
    covariance: &mut Covariance,
) -> Estimate {
    covariance.clear();
    c.finish_with(
        log,
        passes,
        |e| observer.step(e),
        |f| {
            for v in f.covariance().transpose().iter() {
                // N ≤ MAX_STATES for every configuration: the pushes
                // cannot fail.
                let _ = covariance.push(v.to_subset().unwrap_or(f64::NAN));
            }
        },
    )
}
