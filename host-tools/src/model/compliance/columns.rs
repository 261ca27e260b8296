//! The gains' columns: per compliance gain, the motion of the end point at a pose, which the
//! identification fits (linear in the gains). They are the core's (`Compliance::gain_column`):
//! the deflection the controller applies, evaluated with one gain at a time, so that what is
//! fitted is what the controller applies, for any joint count.

use super::{Gravity, gains};
use calib_core::model::JointVec;
use calib_core::{Kinematics, ParameterErrors, Robot};
use nalgebra::Dyn;

/// Per gain (in the order of [`gains`]), the motion `[v (mm); w (rad)]` of the end point (the
/// origin of the tool frame) per urad/(N m) at kinematic joint angles `q` (rad), for the model
/// `robot + errors` (in whatever frames it is given: gravity is turned by its base rotation).
/// Error: masses of another joint count than the robot's, a robot without gains (fewer than 3
/// joints), a non-finite angle.
pub fn columns(
    gravity: &Gravity,
    robot: &Robot<f64, Dyn>,
    errors: &ParameterErrors<f64, Dyn>,
    q: &JointVec<f64>,
) -> crate::Result<Vec<[f64; 6]>> {
    let joints = robot.joints.len();
    let gains = gains(joints);
    let masses = gravity.to_core::<f64>(&vec![0.0; gains.len()], joints)?;
    let kinematics = Kinematics::new(robot, errors)?;
    gains
        .iter()
        .map(|gain| {
            let (j, axis) = gain.slot();
            let d = masses
                .gain_column(&kinematics, q, (j - 1, axis))?
                .ok_or_else(|| crate::numerical!("the {gain} is not a gain of the model"))?;
            let (v, w) = (d.translation, d.rotation);
            Ok([v.x, v.y, v.z, w.x, w.y, w.z])
        })
        .collect()
}

/// The end point's motion `[v (mm); w (rad)]` for `gains` (urad/(N m)) from [`columns`].
pub fn displacement(columns: &[[f64; 6]], gains: &[f64]) -> [f64; 6] {
    let mut out = [0.0; 6];
    for (column, gain) in columns.iter().zip(gains) {
        for (o, c) in out.iter_mut().zip(column) {
            *o += c * gain;
        }
    }
    out
}
