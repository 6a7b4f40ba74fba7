//! `--matrices PATH` and `--matrices-txt PATH` of `run` and `calibrate`:
//! the calibrated matrices as JSON, and their text report to a file or
//! stdout ([`crate::analysis::compensation`]).

use std::path::{Path, PathBuf};

use super::Error;
use crate::analysis::compensation::{of_run, Compensation};
use crate::analysis::runner::RunResult;
use crate::output::report::write_json;

/// `--matrices PATH` and `--matrices-txt PATH` of `run` and `calibrate`:
/// writes the JSON to `json` and the text report to `txt`, or to stdout
/// when only `json` is given. Nothing when neither is.
pub fn write_outputs(
    c: &Compensation,
    prior_sigma: f64,
    json: Option<&Path>,
    txt: Option<&Path>,
    out: &mut dyn std::io::Write,
) -> Result<(), Error> {
    if let Some(path) = json {
        write_json(path, &c.to_json())?;
    }
    match (json, txt) {
        (_, Some(path)) => std::fs::write(path, c.text(prior_sigma))
            .map_err(|e| format!("cannot write {}: {e}", path.display()).into()),
        (Some(_), None) => Ok(write!(out, "{}", c.text(prior_sigma))?),
        (None, None) => Ok(()),
    }
}

/// The `--matrices` options of `run` and `calibrate`.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct MatricesArgs {
    /// Write the calibrated matrices G and A, the compensation of the raw
    /// gyro and accelerometer outputs, R(λ), the estimates, σ and the
    /// correlation matrix as JSON to PATH, and print them as text (see
    /// docs/cli.md, "Applying the result"). With `--errors full` also every
    /// instrument term (dg, D_g, kg, ba, ka) with its unit and σ, the
    /// torquer command and the compensated specific force they give, and
    /// the covariance of all states.
    #[arg(long, value_name = "PATH")]
    pub matrices: Option<PathBuf>,
    /// Write the text report of the matrices to PATH instead of stdout.
    #[arg(long, value_name = "PATH")]
    pub matrices_txt: Option<PathBuf>,
}

impl MatricesArgs {
    /// Writes what was asked for of the final result `r`, in its error
    /// model (`r.errors`: the installation model's document, or the full
    /// model's with the instrument terms).
    pub fn write(&self, r: &RunResult) -> Result<(), Error> {
        self.write_to(r, &mut std::io::stdout().lock())
    }

    /// [`MatricesArgs::write`] with the text to `out` instead of stdout
    /// (when it goes to neither file).
    pub fn write_to(&self, r: &RunResult, out: &mut dyn std::io::Write) -> Result<(), Error> {
        if self.matrices.is_none() && self.matrices_txt.is_none() {
            return Ok(());
        }
        let c = of_run(r).map_err(|e| format!("--matrices: {e}"))?;
        write_outputs(
            &c,
            r.prior_sigma_rad,
            self.matrices.as_deref(),
            self.matrices_txt.as_deref(),
            out,
        )
    }
}
