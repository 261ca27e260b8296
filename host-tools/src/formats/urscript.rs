//! Robot programs in URScript (Universal Robots): a `movej` to each joint target in order, with
//! an optional pause at each. `calib plan --urscript` writes the measurement plan this way and
//! `calib compensate --urscript` the corrected program; one writer serves both, so the two agree
//! on the joints' format (rad, 9 decimals) and the motion's settings.

use std::fmt::Write as _;

/// How the robot moves between the targets of a URScript program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// Joint speed of `movej`, rad/s.
    pub speed_rad_s: f64,
    /// Joint acceleration of `movej`, rad/s^2.
    pub acceleration_rad_s2: f64,
    /// Time the robot stands still at each target (for a tracker to measure), s; 0: no pause.
    pub settle_s: f64,
}

/// A URScript program `def {function}(): ... end` and its call: `header` as comment lines, then
/// per target its comment line and a `movej` to its joints (rad), and a `sleep` of the settle
/// time when it is above 0. Refused: a motion setting that is not finite, a speed or
/// acceleration not above 0, a negative settle time, or a target that is not of 6 joints
/// (URScript drives Universal Robots' 6-joint arms).
pub fn movej_program(
    function: &str,
    header: &[String],
    targets: &[(String, Vec<f64>)],
    motion: &Motion,
) -> crate::Result<String> {
    for (name, value, least) in [
        ("--speed-rad-s", motion.speed_rad_s, false),
        ("--acceleration-rad-s2", motion.acceleration_rad_s2, false),
        ("--settle-s", motion.settle_s, true),
    ] {
        if !(value.is_finite() && (value > 0.0 || (least && value == 0.0))) {
            return Err(crate::refused!(option name;
                "{name} must be a finite number > 0, got {value}"
            ));
        }
    }
    if let Some((comment, q)) = targets.iter().find(|(_, q)| q.len() != 6) {
        return Err(crate::refused!(unsupported "--urscript";
            "--urscript drives a Universal Robots arm (6 joints); {} has {} joints: write \
             --joint-targets for this robot's controller instead",
            crate::io::text::one_line(comment),
            q.len()
        ));
    }
    let mut text = String::new();
    for line in header {
        let _ = writeln!(text, "# {}", crate::io::text::one_line(line));
    }
    let _ = writeln!(text, "def {function}():");
    for (comment, q) in targets {
        let q: Vec<String> = q.iter().map(|v| format!("{v:.9}")).collect();
        let _ = writeln!(
            text,
            "  # {}\n  movej([{}], a={}, v={})",
            crate::io::text::one_line(comment),
            q.join(", "),
            motion.acceleration_rad_s2,
            motion.speed_rad_s
        );
        if motion.settle_s > 0.0 {
            let _ = writeln!(text, "  sleep({})", motion.settle_s);
        }
    }
    let _ = writeln!(text, "end\n{function}()");
    Ok(text)
}
