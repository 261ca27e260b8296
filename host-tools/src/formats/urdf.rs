//! The robot model as a URDF: joint origins that reproduce our forward kinematics
//! exactly, for ROS (robot_state_publisher, MoveIt) and every tool that reads URDF.
//!
//! The Hayati joint transform of eq. (1), `A_i = Rz(q_i + theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)
//! Ry(beta_i)`, is a rotation about z by the joint reading followed by the fixed transform
//! `F_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)` (`Rz(q)` and `Rz(theta) Tz(d)`
//! commute). So `T = T_base A_1 ... A_N T_tool = T_base Rz(q_1) F_1 Rz(q_2) F_2 ... Rz(q_N) F_N
//! T_tool`, which a URDF chain says exactly: joint 1's origin is `T_base`, joint i's (i > 1) is
//! `F_(i-1)`, every axis is z; the flange is a fixed joint with origin `F_N`, the controller's
//! tool a fixed joint with origin `T_tool`. Origins in metres and URDF's roll-pitch-yaw
//! (`R = Rz(yaw) Ry(pitch) Rx(roll)`), printed with every digit of the f64 value.
//!
//! Only the geometry: a URDF has no place for joint maps or gravity compliance, so a file with
//! them is refused unless the caller accepts the geometry alone
//! ([`UrdfSettings::geometry_only`]). The measurement setup (`[measurement]`: tracker, probe) is
//! never exported: the URDF is the controller's model, base and tool as in `[base]` and `[tool]`.

use crate::JOINTS;
use crate::io::text::{xml_attribute, xml_comment};
use calib_core::{FramePose, MdhJoint, Robot};
use nalgebra::Dyn;
use nalgebra::{IsometryMatrix3, Rotation3, Translation3, Vector3};

/// A joint origin as a URDF says it: translation in metres, roll-pitch-yaw in radians.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Origin {
    /// Translation, m.
    pub xyz_m: [f64; 3],
    /// `[roll, pitch, yaw]`, rad (`R = Rz(yaw) Ry(pitch) Rx(roll)`).
    pub rpy_rad: [f64; 3],
}

impl Origin {
    /// The origin of a transform whose translation is in mm.
    pub fn of(transform: &IsometryMatrix3<f64>) -> Self {
        let (roll, pitch, yaw) = transform.rotation.euler_angles();
        // `+ 0.0` writes -0 as 0.
        Self {
            xyz_m: (transform.translation.vector / 1000.0)
                .map(|v| v + 0.0)
                .into(),
            rpy_rad: [roll + 0.0, pitch + 0.0, yaw + 0.0],
        }
    }

    /// `<origin xyz=".." rpy=".."/>`.
    fn element(&self) -> String {
        let [x, y, z] = self.xyz_m;
        let [r, p, w] = self.rpy_rad;
        format!("<origin xyz=\"{x} {y} {z}\" rpy=\"{r} {p} {w}\"/>")
    }
}

/// The fixed part `F = Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)` of a joint's transform (mm).
pub(crate) fn fixed_part(joint: &MdhJoint<f64>) -> IsometryMatrix3<f64> {
    let rz = |angle: f64| Rotation3::from_axis_angle(&Vector3::z_axis(), angle);
    let rx = Rotation3::from_axis_angle(&Vector3::x_axis(), joint.alpha);
    let ry = Rotation3::from_axis_angle(&Vector3::y_axis(), joint.beta);
    let step =
        |t: Vector3<f64>, r: Rotation3<f64>| IsometryMatrix3::from_parts(Translation3::from(t), r);
    step(Vector3::zeros(), rz(joint.theta_offset))
        * step(Vector3::new(0.0, 0.0, joint.d), Rotation3::identity())
        * step(Vector3::new(joint.a, 0.0, 0.0), rx * ry)
}

/// A frame of the robot file as a transform (mm).
pub fn frame(pose: &FramePose<f64>) -> IsometryMatrix3<f64> {
    pose.isometry()
}

/// The origins of the chain: joint 1 (`T_base`), joints 2..N (`F_1..F_(N-1)`), the flange
/// (`F_N`) and the tool (`T_tool`), N + 2 transforms in mm.
pub fn chain(robot: &Robot<f64, Dyn>) -> Vec<IsometryMatrix3<f64>> {
    let mut out = vec![frame(&robot.base)];
    out.extend(robot.joints.iter().map(fixed_part));
    out.push(frame(&robot.tool));
    out
}

/// Names in the URDF and what the export writes.
#[derive(Clone, Debug)]
pub struct UrdfSettings {
    /// The `<robot name>`.
    pub robot_name: String,
    /// The root link (the robot's mounting frame, where `[base]` is given).
    pub base_link: String,
    /// The link after each joint, joint 1 first (N names).
    pub links: Vec<String>,
    /// The revolute joints, joint 1 first (N names).
    pub joints: Vec<String>,
    /// The flange link (after the last joint's fixed part).
    pub flange: String,
    /// The controller's tool frame (`[tool]` from the flange).
    pub tool: String,
    /// Only the `<joint>` elements, to merge into an existing robot description whose links
    /// carry these names.
    pub joints_only: bool,
    /// Export the geometry of a file with joint maps or gravity compliance (which a URDF cannot
    /// carry) instead of refusing it.
    pub geometry_only: bool,
}

