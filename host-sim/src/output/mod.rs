//! What host-sim writes for a reader: the terminal tables, JSON and CSV of
//! runs ([`report`]), of a calibration ([`calibration`]), the HTML report
//! ([`html`]), the PNG figures ([`plots`], one file per figure), the
//! progress on stderr ([`progress`]), a path design's result and files
//! ([`design`]) and the groups' titles ([`groups`]). Rendering only: the
//! numbers come computed.

pub mod calibration;
pub mod design;
pub mod groups;
pub mod html;
pub mod plots;
pub mod progress;
pub mod report;
