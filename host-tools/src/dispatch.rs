//! The core takes the number of identified parameters as a const generic; `calib` learns it from
//! the robot file at run time. [`with_parameter_count!`](crate::with_parameter_count) maps one to
//! the other for 1 to 42 parameters (5 N + 12 for a 6-joint robot).

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
