//! Rotation and trigonometry helpers of the model and the kinematics: the exact rotation log map,
//! its Jacobian and rotations from roll, pitch and yaw ([`so3`]), the small-angle sine and
//! cosine that prepare candidate models without libm calls (internal), and the small Cholesky
//! solve of on-line compensation ([`cholesky`]).

pub mod cholesky;
pub mod so3;
pub(crate) mod trig;

use nalgebra::SVector;

use crate::scalar::Real;

/// The Euclidean norm of a fixed-size vector by the core's square root ([`Real::sqrt_ieee`]):
/// nalgebra's `norm()` to the bit (the same sum of squares, then a correctly rounded root), without
/// linking libm's software `sqrtf` into the controller.
#[inline]
pub fn norm<T: Real, const D: usize>(v: &SVector<T, D>) -> T {
    v.norm_squared().sqrt_ieee()
}
