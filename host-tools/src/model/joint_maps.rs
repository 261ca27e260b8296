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
/// The sines and cosines are the core's ([`calib_core::model::joint_maps::harmonics`]): the
/// controller evaluates the maps identified from this basis with the same numbers.
pub(crate) fn harmonic_basis(harmonics: usize, q: f64) -> DVector<f64> {
    let mut basis = DVector::zeros(2 * harmonics);
    for (k, (s, c)) in calib_core::model::joint_maps::harmonics(q)
        .take(harmonics)
        .enumerate()
    {
        basis[k] = s;
        basis[harmonics + k] = c;
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

    /// The angle error of joint `joint` (0-based) at reading `q`, rad: the core's series
    /// ([`calib_core::model::joint_maps::series`]), as the controller evaluates it.
    pub fn error(&self, joint: usize, q: f64) -> f64 {
        self.coefficients.get(joint).map_or(0.0, |c| {
            let (sin, cos) = c.split_at(self.harmonics.min(c.len()));
            calib_core::model::joint_maps::series(sin, cos, q)
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

#[cfg(test)]
mod tests {
    use super::{JointMaps, harmonic_basis};

    /// Issue 53 (item 6): the host evaluates a map with the controller's arithmetic, so the value
    /// the identification fitted is the value the core computes, to the last bit; and the basis
    /// the identification fits with gives that value (summed in the same order) and equals
    /// `sin(h q)`, `cos(h q)` to within the recurrence's rounding (a closed form).
    #[test]
    fn the_host_evaluates_maps_as_the_controller_does() {
        let h = 30;
        let maps = JointMaps {
            harmonics: h,
            coefficients: (0..6)
                .map(|j| {
                    (0..2 * h)
                        .map(|k| 1e-5 * ((j * 7 + k * 3) % 11) as f64 / (1.0 + k as f64))
                        .collect()
                })
                .collect(),
        };
        let core = maps.to_core::<f64, 30>().unwrap();
        for j in 0..6 {
            for q in [-3.1, -1.234, 0.0, 0.5, 2.9, 6.2] {
                assert_eq!(maps.error(j, q).to_bits(), core.error(j, q).to_bits());
                let basis = harmonic_basis(h, q);
                let c = &maps.coefficients[j];
                let summed =
                    (0..h).fold(0.0, |e, k| e + (c[k] * basis[k] + c[h + k] * basis[h + k]));
                assert_eq!(summed.to_bits(), maps.error(j, q).to_bits());
                for k in 0..h {
                    let (s, c) = ((k + 1) as f64 * q).sin_cos();
                    assert!((basis[k] - s).abs() < 1e-13 && (basis[h + k] - c).abs() < 1e-13);
                }
            }
        }
    }
}
