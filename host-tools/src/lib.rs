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
//! - [`calibration`]: a calibration session ([`calibration::Session`]: a dataset, a hold-out rule,
//!   a configuration and the provenance in; [`calibration::Calibrated`] out: the identified
//!   robot as a model, the typed result, the provenance) and its pipeline of stages (frames,
//!   selection, solve, joint maps and their evidence solver, one evaluation, cross-validation,
//!   plausibility); each stage takes the model of the robot the one before returned;
//! - [`report`]: the text and HTML reports and their plots, and a calibration from touches as
//!   text.
//!
//! The `calib` command line (`src/bin/calib/`) is not part of the library: its `cli/` turns clap
//! options into the configurations above, reads and writes the files, and prints.
//!
//! A folder uses only folders listed before it; `.ci/check-module-cycles` fails when one uses a
//! folder listed after it, and on a cycle between the files of one folder.
//!
//! A calibration ([`calibration::Session::run`]) reads the data once into a
//! [`measurement::dataset::Dataset`] and passes the model of the robot
//! ([`kinematics::actual::ActualRobot`]) from stage to stage, each taking one and returning the
//! one it found; a stage sees the poses through its model ([`measurement::dataset::Seen`]: the
//! joint maps added to the readings, the compliance taken off the measured poses). Where each
//! part lives, one place each:
//!
//! - which poses are held out: [`calibration::HoldOut`] (a new rule is a variant there and an
//!   arm of `Session::split` in `calibration/session.rs`); where the result came from:
//!   [`calibration::Provenance`], stamped into the file in `calibration/session.rs`;
//! - the frames: `measurement/frames.rs` ([`measurement::frames::prepare`]); the selection of the
//!   parameters: `calibration/mod.rs` ([`calibration::select_parameters`], on the analysis of
//!   `analysis/identifiability.rs`);
//! - the solve (swarm and least squares, the compliance held, covariance, cross-validation):
//!   `calibration/solve.rs`, its swarm run by `runtime/swarm_team.rs`; the joint maps:
//!   `calibration/maps.rs` and `calibration/maps/evidence.rs`;
//! - the evaluation of the model found (Table 3, per pose, held-out accuracy, the predicted
//!   band): `calibration/evaluation.rs`, on `analysis/accuracy.rs`, `analysis/uncertainty.rs`
//!   and `analysis/workspace.rs`; the result, built once: `finish` in `calibration/mod.rs`;
//! - the identified robot file: `calibration/identified_file.rs` (a new field of the file is
//!   written there, from the model; the maps' sections come from `calibration/maps.rs`), emitted
//!   by [`calibration::Calibrated::robot_toml`];
//! - the plausibility: `calibration/plausibility.rs`; the refusals a caller can tell apart:
//!   [`Error`] (every refusal a variant with its data: `InvalidOption`, `InvalidInput`,
//!   `Unsupported`, `TooFew`, `Unidentifiable`, `Implausible`, ..., made by [`refused!`]).
//!
//! A kind of measurement is one place: its residual and Jacobian in the core
//! (`identify::residuals::Residuals`: measured poses are the core's `Problem`, a ball touched in
//! unknown sockets its `identify::common_point::CommonPoints`), and on the host an implementation
//! of [`analysis::kind::MeasurementKind`] in `analysis/kind.rs` (what it leaves free
//! whatever the data's spread, its held-out statistic), with its reader in `io/`. The stages every
//! kind shares take the trait: the selection ([`calibration::select_parameters_of`], on
//! [`analysis::kind::analyse_kind`]) and least squares with its covariance
//! ([`calibration::fit::least_squares_of`]); a calibration from touches
//! ([`calibration::touches::TouchSession`]) is those stages and the kind's statistic per
//! placement. What only poses have stays with poses: the tracker's frames, the swarm, the robust
//! loss, the joint maps and compliance, Table 3 and the plan check (the `Session`'s stages).
#![deny(missing_docs)]

/// The joint count of the models defined for 6R arms only: the paper's Table 2, the UR formats;
/// and the default of the generic types.
/// Every command takes 2 to 9 joints ([`model::counts::JOINT_COUNTS`]).
pub const JOINTS: usize = 6;

pub use error::{Error, Result};

pub mod analysis;
pub mod calibration;
pub mod error;
pub mod formats;
pub mod io;
pub mod kinematics;
pub mod measurement;
pub mod model;
pub mod planning;
pub mod pose_test;
pub mod registry;
pub mod report;
pub mod runtime;
