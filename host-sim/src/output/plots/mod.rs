//! PNG figures of estimator runs (as the paper's figs 1–28): per state, the
//! estimation error against time, the filter's ±3σ band and the Cramér–Rao
//! bound σ_CRLB.
//!
//! Each state gets one row of two panels sharing the time axis `t [s]`:
//! - left, **log scale** over the whole run: |error|, 3σ of the filter and
//!   3σ_CRLB (shows the convergence from the prior, ~3600″, down to the
//!   converged level, and how σ compares to σ_CRLB);
//! - right, **linear zoom** on the converged part: the signed error, the
//!   shaded ±3σ band and the ±3σ_CRLB lines, from the time the converged
//!   part starts (after 20 % of the run and after 3σ has settled within
//!   twice its final value) to the end. The y-range is
//!   ±1.5 × max(|error|, 3σ, 3σ_CRLB) over that part, so nothing is clipped:
//!   the early transient is not in this panel (it is on the left, whole).
//!
//! The filter's 3σ is a solid vermilion line drawn *over* a wide dark
//! dashed 3σ_CRLB line: where the filter reaches the bound both stay
//! visible (the dashes stick out on both sides of the solid line). Path
//! segment switches ([`crate::sim::segments`]) are thin vertical purple lines in
//! every panel ([`plot_group_marked`]).
//!
//! Text is rendered with the DejaVu Sans font embedded in the binary
//! (`assets/DejaVuSans.ttf`, licence next to it) through plotters'
//! `ab_glyph` backend: no system font or font library is needed.
//!
//! Non-finite values (NaN, ±inf) are skipped (the curve is broken there);
//! invalid input (empty, mismatched lengths, too many panels) and I/O
//! failures are returned as `Err(String)`.
//!
//! One file per figure: the error figure (`error.rs`, its panels in
//! `error_panels.rs`), the σ(t) comparison of two paths (`sigma.rs`), the
//! σ(t) convergence (`convergence.rs`), the NIS and innovations
//! (`innovations.rs`); the shared style (font, colours, ticks, ranges) in
//! `style.rs`.

mod convergence;
mod error;
mod error_panels;
mod innovations;
mod sigma;
mod style;

pub use convergence::{convergence_size, plot_convergence, SigmaSeries};
pub use error::{figure_size, plot_group, plot_group_marked, Curve};
pub use innovations::{moving_average, plot_innovations, Innovations, INNOVATIONS_SIZE};
pub use sigma::{plot_sigma_comparison, plot_sigma_comparison_in, SigmaCurve};
pub use style::{HEADER_HEIGHT, MAX_PANELS, PANEL_HEIGHT, WIDTH};
