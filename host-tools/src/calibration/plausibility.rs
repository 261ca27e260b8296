//! The final plausibility check of every calibration: a robot's geometric errors are a few
//! millimetres and a fraction of a degree, and a geometric model fits good tracker data to well
//! under a millimetre. A result beyond these bounds comes from wrong input (units, Euler
//! convention, joint order or sign, frames), a pose set that cannot determine the parameters, or
//! errors that are not geometric; it is refused unless the user accepts it
//! (`--accept-implausible`).

use super::CalibrationResult;

/// Largest plausible identified length error (joints, and frames relative to their registration),
/// mm. Manufacturing errors of a robot's links are below a few millimetres. A robot file's
/// `max_length_error_mm` replaces it for that robot (and `max_angle_error_deg` the angle bound).
pub(crate) const MAX_LENGTH_ERROR_MM: f64 = 20.0;

/// Largest plausible identified angle error, degrees. Twist and joint zero errors are a fraction
/// of a degree.
pub(crate) const MAX_ANGLE_ERROR_DEG: f64 = 3.0;

/// Largest plausible RMS position residual after calibration, mm. Real robots calibrated with
/// a geometric model reach 0.1-0.5 mm (the UR10 of the bundled data: 0.42 mm mean). A robot
/// file's `repeatability_mm` raises it to [`REPEATABILITY_FACTOR`] times that: a cable-driven
/// Barrett WAM (2 mm repeatability) fits its tracker data to 2.2 mm RMS.
pub(crate) const MAX_FIT_RMS_MM: f64 = 2.0;

/// The plausible fit as a multiple of the robot's repeatability.
pub(crate) const REPEATABILITY_FACTOR: f64 = 2.0;

/// What to check when a result is refused.
pub(crate) const LIKELY_CAUSES: &str = "Likely causes: the units of the data columns (mm or m, deg or rad), the Euler convention of a \
data profile, the joint order or signs against the robot file, the frames (--frames), or a pose set that cannot \
determine the parameters (`calib check`). If the result is right, --accept-implausible writes it.";

/// The problems of `result`, each naming the value and its bound; empty when it is plausible.
pub fn check(result: &CalibrationResult) -> Vec<String> {
    let mut problems = Vec::new();
    let robot = &result.identified_robot;
    for p in &result.parameters {
        let (value, (bound, whose), unit) = if p.parameter.is_angle() {
            let bound = robot.max_angle_error_deg.map_or(
                (MAX_ANGLE_ERROR_DEG, "a robot's geometric errors"),
                |b| {
                    (
                        b,
                        "this robot's geometric errors (its file's max_angle_error_deg)",
                    )
                },
            );
            (p.value.to_degrees(), bound, "deg")
        } else {
            let bound = robot.max_length_error_mm.map_or(
                (MAX_LENGTH_ERROR_MM, "a robot's geometric errors"),
                |b| {
                    (
                        b,
                        "this robot's geometric errors (its file's max_length_error_mm)",
                    )
                },
            );
            (p.value, bound, "mm")
        };
        if !value.is_finite() || value.abs() > bound {
            problems.push(format!(
                "{} = {value:.4} {unit} is beyond the plausible {bound} {unit} of {whose}",
                p.parameter
            ));
        }
    }
    let rms = result.calibration.after.position_mm.rms;
    let (limit, why) = match result.identified_robot.repeatability_mm {
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
