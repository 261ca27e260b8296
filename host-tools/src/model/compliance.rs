//! Gravity compliance: joints and bearings that yield under the weight of the links
//! beyond them, identified with the joint maps (`calibrate --model joint-maps+compliance`).
//!
//! For joint `j`, the gravity moment of everything beyond it (links `j..N` and the tool's load,
//! masses and centres of mass from the robot file's `[dynamics]`) about the joint's origin is
//! `M_j = sum_k m_k (c_k - o_j) x g` (N m). The model turns the distal chain about the joint's
//! origin by the small rotation
//!
//! `phi_j = t_j (z_j . M_j) z_j + x_j (x_j . M_j) x_j' + y_j (y_j . M_j) y_j'`,
//!
//! with `z_j` the joint's axis and `x_j`, `y_j` the other axes of the frame it turns in: a torsion
//! `t_j` for joints 2-4 and two bearing tilts for joints 1-4, 11 gains in urad per N m. The end
//! point moves by `sum_j phi_j x (p - o_j)` and turns by `sum_j phi_j` (first order: the
//! deflections are below 1 mrad, the neglected terms below 1e-5 mm). A gain whose moment
//! component vanishes in every pose (on a UR, joint 2's tilt about the vertical axis) is not
//! identified and stays zero.

use crate::JOINTS;
use calib_core::model::{JointCount, JointVec};
use calib_core::{Kinematics, ParameterErrors, Robot};
use nalgebra::Dyn;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// The identified gains, in this order.
pub const GAINS: [Gain; 11] = [
    Gain::TiltX(1),
    Gain::TiltY(1),
    Gain::Torsion(2),
    Gain::TiltX(2),
    Gain::TiltY(2),
    Gain::Torsion(3),
    Gain::TiltX(3),
    Gain::TiltY(3),
    Gain::Torsion(4),
    Gain::TiltX(4),
    Gain::TiltY(4),
];

/// Number of gains.
pub(crate) const GAIN_COUNT: usize = GAINS.len();

/// Largest plausible gain, urad per N m (a 100 N m moment would turn a joint by 0.1 rad).
pub const MAX_GAIN_URAD_PER_NM: f64 = 1000.0;

/// One compliance gain; the joint is 1-based.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gain {
    /// Torsion about the joint's axis.
    Torsion(usize),
    /// Tilt about the x axis of the frame the joint turns in.
    TiltX(usize),
    /// Tilt about the y axis of the frame the joint turns in.
    TiltY(usize),
}

impl std::fmt::Display for Gain {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Torsion(j) => write!(f, "torsion of joint {j}"),
            Self::TiltX(j) => write!(f, "tilt about x of joint {j}"),
            Self::TiltY(j) => write!(f, "tilt about y of joint {j}"),
        }
    }
}

/// A mass and its centre, as a robot file gives it.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MassEntry {
    /// Mass, kg.
    pub mass_kg: f64,
    /// Centre of mass, mm: for a link in the frame after its joint's transform, for the tool's
    /// load in the flange frame.
    pub com_mm: [f64; 3],
}

/// The `[dynamics]` section of a robot file: what gravity pulls on.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct DynamicsSection {
    /// Gravity in the robot's base frame, m/s^2 (upright: `[0, 0, -9.81]`).
    pub gravity_mps2: [f64; 3],
    /// One entry per link, link 1 (moved by joint 1) first.
    pub link: Vec<MassEntry>,
    /// What the flange carries while measured (probe or reflector and its mount).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool: Option<MassEntry>,
}

/// Masses and gravity, checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gravity {
    /// Gravity in the base frame, m/s^2.
    pub gravity: Vector3<f64>,
    /// Per link: mass (kg) and centre (mm, in the frame after the joint's transform).
    pub links: [(f64, Vector3<f64>); JOINTS],
    /// The flange's load: mass (kg) and centre (mm, flange frame).
    pub tool: (f64, Vector3<f64>),
}

