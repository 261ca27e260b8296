//! An identified robot put to use off line: the end pose for joint readings (`calib fk`) and the
//! joints that put the actual robot on target poses (`calib compensate`).

pub mod compensate;
pub mod fk;
