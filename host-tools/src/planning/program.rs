//! A plan as a program that moves the robot through its poses, for the cell to run while the
//! tracker measures: URScript for Universal Robots, and a plain joint-target CSV for any other
//! controller's import. Both list the poses in the plan's order, which keeps the joint motion
//! short and is the order `calib merge --by order` pairs the tracker's points in.

use super::Plan;

pub use crate::formats::urscript::Motion;

/// The plan as a URScript program (`def calib_plan(): ... end`): per pose a `movej` to its joints
/// (rad, the controller's readings) and a `sleep` of the settle time, each commented with the
/// pose's id and role. `robot` names the robot in the header comment. Refused for a robot that
/// is not a 6-joint arm (URScript drives Universal Robots), or a settle time of 0.
pub fn urscript(plan: &Plan, robot: &str, motion: &Motion) -> crate::Result<String> {
    if !(motion.settle_s.is_finite() && motion.settle_s > 0.0) {
        return Err(crate::refused!(option "--settle-s";
            "--settle-s must be a finite number > 0, got {}",
            motion.settle_s
        ));
    }
    let header = [
        format!(
            "Measurement plan for {}, written by calib plan: {} poses in the planned order.",
            robot,
            plan.poses.len()
        ),
        format!(
            "The robot stands still {} s at each pose for the tracker to measure it.",
            motion.settle_s
        ),
    ];
    let targets: Vec<(String, Vec<f64>)> = (plan.poses.iter())
        .map(|p| (format!("{} ({})", p.id, p.role.name()), p.q.clone()))
        .collect();
    crate::formats::urscript::movej_program("calib_plan", &header, &targets, motion)
}

/// The plan as joint targets for any controller: `id`, `role`, `q1_deg..qN_deg`, one row per
/// pose in the planned order.
pub fn joint_targets(plan: &Plan) -> crate::Result<String> {
    plan.poses_csv(&[])
}
