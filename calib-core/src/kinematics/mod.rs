//! Kinematics of the actual model (nominal + errors): the joint transform of the paper's eq. (1),
//! forward kinematics (eq. 2-3), the pose error of a measurement, the Jacobians and closed-form
//! inverse kinematics.
//!
//! - [`forward`](Kinematics): `T = T_base A_1 ... A_N T_tool`, also over precomputed joint
//!   trigonometry;
//! - [`pose_error`]: `dp = p_measured - p_predicted` (mm), `dr = log(R_measured R_predicted^T)`
//!   (rad), and its parameter Jacobian;
//! - [`jacobian`]: the geometric (joint) Jacobian and the parameter Jacobian of the end pose;
//! - [`deflection`]: the end frame's motion under gravity compliance;
//! - [`mapped`]: the geometry with each joint's angle-error map added to its reading;
//! - [`ik`]: closed-form nominal inverse kinematics of spherical-wrist 6R robots (8 branches).

pub mod deflection;
mod forward;
pub mod ik;
pub mod jacobian;
pub mod mapped;
pub(crate) mod mdh;
pub mod pose_error;

pub use forward::{JointAngles, Kinematics, Pose, PreparedRobot};
pub use mapped::MappedKinematics;
