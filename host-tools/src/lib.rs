//! host-tools: everything around the core that needs `std`: robot and tracker files, the
//! independent float64 reference, simulation, calibration runs, reports, plots and the `calib`
//! command line.
#![deny(missing_docs)]

/// The joint count of the models defined for 6R arms only: gravity compliance (the gains of
/// joints 1 to 4), the paper's Table 2, the UR formats; and the default of the generic types.
/// Every command takes 2 to 9 joints ([`dispatch::JOINT_COUNTS`]).
pub const JOINTS: usize = 6;

pub mod calibration;
pub mod cli;
pub mod columns;
pub mod compensate;
pub mod compliance;
pub mod dataset;
pub mod dispatch;
pub mod evaluation;
pub mod export;
pub mod files;
pub mod fk;
pub mod frames;
pub mod html_report;
pub mod identifiability;
pub mod joint_maps;
pub mod orientation_check;
pub mod plan;
pub mod plots;
pub mod profile;
pub mod reference;
pub mod report;
pub mod robot_file;
pub mod simulate;
pub mod statistics;
pub mod tracker_data;
pub mod ur_calibration;
pub mod ur_kinematics;
pub mod urdf;
pub mod verify;
