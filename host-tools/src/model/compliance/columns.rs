//! The gains' columns: per compliance gain, the motion of the end point at a pose, which the
//! identification fits (linear in the gains) and the controller's deflection equals.

use super::{GAIN_COUNT, GAINS, Gain, Gravity, check_joints};
use calib_core::model::JointVec;
use calib_core::{Kinematics, ParameterErrors, Robot};
use nalgebra::Dyn;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

/// Per gain, the motion `[v (mm); w (rad)]` of the end point (the origin of the tool frame) per
/// urad/(N m) at kinematic joint angles `q` (rad), for the model `robot + errors` (in whatever
/// frames it is given: gravity is turned by its base rotation). Error: a robot of other than
/// [`JOINTS`](crate::JOINTS) joints (the gravity model has one mass per joint of a 6-joint robot).
pub fn columns(
    gravity: &Gravity,
    robot: &Robot<f64, Dyn>,
    errors: &ParameterErrors<f64, Dyn>,
    q: &JointVec<f64>,
) -> crate::Result<[[f64; 6]; GAIN_COUNT]> {
    check_joints(robot.joints.len())?;
    let kinematics = Kinematics::new(robot, errors)?;
    let base = kinematics.base();
    let mut frame = Isometry3::from_parts(
        Translation3::from(base.translation.vector),
        UnitQuaternion::from_rotation_matrix(&base.rotation),
    );
    let turn = |axis: &nalgebra::Unit<Vector3<f64>>, angle: f64| {
        Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(axis, angle),
        )
    };
    // frames[j]: the frame joint j + 1 turns in; frames[N]: the flange.
    let mut frames = vec![frame];
    for ((joint, e), qj) in robot.joints.iter().zip(&errors.joints).zip(q.iter()) {
        frame *= turn(&Vector3::z_axis(), qj + joint.theta_offset + e.dtheta)
            * Isometry3::translation(joint.a + e.da, 0.0, joint.d + e.dd)
            * turn(&Vector3::x_axis(), joint.alpha + e.dalpha)
            * turn(&Vector3::y_axis(), joint.beta + e.dbeta);
        frames.push(frame);
    }
    let end = (frame * Point3::from(kinematics.tool().translation.vector)).coords;
    let g = base.rotation * gravity.gravity;
    let masses: Vec<(f64, Vector3<f64>)> = gravity
        .links
        .iter()
        .zip(&frames[1..])
        .map(|((m, c), f)| (*m, (f * Point3::from(*c)).coords))
        .chain(std::iter::once((
            gravity.tool.0,
            (frames[robot.joints.len()] * Point3::from(gravity.tool.1)).coords,
        )))
        .collect();
    let mut out = [[0.0; 6]; GAIN_COUNT];
    for (column, gain) in out.iter_mut().zip(&GAINS) {
        let (j, axis_index) = match gain {
            Gain::Torsion(j) => (*j, 2),
            Gain::TiltX(j) => (*j, 0),
            Gain::TiltY(j) => (*j, 1),
        };
        let f = &frames[j - 1];
        let origin = f.translation.vector;
        // Everything beyond joint j: links j..N and the tool's load (N m from kg mm m/s^2).
        let moment: Vector3<f64> = masses
            .iter()
            .skip(j - 1)
            .map(|(m, c)| (c - origin).cross(&(g * *m)))
            .sum::<Vector3<f64>>()
            * 1e-3;
        let axis = f.rotation * Vector3::ith(axis_index, 1.0);
        let w = axis * axis.dot(&moment) * 1e-6;
        let v = w.cross(&(end - origin));
        *column = [v.x, v.y, v.z, w.x, w.y, w.z];
    }
    Ok(out)
}

/// The end point's motion `[v (mm); w (rad)]` for `gains` (urad/(N m)) from [`columns`].
pub fn displacement(columns: &[[f64; 6]; GAIN_COUNT], gains: &[f64; GAIN_COUNT]) -> [f64; 6] {
    let mut out = [0.0; 6];
    for (column, gain) in columns.iter().zip(gains) {
        for (o, c) in out.iter_mut().zip(column) {
            *o += c * gain;
        }
    }
    out
}
