//! A calibration put in words and pictures: the text report, its Table 3 and truth tables, the
//! HTML report rendered from the JSON report (and printed to PDF), and the plots in it.

pub mod html;
pub mod job;
pub(crate) mod markup;
pub mod pdf;
pub mod plots;
pub mod pose_test;
pub mod tables;
mod text;
pub mod touch_certificate;
pub mod touches;

pub use text::evaluation;
