//! The paper's Table 3 statistics of a model on a dataset, typed (mean, sample standard
//! deviation, maximum and RMS of the absolute position error in mm and of the orientation error
//! per axis in deg), and the per-pose errors behind them.

use crate::measurement::dataset::{Dataset, Seen};
use calib_core::Kinematics;
use calib_core::identify::statistics::{PoseStatistics, Summary};
use nalgebra::Dyn;
use serde::Serialize;

/// Mean, sample standard deviation and maximum of one quantity.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Stat {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n - 1).
    pub std: f64,
    /// Maximum.
    pub max: f64,
    /// Root mean square.
    pub rms: f64,
}

impl Stat {
    fn from_summary(s: &Summary<f64>, scale: f64) -> Self {
        Self {
            mean: s.mean * scale,
            std: s.std() * scale,
            max: s.max * scale,
            rms: {
                // sum x^2 / n = mean^2 + (n - 1) / n * std^2
                let n = f64::from(s.count.max(1));
                (s.mean * s.mean + s.std() * s.std() * (n - 1.0) / n).sqrt() * scale
            },
        }
    }
}

/// Per-axis orientation statistics, degrees.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct AxisStats {
    /// `|dr_x|`, deg.
    pub x: Stat,
    /// `|dr_y|`, deg.
    pub y: Stat,
    /// `|dr_z|`, deg.
    pub z: Stat,
}

/// Table 3 statistics of one model on one data set.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Table3 {
    /// Number of poses.
    pub poses: u32,
    /// Absolute position error `|dp|`, mm.
    pub position_mm: Stat,
    /// Orientation error per axis, deg (`null` for position-only data).
    pub orientation_deg: Option<AxisStats>,
}

impl Table3 {
    /// From the core's accumulated statistics.
    pub(crate) fn from_statistics(s: &PoseStatistics<f64>) -> Self {
        let deg = 180.0 / std::f64::consts::PI;
        let [x, y, z] = s.orientation.map(|o| Stat::from_summary(&o, deg));
        Self {
            poses: s.position.count,
            position_mm: Stat::from_summary(&s.position, 1.0),
            orientation_deg: (s.with_orientation > 0).then_some(AxisStats { x, y, z }),
        }
    }
}

/// Table 3 statistics of `kinematics` on `measurements`, and `|dp|` per pose (mm).
pub(crate) fn table3<'a>(
    kinematics: &Kinematics<f64, Dyn>,
    measurements: impl IntoIterator<Item = &'a calib_core::identify::objective::Measurement<f64, Dyn>>,
) -> (Table3, Vec<f64>) {
    let mut stats = PoseStatistics::default();
    let mut per_pose = Vec::new();
    for m in measurements {
        let error = m.error_of(&kinematics.forward_angles(&m.angles));
        stats.add(&error, m.rotation.is_some());
        per_pose.push(error.position.norm());
    }
    (Table3::from_statistics(&stats), per_pose)
}

/// A model's base frame seen from the frame its poses are measured in (for data in a tracker's
/// frame, the registration): points and directions of that frame along the robot's own axes.
pub struct BaseFrame {
    to_base: nalgebra::Rotation3<f64>,
    origin: nalgebra::Vector3<f64>,
}

impl BaseFrame {
    /// The base frame of `robot` (its `base`).
    pub fn of(robot: &calib_core::Robot<f64, Dyn>) -> Self {
        let [roll, pitch, yaw] = robot.base.rpy;
        Self {
            to_base: nalgebra::Rotation3::from_euler_angles(roll, pitch, yaw).inverse(),
            origin: nalgebra::Vector3::from(robot.base.xyz),
        }
    }

    /// A point (mm) in the base frame.
    pub fn point(&self, p: &nalgebra::Vector3<f64>) -> [f64; 3] {
        self.direction(&(p - self.origin))
    }

    /// A direction (or difference, mm) along the base axes.
    pub(crate) fn direction(&self, v: &nalgebra::Vector3<f64>) -> [f64; 3] {
        let v = self.to_base * v;
        [v.x, v.y, v.z]
    }
}

/// `measured - predicted` position (mm) of `kinematics` for each of `measurements`, along the
/// axes of the robot's base frame: turned back by the rotation of the model's base (for data in a
/// tracker's frame, the registration), so that x, y and z are the robot's.
pub(crate) fn signed_errors<'a>(
    kinematics: &Kinematics<f64, Dyn>,
    robot: &calib_core::Robot<f64, Dyn>,
    measurements: impl IntoIterator<Item = &'a calib_core::identify::objective::Measurement<f64, Dyn>>,
) -> Vec<[f64; 3]> {
    let base = BaseFrame::of(robot);
    measurements
        .into_iter()
        .map(|m| base.direction(&m.error_of(&kinematics.forward_angles(&m.angles)).position))
        .collect()
}

/// The position (mm) `kinematics` predicts for each of `measurements`, in the robot's base frame:
/// turned back by the model's base (for data in a tracker's frame, the registration).
pub(crate) fn base_positions<'a>(
    kinematics: &Kinematics<f64, Dyn>,
    robot: &calib_core::Robot<f64, Dyn>,
    measurements: impl IntoIterator<Item = &'a calib_core::identify::objective::Measurement<f64, Dyn>>,
) -> Vec<[f64; 3]> {
    let base = BaseFrame::of(robot);
    measurements
        .into_iter()
        .map(|m| base.point(&kinematics.forward_angles(&m.angles).translation.vector))
        .collect()
}

/// `|dr_x|, |dr_y|, |dr_z|` (deg) of `kinematics` for every pose of `dataset` that has an
/// orientation, in file order.
pub(crate) fn orientation_per_pose(
    kinematics: &Kinematics<f64, Dyn>,
    dataset: &Seen<'_>,
) -> Vec<[f64; 3]> {
    dataset
        .measurements()
        .iter()
        .filter(|m| m.rotation.is_some())
        .map(|m| {
            let e = m.error_of(&kinematics.forward_angles(&m.angles));
            [0, 1, 2].map(|i| e.rotation[i].abs().to_degrees())
        })
        .collect()
}

/// Table 3 statistics of the dataset's own robot (nominal or identified, its joint maps
/// included) on its measurements.
pub fn evaluate(dataset: &Dataset) -> crate::Result<Table3> {
    let kinematics = Kinematics::nominal(&dataset.robot.model.robot)?;
    Ok(table3(&kinematics, dataset.as_given()?.measurements()).0)
}
