//! The measurement model as the filter evaluates it: the predicted mean
//! accelerometer output over a period and, in M2, the gimbal angles at its
//! end, with their Jacobian (docs/model.md §Configurations, §Installation
//! models), the period's gyro noise as measurement noise ([`Noise`],
//! docs/model.md §Measurement timing) and the measurement noise `R`; the
//! period retraced to end at another state (relinearisation).

use core::any::Any;
use core::marker::PhantomData;

use nalgebra::{Matrix3, RealField, SMatrix, SVector};

use super::cache::MatricesCache;
use super::pending::Pending;
use super::{Error, Filter};
use crate::models::{Model, PeriodPropagation, ATT};
use crate::precision::{scalar_to_f64, to_f64, to_t};

/// The period's gyro noise as both process and measurement noise: with unit
/// noise `u` (3), `x_{k+1} = f(x_k) + G u` and `z = h(x_{k+1}) + D u + v`.
/// The mean accelerometer output of a period sees the noise of that same
/// period (≈ half of it, `D ≈ −½ H G`), so the two are correlated:
/// `C = G Dᵀ` enters the update (decorrelated there).
///
/// `G` is kept by its attitude rows (`G`'s other rows are zero: the
/// parameters are constant), 3×3 instead of `N`×3 on the stack of every
/// update (0.9 KB of f64 for the full model's 39 states).
pub(super) struct Noise<T: RealField + Copy, const N: usize, const Z: usize> {
    /// The attitude rows of `G` (rad per unit noise).
    pub(super) g_att: Matrix3<T>,
    pub(super) d: SMatrix<T, Z, 3>,
    _states: PhantomData<[(); N]>,
}

impl<T: RealField + Copy, const N: usize, const Z: usize> Noise<T, N, Z> {
    pub(super) fn new(g_att: Matrix3<T>, d: SMatrix<T, Z, 3>) -> Self {
        Self {
            g_att,
            d,
            _states: PhantomData,
        }
    }

    /// `G` (N×3), its parameter rows zero.
    pub(super) fn g(&self) -> SMatrix<T, N, 3> {
        let mut g = SMatrix::<T, N, 3>::zeros();
        g.fixed_rows_mut::<3>(ATT).copy_from(&self.g_att);
        g
    }
}

pub(super) struct Measured<T: RealField + Copy, const N: usize, const Z: usize> {
    /// The predicted measurement (f64: it must resolve 1e-7 g of 1 g).
    pub(super) z: SVector<f64, Z>,
    /// Its Jacobian, in the filter's precision (where it was computed).
    pub(super) h: SMatrix<T, Z, N>,
    pub(super) noise: Noise<T, N, Z>,
}

impl<T: RealField + Copy, const N: usize, const Z: usize> Measured<T, N, Z> {
    pub(super) fn zeros() -> Self {
        Self {
            z: SVector::zeros(),
            h: SMatrix::zeros(),
            noise: Noise::new(Matrix3::zeros(), SMatrix::zeros()),
        }
    }
}

/// A period's trajectory and transition in precision `T`.
fn propagation_t<T: RealField + Copy, const N: usize>(
    p: &PeriodPropagation<f64, N>,
) -> PeriodPropagation<T, N> {
    let [a0, am, a1] = p.att;
    PeriodPropagation {
        att: [to_t(&a0), to_t(&am), to_t(&a1)],
        phi_att: to_t(&p.phi_att),
        f_mid: to_t(&p.f_mid),
        f_end: to_t(&p.f_end),
        noise_map: to_t(&p.noise_map),
    }
}

impl<T: RealField + Copy, M: Model<N, Z>, const N: usize, const Z: usize> Filter<T, M, N, Z> {
    /// Predicted measurement, its Jacobian (w.r.t. the state at the end of
    /// the period) for the state `x` whose period trajectory is `prop`, and
    /// the measurement's share of the period's process noise (see [`Noise`]).
    /// `m` holds the installation matrices of `x`'s parameters: the caller
    /// builds or refreshes them, so that their trigonometry is not nested
    /// below the measurement model's frames on the stack.
    fn measure(
        &self,
        x: &SVector<f64, N>,
        pending: &Pending<T, N>,
        m: &MatricesCache<T>,
    ) -> Measured<T, N, Z> {
        let mut out = Measured::zeros();
        self.measure_into(x, pending, m, &mut out);
        out
    }

