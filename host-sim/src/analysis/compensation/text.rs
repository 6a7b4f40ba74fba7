//! The readable text report of `--matrices` ([`Compensation::text`]):
//! the matrices, how to apply them (for the full model the torquer command
//! and the compensated specific force in words and formulas, with the
//! instrument terms to use), the parameters with σ, and the strongest
//! correlations.

use std::fmt::Write;

use nalgebra::{Matrix3, Vector3};
use rollcal::models::ErrorModel;

use super::Compensation;

/// The text of `c`; see [`Compensation::text`].
pub(super) fn text(c: &Compensation, prior_sigma: f64) -> String {
    const ARCSEC: f64 = std::f64::consts::PI / (180.0 * 3600.0);
    let mut t = String::new();
    let frame = c.frame();
    let n = c.installation_n();
    let full = if c.errors == ErrorModel::Full {
        ", full model (installation and instrument errors)"
    } else {
        ""
    };
    let _ = writeln!(
        t,
        "Calibration result, {}{full} (platform frame {frame}{})",
        c.config,
        if frame == "pa" {
            ": the accelerometer axes; θaC is absorbed into the frame"
        } else {
            ": the platform cube"
        }
    );
    let mat = |t: &mut String, name: &str, a: &Matrix3<f64>| {
        let _ = writeln!(t, "  {name}");
        for i in 0..3 {
            let _ = writeln!(
                t,
                "    [{:>19.15} {:>19.15} {:>19.15}]",
                a[(i, 0)],
                a[(i, 1)],
                a[(i, 2)]
            );
        }
    };
    mat(
        &mut t,
        if frame == "pa" {
            "G = R(θgC^pa)(I + L(θgT))  (gyros)"
        } else {
            "G = R(θgC)(I + L(θgT))  (gyros)"
        },
        &c.gyro_matrix,
    );
    mat(
        &mut t,
        &if frame == "pa" {
            "A = I + L(θaT)  (accelerometers)".to_string()
        } else {
            "A = (I + L(θaT)) R(−θaC)  (accelerometers)".to_string()
        },
        &c.accel_matrix,
    );
    if c.errors == ErrorModel::Full {
        full_apply(&mut t, c, &mat);
    } else {
        let _ = writeln!(t, "Apply:");
        let _ = writeln!(
            t,
            "  gyro rate ω_g (its torquing command) into the platform: ω^{frame}_ip = G ω_g"
        );
        mat(
            &mut t,
            "G⁻¹: the command for a wanted platform rate, ω_g = G⁻¹ ω^p",
            &c.platform_to_gyro_command(),
        );
        mat(
            &mut t,
            "A⁻¹: accelerometer output into the platform, f^p = A⁻¹ Z_a",
            &c.accel_to_platform(),
        );
    }
    if let Some(b) = &c.base_dcm {
        mat(&mut t, "C^r_n = R(λ)  (base mounting)", b);
    }
    let _ = writeln!(t, "Parameters (″; attitude states at the final time):");
    let _ = writeln!(t, "  {:<11} {:>12} {:>10}", "state", "estimate ″", "σ ″");
    for (i, name) in c.names.iter().enumerate().take(n) {
        let note = if c.sigma[i] >= 0.01 * prior_sigma {
            "  not determined (σ ≥ 1 % of the prior)"
        } else {
            ""
        };
        let _ = writeln!(
            t,
            "  {:<11} {:>12.3} {:>10.4}{note}",
            name,
            c.estimate[i] / ARCSEC,
            c.sigma[i] / ARCSEC
        );
    }
    if c.errors == ErrorModel::Full {
        instrument_table(&mut t, c);
    }
    if c.covariance_known {
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for i in 0..c.names.len() {
            for j in 0..i {
                pairs.push((c.correlation[i][j], i, j));
            }
        }
        pairs.sort_by(|a, b| b.0.abs().total_cmp(&a.0.abs()));
        let _ = writeln!(t, "Strongest correlations (full matrix in the JSON):");
        for (r, i, j) in pairs.iter().take(5) {
            let _ = writeln!(t, "  {:<11} {:<11} {:>+7.3}", c.names[*i], c.names[*j], r);
        }
    } else {
        let _ = writeln!(t, "Correlations: not available (σ only).");
    }
    t
}

