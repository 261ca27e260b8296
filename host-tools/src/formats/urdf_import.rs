//! A robot brought in from its URDF (`calib import-urdf`): the chain of joints from a base link to
//! a tip link converted exactly into our model, whatever the joints' axes and origins.
//!
//! The URDF places each joint by a fixed origin (`xyz`, `rpy`) in its parent link and turns it
//! about an `axis` in its own frame. At zero joint values every axis is a line in the base link's
//! frame; our joints are those lines in the standard DH convention (`T_i = Rz(theta_i) Tz(d_i)
//! Tx(a_i) Rx(alpha_i) Ry(beta_i)`, joint `i` turning about `z_(i-1)`):
//!
//! - frame 0 (the `[base]` frame) has its `z` on joint 1's axis, at the foot of the perpendicular
//!   from the base link's origin, its `x` the base link's `x` (or `y`) made perpendicular;
//! - from frame `i-1` (its `z` on axis `i`) to frame `i` (its `z` on axis `i+1`, its origin on it):
//!   for axes that are not near parallel, the common normal (`a_i` its length, `d_i` where it
//!   leaves axis `i`, `theta_i` and `alpha_i` the turns about `z` and `x`; intersecting axes: `a_i
//!   = 0`, `x_i` along their cross product); for axes within [`PARALLEL_DEG`] of parallel, Hayati's
//!   `beta` instead (`d_i = 0`: the origin where axis `i+1` meets the plane of frame `i-1`'s `x`
//!   and `y`), so that a small misalignment does not throw the common normal far away;
//! - frame `N` is frame `N-1` turned by the last joint; the `[tool]` frame takes the tip link
//!   from there.
//!
//! Each frame is computed from the one before through our own transform, so nothing
//! accumulates: the file's forward kinematics equal the URDF's to rounding (the test compares
//! them with the `k` crate's, an independent URDF kinematics). Lengths in mm, angles in degrees in
//! the file written. Refused by name: a prismatic, floating, planar or spherical joint in the
//! chain, a mimic joint, a link that is not in the file, a tip not below the base, an axis of
//! zero length, a revolute joint with limits `lower > upper`. Continuous joints have no limits.

use crate::io::robot_file::FrameEntry;
use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use std::path::Path;

/// Axes closer than this to parallel (degrees) are related by Hayati's `beta` instead of a common
/// normal.
pub const PARALLEL_DEG: f64 = 5.0;

/// One joint of the chain: its name, its axis line at zero joint values in the base link's frame
/// (a point, mm, and a unit direction), its limits (rad; `None`: continuous).
struct AxisLine {
    name: String,
    point: Point3<f64>,
    direction: Unit<Vector3<f64>>,
    limits: Option<[f64; 2]>,
}

/// The robot file of the chain of `urdf` (the file's text; `path` names it) from the link `base`
/// to the link `tip`: its TOML text, which [`crate::io::robot_file::RobotFile::parse`] reads back.
pub fn import_urdf(text: &str, path: &Path, base: &str, tip: &str) -> crate::Result<String> {
    let refuse =
        |message: String| crate::refused!(input path.display(); "{}: {message}", path.display());
    let robot = urdf_rs::read_from_string(text).map_err(|e| refuse(format!("not a URDF: {e}")))?;
    let chain = chain(&robot, base, tip).map_err(refuse)?;
    let (axes, tip_pose) = axis_lines(&chain).map_err(refuse)?;
    if !(2..=9).contains(&axes.len()) {
        return Err(crate::refused!(unsupported "joint count";
            "{}: the chain from {base} to {tip} has {} revolute joints; calib takes 2 to 9",
            path.display(), axes.len()));
    }
    Ok(robot_toml(&robot.name, &axes, &tip_pose, (path, base, tip)))
}

/// [`import_urdf`] of the file at `path`, read whole within the size limit of a document.
pub fn import_urdf_file(path: &Path, base: &str, tip: &str) -> crate::Result<String> {
    let text = crate::io::input::read_text(path, crate::io::input::Input::Document).map_err(
        |e| crate::refused!(input path.display(); "{}: cannot read it: {e}", path.display()),
    )?;
    import_urdf(&text, path, base, tip)
}