    /// [`Filter::measure`] into `out` (every part of it written). Out of
    /// line, into the caller's slot: the model's temporaries are not in the
    /// frame that holds the measurement while the factor is updated
    /// (firmware stack).
    #[inline(never)]
    pub(super) fn measure_into(
        &self,
        x: &SVector<f64, N>,
        pending: &Pending<T, N>,
        m: &MatricesCache<T>,
        out: &mut Measured<T, N, Z>,
    ) {
        let layout = Self::LAYOUT;
        let env = &self.config.env;
        let as_f64 = (&pending.prop as &dyn Any).downcast_ref::<PeriodPropagation<f64, N>>();
        out.z.fill(0.0);
        out.h.fill(T::zero());
        out.noise.d.fill(T::zero());
        let accel_row = Self::ACCEL_ROW;
        let h64 = (&mut out.h as &mut dyn Any).downcast_mut::<SMatrix<f64, Z, N>>();
        let (za, da) = if let (Some(prop), Some(h64), Some(m)) = (as_f64, h64, m.as_f64()) {
            // T = f64: the nodes in `prop` are the f64 ones. The Jacobian
            // is written into its rows of `out.h`.
            let mut ha = h64.fixed_rows_mut::<3>(accel_row);
            layout.mean_accel(env, m, prop, &pending.period, &mut ha)
        } else {
            // The value in f64 (it must resolve 1e-7 g of 1 g), the
            // Jacobians in T (they need a few digits; f64 is emulated on an
            // FPU without it), on the f64 installation matrices rounded.
            let za = layout.mean_accel_output::<T>(
                env,
                &m.a,
                &m.c_rn,
                &m.params.instruments,
                &pending.att,
                &pending.period,
                &pending.period_t.turn,
            );
            let mut ha = out.h.fixed_rows_mut::<3>(accel_row);
            let (_, da) = layout.mean_accel(
                &self.env_t,
                &m.m,
                &pending.prop,
                &pending.period_t.period,
                &mut ha,
            );
            (za, to_f64(&da))
        };
        if layout.gimbal_obs {
            let att = layout.attitude(x);
            out.z.fixed_rows_mut::<3>(0).copy_from(&att);
            out.h
                .fixed_view_mut::<3, 3>(0, ATT)
                .copy_from(&Matrix3::identity());
        }
        out.z.fixed_rows_mut::<3>(accel_row).copy_from(&za);
        // Unit-variance noise w = σ_g u: x_{k+1} gets G u, z gets D u.
        let sigma_g = scalar_to_f64(self.config.sigma_gyro);
        out.noise.g_att = pending.prop.noise_map
            * (self.config.sigma_gyro * nalgebra::convert::<f64, T>(pending.period.dt));
        out.noise
            .d
            .fixed_rows_mut::<3>(accel_row)
            .copy_from(&to_t(&(da * sigma_g)));
    }

    /// The trajectory over the pending period that ends at state `x`
    /// (integrated backwards), for relinearisation.
    pub(super) fn retrace(
        &self,
        x: &SVector<f64, N>,
        pending: &Pending<T, N>,
    ) -> Result<Pending<T, N>, Error> {
        let layout = Self::LAYOUT;
        let pr = &pending.period;
        let reversed = pr.reversed();
        let m = layout.matrices(x);
        let back: PeriodPropagation<f64, N> = layout
            .propagate(&self.config.env, &m, &layout.attitude(x), &reversed)
            .ok_or(Error::GimbalLock)?;
        let [a1, am, a0] = back.att;
        let prop = PeriodPropagation {
            att: [a0, am, a1],
            phi_att: crate::models::transition_rows(&back.f_mid, pr.dt),
            f_mid: back.f_mid,
            f_end: layout
                .attitude_rate_jacobian(
                    &self.config.env,
                    &m,
                    &layout.attitude(x),
                    &pr.omega_c[2],
                    &pr.c_cn[2],
                )
                .ok_or(Error::GimbalLock)?,
            noise_map: back.noise_map,
        };
        let mut prop_t = propagation_t(&prop);
        Self::columns_to_factor_order(&mut prop_t.phi_att);
        Ok(Pending {
            period: *pr,
            period_t: pending.period_t,
            att: prop.att,
            prop: prop_t,
            q_extra: pending.q_extra,
        })
    }

    /// The measurement noise covariance `R` (diagonal: gimbal σ² (rad²) in
    /// M2's first three rows, accelerometer σ² (g²) in the others).
    pub(super) fn measurement_noise(&self) -> SMatrix<T, Z, Z> {
        let mut r = SVector::<T, Z>::zeros();
        if Self::LAYOUT.gimbal_obs {
            let sg2 = self.config.sigma_gimbal * self.config.sigma_gimbal;
            r.fixed_rows_mut::<3>(0).fill(sg2);
        }
        let sa2 = self.config.sigma_accel * self.config.sigma_accel;
        r.fixed_rows_mut::<3>(Self::ACCEL_ROW).fill(sa2);
        SMatrix::<T, Z, Z>::from_diagonal(&r)
    }

    /// Measurement function and Jacobian at an arbitrary end-of-period state,
    /// for tests and the observability analysis: returns `(h(x), H)` for the
    /// period that [`Filter::predict`] last propagated over.
    pub fn measurement_at(
        &self,
        x: &SVector<f64, N>,
    ) -> Result<(SVector<f64, Z>, SMatrix<f64, Z, N>), Error> {
        let pending = self.pending.get().ok_or(Error::NoPrediction)?;
        let lin = self.retrace(x, pending)?;
        let m = self.measure(x, &lin, &MatricesCache::new(Self::LAYOUT.installation(x)));
        Ok((m.z, to_f64(&m.h)))
    }
}
