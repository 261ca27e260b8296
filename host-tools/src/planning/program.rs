//! A plan as a program that moves the robot through its poses, for the cell to run while the
//! tracker measures: URScript for Universal Robots, and a plain joint-target CSV for any other
//! controller's import. Both list the poses in the plan's order, which keeps the joint motion
//! short and is the order `calib merge --by order` pairs the tracker's points in.

use super::Plan;
use std::fmt::Write as _;

/// How the robot moves between the poses of a URScript program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// Joint speed of `movej`, rad/s.
    pub speed_rad_s: f64,
    /// Joint acceleration of `movej`, rad/s^2.
    pub acceleration_rad_s2: f64,
    /// Time the robot stands still at each pose for the tracker to measure, s.
    pub settle_s: f64,
}

/// The plan as a URScript program (`def calib_plan(): ... end`): per pose a `movej` to its joints
/// (rad, the controller's readings) and a `sleep` of the settle time, each commented with the
/// pose's id and role. `robot` names the robot in the header comment. Refused for a robot that
/// is not a 6-joint arm (URScript drives Universal Robots).
pub fn urscript(plan: &Plan, robot: &str, motion: &Motion) -> crate::Result<String> {
    for (name, value) in [
        ("--speed-rad-s", motion.speed_rad_s),
        ("--acceleration-rad-s2", motion.acceleration_rad_s2),
        ("--settle-s", motion.settle_s),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(crate::refused!(
                "{name} must be a finite number > 0, got {value}"
            ));
        }
    }
    if let Some(p) = plan.poses.iter().find(|p| p.q.len() != 6) {
        return Err(crate::refused!(
            "--urscript drives a Universal Robots arm (6 joints); pose {} has {} joints: write \
             --joint-targets for this robot's controller instead",
            p.id,
            p.q.len()
        ));
    }
    let mut text = String::new();
    let _ = writeln!(
        text,
        "# Measurement plan for {}, written by calib plan: {} poses in the planned order.\n\
         # The robot stands still {} s at each pose for the tracker to measure it.",
        crate::io::text::one_line(robot),
        plan.poses.len(),
        motion.settle_s
    );
    text.push_str("def calib_plan():\n");
    for p in &plan.poses {
        let q: Vec<String> = p.q.iter().map(|v| format!("{v:.9}")).collect();
        let _ = writeln!(
            text,
            "  # {} ({})\n  movej([{}], a={}, v={})\n  sleep({})",
            crate::io::text::one_line(&p.id),
            p.role.name(),
            q.join(", "),
            motion.acceleration_rad_s2,
            motion.speed_rad_s,
            motion.settle_s
        );
    }
    text.push_str("end\ncalib_plan()\n");
    Ok(text)
}

/// The plan as joint targets for any controller: `id`, `role`, `q1_deg..qN_deg`, one row per
/// pose in the planned order.
pub fn joint_targets(plan: &Plan) -> crate::Result<String> {
    plan.poses_csv(&[])
}
