//! The final plausibility check of every calibration: a robot's geometric errors are a few
//! millimetres and a fraction of a degree, and a geometric model fits good tracker data to well
//! under a millimetre. A result beyond these bounds comes from wrong input (units, Euler
//! convention, joint order or sign, frames), a pose set that cannot determine the parameters, or
//! errors that are not geometric; it is refused unless the user accepts it
//! (`--accept-implausible`).

use super::CalibrationResult;

/// Largest plausible identified length error (joints, and frames relative to their registration),
/// mm. Manufacturing errors of a robot's links are below a few millimetres.
pub const MAX_LENGTH_ERROR_MM: f64 = 20.0;

/// Largest plausible identified angle error, degrees. Twist and joint zero errors are a fraction
/// of a degree.
pub const MAX_ANGLE_ERROR_DEG: f64 = 3.0;

/// Largest plausible RMS position residual after calibration, mm. Real robots calibrated with
/// a geometric model reach 0.1-0.5 mm (the UR10 of the bundled data: 0.42 mm mean).
pub const MAX_FIT_RMS_MM: f64 = 2.0;

/// What to check when a result is refused.
pub const LIKELY_CAUSES: &str = "Likely causes: the units of the data columns (mm or m, deg or rad), the Euler convention of a \
data profile, the joint order or signs against the robot file, the frames (--frames), or a pose set that cannot \
determine the parameters (`calib check`). If the result is right, --accept-implausible writes it.";

/// The problems of `result`, each naming the value and its bound; empty when it is plausible.
pub fn check(result: &CalibrationResult) -> Vec<String> {
    let mut problems = Vec::new();
    for p in &result.parameters {
        let (value, bound, unit) = if p.parameter.is_angle() {
            (p.value.to_degrees(), MAX_ANGLE_ERROR_DEG, "deg")
        } else {
            (p.value, MAX_LENGTH_ERROR_MM, "mm")
        };
        if !value.is_finite() || value.abs() > bound {
            problems.push(format!(
                "{} = {value:.4} {unit} is beyond the plausible {bound} {unit} of a robot's geometric errors",
                p.parameter
            ));
        }
    }
    let rms = result.calibration.after.position_mm.rms;
    if !rms.is_finite() || rms > MAX_FIT_RMS_MM {
        problems.push(format!(
            "the calibrated model misses the calibration poses by {rms:.3} mm RMS, more than the {MAX_FIT_RMS_MM} mm \
             a geometric model reaches on good data"
        ));
    }
    problems
}
