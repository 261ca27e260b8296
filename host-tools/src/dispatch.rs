//! The core takes the number of identified parameters and the joint count as const generics;
//! `calib` learns them from the robot file at run time.
//! [`with_parameter_count!`](crate::with_parameter_count) maps one to the other for 1 to 40
//! parameters (the most a 7-joint robot can have identified); [`with_joint_count!`](crate::with_joint_count)
//! for the joint counts in [`JOINT_COUNTS`] and
//! [`with_identification_joint_count!`](crate::with_identification_joint_count) for those in
//! [`IDENTIFICATION_JOINT_COUNTS`]: the places that decide which are compiled.

/// The joint counts the commands that dispatch on the robot file's joint count are compiled for.
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

/// The joint counts the identification commands (`calibrate`, `check`, `evaluate`, `verify`)
/// are compiled for: each count instantiates the swarm and least squares once per parameter count
/// (measured: about 3.8 s of release build per parameter count; 40 counts per joint count), so
/// they are compiled for the 6- and 7-joint arms nearly every industrial robot and cobot has. To
/// add a count, add it here and an arm to [`with_identification_joint_count!`](crate::with_identification_joint_count).
pub const IDENTIFICATION_JOINT_COUNTS: [usize; 2] = [6, 7];

/// Calls `f::<N>(args...)` for the run-time joint count `N` in [`IDENTIFICATION_JOINT_COUNTS`];
/// other counts give an error naming the supported ones.
#[macro_export]
macro_rules! with_identification_joint_count {
    ($count:expr, $f:ident ( $($arg:expr),* $(,)? )) => {
        match $count {
            6 => $f::<6>($($arg),*),
            7 => $f::<7>($($arg),*),
            n => Err(anyhow::anyhow!(
                "the robot file has {n} joints; identification (calibrate, check, evaluate, verify) is compiled for {:?} joints (see host_tools::dispatch::IDENTIFICATION_JOINT_COUNTS)",
                $crate::dispatch::IDENTIFICATION_JOINT_COUNTS
            )),
        }
    };
}

/// Calls `f::<_, D>(args...)` for the run-time count `D` of identified parameters in 1..=40
/// (at most 5 per joint, 35 for the 7-joint robots of [`IDENTIFICATION_JOINT_COUNTS`], plus the
/// frames less what they absorb: 6 base - 2 + 6 tool - 5; `@frames`: 1..=12, the frames alone);
/// other counts give an error.
#[macro_export]
macro_rules! with_parameter_count {
    ($count:expr, $f:ident ( $($arg:expr),* $(,)? )) => {
        $crate::with_parameter_count!(@arms $count, $f, ($($arg),*),
            1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32
            33 34 35 36 37 38 39 40)
    };
    (@frames $count:expr, $f:ident ( $($arg:expr),* $(,)? )) => {
        $crate::with_parameter_count!(@arms $count, $f, ($($arg),*), 1 2 3 4 5 6 7 8 9 10 11 12)
    };
    (@arms $count:expr, $f:ident, $args:tt, $($d:literal)*) => {
        match $count {
            $($d => $crate::with_parameter_count!(@call $f, $d, $args),)*
            n => Err(anyhow::anyhow!("{n} identified parameters; calib supports 1 to 40 (5 per joint of 7 and the frames)")),
        }
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
