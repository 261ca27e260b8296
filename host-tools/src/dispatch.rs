//! The core takes the joint count as a const generic and the number of identified parameters as
//! a nalgebra dimension; `calib` learns both from the robot file at run time.
//! [`with_joint_count!`](crate::with_joint_count) maps the joint count to the core's for the
//! counts in [`JOINT_COUNTS`], the one place that decides which are compiled; the parameter
//! count is [`nalgebra::Dyn`] (one compiled solver for every count), limited per joint count by
//! [`solvable_set`] and [`analysable_set`] ([`solvable_parameters`] to solve, [`all_parameters`]
//! to analyse).

use calib_core::{ParameterMask, ParameterSet};
use nalgebra::Dyn;

/// The joint counts every command is compiled for.
pub const JOINT_COUNTS: std::ops::RangeInclusive<usize> = 2..=9;

/// Calls `f::<N>(args...)` for the run-time joint count `N` in [`JOINT_COUNTS`]; other counts
/// give an error naming the supported ones.
#[macro_export]
macro_rules! with_joint_count {
    ($count:expr, $f:ident ( $($arg:expr),* $(,)? )) => {
        match $count {
            2 => $f::<2>($($arg),*),
            3 => $f::<3>($($arg),*),
            4 => $f::<4>($($arg),*),
            5 => $f::<5>($($arg),*),
            6 => $f::<6>($($arg),*),
            7 => $f::<7>($($arg),*),
            8 => $f::<8>($($arg),*),
            9 => $f::<9>($($arg),*),
            n => Err(anyhow::anyhow!(
                "the robot file has {n} joints; this command handles {} to {} joints",
                $crate::dispatch::JOINT_COUNTS.start(),
                $crate::dispatch::JOINT_COUNTS.end()
            )),
        }
    };
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
pub fn solvable_set<const N: usize>(
    mask: &ParameterMask<N>,
) -> anyhow::Result<ParameterSet<N, Dyn>> {
    parameter_set(mask, solvable_parameters(N))
}

/// The parameters of `mask` as the identifiability analysis takes them, refused beyond
/// [`all_parameters`]`(N)`.
pub fn analysable_set<const N: usize>(
    mask: &ParameterMask<N>,
) -> anyhow::Result<ParameterSet<N, Dyn>> {
    parameter_set(mask, all_parameters(N))
}

/// The set of `mask`'s 1 to `limit` parameters.
fn parameter_set<const N: usize>(
    mask: &ParameterMask<N>,
    limit: usize,
) -> anyhow::Result<ParameterSet<N, Dyn>> {
    let count = mask.count();
    if !(1..=limit).contains(&count) {
        anyhow::bail!(
            "{count} identified parameters; calib supports 1 to {limit} for a robot of {N} joints"
        );
    }
    Ok(ParameterSet::from_mask(mask)?)
}
