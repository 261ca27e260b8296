//! The robot model: the nominal robot ([`Robot`]: Hayati MDH joints, joint limits, base and tool
//! frames), its parameter errors and the identification mask ([`parameters`]), and the robot of
//! the source paper ([`paper`]), and the per-joint angle-error maps beyond geometry
//! ([`joint_maps`]) and gravity compliance ([`compliance`]).

pub mod compliance;
mod error;
pub mod joint_count;
pub mod joint_maps;
pub mod paper;
pub mod parameters;
mod robot;

pub use error::KinematicsError;
pub use joint_count::{JacobianColumns, JointCount, JointTable, JointVec, MAX_JOINTS, joint_count};
pub use robot::{FramePose, JointLimits, MdhJoint, Robot};
pub(crate) use robot::{check_count, joint_number};
