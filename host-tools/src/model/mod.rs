//! The actual robot as the host models it, beyond the core's geometry: joint maps (each joint's
//! reading corrected by a smooth function of itself), compliance (deflection under gravity and
//! payload), and the joint and parameter counts every command checks a robot against. The whole
//! model as one value is `crate::kinematics::actual::ActualRobot` (it holds the robot file's
//! converted geometry, which `io` defines).

pub mod compliance;
pub mod counts;
pub mod joint_maps;
