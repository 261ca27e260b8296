//! The independent float64 reference ([`calib_reference`], a crate that cannot use calib-core)
//! fed from our files: a robot file's nominal values in mm and rad, a data file's records as
//! observations. Only unit conversion happens here; the kinematics and the fit are the crate's.

use crate::io::robot_file::RobotFile;
use crate::io::tracker_data::TrackerData;
pub use calib_reference::lm::ReferenceFit;
pub use calib_reference::{
    IDENTITY, Mat4, RefFrame, RefFrameErrors, RefJoint, RefModel, RefRobot, pose_error, quaternion,
    rotation_vector,
};

/// The nominal robot of a robot file, in mm and rad.
pub fn robot(file: &RobotFile) -> RefRobot {
    let frame = |entry: &Option<crate::io::robot_file::FrameEntry>| match entry {
        Some(f) => RefFrame {
            xyz_mm: f.xyz_mm,
            rpy_rad: f.rpy_deg.map(f64::to_radians),
        },
        None => RefFrame::default(),
    };
    RefRobot {
        joints: file
            .joint
            .iter()
            .map(|j| RefJoint {
                a: j.a_mm,
                alpha: j.alpha_deg.to_radians(),
                theta_offset: j.theta_offset_deg.to_radians(),
                d: j.d_mm,
                beta: j.beta_deg.to_radians(),
            })
            .collect(),
        base: frame(&file.base),
        tool: frame(&file.tool),
    }
}

/// The reference model of a robot file plus errors: per joint `[da, dalpha, dtheta, dd, dbeta]`
/// (mm, rad), base and tool errors `[tx, ty, tz, rx, ry, rz]` (mm, rad). Missing joint errors
/// count as zero.
pub fn model(
    file: &RobotFile,
    joint_errors: &[[f64; 5]],
    base_errors: &RefFrameErrors,
    tool_errors: &RefFrameErrors,
) -> RefModel {
    RefModel::new(&robot(file), joint_errors, base_errors, tool_errors)
}

/// The records of a data file as the reference's observations (a position-only record has an
/// identity rotation that does not count).
pub(crate) fn observations(data: &TrackerData) -> Vec<calib_reference::lm::Observation> {
    data.records
        .iter()
        .map(|r| {
            let mut pose = IDENTITY;
            for (i, row) in pose.iter_mut().take(3).enumerate() {
                if let Some(rotation) = &r.rotation {
                    for (j, v) in row.iter_mut().take(3).enumerate() {
                        *v = rotation[(i, j)];
                    }
                }
                row[3] = r.position[i];
            }
            calib_reference::lm::Observation {
                q: r.q.clone(),
                pose,
                oriented: r.rotation.is_some(),
                weight: r.weight,
            }
        })
        .collect()
}

/// The reference fit of the errors of `names` (such as `da1`, `dbeta2`) of a robot file to a
/// data file from `start`; `k` weighs orientation (rad) against position (mm).
pub fn fit(
    file: &RobotFile,
    names: &[String],
    data: &TrackerData,
    k: f64,
    start: &[f64],
) -> Result<ReferenceFit, calib_reference::lm::UnknownParameter> {
    calib_reference::lm::fit(&robot(file), names, &observations(data), k, start)
}

/// Root mean square of the absolute position error `|dp|` (mm) of a robot file's reference
/// model (its values as they are, no errors added) on a data file.
pub fn rms_position_error(file: &RobotFile, data: &TrackerData) -> f64 {
    calib_reference::lm::rms_position_error(
        &model(file, &[], &[0.0; 6], &[0.0; 6]),
        &observations(data),
    )
}
