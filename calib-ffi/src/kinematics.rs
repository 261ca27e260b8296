//! Forward kinematics of the nominal robot and of the identified model, and closed-form nominal
//! inverse kinematics.

use crate::access;
use crate::model::{
    CALIB_JOINTS, CALIB_ROTATION_TOLERANCE_F32, CALIB_ROTATION_TOLERANCE_F64, CalibModelF32,
    CalibModelF64, CalibPose, CalibPoseF32, CalibPoseF64, CalibRobotF32, CalibRobotF64,
    IdentifiedModel, NominalRobot, Opaque,
};
use crate::status::{CalibStatus, status};
use calib_core::Real;
use calib_core::kinematics::ik::{BRANCHES, closest, inverse_kinematics};

/// # Safety
/// See [`calib_robot_forward_f32`].
unsafe fn robot_forward<T: Real, R: Opaque<Value = NominalRobot<T>>>(
    robot: *const R,
    q: *const T,
    pose: *mut CalibPose<T>,
) -> Result<(), CalibStatus> {
    // SAFETY: the caller's contract.
    let (robot, q) = unsafe { (access::filled(robot)?, access::joints(q)?) };
    let end = robot
        .kinematics
        .forward(&q)
        .map_err(|_| CalibStatus::Kinematics)?;
    // SAFETY: the caller's contract.
    unsafe { access::write(pose, access::to_c(&end)) }
}

/// # Safety
/// See [`calib_model_forward_f32`].
unsafe fn model_forward<T: Real, O>(
    model: *const O,
    q: *const T,
    pose: *mut CalibPose<T>,
) -> Result<(), CalibStatus>
where
    O: Opaque<Value = IdentifiedModel<T>>,
{
    // SAFETY: the caller's contract.
    let (model, q) = unsafe { (access::filled(model)?, access::joints(q)?) };
    let end = model
        .kinematics()
        .forward(&q)
        .map_err(|_| CalibStatus::Kinematics)?;
    // SAFETY: the caller's contract.
    unsafe { access::write(pose, access::to_c(&end)) }
}

/// # Safety
/// See [`calib_inverse_kinematics_f32`].
unsafe fn inverse<T: Real, R: Opaque<Value = NominalRobot<T>>>(
    robot: *const R,
    target: *const CalibPose<T>,
    tolerance: T,
    reference: *const T,
    q: *mut T,
    branch: *mut u32,
) -> Result<(), CalibStatus> {
    // SAFETY: the caller's contract.
    let (robot, target, reference) = unsafe {
        (
            access::filled(robot)?,
            access::read(target)?,
            access::joints::<T, CALIB_JOINTS>(reference)?,
        )
    };
    let target = access::pose(&target, tolerance)?;
    let solutions = inverse_kinematics(&robot.robot, &target)?;
    let best = closest(&solutions, &reference).ok_or(CalibStatus::Unreachable)?;
    let index = (0..BRANCHES)
        .find(|b| solutions.get(*b).copied().flatten() == Some(best))
        .unwrap_or(0);
    // SAFETY: the caller's contract.
    unsafe {
        access::write(q.cast::<[T; CALIB_JOINTS]>(), best)?;
        if !branch.is_null() {
            access::write(branch, u32::try_from(index).unwrap_or(u32::MAX))?;
        }
    }
    Ok(())
}

/// The nominal robot's pose (tool in the base frame) at joint readings `q` (`CALIB_JOINTS`
/// values, rad), written to `pose`.
///
/// # Safety
/// `robot` points to a filled [`CalibRobotF32`], `q` to `CALIB_JOINTS` readable floats, `pose` to
/// a writable [`CalibPose`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_robot_forward_f32(
    robot: *const CalibRobotF32,
    q: *const f32,
    pose: *mut CalibPoseF32,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe { robot_forward(robot, q, pose) })
}

/// [`calib_robot_forward_f32`] in f64.
///
/// # Safety
/// As [`calib_robot_forward_f32`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_robot_forward_f64(
    robot: *const CalibRobotF64,
    q: *const f64,
    pose: *mut CalibPoseF64,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe { robot_forward(robot, q, pose) })
}

/// The identified model's pose (geometry, angle-error maps and gravity deflection) at joint
/// readings `q` (`CALIB_JOINTS` values, rad): where the real robot goes.
///
/// # Safety
/// `model` points to a filled [`CalibModelF32`], `q` to `CALIB_JOINTS` readable floats, `pose` to
/// a writable [`CalibPose`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_model_forward_f32(
    model: *const CalibModelF32,
    q: *const f32,
    pose: *mut CalibPoseF32,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe { model_forward(model, q, pose) })
}

/// [`calib_model_forward_f32`] in f64.
///
/// # Safety
/// As [`calib_model_forward_f32`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_model_forward_f64(
    model: *const CalibModelF64,
    q: *const f64,
    pose: *mut CalibPoseF64,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe { model_forward(model, q, pose) })
}

/// Closed-form inverse kinematics of the nominal robot (spherical wrist as the ER10L-C10, or the
/// UR family's offset wrist; 8 branches): the solution nearest `reference` (largest wrapped
/// joint difference) is written to `q` (`CALIB_JOINTS` values, rad, wrapped into (-pi, pi]) and
/// its branch (bits: 4 shoulder, 2 elbow, 1 wrist) to `branch` unless that is NULL. The start of
/// a compensation for a target given without joints.
///
/// # Safety
/// `robot` points to a filled [`CalibRobotF32`], `target` to a readable [`CalibPose`],
/// `reference` to `CALIB_JOINTS` readable floats, `q` to `CALIB_JOINTS` writable floats, `branch`
/// is NULL or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_inverse_kinematics_f32(
    robot: *const CalibRobotF32,
    target: *const CalibPoseF32,
    reference: *const f32,
    q: *mut f32,
    branch: *mut u32,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        inverse(
            robot,
            target,
            CALIB_ROTATION_TOLERANCE_F32,
            reference,
            q,
            branch,
        )
    })
}

/// [`calib_inverse_kinematics_f32`] in f64.
///
/// # Safety
/// As [`calib_inverse_kinematics_f32`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_inverse_kinematics_f64(
    robot: *const CalibRobotF64,
    target: *const CalibPoseF64,
    reference: *const f64,
    q: *mut f64,
    branch: *mut u32,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        inverse(
            robot,
            target,
            CALIB_ROTATION_TOLERANCE_F64,
            reference,
            q,
            branch,
        )
    })
}
