//! Per-joint angle-error maps: the part of the actual robot's model that a geometric
//! calibration leaves.
//!
//! What a geometric calibration leaves on a real robot is mostly an angle error of each joint that
//! repeats with that joint's own angle (gearbox or encoder). Each joint `j` gets a map
//!
//! `dq_j(q_j) = sum_{h=1..H} a_jh sin(h q_j) + b_jh cos(h q_j)`  (rad)
//!
//! added to the joint reading before the forward kinematics ([`JointMaps`]). The robot file holds
//! them in its `[joint_maps]` section ([`section`]); they are identified jointly with the geometry
//! by the evidence solver of [`crate::calibration::maps::evidence`].

pub mod section;

pub(crate) use section::MAX_FILE_HARMONICS;
pub use section::{JointMapEntry, JointMapsSection};

use calib_core::Real;
use calib_core::model::joint_maps::JointMaps as CoreMaps;
use calib_core::model::{JointCount, JointVec};
use nalgebra::DVector;
use nalgebra::Dyn;

/// A prior amplitude below this (rad) is treated as zero: the evidence does not support a map.
pub(crate) const NEGLIGIBLE_AMPLITUDE_RAD: f64 = 1e-7;

/// The basis of a map at reading `q` (rad), in the order of [`JointMaps::coefficients`]:
/// `[sin(q), ..., sin(H q), cos(q), ..., cos(H q)]`.
pub(crate) fn harmonic_basis(harmonics: usize, q: f64) -> DVector<f64> {
    let mut basis = DVector::zeros(2 * harmonics);
    for k in 1..=harmonics {
        let (s, c) = (k as f64 * q).sin_cos();
        basis[k - 1] = s;
        basis[harmonics + k - 1] = c;
    }
    basis
}

/// The angle-error map of every joint.
#[derive(Clone, Debug, PartialEq)]
pub struct JointMaps {
    /// Harmonics per joint, `H`.
    pub harmonics: usize,
    /// Per joint (joint 1 first, one per joint of the robot), `[a_1..a_H, b_1..b_H]`, rad.
    pub coefficients: Vec<Vec<f64>>,
}

impl JointMaps {
    /// Maps of `joints` joints that are zero everywhere.
    pub fn zero(joints: usize, harmonics: usize) -> Self {
        Self {
            harmonics,
            coefficients: vec![vec![0.0; 2 * harmonics]; joints],
        }
    }

    /// The number of joints mapped.
    pub fn joints(&self) -> usize {
        self.coefficients.len()
    }

    /// The angle error of joint `joint` (0-based) at reading `q`, rad.
    pub fn error(&self, joint: usize, q: f64) -> f64 {
        self.coefficients.get(joint).map_or(0.0, |c| {
            harmonic_basis(self.harmonics, q)
                .iter()
                .zip(c)
                .map(|(b, c)| b * c)
                .sum()
        })
    }

    /// Whether the map of joint `joint` (0-based) is zero everywhere.
    pub(crate) fn is_zero(&self, joint: usize) -> bool {
        self.coefficients
            .get(joint)
            .is_none_or(|c| c.iter().all(|v| *v == 0.0))
    }

    /// The joint readings `q` (rad) with every map added: what the kinematics sees.
    /// Joints without a map (beyond the maps' joint count) are read as they are.
    pub fn apply(&self, q: &JointVec<f64>) -> JointVec<f64> {
        JointVec::from_fn(q.len(), |j| q[j] + self.error(j, q[j]))
    }

    /// The maps as the core evaluates them on the controller, in scalar `T` with room for `C`
    /// harmonics (rounded to `T`). Error: more than `C` harmonics, or a map the core refuses
    /// (see [`calib_core::model::joint_maps::JointMaps::new`]; the error names the joint).
    /// The maps hold one map per joint of the robot they are for (a [`JointMapsSection`] read
    /// for the robot file is checked so); more joints than the core's tables hold are refused as
    /// the maps of joint 1.
    pub fn to_core<T: Real, const C: usize>(
        &self,
    ) -> Result<CoreMaps<T, Dyn, C>, calib_core::KinematicsError> {
        let h = self.harmonics;
        if h > C {
            return Err(calib_core::KinematicsError::TooManyHarmonics);
        }
        let joints = calib_core::model::joint_count(self.coefficients.len())
            .ok_or(calib_core::KinematicsError::InvalidJointMap { joint: 1 })?;
        let mut sin = joints.table([T::zero(); C]);
        let mut cos = joints.table([T::zero(); C]);
        for ((a, b), c) in sin.iter_mut().zip(cos.iter_mut()).zip(&self.coefficients) {
            for (k, v) in c.iter().enumerate() {
                let slot = if k < h { &mut a[k] } else { &mut b[k - h] };
                *slot = T::of(*v);
            }
        }
        CoreMaps::new(h, sin, cos)
    }
}
