//! The computed (mathematical) platform frame `c` and the commanded rate
//! within one filter period (docs/model.md §Frames and §Measurement
//! timing: the computed frame c follows the commanded path exactly).
//!
//! The platform computer commands `ωc = ω^c_ic = C^c_n (ω^n_ie + ω^n_path)`.
//! A sample carries only the angle increment `Δθc = ∫ωc dt` over the period,
//! but `ωc` is not constant within the period: the Earth-rate part
//! `C^c_n ω^n_ie` turns with the platform. Treating `ωc` as constant biases
//! the mean specific force by up to 1e-8 g at 0.1°/s. The filter therefore
//! holds `C^c_n` itself and assumes, as the rolling path does, that the path
//! rate `u = ω^c_nc` is constant over a period. `u` then solves
//! `Δθc = u T + T J_r(u T) C^c_n(t_k) ω^n_ie` exactly, and
//! `C^c_n(t_k + s) = R(u s) C^c_n(t_k)`.
//!
//! Consequence: a path segment must start and end on a period boundary.

use core::any::TypeId;

use nalgebra::{Matrix3, RealField, Vector3};

use crate::geometry::{
    dcm, dcm_deviation, right_jacobian_deviation_times, right_jacobian_times, rotated_in,
};
use crate::precision::{to_f64, to_t};

mod gap;
pub use gap::{Gap, GapMotion};

/// The commanded motion over one period, at the three nodes `t_k`,
/// `t_k + T/2`, `t_k + T` used by the RK4 step and by Simpson's rule.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Period<T: RealField + Copy> {
    /// Period length `T` (s).
    pub dt: T,
    /// Commanded rate `ωc` (rad/s, c-frame components) at the three nodes.
    pub omega_c: [Vector3<T>; 3],
    /// `C^c_n` at the three nodes.
    pub c_cn: [Matrix3<T>; 3],
}

impl<T: RealField + Copy> Period<T> {
    /// An all-zero period (a slot's content before its first period).
    pub fn zeros() -> Self {
        Self {
            dt: T::zero(),
            omega_c: [Vector3::zeros(); 3],
            c_cn: [Matrix3::zeros(); 3],
        }
    }

    /// The same period traversed backwards in time (`dt < 0`, nodes
    /// reversed), for integrating the dynamics from `t_{k+1}` back to `t_k`.
    pub fn reversed(&self) -> Self {
        let [w0, wm, w1] = self.omega_c;
        let [c0, cm, c1] = self.c_cn;
        Self {
            dt: -self.dt,
            omega_c: [w1, wm, w0],
            c_cn: [c1, cm, c0],
        }
    }
}

impl Period<f64> {
    /// The period in precision `J` (each value rounded; the identity for
    /// `J = f64`).
    pub fn to_precision<J: RealField + Copy>(&self) -> Period<J> {
        let [w0, wm, w1] = &self.omega_c;
        let [c0, cm, c1] = &self.c_cn;
        Period {
            dt: nalgebra::convert(self.dt),
            omega_c: [to_t(w0), to_t(wm), to_t(w1)],
            c_cn: [to_t(c0), to_t(cm), to_t(c1)],
        }
    }
}

/// A period as a filter that computes in precision `J` reads it
/// ([`CommandFrame::period_in_into`]): the nodes and rates for its
/// Jacobians and the attitude's increments, and the frame's turn within
/// the period for the value of M1's specific force
/// ([`crate::models::Layout::mean_accel_output`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodIn<J: RealField + Copy> {
    /// The period, each value rounded to `J` once ([`Period::to_precision`]).
    pub period: Period<J>,
    /// The computed frame's turn within the period, `C^c_n(t) − C^c_n(t_k)`
    /// at the midpoint and the end node (≈ `|uT|`), formed without
    /// `C^c_n(t_k)`: to a few `ε_J |uT|`, which the difference of the
    /// rounded nodes would lose to cancellation.
    pub turn: [Matrix3<J>; 2],
}