/// The joints from `base` down to `tip`, in order.
fn chain<'a>(
    robot: &'a urdf_rs::Robot,
    base: &str,
    tip: &str,
) -> Result<Vec<&'a urdf_rs::Joint>, String> {
    for link in [base, tip] {
        if !robot.links.iter().any(|l| l.name == link) {
            let names: Vec<&str> = robot.links.iter().map(|l| l.name.as_str()).collect();
            return Err(format!(
                "no link named {link}; the links are {}",
                names.join(", ")
            ));
        }
    }
    let mut joints = Vec::new();
    let mut link = tip;
    while link != base {
        let Some(joint) = robot.joints.iter().find(|j| j.child.link == link) else {
            return Err(format!(
                "{tip} is not below {base}: {link} has no parent joint"
            ));
        };
        if joints.len() > robot.joints.len() {
            return Err(format!("the joints above {tip} form a loop"));
        }
        joints.push(joint);
        link = &joint.parent.link;
    }
    joints.reverse();
    Ok(joints)
}

/// The axis lines of the chain's moving joints at zero joint values and the tip link's pose, in
/// the base link's frame (mm).
fn axis_lines(chain: &[&urdf_rs::Joint]) -> Result<(Vec<AxisLine>, Isometry3<f64>), String> {
    use urdf_rs::JointType;
    let mut pose = Isometry3::identity();
    let mut axes = Vec::new();
    for joint in chain {
        if joint.mimic.is_some() {
            return Err(format!(
                "joint {} is a mimic joint (it follows another): calib models independent joints only",
                joint.name
            ));
        }
        let [x, y, z] = *joint.origin.xyz;
        let [roll, pitch, yaw] = *joint.origin.rpy;
        pose *= Isometry3::from_parts(
            Translation3::new(x * 1000.0, y * 1000.0, z * 1000.0),
            UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        );
        let limits = match joint.joint_type {
            JointType::Fixed => continue,
            JointType::Revolute => {
                let (lower, upper) = (joint.limit.lower, joint.limit.upper);
                if !(lower.is_finite() && upper.is_finite() && lower <= upper) {
                    return Err(format!(
                        "joint {}: limits lower {lower} upper {upper} rad: give lower <= upper",
                        joint.name
                    ));
                }
                Some([lower, upper])
            }
            JointType::Continuous => None,
            ref other => {
                return Err(format!(
                    "joint {} is {other:?}: calib models revolute joints (and fixed ones, folded into the next)",
                    joint.name
                ));
            }
        };
        let axis = Vector3::from(*joint.axis.xyz);
        let Some(direction) = Unit::try_new(pose.rotation * axis, 1e-12) else {
            return Err(format!("joint {} has an axis of zero length", joint.name));
        };
        axes.push(AxisLine {
            name: joint.name.clone(),
            point: pose.translation.vector.into(),
            direction,
            limits,
        });
    }
    Ok((axes, pose))
}

/// Our transform `Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)` (mm, rad).
fn transform(theta: f64, d: f64, a: f64, alpha: f64, beta: f64) -> Isometry3<f64> {
    let rz = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), theta);
    let rx = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), alpha);
    let ry = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), beta);
    Isometry3::from_parts(Translation3::identity(), rz)
        * Isometry3::from_parts(Translation3::new(a, 0.0, d), UnitQuaternion::identity())
        * Isometry3::from_parts(Translation3::identity(), rx * ry)
}

/// One joint's parameters `[theta, d, a, alpha, beta]` (mm, rad) from `frame` (its `z` on this
/// joint's axis) to the next axis `next`.
fn joint_parameters(frame: &Isometry3<f64>, next: &AxisLine) -> [f64; 5] {
    let z = frame.rotation * Vector3::z();
    let x_prev = frame.rotation * Vector3::x();
    let y_prev = frame.rotation * Vector3::y();
    let origin: Point3<f64> = frame.translation.vector.into();
    let u = next.direction.into_inner();
    let angle_about_z = |x: &Vector3<f64>| x.dot(&y_prev).atan2(x.dot(&x_prev));
    let cross = z.cross(&u);
    if cross.norm() < PARALLEL_DEG.to_radians().sin() {
        // Hayati: the origin where the next axis meets frame's x-y plane.
        let t = (origin - next.point).dot(&z) / u.dot(&z);
        let meet = next.point + u * t;
        let along = meet - origin;
        let a = along.norm();
        let x = if a > 1e-12 { along / a } else { x_prev };
        let theta = angle_about_z(&x);
        let y = z.cross(&x);
        let beta = u.dot(&x).clamp(-1.0, 1.0).asin();
        let alpha = (-u.dot(&y)).atan2(u.dot(&z));
        return [theta, 0.0, a, alpha, beta];
    }
    // The common normal: the closest points of the two lines.
    let w = origin - next.point;
    let (b, d_, e) = (z.dot(&u), z.dot(&w), u.dot(&w));
    let denominator = 1.0 - b * b;
    let s = (b * e - d_) / denominator;
    let t = (e - b * d_) / denominator;
    let foot = origin + z * s;
    let other = next.point + u * t;
    let normal = other - foot;
    let a = normal.norm();
    let x = if a > 1e-9 {
        normal / a
    } else {
        // Intersecting axes: x along their cross product, the sign nearer the frame's x.
        let c = cross.normalize();
        if c.dot(&x_prev) < 0.0 { -c } else { c }
    };
    let theta = angle_about_z(&x);
    let y = z.cross(&x);
    // Rx(alpha) turns z towards -y: the next axis is cos(alpha) z - sin(alpha) y.
    let alpha = (-u.dot(&y)).atan2(u.dot(&z));
    [theta, s, a, alpha, 0.0]
}

