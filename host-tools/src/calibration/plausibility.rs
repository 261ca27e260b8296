//! The final plausibility check of every calibration: a robot's geometric errors are a few
//! millimetres and a fraction of a degree, and a geometric model fits good tracker data to well
//! under a millimetre. A result beyond these bounds comes from wrong input (units, Euler
//! convention, joint order or sign, frames), a pose set that cannot determine the parameters, or
//! errors that are not geometric; it is refused unless the user accepts it
//! (`--accept-implausible`).

use super::{CalibrationResult, IdentifiedParameter};
use crate::io::robot_file::RobotFile;
use calib_core::Parameter;

/// Largest plausible identified length error (joints, and frames relative to their registration),
/// mm. Manufacturing errors of a robot's links are below a few millimetres. A robot file's
/// `max_length_error_mm` replaces it for that robot (and `max_angle_error_deg` the angle bound).
/// A convention, not fitted to data (docs/RESULTS.md, "Thresholds set from data").
pub const MAX_LENGTH_ERROR_MM: f64 = 20.0;

/// Largest plausible identified angle error, degrees. Twist and joint zero errors are a fraction
/// of a degree.
pub(crate) const MAX_ANGLE_ERROR_DEG: f64 = 3.0;

/// Largest plausible RMS position residual after calibration, mm. Real robots calibrated with
/// a geometric model reach 0.1-0.5 mm (the UR10 of the bundled data: 0.42 mm mean). A robot
/// file's `repeatability_mm` raises it to [`REPEATABILITY_FACTOR`] times that: a cable-driven
/// Barrett WAM (2 mm repeatability) fits its tracker data to 2.2 mm RMS.
/// One of the thresholds set from data (docs/RESULTS.md, "Thresholds set from data").
pub(crate) const MAX_FIT_RMS_MM: f64 = 2.0;

/// The plausible fit as a multiple of the robot's repeatability.
pub(crate) const REPEATABILITY_FACTOR: f64 = 2.0;

/// What to check when a result is refused.
pub(crate) const LIKELY_CAUSES: &str = "Likely causes: the units of the data columns (mm or m, deg or rad), the Euler convention of a \
data profile, the joint order or signs against the robot file, the frames (--frames), or a pose set that cannot \
determine the parameters (`calib check`). If the result is right, --accept-implausible writes it.";

/// The bound (in the parameter's unit, mm or deg) of an identified parameter, and whose bound it
/// is. A robot file's `max_length_error_mm` and `max_angle_error_deg` bound its joints' errors
/// (the robot's geometry); the frames of the measurement set-up keep the general bounds.
pub fn bound_of(robot: &RobotFile, parameter: Parameter) -> (f64, &'static str) {
    let own = match parameter {
        Parameter::Joint { .. } if parameter.is_angle() => robot.max_angle_error_deg,
        Parameter::Joint { .. } => robot.max_length_error_mm,
        _ => None,
    };
    match (own, parameter.is_angle()) {
        (Some(b), true) => (b, OWN_ANGLE_BOUND),
        (Some(b), false) => (b, OWN_LENGTH_BOUND),
        (None, true) => (MAX_ANGLE_ERROR_DEG, "a robot's geometric errors"),
        (None, false) => (MAX_LENGTH_ERROR_MM, "a robot's geometric errors"),
    }
}

const OWN_ANGLE_BOUND: &str = "this robot's geometric errors (its file's max_angle_error_deg)";
const OWN_LENGTH_BOUND: &str = "this robot's geometric errors (its file's max_length_error_mm)";

/// The problems of a calibration's identified `parameters` and its fit (`fit_rms_mm`, the RMS
/// position error on the calibration poses), each naming the value and its bound (those of the
/// robot file `file`); empty when it is plausible.
pub fn check(parameters: &[IdentifiedParameter], fit_rms_mm: f64, file: &RobotFile) -> Vec<String> {
    let mut problems = Vec::new();
    for p in parameters {
        let (bound, whose) = bound_of(file, p.parameter);
        let (value, unit) = if p.parameter.is_angle() {
            (p.value.to_degrees(), "deg")
        } else {
            (p.value, "mm")
        };
        if !value.is_finite() || value.abs() > bound {
            problems.push(format!(
                "{} = {value:.4} {unit} is beyond the plausible {bound} {unit} of {whose}",
                p.parameter
            ));
        }
    }
    let rms = fit_rms_mm;
    let (limit, why) = match file.repeatability_mm {
        Some(r) if REPEATABILITY_FACTOR * r > MAX_FIT_RMS_MM => (
            REPEATABILITY_FACTOR * r,
            format!("{REPEATABILITY_FACTOR} times the robot's repeatability of {r} mm"),
        ),
        _ => (
            MAX_FIT_RMS_MM,
            "what a geometric model reaches on good data".to_string(),
        ),
    };
    if !rms.is_finite() || rms > limit {
        problems.push(format!(
            "the calibrated model misses the calibration poses by {rms:.3} mm RMS, more than the {limit} mm \
             of {why}"
        ));
    }
    problems
}

/// The question a refusal asks when a joint's error is beyond the bounds the robot's own file
/// states: a model of another robot or variant (a UR10e file for a UR10) shows as errors of
/// centimetres that the file's bounds, taken from real calibrations of the robot, rule out.
pub fn question(result: &CalibrationResult) -> Option<String> {
    result
        .implausible
        .iter()
        .any(|p| p.contains(OWN_ANGLE_BOUND) || p.contains(OWN_LENGTH_BOUND))
        .then(|| {
            format!(
                "Is {} ({}) the model of the robot that was measured? A model of another robot or \
                 variant shows as geometric errors beyond the bounds its file states.",
                result.robot,
                result.robot_path.display()
            )
        })
}