impl<J: RealField + Copy> PeriodIn<J> {
    /// An all-zero period (a slot's content before its first period).
    pub fn zeros() -> Self {
        Self {
            period: Period::zeros(),
            turn: [Matrix3::zeros(); 2],
        }
    }

    /// `period` in `J`: each value, and each turn `C_j − C_0` formed in
    /// f64, rounded to `J` once.
    pub fn of(period: &Period<f64>) -> Self {
        let [c0, cm, c1] = &period.c_cn;
        Self {
            period: period.to_precision(),
            turn: [to_t(&(cm - c0)), to_t(&(c1 - c0))],
        }
    }
}

/// The computed frame `c`: `C^c_n`, integrated from the commanded increments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandFrame<T: RealField + Copy> {
    /// `C^c_n` at the start of the next period.
    pub c_cn: Matrix3<T>,
    /// Earth rate in the navigation frame, `ω^n_ie` (rad/s).
    pub earth_rate_n: Vector3<T>,
}

impl<T: RealField + Copy> CommandFrame<T> {
    /// A computed frame aligned with n (`C^c_n(0) = I`, docs/model.md §The paper's scenario).
    pub fn aligned(earth_rate_n: Vector3<T>) -> Self {
        Self {
            c_cn: Matrix3::identity(),
            earth_rate_n,
        }
    }

    /// The constant path rate `u = ω^c_nc` (rad/s, c frame) of a period of
    /// length `dt` (s) starting at this frame whose commanded angle
    /// increment is `dtheta_c` (rad, c frame): the solution of
    /// `Δθc = u T + T J_r(u T) C^c_n(t_k) ω^n_ie`.
    ///
    /// # Examples
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use rollcal::command::CommandFrame;
    /// use rollcal::geometry::{earth_rate_n, EARTH_RATE};
    ///
    /// // A frame aligned with North–Up–East, rolling at 1 °/s about its y axis.
    /// let frame = CommandFrame::aligned(earth_rate_n(EARTH_RATE, 34.25f64.to_radians()));
    /// let u = Vector3::y() * 1f64.to_radians();
    /// // A period's commanded increment holds the Earth rate too; path_rate
    /// // takes it out again.
    /// let dtheta_c = frame.increment(&u, 1.0);
    /// assert!((dtheta_c - u).norm() > 1e-5);
    /// assert!((frame.path_rate(&dtheta_c, 1.0) - u).norm() < 1e-15);
    /// ```
    pub fn path_rate(&self, dtheta_c: &Vector3<T>, dt: T) -> Vector3<T> {
        let e = self.c_cn * self.earth_rate_n;
        let rate = dtheta_c / dt;
        // Fixed point u = Δθ/T − J_r(uT) e; contraction factor ≈ |e| T / 2 < 1e-4.
        let mut u = rate - e;
        for _ in 0..3 {
            u = rate - right_jacobian_times(&(u * dt), &e);
        }
        u
    }

    /// The commanded angle increment `Δθc = u T + T J_r(u T) C^c_n ω^n_ie`
    /// (rad, c frame) of a period of length `dt` (s) at the constant path
    /// rate `path_rate` (rad/s, c frame) starting at this frame: the inverse
    /// of [`CommandFrame::path_rate`].
    pub fn increment(&self, path_rate: &Vector3<T>, dt: T) -> Vector3<T> {
        let e = self.c_cn * self.earth_rate_n;
        (path_rate + right_jacobian_times(&(path_rate * dt), &e)) * dt
    }

