//! The measured poses and the set-up that measured them: a dataset (a robot and its tracker
//! records), the frames that register the tracker and the probe, the error statistics of a model
//! on a dataset, the check of the data's orientation convention, simulated measurements, and a
//! tracker's export merged into the plan it measured, and the conditions of the measurement as a
//! certificate states them.

pub mod conditions;
pub mod dataset;
pub mod frames;
pub mod merge;
pub mod orientation_check;
pub mod simulate;
pub mod simulate_touches;
pub mod statistics;
