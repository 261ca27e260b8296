//! The core takes the number of identified parameters and the joint count as const generics;
//! `calib` learns them from the robot file at run time.
//! [`with_parameter_count!`](crate::with_parameter_count) maps one to the other for 1 to 42
//! parameters (5 N + 12 for a 6-joint robot); [`with_joint_count!`](crate::with_joint_count)
//! for the joint counts in [`JOINT_COUNTS`], the one place that decides which are compiled.

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

/// Calls `f::<D>(args...)` for the run-time count `D` in 1..=42; other counts give an error.
#[macro_export]
macro_rules! with_parameter_count {
    ($count:expr, $f:ident ( $($arg:expr),* $(,)? )) => {
        $crate::with_parameter_count!(@arms $count, $f, ($($arg),*),
            1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32
            33 34 35 36 37 38 39 40 41 42)
    };
    (@arms $count:expr, $f:ident, $args:tt, $($d:literal)*) => {
        match $count {
            $($d => $crate::with_parameter_count!(@call $f, $d, $args),)*
            n => Err(anyhow::anyhow!("{n} identified parameters; calib supports 1 to 42")),
        }
    };
    (@call $f:ident, $d:literal, ($($arg:expr),*)) => {
        $f::<$d>($($arg),*)
    };
}