impl DynamicsSection {
    /// The masses, checked: one link per joint, masses 0-1000 kg, centres within 5 m, gravity
    /// 9-10.5 m/s^2. The error names the field.
    pub fn to_gravity(&self) -> Result<Gravity, String> {
        if self.link.len() != JOINTS {
            return Err(format!(
                "[dynamics]: {} [[dynamics.link]] tables, expected {JOINTS} (one per joint)",
                self.link.len()
            ));
        }
        let g = Vector3::from(self.gravity_mps2);
        if !(g.iter().all(|v| v.is_finite()) && (9.0..=10.5).contains(&g.norm())) {
            return Err(format!(
                "[dynamics]: gravity_mps2 = {:?} is not a gravity vector (magnitude 9 to 10.5 m/s^2, in the base frame)",
                self.gravity_mps2
            ));
        }
        let check = |what: String, m: &MassEntry| -> Result<(f64, Vector3<f64>), String> {
            if !(m.mass_kg.is_finite() && (0.0..=1000.0).contains(&m.mass_kg)) {
                return Err(format!(
                    "[dynamics] {what}: mass_kg = {} is not 0 to 1000",
                    m.mass_kg
                ));
            }
            if !m.com_mm.iter().all(|v| v.is_finite() && v.abs() <= 5000.0) {
                return Err(format!(
                    "[dynamics] {what}: com_mm = {:?} is not within 5000 mm",
                    m.com_mm
                ));
            }
            Ok((m.mass_kg, Vector3::from(m.com_mm)))
        };
        let mut links = [(0.0, Vector3::zeros()); JOINTS];
        for (j, (slot, entry)) in links.iter_mut().zip(&self.link).enumerate() {
            *slot = check(format!("link {}", j + 1), entry)?;
        }
        let tool = match &self.tool {
            Some(t) => check("tool".into(), t)?,
            None => (0.0, Vector3::zeros()),
        };
        Ok(Gravity {
            gravity: g,
            links,
            tool,
        })
    }
}

/// The `[compliance]` section of an identified robot file, urad per N m, joint 1 first (zero
/// where not identified).
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ComplianceSection {
    /// Torsion gains (joints 2-4).
    pub torsion_urad_per_nm: Vec<f64>,
    /// Tilt gains about x (joints 1-4).
    pub tilt_x_urad_per_nm: Vec<f64>,
    /// Tilt gains about y (joints 1-4).
    pub tilt_y_urad_per_nm: Vec<f64>,
}

impl ComplianceSection {
    /// The section of `gains` (in the order of [`GAINS`]).
    pub fn new(gains: &[f64; GAIN_COUNT]) -> Self {
        let mut out = Self {
            torsion_urad_per_nm: vec![0.0; JOINTS],
            tilt_x_urad_per_nm: vec![0.0; JOINTS],
            tilt_y_urad_per_nm: vec![0.0; JOINTS],
        };
        for (gain, value) in GAINS.iter().zip(gains) {
            let (list, j) = match gain {
                Gain::Torsion(j) => (&mut out.torsion_urad_per_nm, j),
                Gain::TiltX(j) => (&mut out.tilt_x_urad_per_nm, j),
                Gain::TiltY(j) => (&mut out.tilt_y_urad_per_nm, j),
            };
            list[j - 1] = *value;
        }
        out
    }

    /// The gains, checked: finite, within [`MAX_GAIN_URAD_PER_NM`], zero where the model has no
    /// gain. The error names the gain.
    pub fn to_gains(&self) -> Result<[f64; GAIN_COUNT], String> {
        for (name, list) in [
            ("torsion_urad_per_nm", &self.torsion_urad_per_nm),
            ("tilt_x_urad_per_nm", &self.tilt_x_urad_per_nm),
            ("tilt_y_urad_per_nm", &self.tilt_y_urad_per_nm),
        ] {
            if list.len() != JOINTS {
                return Err(format!(
                    "[compliance]: {name} has {} values, expected {JOINTS}",
                    list.len()
                ));
            }
        }
        let gains: [f64; GAIN_COUNT] = std::array::from_fn(|i| match GAINS[i] {
            Gain::Torsion(j) => self.torsion_urad_per_nm[j - 1],
            Gain::TiltX(j) => self.tilt_x_urad_per_nm[j - 1],
            Gain::TiltY(j) => self.tilt_y_urad_per_nm[j - 1],
        });
        if let Some((gain, value)) = GAINS
            .iter()
            .zip(&gains)
            .find(|(_, v)| !(v.is_finite() && v.abs() <= MAX_GAIN_URAD_PER_NM))
        {
            return Err(format!(
                "[compliance]: the {gain} is {value} urad/(N m), beyond the plausible +-{MAX_GAIN_URAD_PER_NM}"
            ));
        }
        if ComplianceSection::new(&gains) != *self {
            return Err(
                "[compliance]: a gain is set where the model has none (torsion: joints 2-4; tilts: joints 1-4)"
                    .into(),
            );
        }
        Ok(gains)
    }
}

