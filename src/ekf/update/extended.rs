//! The extended filter's update (pass 1) linearised at the prediction, with
//! the cold-start remedies of [`Options`](crate::ekf::Options): the
//! second-order terms of the accelerometer measurement from its analytic
//! Hessian (the Gaussian second-order filter; docs/model.md §Estimator)
//! added to `R` and, optionally, to the predicted measurement.

use nalgebra::{Matrix3, RealField, SMatrix, SVector, Vector3};

use crate::ekf::cache::MatricesCache;
use crate::ekf::factored::Base;
use crate::ekf::measure::Measured;
use crate::ekf::options::RESEARCH_OPTIONS;
use crate::ekf::pending::Pending;
use crate::ekf::second_order::AccelCovariance;
use crate::ekf::{linear_term, Error, Filter, Innovation};
use crate::geometry::wrap_angle;
use crate::models::{Layout, Model};
use crate::precision::{to_f64, to_t};

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
            |i, j| {
                let (i, j) = (
                    Filter::<T, M, N, Z>::position(i),
                    Filter::<T, M, N, Z>::position(j),
                );
                match &rows {
                    Some(rows) => f.ud.covariance_entry_with_rows(rows, i, j),
                    // As `settled` (the unpropagated factor; predict checks it).
                    None => f.ud.covariance_entry(i, j),
                }
            },
            p_r,
        );
    }
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Second-order terms of the accelerometer rows (out of line: the N×N
    /// covariance it reads stays out of the update's frame): returns
    /// (`½ tr(∇²h_a P)`, `½ tr(∇²h_a P ∇²h_b P)`) of the instantaneous
    /// accelerometer output at the end of the period, from its analytic
    /// Hessian ([`Layout::accel_second_order_from`]).
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

    /// The EKF's update of the pending period (pass 1), with the
    /// cold-start remedies of [`Options`].
    #[inline(never)]
    pub(super) fn update_extended(
        &mut self,
        z: &SVector<f64, Z>,
    ) -> Result<Innovation<T, Z>, Error> {
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
    pub(super) fn extended_noise(&self, cov2: &Matrix3<f64>) -> SMatrix<T, Z, Z> {
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
        self.factored(
            &mut measured.h,
            &nu,
            &r_v,
            &measured.noise,
            true,
            Base::Estimate,
        )
    }

    /// The innovation `ν = z − h(x_i) − H (x̂ − x_i)` of the EKF update
    /// linearised at `x_lin` (trajectory `lin`), less the second-order mean
    /// `mean2` when enabled, gimbal components wrapped; with the measurement
    /// model there written into `measured`. `m`: the installation matrices
    /// of `x_lin`.
    pub(super) fn innovation_at(
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
}
