//! Undoing predictions without a copy of the filter ([`Filter::rollback_point`],
//! [`Filter::roll_back`]): what the calibrator needs when a gap it bridges
//! fails part-way (`Calibrator::bridge_gap`).
//!
//! A prediction ([`Filter::predict`]) moves the state, the computed frame
//! and, through its time update, the U-D factor: its attitude rows, and
//! for the full model with errors that wander, the rows and columns of the
//! wandering states (`wander`). Re-acquiring the attitude
//! ([`Filter::reacquire_attitude`]) changes the attitude rows, the frame
//! and the nominal's attitude. So the point to roll back to is the state,
//! the frame and the factor. The factor is kept in the filter's working
//! memory (the update's saved factor, which no prediction or
//! re-acquisition uses): the point itself is 0.5 KB for the full M2-ps
//! model in f64, where a copy of the filter is 27 KB (a firmware's whole
//! stack budget is 16 KB).

use nalgebra::{RealField, SVector, Vector3};

use super::{Error, Filter};
use crate::command::CommandFrame;
use crate::models::{Model, ATT};

/// What [`Filter::roll_back`] puts back, with the factor the filter saved
/// in its working memory: taken by [`Filter::rollback_point`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rollback<const N: usize> {
    x: SVector<f64, N>,
    command: CommandFrame<f64>,
    reference_attitude: Option<Vector3<f64>>,
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Applies the pending period's time update, if any (what the next
    /// [`Filter::predict`] does first), saves the factor in the filter's
    /// working memory and returns the point that [`Filter::roll_back`]
    /// brings the filter back to after any number of predictions and
    /// attitude re-acquisitions (and nothing else: an update overwrites the
    /// saved factor). On error (the pending time update fails, as the next
    /// prediction would) the filter is unchanged.
    pub(crate) fn rollback_point(&mut self) -> Result<Rollback<N>, Error> {
        self.settle()?;
        self.pending.clear();
        self.ud.save_into(&mut self.scratch.factor);
        Ok(Rollback {
            x: self.x,
            command: self.command,
            reference_attitude: self
                .reference
                .as_ref()
                .map(|r| r.fixed_rows::<3>(ATT).into_owned()),
        })
    }

    /// The filter as it was at `point` ([`Filter::rollback_point`]), after
    /// predictions and attitude re-acquisitions only: equal (`==`, bit for
    /// bit) to the filter then.
    pub(crate) fn roll_back(&mut self, point: &Rollback<N>) {
        self.x = point.x;
        self.ud.restore_from(&self.scratch.factor);
        self.command = point.command;
        if let (Some(r), Some(att)) = (self.reference.as_mut(), point.reference_attitude) {
            r.fixed_rows_mut::<3>(ATT).copy_from(&att);
        }
        self.pending.clear();
        // The installation matrices are those of the linearisation point's
        // parameters, which predictions do not move: still this point's.
        let x_lin = self.reference.as_ref().unwrap_or(&self.x);
        self.matrices.refresh(&Self::LAYOUT, x_lin);
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use nalgebra::{Matrix3, SVector, Vector3};

    use crate::ekf::{Filter, FilterConfig, Observation, Options};
    use crate::geometry::{earth_rate_n, gravity_n, EARTH_RATE};
    use crate::models::{Environment, M1Pa, M2PsFull, Model, Wander};

    /// The realistic scenario's wandering errors (docs/model.md §The
    /// realistic scenario), in internal units.
    fn realistic() -> Wander<f64> {
        let deg_h = core::f64::consts::PI / 180.0 / 3600.0;
        Wander {
            gyro_markov_sigma: 0.003 * deg_h,
            gyro_markov_tau_s: 600.0,
            gyro_random_walk: 0.002 * deg_h / 60.0,
            accel_markov_sigma: 2e-6,
            accel_markov_tau_s: 900.0,
            accel_random_walk: 1e-6 / 60.0,
            gyro_warmup_sigma: 0.005 * deg_h,
            accel_warmup_sigma: 3e-6,
            warmup_tau_s: 1200.0,
        }
    }

    fn config(options: Options, wander: Wander<f64>) -> FilterConfig<f64> {
        let deg = core::f64::consts::PI / 180.0;
        FilterConfig {
            env: Environment {
                earth_rate_n: earth_rate_n(EARTH_RATE, 34.25 * deg),
                gravity_n: gravity_n(),
            },
            sigma_accel: 1e-6,
            sigma_gyro: 0.1 * deg / 3600.0,
            sigma_gimbal: 10.0 * deg / 3600.0,
            options,
            wander,
        }
    }

    /// A filter after a few steps of a roll (with or without a nominal),
    /// then predictions and a re-acquisition, rolled back: equal to the
    /// filter before, bit for bit.
    fn rolls_back<
        M: Model<N, Z> + Clone + PartialEq + core::fmt::Debug,
        const N: usize,
        const Z: usize,
    >(
        linearised: bool,
        wander: Wander<f64>,
    ) {
        let deg = core::f64::consts::PI / 180.0;
        let x0 = SVector::<f64, N>::from_fn(|i, _| 1e-4 * (i as f64 + 1.0).sin());
        let sigma0 = SVector::<f64, N>::repeat(1e-3);
        let mut f =
            Filter::<f64, M, N, Z>::new(config(Options::default(), wander), x0, sigma0).unwrap();
        if linearised {
            f.set_nominal(Some(x0));
        }
        let inc = Vector3::new(0.02 * deg, -0.01 * deg, 0.1 * deg);
        for _ in 0..5 {
            let c_end = f.command_frame().period(&inc, 1.0).c_cn[2];
            let obs = Observation {
                accel_mean: c_end * gravity_n::<f64>(),
                gimbal: Some(Vector3::new(1e-5, -2e-5, 3e-5)),
            };
            let _ = f.step(&inc, 1.0, &obs);
        }
        // A pending period too: the rollback point applies it first.
        f.predict(&inc, 1.0).unwrap();
        let mut settled = f.clone();
        settled.settle().unwrap();
        settled.pending.clear();
        let point = f.rollback_point().unwrap();
        assert_eq!(f, settled);
        for _ in 0..7 {
            f.predict(&inc, 1.0).unwrap();
        }
        f.reacquire_attitude(&Matrix3::identity(), 1e-2).unwrap();
        f.predict(&inc, 1.0).unwrap();
        assert_ne!(f, settled);
        f.roll_back(&point);
        assert_eq!(f, settled);
    }

    #[test]
    fn predictions_and_a_reacquisition_roll_back_bit_for_bit() {
        rolls_back::<M1Pa, 12, 3>(false, Wander::none());
        rolls_back::<M1Pa, 12, 3>(true, Wander::none());
        rolls_back::<M2PsFull, 54, 6>(false, Wander::none());
        rolls_back::<M2PsFull, 54, 6>(true, Wander::none());
        // Predictions move the wandering states' rows and columns of the
        // factor too: rolled back all the same.
        rolls_back::<M2PsFull, 54, 6>(false, realistic());
        rolls_back::<M2PsFull, 54, 6>(true, realistic());
    }
}
