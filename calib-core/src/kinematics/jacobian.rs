//! Jacobians of the end pose: the geometric (joint) Jacobian and the parameter Jacobian.
//!
//! Both give, per unit change of a joint reading or parameter, the end-point velocity `v` (mm per
//! unit) and the angular velocity `omega` (rad per unit), both in the base (world) frame, stacked as
//! the 6 rows `[v; omega]`. The end point is the origin of the tool frame.

use crate::kinematics::{JointAngles, Kinematics, Pose};
use crate::model::parameters::{FrameParameter, JointParameter, Parameter, ParameterSet};
use crate::model::{JacobianColumns, JointCount, JointTable};
use crate::model::{KinematicsError, check_count};
use crate::scalar::Real;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, Matrix3, OMatrix, U6, Vector3, Vector6};

/// `[v; omega]` of a rotation about `axis` through `pivot`, seen at the end point `end`.
// Called, not inlined, on a controller: inlined, the joint Jacobian's loop is unrolled there
// (380 bytes more flash).
#[cfg_attr(target_arch = "arm", inline(never))]
fn rotation_twist<T: Real>(axis: Vector3<T>, pivot: &Vector3<T>, end: &Vector3<T>) -> Vector6<T> {
    let v = axis.cross(&(end - pivot));
    Vector6::new(v.x, v.y, v.z, axis.x, axis.y, axis.z)
}

/// `[v; 0]` of a translation along `axis`.
fn translation_twist<T: Real>(axis: Vector3<T>) -> Vector6<T> {
    Vector6::new(axis.x, axis.y, axis.z, T::zero(), T::zero(), T::zero())
}

/// The geometric Jacobian of an N-joint robot, 6 x N: joint j's column `[v; omega]` (mm/rad,
/// rad/rad), read and changed through [`JacobianColumns`].
pub type JointJacobian<T, N> = <N as JointCount>::Jacobian<T>;

fn axis_of<T: Real>(axes: &Matrix3<T>, kind: FrameParameter) -> Vector3<T> {
    match kind {
        FrameParameter::Tx | FrameParameter::Rx => axes.column(0).into_owned(),
        FrameParameter::Ty | FrameParameter::Ry => axes.column(1).into_owned(),
        FrameParameter::Tz | FrameParameter::Rz => axes.column(2).into_owned(),
    }
}

impl<T: Real, N: JointCount> Kinematics<T, N> {
    /// End pose and geometric Jacobian (its N columns `[v (mm/rad); omega (rad/rad)]`, one per
    /// joint) for joint readings `q` (rad). Error: a non-finite reading, or another joint count
    /// than the model's.
    pub fn geometric_jacobian(
        &self,
        q: &N::Table<T>,
    ) -> Result<(Pose<T>, JointJacobian<T, N>), KinematicsError> {
        check_count(self.joint_count().value(), q.len())?;
        let chain = self.chain(&JointAngles::new(q)?);
        let end = chain.end.translation.vector;
        let mut jacobian = self.joint_count().jacobian();
        let (z, o) = (chain.before_z.as_slice(), chain.before_origin.as_slice());
        jacobian.fill_columns(|j| match (z.get(j), o.get(j)) {
            (Some(z), Some(o)) => rotation_twist(*z, o, &end),
            _ => Vector6::zeros(),
        });
        Ok((chain.end, jacobian))
    }

