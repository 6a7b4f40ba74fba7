//! One filter period ([`Filter::step`]): [`Filter::predict`] then
//! [`Filter::update`], the filter left as it was on error; and the
//! noise-free step of the posterior Cramér–Rao recursion.

use nalgebra::{RealField, Vector3};

use super::{Error, Filter, Innovation, Observation};
use crate::models::{Model, ATT};

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
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
}
