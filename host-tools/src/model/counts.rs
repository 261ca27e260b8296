//! The core takes the joint count and the number of identified parameters as nalgebra
//! dimensions; `calib` learns both from the robot file at run time and uses [`nalgebra::Dyn`]
//! for both: one compiled solver for every robot. The joint count is checked once where a robot
//! enters ([`joint_count`], [`JOINT_COUNTS`]); the parameter count is limited per joint count by
//! [`solvable_set`] and [`analysable_set`] ([`solvable_parameters`] to solve, [`all_parameters`]
//! to analyse).

use calib_core::{ParameterMask, ParameterSet};
use nalgebra::{Dim, Dyn};

/// The joint counts every command handles (the host's tables hold at most
/// [`calib_core::model::MAX_JOINTS`]).
pub const JOINT_COUNTS: std::ops::RangeInclusive<usize> = 2..=calib_core::model::MAX_JOINTS;

/// The run-time joint count of a robot of `joints` joints, or an error naming the supported
/// counts ([`JOINT_COUNTS`]).
pub fn joint_count(joints: usize) -> crate::Result<Dyn> {
    match calib_core::model::joint_count(joints) {
        Some(count) if JOINT_COUNTS.contains(&joints) => Ok(count),
        _ => Err(crate::refused!(unsupported "joint count";
            "the robot file has {joints} joints; this command handles {} to {} joints",
            JOINT_COUNTS.start(),
            JOINT_COUNTS.end()
        )),
    }
}

/// Every parameter of a robot of `joints` joints: 5 per joint (`a, d, alpha, beta, theta`) and
/// 6 each for the base and the tool frame. The identifiability analysis takes any selection of
/// them (it says which the data cannot determine).
pub const fn all_parameters(joints: usize) -> usize {
    5 * joints + 12
}

/// The most parameters of a robot of `joints` revolute joints the data can determine, and so
/// the most the solvers take: `4 joints + 6` (Zhuang, Roth and Hamano 1992, "On the
/// minimality of kinematic parameters": a complete and minimal model has `4R + 2P + 6`; 34 for
/// 7 joints). A larger selection is refused by the rank check before it reaches a solver.
pub const fn solvable_parameters(joints: usize) -> usize {
    4 * joints + 6
}

/// The parameters of `mask` as the solvers take them (the count at run time), refused with a
/// message that says the limit beyond [`solvable_parameters`]`(N)`: more than a robot's data can
/// determine.
pub fn solvable_set(mask: &ParameterMask<Dyn>) -> crate::Result<ParameterSet<Dyn, Dyn>> {
    parameter_set(mask, solvable_parameters(mask.joint_count().value()))
}

/// The parameters of `mask` as the identifiability analysis takes them, refused beyond
/// [`all_parameters`]`(N)`.
pub fn analysable_set(mask: &ParameterMask<Dyn>) -> crate::Result<ParameterSet<Dyn, Dyn>> {
    parameter_set(mask, all_parameters(mask.joint_count().value()))
}

/// The set of `mask`'s 1 to `limit` parameters.
fn parameter_set(mask: &ParameterMask<Dyn>, limit: usize) -> crate::Result<ParameterSet<Dyn, Dyn>> {
    let count = mask.count();
    if !(1..=limit).contains(&count) {
        return Err(crate::refused!(unsupported "parameter count";
            "{count} identified parameters; calib supports 1 to {limit} for a robot of {} joints",
            mask.joint_count().value()
        ));
    }
    Ok(ParameterSet::from_mask(mask)?)
}