/// The gravity compliance of an identified robot file: its masses and gains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FileCompliance {
    /// The masses (`[dynamics]`).
    pub gravity: Gravity,
    /// The gains, urad/(N m), in the order of [`GAINS`] (`[compliance]`).
    pub gains: [f64; GAIN_COUNT],
}

/// `Ok` for a robot of [`JOINTS`] joints, the one the gravity model describes.
fn check_joints(joints: usize) -> crate::Result<()> {
    if joints != JOINTS {
        return Err(crate::refused!(
            "gravity compliance is modelled for {JOINTS}-joint robots; this robot has {joints} joints"
        ));
    }
    Ok(())
}

impl FileCompliance {
    /// The core's model, in scalar `T`, for a robot of `joints` joints: refused unless it has
    /// [`JOINTS`] (the gains are those of a 6R arm's joints 1 to 4).
    pub fn to_core<T: calib_core::Real>(
        &self,
        joints: usize,
    ) -> crate::Result<calib_core::model::compliance::Compliance<T, Dyn>> {
        self.gravity.to_core(&self.gains, joints)
    }
}

impl Gravity {
    /// The core's model of these masses with `gains` (urad/(N m), in the order of [`GAINS`]), in
    /// scalar `T`: what the controller evaluates (`calib_core::model::compliance`), for a robot
    /// of `joints` joints; refused unless it has [`JOINTS`].
    pub fn to_core<T: calib_core::Real>(
        &self,
        gains: &[f64; GAIN_COUNT],
        joints: usize,
    ) -> crate::Result<calib_core::model::compliance::Compliance<T, Dyn>> {
        check_joints(joints)?;
        use calib_core::model::compliance::{Compliance, PointMass, TILT_X, TILT_Y, TORSION};
        let mass = |(m, c): &(f64, Vector3<f64>)| PointMass {
            mass_kg: T::of(*m),
            centre_mm: [T::of(c.x), T::of(c.y), T::of(c.z)],
        };
        let count = calib_core::model::joint_count(joints)
            .ok_or_else(|| crate::refused!("{joints} joints are too many"))?;
        let mut per_joint = count.table([T::zero(); 3]);
        for (gain, value) in GAINS.iter().zip(gains) {
            let (j, axis) = match gain {
                Gain::TiltX(j) => (j, TILT_X),
                Gain::TiltY(j) => (j, TILT_Y),
                Gain::Torsion(j) => (j, TORSION),
            };
            if let Some(slot) = per_joint.get_mut(j - 1).and_then(|g| g.get_mut(axis)) {
                *slot = T::of(*value);
            }
        }
        let none = (0.0, Vector3::zeros());
        let mut links = count.table(PointMass::none());
        for (j, link) in links.iter_mut().enumerate() {
            *link = mass(self.links.get(j).unwrap_or(&none));
        }
        Ok(Compliance::new(
            [self.gravity.x, self.gravity.y, self.gravity.z].map(T::of),
            links,
            mass(&self.tool),
            per_joint,
        )?)
    }
}

