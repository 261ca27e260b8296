//! host-tools: everything around the core that needs `std`, the library under the `calib`
//! command line. Its folders follow the data through a calibration:
//!
//! - [`model`]: the actual robot beyond the core's geometry (joint maps, compliance, each with its
//!   robot-file sections) and the joint and parameter counts every robot is checked against;
//! - [`io`]: files in and out: robot files, tracker data read through a data profile, and the
//!   outputs every command stages and replaces all together;
//! - [`kinematics`]: the actual robot as one model ([`kinematics::actual::ActualRobot`]: the
//!   robot file, geometry and frames, joint maps, compliance), and an identified robot put to use
//!   off line: forward kinematics, compensation;
//! - [`measurement`]: a dataset (the measured poses, read once, with the robot file they were
//!   checked against) and the poses as a model sees them, the frames that register the tracker
//!   and the probe, error statistics, the orientation-convention check, simulated data;
//! - [`formats`]: exports for controllers and other tools, and the UR factory-calibration import;
//! - [`analysis`]: identifiability, evaluation on new poses, comparison with a known truth, and
//!   verification against the independent float64 reference ([`analysis::reference`], on the crate `calib_reference`);
//! - [`planning`]: which poses to measure (candidates, information, D-optimal design, tour,
//!   predicted accuracy, plan check, the robot program);
//! - [`runtime`]: the threads and SIMD lanes that make the identification fast;
//! - [`calibration`]: the pipeline of stages, from a dataset and a configuration to a typed
//!   result (frames, selection, solve, joint maps and their evidence solver, cross-validation,
//!   plausibility); each stage takes the model of the robot the one before returned;
//! - [`report`]: the text and HTML reports and their plots;
//! - [`cli`]: the `calib` commands, thin layers over the above.
//!
//! A folder uses only folders listed before it; `.ci/check-module-cycles` fails when one uses a
//! folder listed after it, and on a cycle between the files of one folder.
//!
//! A calibration ([`calibration::calibrate`]) reads the data once into a
//! [`measurement::dataset::Dataset`] and passes the model of the robot
//! ([`kinematics::actual::ActualRobot`]) from stage to stage, each taking one and returning the
//! one it found; a stage sees the poses through its model ([`measurement::dataset::Seen`]: the
//! joint maps added to the readings, the compliance taken off the measured poses). Where each
//! stage lives: the frames in `measurement/frames.rs` ([`measurement::frames::prepare`]); the
//! selection of the parameters in `calibration/mod.rs` ([`calibration::select_parameters`], on
//! the analysis of `analysis/identifiability.rs`); the solve (swarm and least squares, the
//! compliance held) in `calibration/mod.rs`, its swarm run by `runtime/swarm_team.rs`; the
//! cross-validation in `calibration/cross_validation.rs`; the joint maps in
//! `calibration/maps.rs` and `calibration/maps/evidence.rs`; the held-out accuracy in
//! `analysis/accuracy.rs`, `analysis/uncertainty.rs` and `analysis/workspace.rs`; the
//! plausibility in `calibration/plausibility.rs`.
#![deny(missing_docs)]

/// The joint count of the models defined for 6R arms only: gravity compliance (the gains of
/// joints 1 to 4), the paper's Table 2, the UR formats; and the default of the generic types.
/// Every command takes 2 to 9 joints ([`model::counts::JOINT_COUNTS`]).
pub const JOINTS: usize = 6;

pub use error::{Error, Result};

pub mod analysis;
pub mod calibration;
pub mod cli;
pub mod error;
pub mod formats;
pub mod io;
pub mod kinematics;
pub mod measurement;
pub mod model;
pub mod planning;
pub mod report;
pub mod runtime;
