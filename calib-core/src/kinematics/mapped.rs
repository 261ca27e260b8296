//! The actual robot beyond geometry: the identified geometry ([`Kinematics`]) with each joint's
//! angle-error map ([`JointMaps`]) added to its reading, and optionally the gravity compliance
//! ([`Compliance`]) deflecting the end pose.
//!
//! The end pose for readings `q` is the geometric model's at the kinematic angles
//! `t = q + dq(q)`; its geometric Jacobian is the geometric model's at `t` times
//! `diag(1 + dq_j'(q_j))` (chain rule); the Jacobian of the pose with respect to a map coefficient
//! `a_jh` (`b_jh`) is column `j` of the geometric Jacobian at `t` times `sin(h q_j)` (`cos(h q_j)`).
//! With compliance, the pose is deflected by [`Compliance::deflect`] at `t`; the Jacobian leaves
//! out the deflection's change with the joints (the deflection is below 1 mrad and changes by
//! less than that per radian: a relative error below 1e-3 of a Newton step, which changes its
//! convergence rate, not the solution).

use crate::kinematics::jacobian::JointJacobian;
use crate::kinematics::{Kinematics, Pose};
use crate::model::JacobianColumns;
use crate::model::compliance::Compliance;
use crate::model::joint_maps::JointMaps;
use crate::model::parameters::ParameterErrors;
use crate::model::{JointCount, JointTable};
use crate::model::{KinematicsError, Robot};
use crate::scalar::Real;
use core::borrow::Borrow;

/// Geometry and angle-error maps of the actual robot, `C` harmonics of capacity per joint. The
/// maps are borrowed: a controller keeps one copy of their coefficients. The geometry is owned
/// (`G` = [`Kinematics`], the default) or borrowed (`G` = `&Kinematics`: a controller that keeps
/// the prepared geometry with the model's coefficients builds this per call without a copy).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MappedKinematics<'a, T: Real, N: JointCount, const C: usize, G = Kinematics<T, N>> {
    /// The geometric model, evaluated at the kinematic angles.
    pub geometry: G,
    /// The maps from readings to kinematic angles.
    pub maps: &'a JointMaps<T, N, C>,
    /// The gravity compliance, if the model has any (`None`: no deflection).
    pub compliance: Option<&'a Compliance<T, N>>,
}

impl<'a, T: Real, N: JointCount, const C: usize> MappedKinematics<'a, T, N, C> {
    /// `robot + errors` with `maps`; an error names the first non-finite value.
    pub fn new(
        robot: &Robot<T, N>,
        errors: &ParameterErrors<T, N>,
        maps: &'a JointMaps<T, N, C>,
    ) -> Result<Self, KinematicsError> {
        Ok(Self {
            geometry: Kinematics::new(robot, errors)?,
            maps,
            compliance: None,
        })
    }
}

impl<'a, T: Real, N: JointCount, const C: usize, G: Borrow<Kinematics<T, N>>>
    MappedKinematics<'a, T, N, C, G>
{
    /// This model with `compliance` (kept only when a gain is set: a model without gains costs
    /// nothing). Error: an invalid compliance model.
    pub fn with_compliance(
        self,
        compliance: &'a Compliance<T, N>,
    ) -> Result<Self, KinematicsError> {
        compliance.validate()?;
        Ok(Self {
            compliance: compliance.is_active().then_some(compliance),
            ..self
        })
    }

    /// End pose (mm) for joint readings `q` (rad). Error: a non-finite reading.
    pub fn forward(&self, q: &N::Table<T>) -> Result<Pose<T>, KinematicsError> {
        let t = self.maps.apply(q);
        match self.compliance {
            None => self.geometry.borrow().forward(&t),
            Some(compliance) => compliance.forward(self.geometry.borrow(), &t),
        }
    }

    /// End pose and geometric Jacobian (N columns `[v (mm/rad); omega (rad/rad)]` per radian of
    /// each reading) for readings `q` (rad); with compliance the pose is deflected, the Jacobian
    /// is the mapped geometry's (see the module documentation).
    pub fn geometric_jacobian(
        &self,
        q: &N::Table<T>,
    ) -> Result<(Pose<T>, JointJacobian<T, N>), KinematicsError> {
        let t = self.maps.apply(q);
        let (mut pose, mut jacobian) = self.geometry.borrow().geometric_jacobian(&t)?;
        if let Some(compliance) = self.compliance {
            pose = compliance.forward(self.geometry.borrow(), &t)?;
        }
        for (j, reading) in q.iter().enumerate() {
            let slope = self.maps.error_and_slope(j, *reading).1;
            jacobian.scale_column(j, T::one() + slope);
        }
        Ok((pose, jacobian))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::paper::{er10l_c10, table2};
    use nalgebra::U6;
    extern crate std;

    fn maps() -> JointMaps<f64, U6, 8> {
        let mut sin = [[0.0; 8]; 6];
        let mut cos = [[0.0; 8]; 6];
        for j in 0..6 {
            for h in 0..8 {
                sin[j][h] = 2e-4 / (1.0 + h as f64) * if (j + h) % 2 == 0 { 1.0 } else { -1.0 };
                cos[j][h] = 1e-4 * ((j * 3 + h) % 5) as f64 / 5.0;
            }
        }
        JointMaps::new(8, sin, cos).unwrap()
    }

    fn model(maps: &JointMaps<f64, U6, 8>) -> MappedKinematics<'_, f64, U6, 8> {
        MappedKinematics::new(&er10l_c10(), &table2(), maps).unwrap()
    }

    #[test]
    fn forward_is_the_geometry_at_the_mapped_angles() {
        let maps = maps();
        let m = model(&maps);
        let q = [0.3, -0.4, 0.5, 0.2, 0.9, -0.3];
        let t: [f64; 6] = core::array::from_fn(|j| {
            let x = q[j];
            x + (1..=8)
                .map(|h| {
                    let (s, c) = (h as f64 * x).sin_cos();
                    m.maps.sin_coefficients(j).unwrap()[h - 1] * s
                        + m.maps.cos_coefficients(j).unwrap()[h - 1] * c
                })
                .sum::<f64>()
        });
        let a = m.forward(&q).unwrap();
        let b = m.geometry.forward(&t).unwrap();
        assert!((a.translation.vector - b.translation.vector).norm() < 1e-10);
        // The maps move the end by a fraction of a millimetre here.
        let plain = m.geometry.forward(&q).unwrap();
        let moved = (a.translation.vector - plain.translation.vector).norm();
        assert!(moved > 0.05 && moved < 5.0, "{moved}");
    }

    #[test]
    fn the_jacobian_matches_central_differences() {
        let maps = maps();
        let m = model(&maps);
        let q = [0.3, -0.4, 0.5, 0.2, 0.9, -0.3];
        let (_, jacobian) = m.geometric_jacobian(&q).unwrap();
        let h = 1e-6;
        for j in 0..6 {
            let mut plus = q;
            let mut minus = q;
            plus[j] += h;
            minus[j] -= h;
            let (p, n) = (m.forward(&plus).unwrap(), m.forward(&minus).unwrap());
            let v = (p.translation.vector - n.translation.vector) / (2.0 * h);
            let w = crate::math::so3::log((p.rotation * n.rotation.inverse()).matrix()) / (2.0 * h);
            for r in 0..3 {
                assert!((jacobian[(r, j)] - v[r]).abs() < 1e-5, "v {r} {j}");
                assert!((jacobian[(r + 3, j)] - w[r]).abs() < 1e-8, "w {r} {j}");
            }
        }
    }
}
