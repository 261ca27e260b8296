//! host-tools: everything around the core that needs `std`: the robot file, the independent
//! float64 reference, and the `calib` command line.
#![deny(missing_docs)]

pub mod fk;
pub mod reference;
pub mod robot_file;
