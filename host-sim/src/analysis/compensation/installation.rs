//! The installation left after compensation (docs/model.md
//! §Compensation): the residual matrices `G_true G⁻¹` and `A⁻¹ A_true`
//! read back as installation angles, to first order.

use nalgebra::{Matrix3, Vector3};
use rollcal::geometry::rotation_vector;
use rollcal::models::Group;

use super::Compensation;

impl Compensation {
    /// The installation parameters (not the attitude) left after applying
    /// this compensation to instruments whose true matrices (in this
    /// configuration's frame) are `g_true`, `a_true` and, with a base,
    /// `base_true` = `R(λ)`: [`residual_angles`] of the residual
    /// installations. One value per installation state (the first
    /// [`Compensation::installation_n`]; the full model's instrument terms
    /// have no installation residual), in state order, NaN for the
    /// attitude states.
    pub fn residual(
        &self,
        g_true: &Matrix3<f64>,
        a_true: &Matrix3<f64>,
        base_true: Option<&Matrix3<f64>>,
    ) -> Vec<f64> {
        // The compensated triads: commanded with G⁻¹ the platform turns at
        // G_true G⁻¹ ω; compensated with A⁻¹ the accelerometers read
        // A⁻¹ A_true f^p.
        let g_res = g_true * self.platform_to_gyro_command();
        let a_res = self.accel_to_platform() * a_true;
        let (gc, gt) = residual_angles(&g_res, Triad::Gyro);
        let (ac, at) = residual_angles(&a_res, Triad::Accel);
        let lam = match (base_true, self.base_dcm) {
            (Some(t), Some(e)) => rotation_vector(&(t * e.transpose())),
            _ => Vector3::repeat(f64::NAN),
        };
        let mut count = [0usize; 6];
        self.config
            .states()
            .iter()
            .map(|s| {
                let (v, k) = match s.group {
                    // The instrument errors of the full model are no
                    // installation residual (`states()` has none of them).
                    Group::Attitude
                    | Group::GyroDrift
                    | Group::GyroGDrift
                    | Group::GyroScale
                    | Group::AccelBias
                    | Group::AccelScale
                    | Group::AccelSecondOrder
                    | Group::GyroMarkov
                    | Group::AccelMarkov
                    | Group::GyroWarmup
                    | Group::AccelWarmup => (Vector3::repeat(f64::NAN), 0),
                    Group::ThetaGC => (gc, 1),
                    Group::ThetaGT => (gt, 2),
                    Group::ThetaAC => (ac, 3),
                    Group::ThetaAT => (at, 4),
                    Group::Lambda => (lam, 5),
                };
                let i = count[k];
                count[k] += 1;
                v[i.min(2)]
            })
            .collect()
    }
}

/// Which triad's model a residual matrix follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Triad {
    /// `G = R(c)(I + L(t)) ≈ I − [c×] + L(t)`.
    Gyro,
    /// `A = (I + L(t)) R(−c) ≈ I + [c×] + L(t)`.
    Accel,
}

/// The misalignment `c` and non-orthogonality `t` (rad) of a near-identity
/// installation matrix `e` of the given triad's model, to first order:
/// with `X = e − I`, the upper triangle of `X` is the rotation part alone
/// and `t_k` is the sum of the two mirrored entries
/// (`t = (X21 + X12, X31 + X13, X32 + X23)`). Exact to first order in
/// the angles; the neglected terms are products of angles (≤ 1e-8 rad for
/// residuals of a few µrad on 0.4° errors).
pub fn residual_angles(e: &Matrix3<f64>, triad: Triad) -> (Vector3<f64>, Vector3<f64>) {
    let x = e - Matrix3::identity();
    let rot = Vector3::new(x[(1, 2)], -x[(0, 2)], x[(0, 1)]);
    let c = match triad {
        Triad::Gyro => rot,
        Triad::Accel => -rot,
    };
    let t = Vector3::new(
        x[(1, 0)] + x[(0, 1)],
        x[(2, 0)] + x[(0, 2)],
        x[(2, 1)] + x[(1, 2)],
    );
    (c, t)
}

#[cfg(test)]
mod tests {
    use super::super::tests::paper_ps;
    use super::*;
    use rollcal::instruments::{accel_matrix, gyro_matrix};
    use rollcal::models::ConfigId;

    #[test]
    fn residual_angles_invert_the_models_to_first_order() {
        // Small angles: the first-order inverse is good to |θ|².
        let c = Vector3::new(3e-6, -2e-6, 5e-6);
        let t = Vector3::new(-1e-6, 4e-6, 2e-6);
        for (triad, m) in [
            (Triad::Gyro, gyro_matrix(&c, &t)),
            (Triad::Accel, accel_matrix(&c, &t)),
        ] {
            let (rc, rt) = residual_angles(&m, triad);
            assert!((rc - c).abs().max() < 1e-10, "{triad:?} {rc} {c}");
            assert!((rt - t).abs().max() < 1e-10, "{triad:?} {rt} {t}");
            // The other model's signs would be wrong: the test can fail.
            let other = if triad == Triad::Gyro {
                Triad::Accel
            } else {
                Triad::Gyro
            };
            assert!((residual_angles(&m, other).0 - c).abs().max() > 1e-6);
        }
    }

    #[test]
    fn with_the_true_parameters_the_residual_is_zero() {
        let x = paper_ps();
        let c = Compensation::new(ConfigId::M2Ps, &x, &[1e-6; 18], &[]).unwrap();
        let (g, a, b) = (c.gyro_matrix, c.accel_matrix, c.base_dcm.unwrap());
        let r = c.residual(&g, &a, Some(&b));
        assert!(r[..3].iter().all(|v| v.is_nan()));
        for v in &r[3..] {
            assert!(v.abs() < 1e-15, "{r:?}");
        }
        // A wrong estimate leaves its error: the check can fail.
        let mut y = x.clone();
        y[7] += 1e-5;
        let d = Compensation::new(ConfigId::M2Ps, &y, &[1e-6; 18], &[]).unwrap();
        let r = d.residual(&g, &a, Some(&b));
        assert!((r[7] + 1e-5).abs() < 1e-7, "{}", r[7]);
    }
}