    /// `C^c_n` after `periods` periods of length `dt` (s) at the constant
    /// path rate `path_rate` (rad/s, c frame): `R(u T n) C^c_n` (the rotation
    /// is about a fixed c-frame axis, so its powers add).
    ///
    /// # Examples
    ///
    /// ```
    /// use nalgebra::Vector3;
    /// use rollcal::command::CommandFrame;
    /// use rollcal::geometry::r2;
    ///
    /// // 90 periods of 1 s at 1 °/s about y: C^c_n = R2(90°) (no Earth rate).
    /// let mut frame = CommandFrame::aligned(Vector3::zeros());
    /// let u = Vector3::y() * 1f64.to_radians();
    /// let c_cn = frame.after(&u, 1.0, 90);
    /// assert!((c_cn - r2(90f64.to_radians())).norm() < 1e-14);
    /// // Advancing period by period comes to the same frame.
    /// for _ in 0..90 {
    ///     let period = frame.period_at_rate(&u, 1.0);
    ///     frame.advance(&period);
    /// }
    /// assert!((frame.c_cn - c_cn).norm() < 1e-13);
    /// ```
    pub fn after(&self, path_rate: &Vector3<T>, dt: T, periods: u32) -> Matrix3<T> {
        let n: T = nalgebra::convert(f64::from(periods));
        dcm(&(path_rate * (dt * n))) * self.c_cn
    }

    /// The commanded motion over the next period of length `dt` (s) whose
    /// commanded angle increment is `dtheta_c` (rad, c frame), without
    /// advancing the frame.
    pub fn period(&self, dtheta_c: &Vector3<T>, dt: T) -> Period<T> {
        let u = self.path_rate(dtheta_c, dt);
        self.period_at_rate(&u, dt)
    }

    /// The commanded motion over the next period of length `dt` (s) at the
    /// constant path rate `u` (rad/s, c frame), without advancing the frame.
    pub fn period_at_rate(&self, u: &Vector3<T>, dt: T) -> Period<T> {
        let e = self.c_cn * self.earth_rate_n;
        let half: T = nalgebra::convert(0.5);
        let c_mid = dcm(&(u * (dt * half))) * self.c_cn;
        let c_end = dcm(&(u * dt)) * self.c_cn;
        let w = self.earth_rate_n;
        Period {
            dt,
            omega_c: [e + u, c_mid * w + u, c_end * w + u],
            c_cn: [self.c_cn, c_mid, c_end],
        }
    }

    /// The commanded motion over the period of length `dt` (s) with
    /// commanded angle increment `dtheta_c` (rad, c frame) that *ends* at
    /// this frame: the inverse of [`CommandFrame::period`], without moving
    /// the frame. Walking a run backwards one period at a time with it (and
    /// [`CommandFrame::retreat`]) needs no stored periods.
    ///
    /// Forward, `C^c_n(t_k + T) = R(u T) C^c_n(t_k)` with `u` the path rate
    /// that solves `Δθc = u T + T J_r(u T) C^c_n(t_k) ω^n_ie`. Given the end
    /// frame, `C^c_n(t_k) = R(u T)ᵀ C^c_n(t_k + T)`, so `u` is the fixed
    /// point of `u = Δθc/T − J_r(u T) R(u T)ᵀ C^c_n(t_k + T) ω^n_ie`; the
    /// map contracts by ≈ |ω^n_ie| T (≈ 1e-4 for T = 1 s), so a few
    /// iterations reach rounding. The returned period is then
    /// [`CommandFrame::period`] from the recovered start frame, so it has
    /// exactly the forward structure; its end frame equals this frame to
    /// rounding (≈ 1e-16 per period).
    ///
    /// Never panics; a non-finite or non-positive `dt` gives a non-finite
    /// period, as [`CommandFrame::period`] does.
    pub fn period_before(&self, dtheta_c: &Vector3<T>, dt: T) -> Period<T> {
        let c_end = self.c_cn;
        let e_end = c_end * self.earth_rate_n;
        let rate = dtheta_c / dt;
        let mut u = rate - e_end;
        let tiny: T = T::default_epsilon();
        for _ in 0..8 {
            let r_t = dcm(&(u * dt)).transpose();
            let next = rate - right_jacobian_times(&(u * dt), &(r_t * e_end));
            let moved = (next - u).amax() * dt.abs();
            u = next;
            // Stop at rounding (and on NaN, which never compares smaller).
            if moved <= tiny || !moved.is_finite() {
                break;
            }
        }
        let start = Self {
            c_cn: dcm(&(u * dt)).transpose() * c_end,
            earth_rate_n: self.earth_rate_n,
        };
        start.period(dtheta_c, dt)
    }

