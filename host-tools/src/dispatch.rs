//! The core takes the number of identified parameters and the joint count as const generics;
//! `calib` learns them from the robot file at run time. [`with_joint_count!`](crate::with_joint_count)
//! maps the joint count to the core's for the counts in [`JOINT_COUNTS`], the one place that
//! decides which are compiled; [`with_parameter_count!`](crate::with_parameter_count) maps the
//! parameter count for a robot of `N` joints up to a limit that depends on `N`
//! ([`all_parameters`] to analyse, [`solvable_parameters`] to solve), so that a robot of 2
//! joints does not compile the solver for the 50 parameters of one of 9.

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
/// the most the solvers are compiled for: `4 joints + 6` (Zhuang, Roth and Hamano 1992, "On the
/// minimality of kinematic parameters": a complete and minimal model has `4R + 2P + 6`; 34 for
/// 7 joints). A larger selection is refused by the rank check before it reaches a solver.
pub const fn solvable_parameters(joints: usize) -> usize {
    4 * joints + 6
}

/// Calls `f::<_, D>(args...)` for the run-time count `D` of identified parameters of a robot of
/// `N` joints (`N` a const generic in scope), for `D` in `1..=limit` where `limit` is
/// [`all_parameters`]`(N)` or [`solvable_parameters`]`(N)` (only those `D` are compiled for that
/// `N`); other counts give an error. `@frames`: `f::<_, D>` for `D` in 1..=12, the frames alone.
#[macro_export]
macro_rules! with_parameter_count {
    ($joints:ident, $limit:ident, $count:expr, $f:ident ( $($arg:expr),* $(,)? )) => {
        $crate::with_parameter_count!(@arms $joints, $limit, $count, $f, ($($arg),*),
            1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32
            33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53 54 55 56 57)
    };
    (@frames $count:expr, $f:ident ( $($arg:expr),* $(,)? )) => {
        match $count {
            1 => $f::<_, 1>($($arg),*),
            2 => $f::<_, 2>($($arg),*),
            3 => $f::<_, 3>($($arg),*),
            4 => $f::<_, 4>($($arg),*),
            5 => $f::<_, 5>($($arg),*),
            6 => $f::<_, 6>($($arg),*),
            7 => $f::<_, 7>($($arg),*),
            8 => $f::<_, 8>($($arg),*),
            9 => $f::<_, 9>($($arg),*),
            10 => $f::<_, 10>($($arg),*),
            11 => $f::<_, 11>($($arg),*),
            12 => $f::<_, 12>($($arg),*),
            n => Err(anyhow::anyhow!("{n} frame parameters; the two frames have 1 to 12")),
        }
    };
    (@arms $joints:ident, $limit:ident, $count:expr, $f:ident, $args:tt, $($d:literal)*) => {
        match $count {
            // `if const`: a count beyond the limit for this joint count is not compiled.
            $($d => if const { $d <= $crate::dispatch::$limit($joints) } {
                $crate::with_parameter_count!(@call $f, $d, $args)
            } else {
                $crate::with_parameter_count!(@beyond $joints, $limit, $d)
            },)*
            n => $crate::with_parameter_count!(@beyond $joints, $limit, n),
        }
    };
    (@beyond $joints:ident, $limit:ident, $n:expr) => {
        Err(anyhow::anyhow!(
            "{} identified parameters; calib supports 1 to {} for a robot of {} joints",
            $n,
            $crate::dispatch::$limit($joints),
            $joints
        ))
    };
    (@call $f:ident, $d:literal, ($($arg:expr),*)) => {
        $f::<_, $d>($($arg),*)
    };
}

/// `value` as a `B` when its type `A` is `B` (such as a `Dataset<N>` as a `Dataset<6>` when `N`
/// is 6), else `None`: how code generic over the joint count reaches the models defined for
/// 6-joint robots only (joint maps, gravity compliance).
pub fn same_type<A: std::any::Any, B: std::any::Any>(value: A) -> Option<B> {
    let mut slot = Some(value);
    (&mut slot as &mut dyn std::any::Any)
        .downcast_mut::<Option<B>>()
        .and_then(Option::take)
}

/// [`same_type`] for a borrowed `value`.
pub fn same_type_ref<A: std::any::Any, B: std::any::Any>(value: &A) -> Option<&B> {
    (value as &dyn std::any::Any).downcast_ref()
}
