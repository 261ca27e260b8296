//! What runs on the robot controller after a calibration: on-line compensation of commanded poses
//! ([`compensate`]) and the persistent parameter block with two power-safe slots ([`storage`]).

pub mod compensate;
pub mod storage;