/// `value`, or zero for rounding below 1e-12 (mm or rad): a change far below the exactness the
/// test holds (1e-9 mm).
fn tidy(value: f64) -> f64 {
    if value.abs() < 1e-12 { 0.0 } else { value }
}

/// Frame 0: `z` on joint 1's axis at the foot of the perpendicular from the base link's origin,
/// `x` the base link's `x` (or `y`) made perpendicular to it.
fn first_frame(first: &AxisLine) -> Isometry3<f64> {
    let z = first.direction.into_inner();
    let foot = first.point - z * first.point.coords.dot(&z);
    let mut x = Vector3::x() - z * z.x;
    if x.norm() < 1e-6 {
        x = Vector3::y() - z * z.y;
    }
    let x = x.normalize();
    let y = z.cross(&x);
    let rotation = nalgebra::Rotation3::from_basis_unchecked(&[x, y, z]);
    Isometry3::from_parts(
        Translation3::from(foot.coords),
        UnitQuaternion::from_rotation_matrix(&rotation),
    )
}

/// The robot file's text: the joints, `[base]` and `[tool]`, and where it came from.
fn robot_toml(
    name: &str,
    axes: &[AxisLine],
    tip: &Isometry3<f64>,
    (path, base, tip_link): (&Path, &str, &str),
) -> String {
    let Some(first) = axes.first() else {
        return String::new();
    };
    let frame0 = first_frame(first);
    let mut frame = frame0;
    let mut text = format!(
        "# {name}: imported by calib import-urdf from {} (--base {base} --tip {tip_link}); the chain's joints {}.\n\
         # Our standard DH convention, exact: the URDF's forward kinematics, the base link to the tip link.\n\
         name = \"{}\"\n\n",
        crate::io::text::one_line(&path.display().to_string()),
        axes.iter()
            .map(|a| a.name.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        crate::io::text::one_line(name).replace('"', "'"),
    );
    for (i, axis) in axes.iter().enumerate() {
        let [theta, d, a, alpha, beta] = match axes.get(i + 1) {
            Some(next) => joint_parameters(&frame, next),
            None => [0.0; 5],
        };
        frame *= transform(theta, d, a, alpha, beta);
        // Rounding left by the geometry (1e-15 mm where a value is zero) written as zero.
        let [theta, d, a, alpha, beta] = [theta, d, a, alpha, beta].map(tidy);
        text.push_str(&format!(
            "[[joint]]\n# {}\na_mm = {a:?}\nalpha_deg = {:?}\ntheta_offset_deg = {:?}\nd_mm = {d:?}\nbeta_deg = {:?}\n",
            crate::io::text::one_line(&axis.name),
            alpha.to_degrees(),
            theta.to_degrees(),
            beta.to_degrees()
        ));
        if let Some([lower, upper]) = axis.limits {
            text.push_str(&format!(
                "limits_deg = [{:?}, {:?}]\n",
                lower.to_degrees(),
                upper.to_degrees()
            ));
        }
        text.push('\n');
    }
    let entry = |pose: &Isometry3<f64>, table: &str| {
        let FrameEntry { xyz_mm, rpy_deg } = crate::io::robot_file::craig::frame_entry(pose);
        format!("[{table}]\nxyz_mm = {xyz_mm:?}\nrpy_deg = {rpy_deg:?}\n\n")
    };
    text.push_str(&entry(&frame0, "base"));
    text.push_str(&entry(&(frame.inverse() * tip), "tool"));
    text
}
