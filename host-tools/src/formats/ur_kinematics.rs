//! The UR-style kinematics YAML: the `kinematics:` file of Universal Robots' ROS
//! description packages (`ur_description`, `default_kinematics.yaml` and what `ur_calibration`
//! writes), which the UR ROS drivers load into their URDF.
//!
//! That URDF chains `base_link_inertia` (the DH base) -> `shoulder_pan_joint` -> ... ->
//! `wrist_3_joint` with each joint's origin given as `x, y, z` (m) and `roll, pitch, yaw` (rad,
//! `R = Rz(yaw) Ry(pitch) Rx(roll)`) and rotation about z; `tool0` is the last joint's frame
//! (its `flange` and `tool0` fixed joints compose to the identity). Our chain
//! `T_base Rz(q_1) F_1 ... Rz(q_6) F_6` (see [`crate::formats::urdf`]) regroups exactly into that form:
//! with `F_i = Z_i P_i`, `Z_i = Rz(theta_i) Tz(d_i)` (which commutes with the joint's rotation)
//! and `P_i = Tx(a_i) Rx(alpha_i) Ry(beta_i)`, the segments are `shoulder = T_base Z_1`,
//! `segment_i = P_(i-1) Z_i` (i = 2..6), and what follows the last joint, `P_6`, must be the
//! identity: a UR description has no frame for it. A model with `a_6`, `alpha_6` or `beta_6` off
//! zero is refused, with the remedy. The controller's tool (`[tool]`) is the TCP set on the
//! robot's controller, not part of this file; the export writes it into a comment.

use crate::JOINTS;
use crate::formats::urdf::{Origin, frame};
use calib_core::{MdhJoint, Robot};
use nalgebra::Dyn;
use nalgebra::{IsometryMatrix3, Rotation3, Translation3, Vector3};

/// The segment names of the UR description, joint 1 first.
pub(crate) const SEGMENTS: [&str; 6] = [
    "shoulder",
    "upper_arm",
    "forearm",
    "wrist_1",
    "wrist_2",
    "wrist_3",
];

/// `Z = Rz(theta) Tz(d)` of a joint (mm).
fn z_part(joint: &MdhJoint<f64>) -> IsometryMatrix3<f64> {
    IsometryMatrix3::from_parts(
        Translation3::new(0.0, 0.0, joint.d),
        Rotation3::from_axis_angle(&Vector3::z_axis(), joint.theta_offset),
    )
}

/// `P = Tx(a) Rx(alpha) Ry(beta)` of a joint (mm).
fn x_part(joint: &MdhJoint<f64>) -> IsometryMatrix3<f64> {
    IsometryMatrix3::from_parts(
        Translation3::new(joint.a, 0.0, 0.0),
        Rotation3::from_axis_angle(&Vector3::x_axis(), joint.alpha)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), joint.beta),
    )
}

/// The six segments (mm), or why the model has no UR form (a robot of other than six joints
/// is no UR).
pub fn segments(robot: &Robot<f64, Dyn>) -> crate::Result<Vec<IsometryMatrix3<f64>>> {
    let (Some(last), Some(first)) = (robot.joints.last(), robot.joints.first()) else {
        return Err(crate::refused!(unsupported "UR kinematics file";
            "a UR kinematics file describes a {JOINTS}-joint UR robot; this one has none"
        ));
    };
    if robot.joints.len() != JOINTS {
        return Err(crate::refused!(unsupported "UR kinematics file";
            "a UR kinematics file describes a {JOINTS}-joint UR robot; this one has {} joints",
            robot.joints.len()
        ));
    }
    if last.a != 0.0 || last.alpha != 0.0 || last.beta != 0.0 {
        return Err(crate::refused!(unsupported "UR kinematics file";
            "the model has a fixed transform after joint 6 (a6 = {} mm, alpha6 = {} deg, beta6 = {} deg), \
             for which a UR kinematics file has no frame (its tool0 is joint 6's frame). Export the URDF \
             instead (--format urdf, exact), or calibrate without them (identify = [\"theta\", \"d\"] for joint 6 \
             in the robot file; the tool frame takes them up)",
            last.a,
            last.alpha.to_degrees(),
            last.beta.to_degrees()
        ));
    }
    let mut out = vec![frame(&robot.base) * z_part(first)];
    for pair in robot.joints.windows(2) {
        out.push(x_part(&pair[0]) * z_part(&pair[1]));
    }
    Ok(out)
}

/// The YAML of `robot` (`source` names the file in a comment).
pub fn yaml(robot: &Robot<f64, Dyn>, source: &str) -> crate::Result<String> {
    // Positional notation with every digit (Rust's f64 Display round-trips and never writes an
    // exponent, which YAML 1.1 readers such as PyYAML, used by xacro, would take for a string).
    let mut body = String::from("kinematics:\n");
    for (name, segment) in SEGMENTS.iter().zip(segments(robot)?) {
        let o = Origin::of(&segment);
        let [x, y, z] = o.xyz_m;
        let [roll, pitch, yaw] = o.rpy_rad;
        body.push_str(&format!(
            "  {name}:\n    x: {x}\n    y: {y}\n    z: {z}\n    roll: {roll}\n    pitch: {pitch}\n    yaw: {yaw}\n"
        ));
    }
    let hash = crc32fast::hash(body.as_bytes());
    let tool = Origin::of(&frame(&robot.tool));
    let source = crate::io::text::one_line(source);
    Ok(format!(
        "# Written by calib export --format ur-kinematics-yaml from {source}: the model's joint origins\n\
         # in the form of ur_description's kinematics files (m, rad); geometry only, exact.\n\
         # The hash is this file's (CRC-32 of the values), not the robot controller's: the UR driver warns\n\
         # that they differ, which is true (this calibration is not the controller's own).\n\
         # The model's tool from the flange (the controller's TCP): xyz {:?} m, rpy {:?} rad.\n\
         {body}  hash: calib_{hash:08x}\n",
        tool.xyz_m, tool.rpy_rad
    ))
}
