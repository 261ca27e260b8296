//! The integration tests of host-tools, as one test binary: the tool's library is linked once
//! instead of once per file, and the tests of every file share one run (in parallel, as cargo's
//! test harness runs them). Each module is one subject; `common` holds the helpers they share.
//! One module alone: `cargo test -p host-tools --release --test integration joint_maps::`.

mod common;

mod any_joint_count;
mod arm_configuration;
mod barrett_wam;
mod certificate;
mod cli_calibrate;
mod cli_compensate;
mod cli_demo_verify;
mod cli_fk;
mod craig;
mod frames;
mod fuzz_readers;
mod guards;
mod html_report;
mod input_guards;
mod inputs;
mod interop;
mod joint_maps;
mod least_squares;
mod numerical_ik;
mod option_matrix;
mod outputs;
mod plan;
mod pose_test;
mod real_cell;
mod real_data;
mod refusals;
mod registry;
mod seven_joints;
mod sockets;
mod urdf_import;
mod validation;
