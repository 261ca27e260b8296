//! What runs on the robot controller after a calibration: on-line compensation of commanded poses
//! ([`compensate`]), numerical inverse kinematics for targets without joints on robots without a
//! closed form ([`numerical_ik`]) and the persistent parameter block with two power-safe slots
//! ([`storage`]).

pub mod compensate;
pub mod numerical_ik;
pub mod storage;