    /// End pose and parameter Jacobian (6 x D, rows `[v; omega]` per mm or rad of each parameter
    /// of `set`, in the set's order) for precomputed joint angles.
    pub fn parameter_jacobian<D: Dim>(
        &self,
        set: &ParameterSet<N, D>,
        angles: &JointAngles<T, N>,
    ) -> (Pose<T>, OMatrix<T, U6, D>)
    where
        DefaultAllocator: Allocator<D> + Allocator<U6, D>,
    {
        let chain = self.chain(angles);
        let end = chain.end.translation.vector;
        let zero = Vector6::zeros();
        let jacobian = set.columns(|parameter| match parameter {
            Parameter::Joint { joint, kind } => {
                let Some(j) = usize::from(joint).checked_sub(1) else {
                    return zero;
                };
                let (Some(o_prev), Some(z_prev), Some(x), Some(o), Some(y)) = (
                    chain.before_origin.as_slice().get(j),
                    chain.before_z.as_slice().get(j),
                    chain.x_axis.as_slice().get(j),
                    chain.origin.as_slice().get(j),
                    chain.y_axis.as_slice().get(j),
                ) else {
                    return zero;
                };
                match kind {
                    JointParameter::A => translation_twist(*x),
                    JointParameter::D => translation_twist(*z_prev),
                    JointParameter::Alpha => rotation_twist(*x, o, &end),
                    JointParameter::Beta => rotation_twist(*y, o, &end),
                    JointParameter::Theta => rotation_twist(*z_prev, o_prev, &end),
                }
            }
            Parameter::Base(kind) if kind.is_rotation() => {
                let axis = axis_of(self.base_axes(), kind);
                rotation_twist(axis, &self.base().translation.vector, &end)
            }
            Parameter::Base(kind) => translation_twist(axis_of(&Matrix3::identity(), kind)),
            Parameter::Tool(kind) => {
                let flange = chain.flange.rotation.matrix();
                if kind.is_rotation() {
                    let axis = flange * axis_of(self.tool_axes(), kind);
                    rotation_twist(axis, &end, &end)
                } else {
                    translation_twist(flange * axis_of(&Matrix3::identity(), kind))
                }
            }
        });
        (chain.end, jacobian)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::pose_error::{PoseError, pose_error_jacobian};
    use crate::model::Robot;
    use crate::model::paper::{er10l_with_frames, table2};
    use crate::model::parameters::{ParameterErrors, ParameterMask, all_parameters};
    use nalgebra::U6;
    use nalgebra::U42;

    const Q: [[f64; 6]; 3] = [
        [0.3, -0.7, 1.1, 2.0, -1.4, 0.6],
        [-2.8, 1.2, -0.3, -1.0, 0.9, -2.2],
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    ];

    fn errors_with_frames() -> ParameterErrors<f64, U6> {
        let mut e = table2::<f64>();
        e.base.translation = [0.4, -0.2, 0.7];
        e.base.rotation = [0.003, -0.004, 0.002];
        e.tool.translation = [-0.3, 0.5, 0.1];
        e.tool.rotation = [-0.002, 0.006, 0.001];
        e
    }

    fn all_set() -> ParameterSet<U6, U42> {
        let mut mask = ParameterMask::empty();
        for p in all_parameters(U6) {
            mask.set(p, true);
        }
        ParameterSet::from_mask(&mask).unwrap()
    }

    fn pose_error_at(
        robot: &Robot<f64, U6>,
        errors: &ParameterErrors<f64, U6>,
        q: &[f64; 6],
        measured: &Pose<f64>,
    ) -> [f64; 6] {
        let predicted = Kinematics::new(robot, errors).unwrap().forward(q).unwrap();
        let e = PoseError::between(measured, &predicted);
        [
            e.position.x,
            e.position.y,
            e.position.z,
            e.rotation.x,
            e.rotation.y,
            e.rotation.z,
        ]
    }

    #[test]
    fn pose_error_jacobian_matches_central_differences_for_all_42_parameters() {
        let robot = er10l_with_frames();
        let errors = errors_with_frames();
        let set = all_set();
        let kinematics = Kinematics::new(&robot, &errors).unwrap();
        // "Measured" poses: the model with other errors, so the pose error is far from zero
        // (about 0.05 rad) and the exact log-map derivative matters.
        let mut other = errors;
        for j in &mut other.joints {
            j.dalpha += 0.01;
            j.dtheta -= 0.015;
            j.da += 0.8;
        }
        let truth = Kinematics::new(&robot, &other).unwrap();
        for q in &Q {
            let measured = truth.forward(q).unwrap();
            let angles = JointAngles::new(q).unwrap();
            let (error, jacobian) = pose_error_jacobian(&kinematics, &set, &angles, &measured);
            assert!(error.rotation.norm() > 0.02);
            for (k, parameter) in set.parameters().iter().enumerate() {
                let h = if parameter.is_angle() { 1e-7 } else { 1e-5 };
                let value = errors.get(*parameter).unwrap();
                let mut plus = errors;
                plus.set(*parameter, value + h);
                let mut minus = errors;
                minus.set(*parameter, value - h);
                let ep = pose_error_at(&robot, &plus, q, &measured);
                let em = pose_error_at(&robot, &minus, q, &measured);
                for row in 0..6 {
                    let fd = (ep[row] - em[row]) / (2.0 * h);
                    let analytic = jacobian[(row, k)];
                    let scale = if row < 3 { 1e-5 } else { 1e-8 };
                    assert!(
                        (fd - analytic).abs() < scale * (1.0 + fd.abs()),
                        "{parameter} row {row}: analytic {analytic}, central difference {fd}"
                    );
                }
            }
        }
    }

    #[test]
    fn geometric_jacobian_matches_central_differences() {
        let robot = er10l_with_frames();
        let kinematics = Kinematics::new(&robot, &errors_with_frames()).unwrap();
        for q in &Q {
            let (pose, jacobian) = kinematics.geometric_jacobian(q).unwrap();
            assert_eq!(pose, kinematics.forward(q).unwrap());
            let h = 1e-7;
            for j in 0..6 {
                let mut plus = *q;
                plus[j] += h;
                let mut minus = *q;
                minus[j] -= h;
                let tp = kinematics.forward(&plus).unwrap();
                let tm = kinematics.forward(&minus).unwrap();
                let v = (tp.translation.vector - tm.translation.vector) / (2.0 * h);
                let w = crate::math::so3::log(
                    &(tp.rotation.matrix() * tm.rotation.matrix().transpose()),
                ) / (2.0 * h);
                for r in 0..3 {
                    assert!((v[r] - jacobian[(r, j)]).abs() < 1e-5 * (1.0 + v[r].abs()));
                    assert!((w[r] - jacobian[(r + 3, j)]).abs() < 1e-8);
                }
            }
        }
    }

    #[test]
    fn non_finite_joint_reading_is_an_error() {
        let kinematics = Kinematics::nominal(&er10l_with_frames()).unwrap();
        let mut q = Q[0];
        q[4] = f64::INFINITY;
        assert_eq!(
            kinematics.geometric_jacobian(&q).unwrap_err(),
            KinematicsError::NonFiniteJoint { joint: 5 }
        );
    }
}
