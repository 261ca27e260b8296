//! Other programs' formats: exports of an identified robot (the controller block, TOML, URDF, UR
//! kinematics YAML) and the import of a UR robot's factory calibration.

pub mod export;
pub mod ur_calibration;
pub mod ur_kinematics;
pub mod urdf;
pub mod urscript;