/// Per gain, the motion `[v (mm); w (rad)]` of the end point (the origin of the tool frame) per
/// urad/(N m) at kinematic joint angles `q` (rad), for the model `robot + errors` (in whatever
/// frames it is given: gravity is turned by its base rotation). Error: a robot of other than
/// [`JOINTS`] joints (the gravity model has one mass per joint of a 6-joint robot).
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The core's deflection (what the controller applies) equals the displacement of this
    /// module's gain columns (what the identification fits), on 1,000 random configurations of
    /// the UR10 with its published masses, a measurement base and probe, and UR10-sized gains.
    #[test]
    fn the_core_deflects_as_the_identification_models() {
        use rand::{RngExt, SeedableRng};
        let model = crate::io::robot_file::RobotModel::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/robots/ur10.toml"
        )))
        .unwrap();
        let file = crate::io::robot_file::RobotFile::read(&model.path).unwrap();
        let gravity = file.dynamics.as_ref().unwrap().to_gravity().unwrap();
        let mut robot = model.robot;
        robot.base = calib_core::FramePose {
            xyz: [1500.0, -300.0, 200.0],
            rpy: [0.02, -0.01, 2.5],
        };
        robot.tool = calib_core::FramePose {
            xyz: [10.0, -5.0, 120.0],
            rpy: [0.0; 3],
        };
        let mut errors = ParameterErrors::zeros_for(robot.joint_count());
        errors.joints[1].da = 0.7;
        errors.joints[2].dtheta = 1e-3;
        let gains = [4.0, -3.0, 2.5, 1.5, 0.0, 3.0, -2.0, 1.0, 6.0, 4.0, -5.0];
        let core = gravity.to_core::<f64>(&gains, JOINTS).unwrap();
        let kinematics = Kinematics::new(&robot, &errors).unwrap();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(14);
        let (mut worst_v, mut worst_w, mut largest) = (0.0f64, 0.0f64, 0.0f64);
        for _ in 0..1000 {
            let q = JointVec::<f64>::from_fn(JOINTS, |_| rng.random_range(-3.1..3.1));
            let expected = displacement(&columns(&gravity, &robot, &errors, &q).unwrap(), &gains);
            let (_, d) = core.deflect(&kinematics, &q).unwrap();
            let v = Vector3::new(expected[0], expected[1], expected[2]);
            let w = Vector3::new(expected[3], expected[4], expected[5]);
            worst_v = worst_v.max((d.translation - v).norm());
            worst_w = worst_w.max((d.rotation - w).norm());
            largest = largest.max(v.norm());
        }
        assert!(
            worst_v < 1e-9 && worst_w < 1e-12,
            "{worst_v} mm {worst_w} rad"
        );
        // Gains of a few urad/(N m) move the UR10 by tenths of a millimetre.
        assert!(largest > 0.1 && largest < 5.0, "{largest}");
    }

    /// A point mass on a horizontal arm: the torsion of the joint carrying it is `m g r` times its
    /// gain, the end point moves by that angle times its distance from the axis.
    #[test]
    fn a_horizontal_arm_sags_by_the_closed_form() {
        // The UR10 (DH base frame, z up) at zero: the upper arm lies along -x.
        let robot = crate::io::robot_file::RobotModel::load(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/robots/ur10.toml"
        )))
        .unwrap()
        .robot;
        let mut links = [(0.0, Vector3::zeros()); JOINTS];
        // 10 kg at the elbow end of link 2 (its frame origin), nothing else.
        links[1] = (10.0, Vector3::zeros());
        let gravity = Gravity {
            gravity: Vector3::new(0.0, 0.0, -9.81),
            links,
            tool: (0.0, Vector3::zeros()),
        };
        // Upper arm horizontal (q2 = 0), forearm along it (q3 = 0).
        let q = JointVec::<f64>::from_fn(JOINTS, |_| 0.0);
        let errors = ParameterErrors::zeros_for(robot.joint_count());
        let c = columns(&gravity, &robot, &errors, &q).unwrap();
        // Moment about joint 2: 10 kg * 9.81 * 0.612 m = 60.04 N m about the horizontal axis.
        let torsion = c[2];
        let w = Vector3::new(torsion[3], torsion[4], torsion[5]).norm();
        assert!((w - 60.0372e-6).abs() < 1e-9, "{w}");
        // Joint 2's tilt about its frame's y axis (vertical on a UR) never sees a moment.
        assert!(c[4].iter().all(|v| v.abs() < 1e-15), "{:?}", c[4]);
        // The end point (about 1.18 m out along -x at q = 0) sinks by w times its x distance
        // from joint 2's horizontal axis.
        let kinematics = Kinematics::nominal(&robot).unwrap();
        let end = kinematics.forward(&q).unwrap().translation.vector;
        let v = Vector3::new(torsion[0], torsion[1], torsion[2]);
        let lever = end.x.abs();
        assert!(lever > 1000.0, "{end}");
        assert!((v.z.abs() - w * lever).abs() < 1e-9 * lever, "{v} {lever}");
    }
}