/// The full model's "Apply:" block: the torquer command and the
/// compensated specific force in words and formulas, and the terms to use
/// (internal units).
fn full_apply(t: &mut String, c: &Compensation, mat: &dyn Fn(&mut String, &str, &Matrix3<f64>)) {
    let frame = c.frame();
    let e = &c.instruments;
    let d_g = if frame == "pa" { "D_g^pa" } else { "D_g" };
    let lines = [
        "Apply (full model; frame p = {frame}):".to_string(),
        "  Torquer command. To turn the platform at a wanted rate ω^p (rad/s, frame p) under".into(),
        "  the specific force f^p (g, frame p; e.g. the compensated accelerometers below), command".into(),
        format!("    ωc = (I + K_g)⁻¹ (G⁻¹ ω^p − dg − {d_g} f^p)"),
        format!("  i.e. per gyro i: ωc_i = ((G⁻¹ ω^p)_i − dg_i − ({d_g} f^p)_i) / (1 + kg_i); the platform"),
        format!("  then turns at G [(I + K_g) ωc + dg + {d_g} f^p] = ω^p despite G, kg, dg and {d_g}."),
        "  Specific force from a raw accelerometer output Z_a (g):".into(),
        "    f^p = A⁻¹ (I + K_a)⁻¹ (Z_a − ba)".into(),
        "  i.e. subtract the bias, divide axis i by 1 + ka_i, then apply A⁻¹.".into(),
        "  The terms, in internal units:".into(),
    ];
    for l in lines {
        let _ = writeln!(t, "{}", l.replace("{frame}", frame));
    }
    mat(t, "G⁻¹", &c.platform_to_gyro_command());
    mat(t, "A⁻¹", &c.accel_to_platform());
    let vec = |t: &mut String, name: &str, v: &Vector3<f64>| {
        let _ = writeln!(t, "  {name}");
        let _ = writeln!(t, "    [{:>22.15e} {:>22.15e} {:>22.15e}]", v.x, v.y, v.z);
    };
    vec(t, "dg (rad/s)", &e.dg);
    let _ = writeln!(t, "  {d_g} (rad/s per g; row = gyro, column = axis of f^p)");
    for i in 0..3 {
        let _ = writeln!(
            t,
            "    [{:>22.15e} {:>22.15e} {:>22.15e}]",
            e.d_g[(i, 0)],
            e.d_g[(i, 1)],
            e.d_g[(i, 2)]
        );
    }
    let inv = |t: &mut String, name: &str, k: &Vector3<f64>| {
        let v = k.map(|v| 1.0 / (1.0 + v));
        let _ = writeln!(t, "  {name}");
        let _ = writeln!(t, "    [{:>19.15} {:>19.15} {:>19.15}]", v.x, v.y, v.z);
    };
    inv(t, "(I + K_g)⁻¹ diagonal, 1 / (1 + kg_i)", &e.kg);
    vec(t, "ba (g)", &e.ba);
    inv(t, "(I + K_a)⁻¹ diagonal, 1 / (1 + ka_i)", &e.ka);
}

/// The instrument terms in their printed units with σ, marked as not
/// determined when σ is still ≥ 1 % of the prior.
fn instrument_table(t: &mut String, c: &Compensation) {
    let _ = writeln!(t, "Instrument errors (printed units):");
    let _ = writeln!(t, "  {:<11} {:>12} {:>10}  unit", "state", "estimate", "σ");
    let i0 = c.instrument_index().unwrap_or(0);
    for (k, (name, group, unit, est, sigma)) in c.instrument_rows().into_iter().enumerate() {
        let prior = c.prior.get(i0 + k).map(|p| p * group.printed_scale().0);
        let note = match prior {
            Some(p) if sigma >= 0.01 * p => "  not determined (σ ≥ 1 % of the prior)",
            _ => "",
        };
        let _ = writeln!(t, "  {name:<11} {est:>12.4} {sigma:>10.4}  {unit}{note}");
    }
}
