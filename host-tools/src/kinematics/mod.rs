//! An identified robot put to use off line: its whole model as one value (`actual`: geometry,
//! joint maps, compliance), the end pose for joint readings (`calib fk`) and the joints that put
//! the actual robot on target poses (`calib compensate`).

pub mod actual;
pub mod compensate;
pub mod configuration;
pub mod fk;
pub mod reach;
pub mod targets;
