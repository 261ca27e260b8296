//! Rotation and trigonometry helpers of the model and the kinematics: the exact rotation log map,
//! its Jacobian and rotations from roll, pitch and yaw ([`so3`]), and the small-angle sine and
//! cosine that prepare candidate models without libm calls (internal).

pub mod so3;
pub(crate) mod trig;