    /// Moves the frame to the end of `period`.
    pub fn advance(&mut self, period: &Period<T>) {
        self.c_cn = period.c_cn[2];
    }

    /// Moves the frame back to the start of `period` (the inverse of
    /// [`CommandFrame::advance`], for a period from
    /// [`CommandFrame::period_before`]).
    pub fn retreat(&mut self, period: &Period<T>) {
        let [start, _, _] = period.c_cn;
        self.c_cn = start;
    }
}

impl CommandFrame<f64> {
    /// [`CommandFrame::period`] for a filter that computes in precision `J`
    /// (f32 on an FPU without double precision, where f64 is emulated): the
    /// frame and the rates in f64, their small parts in `J`. For `J = f64`
    /// it is `period` itself.
    ///
    /// - The path rate `u = Δθc/T − C^c_n ω^n_ie − c(u)`: the first two
    ///   terms in f64, the Earth-rate term's turn within the period
    ///   `c(u) = (J_r(uT) − I) C^c_n ω^n_ie` (≈ 6e-8 rad/s at 0.1°/s,
    ///   [`right_jacobian_deviation_times`]) in `J`, to `ε_J |c|` (4e-15
    ///   rad/s in f32: < 3e-11 rad of the frame over the paper's 5 400 s).
    /// - The end node `C^c_n(t_k + T) = R(uT) C^c_n(t_k)`, which the frame
    ///   integrates: its first-order part `C − uT × C` in f64, the rest
    ///   (≈ |uT|²/2, 4e-6 at 0.16°/s) in `J` ([`rotated_in`]; `ε_J |uT|²/2`,
    ///   2e-13 per period in f32).
    /// - The midpoint node `C^c_n(t_k) + (R(uT/2) − I) C^c_n(t_k)`, the
    ///   increment in `J` ([`dcm_deviation`]; a few `ε_J |uT|/2`: 3e-10
    ///   at 0.16°/s in f32, so 3e-10 g of the mid node's specific force,
    ///   three orders under the accelerometer noise; not integrated).
    /// - The commanded rate `ω_c(t) = C^c_n(t) ω^n_ie + u` at the nodes, as
    ///   `ω_c(t_k) + (R(u(t − t_k)) − I) C^c_n(t_k) ω^n_ie`, in `J`
    ///   (`ε_J |ω_c|`, 2e-10 rad/s at 0.16°/s in f32): the filter uses it in
    ///   `J` only (the attitude's increments and the Jacobians).
    pub fn period_in<J: RealField + Copy>(
        &self,
        dtheta_c: &Vector3<f64>,
        dt: f64,
    ) -> (Period<f64>, PeriodIn<J>) {
        let (mut out, mut out_j) = (Period::zeros(), PeriodIn::zeros());
        self.period_in_into::<J>(dtheta_c, dt, &mut out, &mut out_j);
        (out, out_j)
    }

