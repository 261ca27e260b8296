//! The joint readings that put the tool point (a ball's centre) at a given point, nearest a
//! starting configuration: for touches, where only the point matters and a 6- or 7-joint arm
//! keeps three or four degrees of freedom. Gauss-Newton on the point's position with the
//! joints' minimum-norm step `dq = J^T (J J^T)^-1 e` (`J` the position rows of the geometric
//! Jacobian), each step at most [`MAX_STEP_RAD`] long so that a start far from the point does
//! not leap across the workspace.

use calib_core::Kinematics;
use calib_core::model::JointVec;
use calib_core::model::joint_count::JacobianColumns;
use nalgebra::{Dyn, Matrix3, Vector3};

/// Steps at most (from a few mm off, three reach 1e-9 mm; from across the workspace, tens).
const STEPS: usize = 100;

/// The longest step, rad (the joints' vector norm).
pub const MAX_STEP_RAD: f64 = 0.3;

/// The joint readings nearest `start` (rad) at which `model`'s tool point lies at `target` (mm,
/// base frame) within `within_mm`, or `None` (no convergence, a singular position Jacobian, a
/// reading of another joint count than the model's).
pub fn reach_point(
    model: &Kinematics<f64, Dyn>,
    start: &[f64],
    target: &Vector3<f64>,
    within_mm: f64,
) -> Option<Vec<f64>> {
    let mut q = start.to_vec();
    for _ in 0..STEPS {
        let (pose, jacobian) = model.geometric_jacobian(&JointVec::from_slice(&q)?).ok()?;
        let error = target - pose.translation.vector;
        if error.norm() < within_mm {
            return Some(q);
        }
        let rows: Vec<Vector3<f64>> = (0..q.len())
            .map(|j| jacobian.column(j).fixed_rows::<3>(0).into_owned())
            .collect();
        let jjt: Matrix3<f64> = rows.iter().map(|c| c * c.transpose()).sum();
        let y = jjt.try_inverse()? * error;
        let step: Vec<f64> = rows.iter().map(|c| c.dot(&y)).collect();
        let length = step.iter().map(|s| s * s).sum::<f64>().sqrt();
        let shrink = if length > MAX_STEP_RAD {
            MAX_STEP_RAD / length
        } else {
            1.0
        };
        for (qj, s) in q.iter_mut().zip(&step) {
            *qj += s * shrink;
        }
    }
    None
}
