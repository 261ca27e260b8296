//! `calib-core`: the allocation-free heart of the robot calibration toolkit.
//!
//! Everything here runs unchanged on a PC (`f64`) and on a Cortex-M4F controller (`f32`):
//! no heap, no `std`, no panics on any input; bad input is an [`KinematicsError`] value.
//!
//! Conventions (see the repository's `DESIGN.md`): lengths in millimetres, angles in radians,
//! the Hayati modified DH joint transform of the paper's eq. (1)
//! `A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)`, `theta_i = q_i + theta_offset_i`,
//! and the end pose `T = T_base A_1 ... A_N T_tool`.
//!
//! Modules map one-to-one to concepts:
//! - [`scalar`]: the scalar trait ([`Real`]) that makes everything generic over `f32`/`f64`;
//! - [`model`]: the nominal robot ([`Robot`]): joints, limits, base and tool frames;
//! - [`parameters`]: parameter errors, the identification mask and the packed parameter vector;
//! - [`mdh`]: the joint transform of eq. (1);
//! - [`kinematics`]: forward kinematics of the actual model (nominal + errors);
//! - [`so3`]: the exact rotation log map and its Jacobian;
//! - [`pose_error`]: the pose error of a measurement and its parameter Jacobian;
//! - [`problem`]: a calibration problem (robot, identified set, measurements, `k`);
//! - [`jacobian`]: the geometric (joint) Jacobian and the parameter Jacobian of the end pose;
//! - [`trig`]: sine and cosine (libm, and a tested small-angle polynomial);
//! - [`halton`]: the Halton sequence of eq. (8)-(9);
//! - [`objective`]: measurements and the objective of eq. (7);
//! - [`ipso`]: the improved particle swarm (Halton start, constriction factor, eq. 10);
//! - [`lm`]: Levenberg-Marquardt least squares with streamed Givens QR, robust losses, uncertainty;
//! - [`identifiability`]: rank, condition, observability and the undetermined parameters;
//! - [`ik`]: closed-form nominal inverse kinematics of spherical-wrist 6R robots (8 branches);
//! - [`compensate`]: on-line compensation (joint space, Cartesian pre-distortion);
//! - [`storage`]: the persistent parameter block with A/B slots;
//! - [`statistics`]: the paper's Table 3 statistics;
//! - [`paper`]: the ER10L-C10 of the source paper (Table 1 nominal, Table 2 errors).
#![no_std]
#![deny(missing_docs)]

pub mod compensate;
pub mod error;
pub mod halton;
pub mod identifiability;
pub mod ik;
pub mod ipso;
pub mod jacobian;
pub mod kinematics;
pub mod lm;
pub mod mdh;
pub mod model;
pub mod objective;
pub mod paper;
pub mod parameters;
pub mod pose_error;
pub mod problem;
pub mod scalar;
pub mod so3;
pub mod statistics;
pub mod storage;
pub mod trig;

pub use error::KinematicsError;
pub use kinematics::{JointAngles, Kinematics, Pose, PreparedRobot};
pub use model::{FramePose, JointLimits, MdhJoint, Robot};
pub use parameters::{
    FrameErrors, FrameParameter, JointErrors, JointParameter, Parameter, ParameterErrors,
    ParameterMask, ParameterSet,
};
pub use pose_error::PoseError;
pub use scalar::Real;
