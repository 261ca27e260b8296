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
//! with `z_j` the joint's axis and `x_j`, `y_j` the other axes of the frame it turns in: two
//! bearing tilts for every joint but the last two (the wrist, which carries little) and a torsion
//! for the same joints but the first (whose axis is vertical on a robot standing upright), in
//! urad per N m ([`gains`]: 11 gains on a 6-joint arm, joints 1-4; 14 on a 7-joint arm). The end
//! point moves by `sum_j phi_j x (p - o_j)` and turns by `sum_j phi_j` (first order: the
//! deflections are below 1 mrad, the neglected terms below 1e-5 mm). A gain whose moment
//! component vanishes in every pose (on a UR, joint 2's tilt about the vertical axis) is not
//! identified and stays zero.
//!
//! The robot file holds the masses and the gains in its `[dynamics]` and `[compliance]` sections
//! ([`sections`]); the gains' columns of the pose's motion, which the identification fits and
//! [`displacement`] sums, are the core's (`Compliance::gain_column`, the deflection the
//! controller applies), gathered in [`columns`](mod@columns).

pub mod columns;
pub mod sections;

pub use columns::{columns, displacement};
pub use sections::{ComplianceSection, DynamicsSection, MassEntry};

use calib_core::model::JointCount;
use nalgebra::Dyn;
use nalgebra::Vector3;

/// The identified gains of a robot of `joints` joints, in this order: per joint `j` from 1 to
/// `joints - 2`, the tilt about x, the tilt about y, and (from joint 2) the torsion. A 6-joint
/// arm has 11 (joints 1-4), a 7-joint arm 14 (joints 1-5); fewer than 3 joints have none.
pub fn gains(joints: usize) -> Vec<Gain> {
    (1..=joints.saturating_sub(2))
        .flat_map(|j| {
            let torsion = (j > 1).then_some(Gain::Torsion(j));
            torsion.into_iter().chain([Gain::TiltX(j), Gain::TiltY(j)])
        })
        .collect()
}

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

impl Gain {
    /// The joint (1-based) and the core's index of the gain among its three
    /// (`calib_core::model::compliance::{TILT_X, TILT_Y, TORSION}`).
    pub fn slot(&self) -> (usize, usize) {
        use calib_core::model::compliance::{TILT_X, TILT_Y, TORSION};
        match *self {
            Self::TiltX(j) => (j, TILT_X),
            Self::TiltY(j) => (j, TILT_Y),
            Self::Torsion(j) => (j, TORSION),
        }
    }
}

/// Masses and gravity, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Gravity {
    /// Gravity in the base frame, m/s^2.
    pub gravity: Vector3<f64>,
    /// Per link (link 1, moved by joint 1, first): mass (kg) and centre (mm, in the frame after
    /// the joint's transform).
    pub links: Vec<(f64, Vector3<f64>)>,
    /// The flange's load: mass (kg) and centre (mm, flange frame).
    pub tool: (f64, Vector3<f64>),
}

/// The gravity compliance of an identified robot file: its masses and gains.
#[derive(Clone, Debug, PartialEq)]
pub struct FileCompliance {
    /// The masses (`[dynamics]`).
    pub gravity: Gravity,
    /// The gains, urad/(N m), in the order of [`gains`] (`[compliance]`).
    pub gains: Vec<f64>,
}

impl FileCompliance {
    /// The core's model, in scalar `T`, for a robot of `joints` joints: refused unless the
    /// masses are of that many links and the robot has gains ([`gains`]).
    pub fn to_core<T: calib_core::Real>(
        &self,
        joints: usize,
    ) -> crate::Result<calib_core::model::compliance::Compliance<T, Dyn>> {
        self.gravity.to_core(&self.gains, joints)
    }
}

impl Gravity {
    /// The end point's motion `[v (mm); w (rad)]` under these masses with `gains` (urad/(N m),
    /// in the order of [`gains`]) at kinematic angles `angles` (rad) of the geometry
    /// `robot + errors`: the controller's deflection (the core's `Compliance::deflect`), in f64.
    pub fn deflection(
        &self,
        gains: &[f64],
        robot: &calib_core::Robot<f64, Dyn>,
        errors: &calib_core::ParameterErrors<f64, Dyn>,
        angles: &calib_core::model::JointVec<f64>,
    ) -> crate::Result<[f64; 6]> {
        let kinematics = calib_core::Kinematics::new(robot, errors)?;
        let model = self.to_core::<f64>(gains, robot.joints.len())?;
        let (_, d) = model.deflect(&kinematics, angles)?;
        let (v, w) = (d.translation, d.rotation);
        Ok([v.x, v.y, v.z, w.x, w.y, w.z])
    }

    /// `Ok` for a robot of `joints` joints: one mass per link, and gains to identify.
    fn check_joints(&self, joints: usize) -> crate::Result<()> {
        if gains(joints).is_empty() {
            return Err(crate::refused!(unsupported "gravity compliance";
                "gravity compliance turns the joints before the wrist's last two, and this robot has {joints} joints"
            ));
        }
        if self.links.len() != joints {
            return Err(crate::refused!(unsupported "gravity compliance";
                "[dynamics] has {} links, and this robot has {joints} joints: give one [[dynamics.link]] per joint",
                self.links.len()
            ));
        }
        Ok(())
    }

    /// The core's model of these masses with `gains` (urad/(N m), in the order of [`gains`]), in
    /// scalar `T`: what the controller evaluates (`calib_core::model::compliance`), for a robot
    /// of `joints` joints (refused unless the masses are of that many links).
    pub fn to_core<T: calib_core::Real>(
        &self,
        gains: &[f64],
        joints: usize,
    ) -> crate::Result<calib_core::model::compliance::Compliance<T, Dyn>> {
        self.check_joints(joints)?;
        use calib_core::model::compliance::{Compliance, PointMass};
        let mass = |(m, c): &(f64, Vector3<f64>)| PointMass {
            mass_kg: T::of(*m),
            centre_mm: [T::of(c.x), T::of(c.y), T::of(c.z)],
        };
        let count = crate::model::counts::joint_count(joints)?;
        let mut per_joint = count.table([T::zero(); 3]);
        for (gain, value) in self::gains(joints).iter().zip(gains) {
            let (j, axis) = gain.slot();
            if let Some(slot) = per_joint.get_mut(j - 1).and_then(|g| g.get_mut(axis)) {
                *slot = T::of(*value);
            }
        }
        let mut links = count.table(PointMass::none());
        for (link, entry) in links.iter_mut().zip(&self.links) {
            *link = mass(entry);
        }
        Ok(Compliance::new(
            [self.gravity.x, self.gravity.y, self.gravity.z].map(T::of),
            links,
            mass(&self.tool),
            per_joint,
        )?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::JOINTS;
    use calib_core::model::JointVec;
    use calib_core::{Kinematics, ParameterErrors};

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
        let gravity = file.dynamics.as_ref().unwrap().to_gravity(JOINTS).unwrap();
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
        let mut links = vec![(0.0, Vector3::zeros()); JOINTS];
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
