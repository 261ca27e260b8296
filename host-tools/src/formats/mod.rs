//! Other programs' formats: exports of an identified robot (the controller block, TOML, URDF, UR
//! kinematics YAML), the import of a UR robot's factory calibration and of a robot's URDF.

pub mod export;
pub mod ur_calibration;
pub mod ur_kinematics;
pub mod urdf;
pub mod urdf_import;
pub mod urscript;