impl UrdfSettings {
    /// The default names: `base_link`, `link_1..link_N`, `joint_1..joint_N`, `flange`, `tool0`.
    pub fn named(robot_name: &str) -> Self {
        Self::named_for(robot_name, JOINTS)
    }

    /// [`UrdfSettings::named`] for a robot of `joints` joints.
    pub(crate) fn named_for(robot_name: &str, joints: usize) -> Self {
        Self {
            robot_name: robot_name.to_string(),
            base_link: "base_link".into(),
            links: (1..=joints).map(|i| format!("link_{i}")).collect(),
            joints: (1..=joints).map(|i| format!("joint_{i}")).collect(),
            flange: "flange".into(),
            tool: "tool0".into(),
            joints_only: false,
            geometry_only: false,
        }
    }

    /// The fixed joints' names: last link to flange, flange to tool.
    pub(crate) fn fixed_joints(&self) -> [String; 2] {
        let last = self.links.last().map_or("", String::as_str);
        [
            format!("{last}-{}", self.flange),
            format!("{}-{}", self.flange, self.tool),
        ]
    }

    /// Checks the names for a robot of `count` joints: the right counts, unique, and plain
    /// (letters, digits, `_ - . /`), so that they need no escaping in XML.
    pub fn check(&self, count: usize) -> crate::Result<()> {
        if self.links.len() != count || self.joints.len() != count {
            let option = if self.links.len() != count {
                "--link-names"
            } else {
                "--joint-names"
            };
            return Err(crate::refused!(option option;
                "--link-names and --joint-names need {count} names each (one per joint), got {} and {}",
                self.links.len(),
                self.joints.len()
            ));
        }
        let mut links: Vec<&str> = vec![&self.base_link, &self.flange, &self.tool];
        links.extend(self.links.iter().map(String::as_str));
        let [flange_joint, tool_joint] = self.fixed_joints();
        let mut joints: Vec<&str> = self.joints.iter().map(String::as_str).collect();
        joints.extend([flange_joint.as_str(), tool_joint.as_str()]);
        for (names, option) in [(&links, "--link-names"), (&joints, "--joint-names")] {
            for (i, name) in names.iter().enumerate() {
                if names[..i].contains(name) {
                    return Err(
                        crate::refused!(option option; "the URDF name \"{name}\" is used twice"),
                    );
                }
                let plain = !name.is_empty()
                    && name
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || "_-./".contains(c));
                if !plain {
                    return Err(crate::refused!(option option;
                        "the URDF name \"{name}\" must be letters, digits and _ - . / only"
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The URDF (or, with `joints_only`, the `<joint>` elements) of `robot`; `source` names the file
/// in a comment.
pub fn urdf(
    robot: &Robot<f64, Dyn>,
    settings: &UrdfSettings,
    source: &str,
) -> crate::Result<String> {
    let n = robot.joints.len();
    settings.check(n)?;
    let origins: Vec<Origin> = chain(robot).iter().map(Origin::of).collect();
    let mut joints = String::new();
    let parents = std::iter::once(&settings.base_link).chain(&settings.links);
    for (i, (((name, child), parent), origin)) in settings
        .joints
        .iter()
        .zip(&settings.links)
        .zip(parents)
        .zip(&origins)
        .enumerate()
    {
        let limits = robot.limits[i];
        let (kind, limit) = if limits.lower.is_finite() && limits.upper.is_finite() {
            (
                "revolute",
                format!(
                    "\n    <limit lower=\"{}\" upper=\"{}\" effort=\"0\" velocity=\"0\"/>",
                    limits.lower, limits.upper
                ),
            )
        } else {
            ("continuous", String::new())
        };
        joints.push_str(&format!(
            "  <joint name=\"{name}\" type=\"{kind}\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    {}\n    <axis xyz=\"0 0 1\"/>{limit}\n  </joint>\n",
            origin.element()
        ));
    }
    let [flange_joint, tool_joint] = settings.fixed_joints();
    let last = &settings.links[n - 1];
    for (name, parent, child, origin) in [
        (flange_joint, last, &settings.flange, &origins[n]),
        (
            tool_joint,
            &settings.flange,
            &settings.tool,
            &origins[n + 1],
        ),
    ] {
        joints.push_str(&format!(
            "  <joint name=\"{name}\" type=\"fixed\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    {}\n  </joint>\n",
            origin.element()
        ));
    }
    let header = format!(
        "<?xml version=\"1.0\"?>\n<!-- {} as a URDF, written by calib export (format urdf) from {}.\n     \
         The joint origins reproduce calib's forward kinematics exactly (metres, radians); geometry only.\n     \
         Revolute limits are the robot file's; effort and velocity (0) are not known to calib: take them from the vendor's description. -->\n",
        xml_comment(&settings.robot_name),
        xml_comment(source)
    );
    if settings.joints_only {
        return Ok(format!("{header}<joints>\n{joints}</joints>\n"));
    }
    let mut links = format!("  <link name=\"{}\"/>\n", settings.base_link);
    for name in settings
        .links
        .iter()
        .chain([&settings.flange, &settings.tool])
    {
        links.push_str(&format!("  <link name=\"{name}\"/>\n"));
    }
    Ok(format!(
        "{header}<robot name=\"{}\">\n{links}{joints}</robot>\n",
        xml_attribute(&settings.robot_name)
    ))
}