    /// [`CommandFrame::period_in`] written into `out` and `out_j` (every
    /// field): the period, and the same period in `J` (each value rounded
    /// to `J` once, [`Period::to_precision`]) for the filter's Jacobians and
    /// the attitude's increments, with the frame's turn within the period
    /// ([`PeriodIn::turn`]: `(R(uT/2) − I) C^c_n(t_k)` as the midpoint
    /// node's increment is formed, and the end node's two parts, each
    /// rounded to `J` once). No copy of either where the caller keeps
    /// them, and no second rounding of what `J` computed. For `J = f64`,
    /// `out_j` is [`PeriodIn::of`] `out`.
    pub fn period_in_into<J: RealField + Copy>(
        &self,
        dtheta_c: &Vector3<f64>,
        dt: f64,
        out: &mut Period<f64>,
        out_j: &mut PeriodIn<J>,
    ) {
        if TypeId::of::<J>() == TypeId::of::<f64>() {
            *out = self.period(dtheta_c, dt);
            *out_j = PeriodIn::of(out);
            return;
        }
        let e = self.c_cn * self.earth_rate_n;
        let base = dtheta_c / dt - e;
        let (e_j, base_j, dt_j): (Vector3<J>, Vector3<J>, J) =
            (to_t(&e), to_t(&base), nalgebra::convert(dt));
        // Fixed point u = base − c(u), as in CommandFrame::path_rate.
        let mut u_j = base_j;
        let mut c_u = Vector3::zeros();
        for _ in 0..3 {
            c_u = right_jacobian_deviation_times(&(u_j * dt_j), &e_j);
            u_j = base_j - c_u;
        }
        let u = base - to_f64(&c_u);
        let half: J = nalgebra::convert(0.5);
        let d_mid = dcm_deviation(&(u_j * (dt_j * half)));
        let d_end = dcm_deviation(&(u_j * dt_j));
        let c_j = to_t::<J, 3, 3>(&self.c_cn);
        let w0 = e_j + u_j;
        let turn_mid = d_mid * c_j;
        let (c_end, turn_end) = rotated_in::<J>(&(u * dt), &self.c_cn);
        out.dt = dt;
        out.c_cn = [self.c_cn, self.c_cn + to_f64(&turn_mid), c_end];
        let p_j = &mut out_j.period;
        p_j.dt = dt_j;
        p_j.omega_c = [w0, w0 + d_mid * e_j, w0 + d_end * e_j];
        let [w0, w_mid, w_end] = &p_j.omega_c;
        out.omega_c = [to_f64(w0), to_f64(w_mid), to_f64(w_end)];
        let [_, c_mid, c_end] = &out.c_cn;
        p_j.c_cn = [c_j, to_t(c_mid), to_t(c_end)];
        out_j.turn = [turn_mid, turn_end];
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use crate::geometry::{earth_rate_n, EARTH_RATE};

    fn max_abs(m: &Matrix3<f64>) -> f64 {
        m.amax()
    }

    /// Forward then backward returns the frame (and the period) to rounding.
    #[test]
    fn period_before_inverts_period() {
        let w = earth_rate_n(EARTH_RATE, 34.25f64.to_radians());
        let mut f = CommandFrame::aligned(w);
        // Start from a frame far from the identity.
        f.c_cn = dcm(&Vector3::new(0.7, -1.9, 2.4));
        // (increment, period, bound): rounding grows with the angle turned.
        let cases = [
            (Vector3::new(-1.685e-3, 4.1e-5, 3.6e-8), 1.0, 1e-15),
            (Vector3::new(0.3, -0.2, 0.5), 1.0, 2e-15),
            (Vector3::new(0.0, 0.0, 0.0), 0.5, 1e-15),
            (Vector3::new(2.0, 1.0, -1.5), 10.0, 2e-14),
        ];
        for (d, dt, bound) in cases {
            let p = f.period(&d, dt);
            let mut g = f;
            g.advance(&p);
            let q = g.period_before(&d, dt);
            g.retreat(&q);
            let start_err = max_abs(&(g.c_cn - f.c_cn));
            let mut node_err: f64 = 0.0;
            let mut rate_err: f64 = 0.0;
            for i in 0..3 {
                node_err = node_err.max(max_abs(&(q.c_cn[i] - p.c_cn[i])));
                rate_err = rate_err.max((q.omega_c[i] - p.omega_c[i]).amax());
            }
            std::eprintln!(
                "|Δθ| {:.1e} rad: start frame {start_err:.1e}, nodes {node_err:.1e}, \
                 rates {rate_err:.1e} rad/s",
                d.norm()
            );
            assert!(start_err < bound, "start frame off by {start_err:e}");
            assert!(node_err < bound, "nodes off by {node_err:e}");
            assert!(rate_err < bound / dt, "rates off by {rate_err:e}");
        }
    }

    /// The single-precision period stays with the f64 one over the paper's
    /// length of run (the frame it integrates, its nodes and rates), and
    /// the f64 filter's is `period` itself.
    #[test]
    fn period_in_single_precision_follows_the_f64_frame() {
        let w = earth_rate_n(EARTH_RATE, 34.25f64.to_radians());
        let d = |k: usize| {
            let s = k as f64 * 1e-3;
            Vector3::new(1.7e-3 * s.cos(), -2.0e-3, 1.0e-3 * s.sin())
        };
        let (mut f64_frame, mut f32_frame) = (CommandFrame::aligned(w), CommandFrame::aligned(w));
        let (mut node_err, mut rate_err, mut turn_err): (f64, f64, f64) = (0.0, 0.0, 0.0);
        for k in 0..5400 {
            let p = f64_frame.period(&d(k), 1.0);
            assert_eq!(
                f64_frame.period_in::<f64>(&d(k), 1.0),
                (p, PeriodIn::of(&p))
            );
            let (q, q_j) = f32_frame.period_in::<f32>(&d(k), 1.0);
            // The f32 period is the f64 one rounded once.
            assert_eq!(q_j.period, q.to_precision::<f32>());
            // Against the f64 period from the same (f32-integrated) frame.
            let r = f32_frame.period(&d(k), 1.0);
            for i in 0..3 {
                node_err = node_err.max(max_abs(&(q.c_cn[i] - r.c_cn[i])));
                rate_err = rate_err.max((q.omega_c[i] - r.omega_c[i]).amax() / r.omega_c[i].norm());
            }
            for (turn, c) in q_j.turn.iter().zip(&r.c_cn[1..]) {
                let exact = c - r.c_cn[0];
                turn_err = turn_err.max(max_abs(&(turn.map(f64::from) - exact)) / d(k).norm());
            }
            f64_frame.advance(&p);
            f32_frame.advance(&q);
        }
        let drift = crate::geometry::angle_between(&f32_frame.c_cn, &f64_frame.c_cn);
        std::eprintln!(
            "5400 periods: frame {drift:.1e} rad from f64's, nodes {node_err:.1e}, \
             rates {rate_err:.1e} of their size, turns {turn_err:.1e} of |Δθ|"
        );
        // The end node's f32 part errs by ≈ ε_f32 |uT|²/2 ≈ 2e-13 rad a
        // period (|uT| ≤ 2.7e-3 rad here), which walks to ≈ 2e-11 rad over
        // 5 400 periods (1.2e-9 if every rounding had one sign): 5e-6″.
        assert!(drift < 1e-10, "frame drifted {drift:e} rad");
        assert!(node_err < 1e-9, "nodes off by {node_err:e}");
        // The rates in f32 (the filter uses them in f32 only): a few of its
        // roundings of their size.
        assert!(
            rate_err < 4.0 * f64::from(f32::EPSILON),
            "rates off by {rate_err:e}"
        );
        // The frame's turns in f32 (M1's specific force turns by them): a
        // few of its roundings of the angle turned.
        assert!(
            turn_err < 4.0 * f64::from(f32::EPSILON),
            "turns off by {turn_err:e} of the angle"
        );
    }

    /// Thousands of periods forward and back return to the start frame.
    #[test]
    fn long_walk_returns() {
        let w = earth_rate_n(EARTH_RATE, 34.25f64.to_radians());
        let mut f = CommandFrame::aligned(w);
        let d = |k: usize| {
            let s = k as f64 * 1e-3;
            Vector3::new(1.7e-3 * s.cos(), -2.0e-3, 1.0e-3 * s.sin())
        };
        let n = 5400;
        for k in 0..n {
            let p = f.period(&d(k), 1.0);
            f.advance(&p);
        }
        for k in (0..n).rev() {
            let p = f.period_before(&d(k), 1.0);
            f.retreat(&p);
        }
        let err = max_abs(&(f.c_cn - Matrix3::identity()));
        std::eprintln!("{n} periods out and back: C^c_n − I {err:.1e}");
        assert!(err < 1e-12, "after {n} periods out and back: {err:e}");
    }
}
