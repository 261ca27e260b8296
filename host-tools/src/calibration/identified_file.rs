//! The identified robot file: the robot file given with the identified errors, the controller's
//! frames, the measurement setup in `[measurement]`, the covariance in `[calibration]`; the maps
//! and compliance sections are added by [`super::maps`]. Emitted once per calibration, from the
//! model the stages return.

use super::{CalibrationConfig, IdentifiedParameter, Identify};
use crate::io::robot_file::RobotFile;
use crate::measurement::dataset::Seen;
use crate::measurement::frames::FramesReport;
use calib_core::{Parameter, ParameterErrors};
use nalgebra::Dyn;

/// The identified robot file and the identified frames in the report. The file is the robot
/// file given plus the identified joint errors, with the controller's base and tool (those of the
/// robot file given); frames identified from tracker data are the measurement setup and go to
/// its `[measurement]` section and the report, never into `[base]` and `[tool]`.
pub(crate) fn identified_robot(
    dataset: &Seen<'_>,
    config: &CalibrationConfig,
    parameters: &[IdentifiedParameter],
    errors: &ParameterErrors<f64, Dyn>,
    (frames, given): (&mut FramesReport, &RobotFile),
) -> crate::io::robot_file::RobotFile {
    let std_errors: Vec<(Parameter, f64)> = parameters
        .iter()
        .filter_map(|p| p.std_error.map(|s| (p.parameter, s)))
        .collect();
    let method = config.method.name();
    let nominal = dataset.robot.model.path.display().to_string();
    let mut file = dataset.robot.file.with_errors(
        errors,
        parameters.iter().map(|p| p.parameter),
        &std_errors,
        method,
        &nominal,
    );
    if !frames.identified.base() {
        return file;
    }
    // The measurement frames: the fitted start plus their identified errors.
    frames.base = file.base.clone();
    if frames.identified.tool() {
        frames.tool = file.tool.clone();
    }
    let is_joint = |p: &Parameter| matches!(p, Parameter::Joint { .. });
    let mut joint_errors = *errors;
    joint_errors.base = calib_core::FrameErrors::default();
    joint_errors.tool = calib_core::FrameErrors::default();
    file = dataset.robot.file.with_errors(
        &joint_errors,
        parameters.iter().map(|p| p.parameter).filter(is_joint),
        &std_errors
            .into_iter()
            .filter(|(p, _)| is_joint(p))
            .collect::<Vec<_>>(),
        method,
        &nominal,
    );
    (file.base, file.tool) = (given.base.clone(), given.tool.clone());
    if config.identify == Identify::Frames {
        // Re-registration: the geometry and its calibration record are the given file's.
        file.calibration = given.calibration.clone();
    }
    file.measurement =
        frames
            .base
            .clone()
            .map(|tracker_base| crate::io::robot_file::MeasurementSection {
                frames: frames.identified.name().to_string(),
                tracker_base,
                flange_tool: frames.tool.clone(),
                registered_at: None,
                geometry_from: None,
                inputs: Vec::new(),
            });
    file
}

/// Records the identified parameters' covariance `covariance` (of `parameters`, in their order;
/// the frames of the measurement setup included: the joint parameters are determined relative to
/// them) in the `[calibration]` of `file`, for a calibration of the geometry.
pub(crate) fn record_covariance(
    file: &mut RobotFile,
    (parameters, covariance): (&[IdentifiedParameter], Option<&nalgebra::DMatrix<f64>>),
    config: &CalibrationConfig,
) {
    let (Some(covariance), Identify::Geometry) = (covariance, config.identify) else {
        return;
    };
    let entry = crate::io::robot_file::CovarianceEntry {
        parameters: parameters.iter().map(|p| p.parameter.to_string()).collect(),
        matrix: (covariance.row_iter())
            .map(|r| r.iter().copied().collect())
            .collect(),
    };
    if let Some(c) = file.calibration.as_mut() {
        c.covariance = Some(entry);
    }
}
