//! The installation matrices of the linearisation point's parameters as the
//! filter uses them ([`MatricesCache`]): computed once per parameter value
//! (docs/model.md §Installation models, through [`InstallationMatrices`]),
//! not once per use.

use core::any::Any;

use nalgebra::{Matrix3, RealField, SVector};

use crate::models::{ErrorModel, Installation, InstallationMatrices, Layout};

/// The installation matrices of one parameter value as the filter uses
/// them: all of them in `T` (the Jacobians' and the attitude increments',
/// and for `T = f64` everything's; computed in `T` from the parameters
/// rounded to `T`), `A` and `C^r_n` in f64 (the single-precision filter's
/// f64 value of the mean specific force, [`Layout::mean_accel_output`]).
/// Computed once per parameter value, not once per use (on the M4F the
/// linearised period fell by 11 k instructions); in `T`, not rounded from
/// f64, so that pass 1, whose parameters move every period, emulates no
/// f64 trigonometry and rounding it does not need (the M4F's pass-1
/// period fell from 79 k to 60 k instructions for M1-pa, 166 k to 144 k
/// for M2-ps).
///
/// As the filter's cache, a pure function of the parameters it holds: not
/// part of the filter's value (every cache equals every other, so two
/// filters with equal state, factor and history compare equal whatever they
/// last evaluated).
#[derive(Copy, Debug)]
pub(super) struct MatricesCache<T: RealField + Copy> {
    /// The parameters (rad) they are the matrices of.
    pub(super) params: Installation<f64>,
    /// `A` in f64.
    pub(super) a: Matrix3<f64>,
    /// `C^r_n` in f64.
    pub(super) c_rn: Matrix3<f64>,
    /// The matrices in `T`.
    pub(super) m: InstallationMatrices<T>,
}

// A copy (the derived `Clone` of a generic struct clones field by field, and
// the filter's `clone` then went through an out-of-line copy with a 4.4 KB
// frame on the M7).
impl<T: RealField + Copy> Clone for MatricesCache<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T: RealField + Copy> PartialEq for MatricesCache<T> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl<T: RealField + Copy> MatricesCache<T> {
    /// The matrices of `params` (rad) as the filter uses them, the same
    /// as [`MatricesCache::fill`] makes them. Out of line: the matrices'
    /// temporaries are not in the frame of the caller, which builds a
    /// calibrator in place (firmware stack).
    #[inline(never)]
    pub(super) fn new(params: Installation<f64>) -> Self {
        let (a, c_rn) = InstallationMatrices::accel_and_base(&params);
        Self {
            params,
            a,
            c_rn,
            m: Self::in_t(&params),
        }
    }

    /// The matrices in `T` of `params` (rad): computed in `T` from the
    /// parameters rounded to `T` (the Jacobians' and the attitude
    /// increments' few digits; for `T = f64`, `InstallationMatrices::new`
    /// of `params` itself).
    fn in_t(params: &Installation<f64>) -> InstallationMatrices<T> {
        InstallationMatrices::new(params.to_precision())
    }

    /// Makes the cache hold the matrices of the parameters of `x`. The
    /// parameters are compared bit for bit (a `−0` for a `0` recomputes the
    /// same matrices; a NaN keeps the NaN matrices it gave): integer
    /// comparisons, where an f64 comparison is a library call on an FPU
    /// without double precision.
    pub(super) fn refresh<const N: usize>(&mut self, layout: &Layout, x: &SVector<f64, N>) {
        let params = layout.installation(x);
        let bits = |p: &Installation<f64>| {
            [p.theta_g_c, p.theta_g_t, p.theta_a_c, p.theta_a_t, p.lambda]
                .map(|v| v.map(f64::to_bits))
        };
        // The instrument errors are zero in an installation-only layout:
        // compared only in the full model's.
        let instrument_bits = |p: &Installation<f64>| {
            let e = &p.instruments;
            (
                [e.dg, e.kg, e.ba, e.ka].map(|v| v.map(f64::to_bits)),
                e.d_g.map(f64::to_bits),
            )
        };
        let changed = bits(&params) != bits(&self.params)
            || (layout.errors == ErrorModel::Full
                && instrument_bits(&params) != instrument_bits(&self.params));
        if changed {
            self.fill(params);
        }
    }

    /// Makes the cache hold the matrices of `params` (rad), in place: the
    /// f64 filter's are built straight into their slot. Out of line: the
    /// matrices' temporaries are in no frame of the filter's step.
    #[inline(never)]
    pub(super) fn fill(&mut self, params: Installation<f64>) {
        if let Some(m) = (&mut self.m as &mut dyn Any).downcast_mut::<InstallationMatrices<f64>>() {
            *m = InstallationMatrices::new(params);
            (self.a, self.c_rn) = (m.a, m.c_rn);
        } else {
            self.m = Self::in_t(&params);
            (self.a, self.c_rn) = InstallationMatrices::accel_and_base(&params);
        }
        self.params = params;
    }

    /// The matrices in f64 when `T` is f64.
    pub(super) fn as_f64(&self) -> Option<&InstallationMatrices<f64>> {
        (&self.m as &dyn Any).downcast_ref()
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;

    /// The installation matrices cache holds the same values however it
    /// got them (built for the parameters, or refilled for them after
    /// others): a pure function of the parameters, in f32 and in f64; the
    /// f64 `A` and `C^r_n` are `InstallationMatrices::new`'s.
    #[test]
    fn matrices_cache_is_a_function_of_its_parameters() {
        let v = |a: f64, b: f64, c: f64| Vector3::new(a, b, c);
        let p = Installation {
            theta_g_c: v(1e-3, -2e-3, 0.5e-3),
            theta_g_t: v(3e-4, 1e-4, -2e-4),
            theta_a_c: v(-7e-4, 2e-4, 9e-4),
            theta_a_t: v(1e-4, -3e-4, 5e-4),
            lambda: v(0.3, -1.2, 2.0),
            instruments: crate::models::InstrumentErrors::zeros(),
        };
        let q = Installation {
            lambda: v(0.0, 0.0, 0.0),
            ..p
        };
        fn check<T: RealField + Copy>(p: Installation<f64>, q: Installation<f64>) {
            let built = MatricesCache::<T>::new(p);
            let mut refilled = MatricesCache::<T>::new(q);
            refilled.fill(p);
            assert_eq!(built.m, refilled.m);
            assert_eq!((built.a, built.c_rn), (refilled.a, refilled.c_rn));
            let f64_matrices = InstallationMatrices::new(p);
            assert_eq!((built.a, built.c_rn), (f64_matrices.a, f64_matrices.c_rn));
        }
        check::<f32>(p, q);
        check::<f64>(p, q);
    }
}
