//! What host-sim writes for a reader: the terminal tables, JSON and CSV of
//! runs ([`report`]), the HTML report ([`html`]), the PNG figures
//! ([`plots`], one file per figure), the progress on stderr
//! ([`progress`]) and a path design's result and files ([`design`]).
//! Rendering only: the numbers come computed.

pub mod design;
pub mod html;
pub mod plots;
pub mod progress;
pub mod report;
