//! The pose error of a measurement (docs/ARCHITECTURE.md): `dp = p_measured - p_predicted` (mm) and
//! `dr = log(R_measured R_predicted^T)` (rad, rotation vector in the base frame, exact log map);
//! and its Jacobian with respect to the identified parameters.

use crate::kinematics::{JointAngles, Kinematics, Pose};
use crate::math::so3;
use crate::model::JointCount;
use crate::model::KinematicsError;
use crate::model::parameters::ParameterSet;
use crate::scalar::Real;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OMatrix, U6, Vector3};

/// Position and orientation error of one measured pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseError<T: Real> {
    /// `p_measured - p_predicted`, mm.
    pub position: Vector3<T>,
    /// `log(R_measured R_predicted^T)`, rad (rotation vector in the base frame).
    pub rotation: Vector3<T>,
}

impl<T: Real> PoseError<T> {
    /// The error of the prediction `predicted` with respect to the measurement `measured`.
    pub fn between(measured: &Pose<T>, predicted: &Pose<T>) -> Self {
        let relative = measured.rotation.matrix() * predicted.rotation.matrix().transpose();
        Self {
            position: measured.translation.vector - predicted.translation.vector,
            rotation: so3::log(&relative),
        }
    }
}

/// Pose error of the model `kinematics` at joint readings `angles` against `measured`, and its
/// Jacobian with respect to the `D` parameters of `set`: rows `[dp (mm); dr (rad)]` per unit
/// parameter (mm or rad). The rotation rows use the exact derivative of the log map
/// (`-Jr^-1(dr) * omega`), not only the small-angle form.
pub fn pose_error_jacobian<T: Real, N: JointCount, D: Dim>(
    kinematics: &Kinematics<T, N>,
    set: &ParameterSet<N, D>,
    angles: &JointAngles<T, N>,
    measured: &Pose<T>,
) -> (PoseError<T>, OMatrix<T, U6, D>)
where
    DefaultAllocator: Allocator<D> + Allocator<U6, D>,
{
    let (predicted, twist) = kinematics.parameter_jacobian(set, angles);
    let error = PoseError::between(measured, &predicted);
    let jr_inv = so3::right_jacobian_inverse(&error.rotation);
    let mut jacobian = OMatrix::<T, U6, D>::zeros_generic(U6, set.dim());
    for (mut out, column) in jacobian.column_iter_mut().zip(twist.column_iter()) {
        let v = column.fixed_rows::<3>(0);
        let w = column.fixed_rows::<3>(3);
        out.fixed_rows_mut::<3>(0).copy_from(&(-v));
        out.fixed_rows_mut::<3>(3).copy_from(&(-(jr_inv * w)));
    }
    (error, jacobian)
}

/// The pose error for joint readings `q` (rad); error on non-finite readings.
pub fn pose_error<T: Real, N: JointCount>(
    kinematics: &Kinematics<T, N>,
    q: &N::Table<T>,
    measured: &Pose<T>,
) -> Result<PoseError<T>, KinematicsError> {
    Ok(PoseError::between(measured, &kinematics.forward(q)?))
}
