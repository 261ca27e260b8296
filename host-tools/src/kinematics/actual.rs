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
#[derive(Clone, Debug)]
pub struct ActualRobot {
    /// The geometry and frames, in core units, with the file's identification mask.
    pub model: RobotModel,
    /// The joint maps (`[joint_maps]`), when the file has them.
    pub maps: Option<JointMaps>,
    /// The gravity compliance (`[compliance]` with `[dynamics]`), when the file has it.
    pub compliance: Option<FileCompliance>,
}

impl ActualRobot {
    /// The model of the robot file `file`, read from `path` (which names it in errors): its
    /// geometry, joint maps and compliance, each checked.
    pub fn from_file(file: &RobotFile, path: &Path) -> crate::Result<Self> {
        Self::from_model(file.to_model(path)?, file, path)
    }

    /// [`Self::from_file`] with the geometry already converted (`model`, of `file`).
    pub fn from_model(model: RobotModel, file: &RobotFile, path: &Path) -> crate::Result<Self> {
        Ok(Self {
            model,
            maps: file.joint_maps(path)?,
            compliance: file.gravity_compliance(path)?,
        })
    }

    /// The kinematic angles (rad) of the joint readings `readings` (rad): the readings with each
    /// joint's map added; the readings themselves without maps.
    pub fn kinematic_angles(&self, readings: &JointVec<f64>) -> JointVec<f64> {
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
        let columns =
            crate::model::compliance::columns(&compliance.gravity, robot, errors, angles)?;
        Ok(Some(crate::model::compliance::displacement(
            &columns,
            &compliance.gains,
        )))
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
