//! `calib fk`: the end pose of a robot model for given joint readings.

use crate::error::Context;
use crate::kinematics::actual::ActualRobot;
use calib_core::math::so3;
use calib_core::model::JointVec;
use calib_core::{Kinematics, Pose};
use nalgebra::{Rotation3, UnitQuaternion};
use serde::Serialize;

/// The end pose as printed by `calib fk --json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FkOutput {
    /// Tool point position `[x, y, z]`, mm.
    pub position_mm: [f64; 3],
    /// Orientation as a unit quaternion `[w, x, y, z]` with `w >= 0`.
    pub quaternion_wxyz: [f64; 4],
    /// Orientation as a rotation vector `[rx, ry, rz]`, rad.
    pub rotation_vector_rad: [f64; 3],
}

impl FkOutput {
    /// Describes a pose of the core.
    pub fn from_pose(pose: &Pose<f64>) -> Self {
        let rotation = Rotation3::from_matrix_unchecked(*pose.rotation.matrix());
        let q = UnitQuaternion::from_rotation_matrix(&rotation);
        let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
        // `+ 0.0` turns a negative zero into zero, so output never shows "-0".
        let p = pose.translation.vector;
        let r = so3::log(pose.rotation.matrix());
        Self {
            position_mm: [p.x, p.y, p.z].map(|v| v + 0.0),
            quaternion_wxyz: [q.w, q.i, q.j, q.k].map(|v| sign * v + 0.0),
            rotation_vector_rad: [r.x, r.y, r.z].map(|v| v + 0.0),
        }
    }

    /// Fixed-width text for people.
    pub fn to_text(&self) -> String {
        let [x, y, z] = self.position_mm;
        let [qw, qx, qy, qz] = self.quaternion_wxyz;
        let [rx, ry, rz] = self.rotation_vector_rad;
        format!(
            "position (mm)          x {x:>14.6}  y {y:>14.6}  z {z:>14.6}\n\
             quaternion (w, x, y, z)  {qw:>12.9} {qx:>12.9} {qy:>12.9} {qz:>12.9}\n\
             rotation vector (rad)  x {rx:>14.9}  y {ry:>14.9}  z {rz:>14.9}\n"
        )
    }
}

/// `calib fk`: the end pose of the robot file's whole model (`kinematics`: geometry, joint maps,
/// compliance) at the joint readings `joints_deg` (degrees, one per joint), each checked: the
/// count, finite, within ten turns, within the joint limits.
pub fn forward_deg(kinematics: &FileKinematics, joints_deg: &[f64]) -> crate::Result<FkOutput> {
    let model = &kinematics.actual.model;
    let joints = model.robot.joints.len();
    if joints_deg.len() != joints {
        return Err(crate::refused!(option "--joints-deg";
            "--joints-deg has {} values, the robot {} has {joints} joints",
            joints_deg.len(),
            model.name
        ));
    }
    let mut q = vec![0.0; joints];
    for (i, (qi, deg)) in q.iter_mut().zip(joints_deg).enumerate() {
        if !deg.is_finite() {
            return Err(crate::refused!(option "--joints-deg";
                "--joints-deg: q{} = {deg} is not a finite number",
                i + 1
            ));
        }
        // As in tracker data: beyond ten turns a reading is a unit or typing error (and its
        // sine and cosine no longer mean anything).
        if deg.abs() > crate::io::tracker_data::MAX_JOINT_DEG {
            return Err(crate::refused!(option "--joints-deg";
                "--joints-deg: q{} = {deg:e} deg is beyond ten turns ({} deg); give the joint readings in degrees",
                i + 1,
                crate::io::tracker_data::MAX_JOINT_DEG
            ));
        }
        *qi = deg.to_radians();
    }
    for (i, (qi, limits)) in q.iter().zip(&model.robot.limits).enumerate() {
        if !limits.contains(*qi) {
            return Err(crate::refused!(option "--joints-deg";
                "--joints-deg: q{} = {} deg is outside the joint limits [{}, {}] deg of {}",
                i + 1,
                qi.to_degrees(),
                limits.lower.to_degrees(),
                limits.upper.to_degrees(),
                model.path.display()
            ));
        }
    }
    let pose = kinematics.pose(&q, &|| "--joints-deg".to_string())?;
    Ok(FkOutput::from_pose(&pose))
}

/// A robot file's whole model at many joint configurations: its geometry, its joint maps (each
/// reading corrected by its map) and its gravity compliance (the pose moved by its displacement),
/// the [`ActualRobot`] with its kinematics prepared once. `calib fk`, the Python package's
/// `Robot.fk` and any caller with many configurations.
pub struct FileKinematics {
    actual: ActualRobot,
    kinematics: Kinematics<f64, nalgebra::Dyn>,
}

impl FileKinematics {
    /// The model of `file` (read from `path`, which names it in errors).
    pub fn new(
        file: &crate::io::robot_file::RobotFile,
        path: &std::path::Path,
    ) -> crate::Result<Self> {
        let actual = ActualRobot::from_file(file.clone(), path)?;
        let kinematics = Kinematics::nominal(&actual.model.robot)
            .with_context(|| format!("robot file {}", path.display()))?;
        Ok(Self { actual, kinematics })
    }

    /// The robot's name.
    pub fn name(&self) -> &str {
        &self.actual.model.name
    }

    /// The joint count.
    pub fn joints(&self) -> usize {
        self.actual.model.robot.joints.len()
    }

    /// The end pose (mm, the robot's base frame) at the joint readings `q_rad` (rad, one per
    /// joint). Refused, naming `what` (such as `row 3`): a count that differs from the joints, a
    /// reading that is not finite or beyond ten turns, one outside the joint limits.
    pub fn pose(&self, q_rad: &[f64], what: &dyn Fn() -> String) -> crate::Result<Pose<f64>> {
        let joints = self.joints();
        if q_rad.len() != joints {
            return Err(crate::refused!(input what();
                "{}: {} joint values, the robot {} has {joints} joints",
                what(),
                q_rad.len(),
                self.actual.model.name
            ));
        }
        for (i, q) in q_rad.iter().enumerate() {
            if !q.is_finite() {
                return Err(crate::refused!(input what();
                    "{}: q{} = {q} is not a finite number",
                    what(),
                    i + 1
                ));
            }
            if q.to_degrees().abs() > crate::io::tracker_data::MAX_JOINT_DEG {
                return Err(crate::refused!(input what();
                    "{}: q{} = {q:e} rad is beyond ten turns; give the joint readings in radians",
                    what(),
                    i + 1
                ));
            }
        }
        if let Some(outside) = self.actual.model.outside_limits(q_rad) {
            return Err(crate::refused!(input what(); "{}: {outside}", what()));
        }
        let readings = JointVec::<f64>::from_fn(joints, |j| q_rad[j]);
        let q = self.actual.kinematic_angles(&readings);
        let pose = self.kinematics.forward(&q)?;
        self.actual.deflected(pose, &q)
    }
}
