//! The model of the actual robot, as one value: its geometry with the base and tool frames (a
//! [`RobotModel`]), its joint maps (each reading corrected by a smooth function of itself) and
//! its gravity compliance (the pose moved by the deflection under the links' weight), built from
//! a robot file in one place.
//!
//! Whatever evaluates a robot file's whole model takes this value: forward kinematics (`calib
//! fk`, the Python package), the controller's parameter block, compensation, and the data's
//! kinematic angles and deflection-free poses the geometry is fitted to. A robot file therefore
//! means the same to every command; a file whose maps or compliance are invalid is refused by all
//! of them in the same words.

use crate::io::robot_file::{RobotFile, RobotModel};
use crate::model::compliance::FileCompliance;
use crate::model::joint_maps::JointMaps;
use calib_core::model::JointVec;
use calib_core::{ParameterErrors, Pose};
use nalgebra::{Dyn, Rotation3, Vector3};
use std::path::Path;

/// The actual robot: geometry and frames, optional joint maps, optional gravity compliance.
///
/// A calibration's stages each take one and return the one they found: the frames registered
/// ([`Self::with_frames`]), the geometry identified, the joint maps and compliance found.
#[derive(Clone, Debug)]
pub struct ActualRobot {
    /// The robot file the model was read from, or written for it (its frames, when a stage
    /// registered them).
    pub file: RobotFile,
    /// The geometry and frames, in core units, with the identification mask a stage uses.
    pub model: RobotModel,
    /// The joint maps (`[joint_maps]`), when the file has them.
    pub maps: Option<JointMaps>,
    /// The gravity compliance (`[compliance]` with `[dynamics]`), when the file has it.
    pub compliance: Option<FileCompliance>,
}

impl ActualRobot {
    /// The model of the robot file `file`, read from `path` (which names it in errors): its
    /// geometry, joint maps and compliance, each checked.
    pub fn from_file(file: RobotFile, path: &Path) -> crate::Result<Self> {
        let model = file.to_model(path)?;
        let joints = model.robot.joints.len();
        Ok(Self {
            model,
            maps: file.joint_maps(path)?,
            compliance: file.gravity_compliance(path, joints)?,
            file,
        })
    }

    /// This robot with the frames (`[base]`, `[tool]`) of `file` and the geometry `model` of
    /// that file (its frames checked by the caller), the identification mask, joint maps and
    /// compliance kept: what registering the frames of a measurement setup returns.
    pub fn with_frames(&self, file: RobotFile, mut model: RobotModel) -> Self {
        model.mask = self.model.mask;
        Self {
            file,
            model,
            maps: self.maps.clone(),
            compliance: self.compliance.clone(),
        }
    }

    /// This robot in its measurement setup ([`RobotFile::in_measurement_setup`]: the tracker's
    /// base and the identified probe or reflector as the tool), the identification mask kept.
    pub fn in_measurement_setup(&self) -> crate::Result<Self> {
        let file = self.file.in_measurement_setup();
        let model = file.to_model(&self.model.path)?;
        Ok(self.with_frames(file, model))
    }

    /// The probe or reflector identified with this robot's model (`[measurement] flange_tool`).
    pub(crate) fn identified_probe(&self) -> Option<&crate::io::robot_file::FrameEntry> {
        self.file
            .measurement
            .as_ref()
            .and_then(|m| m.flange_tool.as_ref())
    }

    /// The kinematic angles (rad) of the joint readings `readings` (rad): the readings with each
    /// joint's map added; the readings themselves without maps.
    pub(crate) fn kinematic_angles(&self, readings: &JointVec<f64>) -> JointVec<f64> {
        match &self.maps {
            Some(maps) => maps.apply(readings),
            None => *readings,
        }
    }

    /// The compliance's displacement of the end pose at the kinematic angles `angles` (rad) of the
    /// geometry `robot + errors` (mm and rad): translation (mm) then rotation vector (rad);
    /// `None` without compliance.
    pub fn deflection(
        &self,
        robot: &calib_core::Robot<f64, Dyn>,
        errors: &ParameterErrors<f64, Dyn>,
        angles: &JointVec<f64>,
    ) -> crate::Result<Option<[f64; 6]>> {
        let Some(compliance) = &self.compliance else {
            return Ok(None);
        };
        let gravity = &compliance.gravity;
        Ok(Some(gravity.deflection(
            &compliance.gains,
            robot,
            errors,
            angles,
        )?))
    }

    /// `pose`, the end pose of this robot's nominal geometry at the kinematic angles `angles`
    /// (rad), moved by the compliance's deflection there (unchanged without compliance).
    pub fn deflected(
        &self,
        mut pose: Pose<f64>,
        angles: &JointVec<f64>,
    ) -> crate::Result<Pose<f64>> {
        let robot = &self.model.robot;
        let zero = ParameterErrors::zeros_for(robot.joint_count());
        if let Some(d) = self.deflection(robot, &zero, angles)? {
            pose.translation.vector += Vector3::new(d[0], d[1], d[2]);
            pose.rotation = Rotation3::new(Vector3::new(d[3], d[4], d[5])) * pose.rotation;
        }
        Ok(pose)
    }
}
