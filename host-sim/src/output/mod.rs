//! What host-sim writes for a reader: the terminal tables, JSON and CSV of
//! runs ([`report`]), of a calibration ([`calibration`]), the HTML report ([`html`]), the PNG figures
//! ([`plots`], one file per figure) and the progress on stderr
//! ([`progress`]). Rendering only: the numbers come computed.

pub mod calibration;
pub mod groups;
pub mod html;
pub mod plots;
pub mod progress;
pub mod report;
