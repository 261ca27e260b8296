//! C ABI over the calibration core, for controller firmware written in C or C++.
//!
//! The controller side of the toolkit as a small, versioned C API (`include/calib.h`, generated
//! by cbindgen from this crate and checked by `tests/header.rs`):
//!
//! - parameter blocks: decode a block ([`calib_model_decode_f32`], [`calib_robot_decode_f32`]),
//!   load the newest valid block of two caller-provided slots A/B with the fallback rule of
//!   `calib_core::controller::storage` ([`calib_model_load_f32`]), write a model to the older
//!   slot through the caller's flash driver ([`calib_model_store_f32`]);
//! - kinematics: forward kinematics of the nominal robot or the whole identified model
//!   ([`calib_robot_forward_f32`], [`calib_model_forward_f32`]), closed-form nominal inverse
//!   kinematics for the spherical-wrist and UR-type robots ([`calib_inverse_kinematics_f32`]);
//! - compensation: joints that put the identified robot on a target
//!   ([`calib_compensate_joints_f32`]) and Cartesian pre-distortion ([`calib_predistort_f32`]);
//! - [`calib_api_version`], [`calib_status_message`].
//!
//! Every function exists in f32 (single-precision FPUs such as the Cortex-M4F) and f64 (for
//! controllers with double-precision hardware; on a Cortex-M4F it runs in software). Units: mm
//! and rad; a pose is a position in mm and a rotation as a row-major 3x3 matrix (checked to be a
//! rotation within [`CALIB_ROTATION_TOLERANCE_F32`] / [`CALIB_ROTATION_TOLERANCE_F64`]).
//!
//! No heap, no global state, no panic: the caller owns all memory (the sizes are the header's
//! `CALIB_*_WORDS` and `CALIB_BLOCK_MAX_BYTES_*` constants), every pointer is checked for null
//! and alignment, and every failure is a [`CalibStatus`]. On the controller the library links with
//! `panic-never`'s handler, which cannot be linked if any panic remains reachable.

#![cfg_attr(target_os = "none", no_std)]
#![deny(missing_docs)]

#[cfg(target_os = "none")]
use panic_never as _;

mod access;
pub mod compensation;
pub mod kinematics;
pub mod model;
pub mod status;
pub mod storage;

pub use compensation::*;
pub use kinematics::*;
pub use model::*;
pub use status::*;
pub use storage::*;

/// Major version of the C API: changes when a function, type or constant changes incompatibly.
pub const CALIB_API_VERSION_MAJOR: u32 = 1;
/// Minor version of the C API: changes when something is added.
pub const CALIB_API_VERSION_MINOR: u32 = 0;

/// The API version this library implements, `major << 16 | minor`: compare the major part with
/// the header's [`CALIB_API_VERSION_MAJOR`] at start-up.
#[unsafe(no_mangle)]
pub extern "C" fn calib_api_version() -> u32 {
    (CALIB_API_VERSION_MAJOR << 16) | CALIB_API_VERSION_MINOR
}
