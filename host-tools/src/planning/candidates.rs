//! The candidate joint configurations a plan chooses from: generated over the joint limits
//! (`--generate`, a Halton sequence within one turn of each joint's limits) or given
//! (`--candidates`), checked against the robot and the poses asked for.

use super::*;

/// The candidates' joint values, after checking that each has the robot's joint count and that
/// there are enough of them for the poses asked for.
pub(super) fn checked_candidates(
    file: &RobotFile,
    candidates: &[(String, Vec<f64>)],
    settings: &PlanSettings,
) -> crate::Result<Vec<Vec<f64>>> {
    settings.check()?;
    let joints = file.joint.len();
    if let Some((id, q)) = candidates.iter().find(|(_, q)| q.len() != joints) {
        return Err(crate::refused!(input format!("candidate {id}");
            "candidate {id} has {} joint values, the robot has {joints} joints",
            q.len()
        ));
    }
    // Saturating: counts beyond any file (`--poses 18446744073709551615`) are refused here, not
    // an overflow.
    let wanted = settings.poses.saturating_add(settings.verify);
    if candidates.len() < wanted {
        return Err(crate::refused!(too_few candidates.len(), wanted;
            "{} candidates cannot give {} fitted and {} verification poses; give more candidates (--generate N or a longer --candidates file) or ask for fewer poses",
            candidates.len(),
            settings.poses,
            settings.verify
        ));
    }
    crate::model::counts::joint_count(joints)?;
    Ok(candidates.iter().map(|(_, q)| q.clone()).collect())
}

/// The range a joint's candidates are drawn from, rad: its limits `[lower, upper]` when they
/// span at most a turn (wherever they lie, as [190, 350] deg), else the turn within them nearest
/// to [-180, 180] deg (readings a turn apart give the same pose).
pub(super) fn one_turn(lower: f64, upper: f64) -> (f64, f64) {
    if upper - lower <= 2.0 * PI {
        (lower, upper)
    } else {
        let start = (-PI).clamp(lower, upper - 2.0 * PI);
        (start, start + 2.0 * PI)
    }
}

/// Candidate configurations spread over the joint limits (an unlimited joint: +-180 deg): `count`
/// points of a Halton sequence (the core's), skipping its first point; with `box_mm` only those
/// whose nominal tool point lies in the box `[x_min, x_max, y_min, y_max, z_min, z_max]` of the
/// base frame (at most 100 times `count` points are tried).
pub fn generate(
    file: &RobotFile,
    robot_path: &std::path::Path,
    count: usize,
    box_mm: Option<[f64; 6]>,
) -> crate::Result<Vec<(String, Vec<f64>)>> {
    crate::model::counts::joint_count(file.joint.len())?;
    let robot: Robot<f64, Dyn> = file.to_model(robot_path)?.robot;
    let joints = robot.joints.len();
    if joints > calib_core::identify::halton::MAX_DIMENSION {
        return Err(crate::refused!(unsupported "--generate";
            "--generate handles up to {} joints",
            calib_core::identify::halton::MAX_DIMENSION
        ));
    }
    let kinematics = Kinematics::nominal(&robot)?;
    let bounds: Vec<(f64, f64)> = robot
        .limits
        .iter()
        .map(|l| one_turn(l.lower, l.upper))
        .collect();
    let mut out = Vec::with_capacity(count);
    let mut point = vec![0.0; joints];
    for index in 1..=(count as u64).saturating_mul(100) {
        if out.len() == count {
            break;
        }
        calib_core::identify::halton::halton_point(
            index,
            calib_core::identify::halton::Scrambling::None,
            &mut point,
        );
        let q = JointVec::<f64>::from_fn(bounds.len(), |j| {
            bounds[j].0 + point[j] * (bounds[j].1 - bounds[j].0)
        });
        if let Some(b) = box_mm {
            let p = kinematics.forward(&q)?.translation.vector;
            let inside = (0..3).all(|a| (b[2 * a]..=b[2 * a + 1]).contains(&p[a]));
            if !inside {
                continue;
            }
        }
        out.push((format!("C{:04}", out.len() + 1), q.to_vec()));
    }
    if out.len() < count {
        return Err(crate::refused!(option "--box-mm";
            "only {} of {count} generated configurations put the tool point in the box {} mm (base frame); widen the box or give candidates (--candidates)",
            out.len(),
            box_mm
                .map(|b| format!(
                    "x {} ... {}, y {} ... {}, z {} ... {} (unbounded sides: inf)",
                    b[0], b[1], b[2], b[3], b[4], b[5]
                ))
                .unwrap_or_default()
        ));
    }
    Ok(out)
}
