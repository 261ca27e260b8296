//! `calib-core`: the allocation-free heart of the robot calibration toolkit.
//!
//! Everything here runs unchanged on a PC (`f64`) and on a Cortex-M4F controller (`f32`):
//! no heap, no `std`, no panics on any input; bad input is an [`KinematicsError`] value.
//!
//! Conventions (`docs/ARCHITECTURE.md` in the repository): lengths in millimetres, angles in radians,
//! the Hayati modified DH joint transform of the paper's eq. (1)
//! `A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)`, `theta_i = q_i + theta_offset_i`,
//! and the end pose `T = T_base A_1 ... A_N T_tool`.
//!
//! The modules group the concepts:
//! - [`scalar`]: the scalar trait ([`Real`]) that makes everything generic over `f32`/`f64`;
//! - [`math`]: the exact rotation log map and rotations from roll, pitch and yaw;
//! - [`model`]: the nominal robot ([`Robot`]), parameter errors, the identification mask and
//!   the packed parameter vector ([`ParameterSet`]), the robot of the source paper, and
//!   [`KinematicsError`];
//! - [`kinematics`]: the joint transform of eq. (1), forward kinematics of the actual model,
//!   pose errors, Jacobians, closed-form inverse kinematics;
//! - [`identify`]: the calibration [`Problem`], the objective of eq. (7), the Halton sequence,
//!   the improved particle swarm, least squares, identifiability, the Table 3 statistics;
//! - [`controller`]: on-line compensation and the persistent parameter block.
//!
//! # A calibration
//!
//! The paper's robot with the errors of its Table 2 plays the real robot; 32 exact measured poses;
//! least squares recovers the 24 errors (see `examples/` for the paper's swarm and for the
//! controller side):
//!
//! ```
//! use calib_core::identify::lm::LmSettings;
//! use calib_core::model::paper;
//! use calib_core::{Kinematics, LeastSquares, Measurement, ParameterErrors, ParameterSet, Problem};
//! use nalgebra::{U24, U6};
//!
//! let robot = paper::er10l_c10::<f64>(); // nominal: the paper's Table 1 (mm, rad)
//! let real = Kinematics::new(&robot, &paper::table2())?; // the robot as built
//! let measurements: Vec<Measurement<f64, U6>> = (0..32)
//!     .map(|i| {
//!         let q: [f64; 6] = core::array::from_fn(|j| ((i * 7 + j * 3) % 11) as f64 * 0.5 - 2.5);
//!         let measured = real.forward(&q)?; // what the tracker measures
//!         Ok::<_, Box<dyn core::error::Error>>(Measurement::from_pose(&q, &measured)?)
//!     })
//!     .collect::<Result<_, _>>()?;
//! // The paper's 24 parameters of its 6 joints; both counts types: `U6` and `U24` fixed at compile
//! // time (a controller), or `nalgebra::Dyn` for counts a robot file sets at run time (a host).
//! let set = ParameterSet::<U6, U24>::default_for(&robot)?;
//! let problem = Problem::new(&robot, &ParameterErrors::zero(), set, &measurements, 1e6)?;
//! let start = problem.set().zeros(); // from the nominal model
//! let fit = LeastSquares::new(&problem).solve(&start, &LmSettings::default())?;
//! let identified = problem.set().unpack(&fit.x)?;
//! assert!((identified.joints[1].da - 0.2565).abs() < 1e-9); // Table 2: da2 = 0.2565 mm
//! # Ok::<(), Box<dyn core::error::Error>>(())
//! ```
#![no_std]
#![deny(missing_docs)]

pub mod controller;
pub mod identify;
pub mod kinematics;
pub mod math;
pub mod model;
pub mod numerics;
pub mod scalar;

pub use identify::Problem;
pub use identify::lm::LeastSquares;
pub use identify::objective::{Measurement, Objective};
pub use kinematics::{JointAngles, Kinematics, Pose, PreparedRobot};
pub use model::parameters::{
    FrameErrors, FrameParameter, JointErrors, JointParameter, Parameter, ParameterErrors,
    ParameterMask, ParameterSet,
};
pub use model::{FramePose, JointLimits, KinematicsError, MdhJoint, Robot};
pub use scalar::Real;
