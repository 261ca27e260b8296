//! Compensation: joint readings that put the identified robot on a target, and Cartesian
//! pre-distortion for controllers that accept only Cartesian targets.

use crate::access;
use crate::model::{
    CALIB_JOINTS, CALIB_ROTATION_TOLERANCE_F32, CALIB_ROTATION_TOLERANCE_F64, CalibCompensated,
    CalibCompensatedF32, CalibCompensatedF64, CalibModelF32, CalibModelF64, CalibPose,
    CalibPoseF32, CalibPoseF64, CalibRobotF32, CalibRobotF64, CalibSettings, CalibSettingsF32,
    CalibSettingsF64, IdentifiedModel, NominalRobot, Opaque,
};
use crate::status::{CalibStatus, status};
use calib_core::Real;
use calib_core::controller::compensate::{
    CompensationError, CompensationSettings, compensate_joints, predistort,
};
use nalgebra::Const;

/// The arguments every compensation reads.
struct Inputs<'a, T: Real> {
    nominal: &'a NominalRobot<T>,
    actual: &'a IdentifiedModel<T>,
    target: calib_core::kinematics::Pose<T>,
    start: [T; CALIB_JOINTS],
    settings: CompensationSettings<T>,
}

/// # Safety
/// The pointer contract of [`calib_compensate_joints_f32`].
unsafe fn inputs<'a, T: Real, R, O>(
    nominal: *const R,
    actual: *const O,
    target: *const CalibPose<T>,
    tolerance: T,
    start: *const T,
    settings: *const CalibSettings<T>,
) -> Result<Inputs<'a, T>, CalibStatus>
where
    R: Opaque<Value = NominalRobot<T>> + 'a,
    O: Opaque<Value = IdentifiedModel<T>> + 'a,
{
    // SAFETY: the caller's contract.
    unsafe {
        Ok(Inputs {
            nominal: access::filled(nominal)?,
            actual: access::filled(actual)?,
            target: access::pose(&access::read(target)?, tolerance)?,
            start: access::joints(start)?,
            settings: if settings.is_null() {
                CompensationSettings::default()
            } else {
                access::read(settings)?.into()
            },
        })
    }
}

fn outcome<T: Real>(
    result: Result<
        calib_core::controller::compensate::Compensated<T, Const<CALIB_JOINTS>>,
        CompensationError,
    >,
    out: *mut CalibCompensated<T>,
) -> Result<CalibCompensated<T>, CalibStatus> {
    match result {
        Ok(c) => Ok(CalibCompensated {
            q: c.q,
            residual_mm: c.residual_mm,
            residual_rad: c.residual_rad,
            iterations: c.iterations,
            limit_joint: 0,
        }),
        Err(CompensationError::JointLimit(joint)) => {
            if !out.is_null() {
                // SAFETY: checked by `access::write` (NULL and alignment); the caller's contract.
                unsafe {
                    let _ = access::write(
                        core::ptr::addr_of_mut!((*out).limit_joint),
                        u32::from(joint),
                    );
                }
            }
            Err(CalibStatus::JointLimit)
        }
        Err(e) => Err(e.into()),
    }
}

/// # Safety
/// See [`calib_compensate_joints_f32`].
unsafe fn joints<T: Real>(
    inputs: Inputs<'_, T>,
    out: *mut CalibCompensated<T>,
) -> Result<(), CalibStatus> {
    if out.is_null() {
        return Err(CalibStatus::NullPointer);
    }
    let actual = inputs.actual.kinematics();
    let result = compensate_joints(
        &inputs.nominal.kinematics,
        &actual,
        &inputs.nominal.robot.limits,
        &inputs.target,
        &inputs.start,
        &inputs.settings,
    );
    let c = outcome(result, out)?;
    // SAFETY: the caller's contract.
    unsafe { access::write(out, c) }
}

/// # Safety
/// See [`calib_predistort_f32`].
unsafe fn command<T: Real>(
    inputs: Inputs<'_, T>,
    command: *mut CalibPose<T>,
    out: *mut CalibCompensated<T>,
) -> Result<(), CalibStatus> {
    if out.is_null() || command.is_null() {
        return Err(CalibStatus::NullPointer);
    }
    let actual = inputs.actual.kinematics();
    let result = predistort(
        &inputs.nominal.kinematics,
        &actual,
        &inputs.nominal.robot.limits,
        &inputs.target,
        &inputs.start,
        &inputs.settings,
    );
    let (pose, c) = match result {
        Ok((pose, c)) => (pose, Ok(c)),
        Err(e) => (inputs.target, Err(e)),
    };
    let c = outcome(c, out)?;
    // SAFETY: the caller's contract.
    unsafe {
        access::write(command, access::to_c(&pose))?;
        access::write(out, c)
    }
}

/// The default settings: 1e-2 mm and 1e-5 rad in f32 (its rounding floor), 60 iterations,
/// corrections up to 5 mm, 0.5 deg and 0.5 rad per joint, manipulability at least 1e-6.
///
/// # Safety
/// `settings` points to a writable [`CalibSettings`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_settings_default_f32(
    settings: *mut CalibSettingsF32,
) -> CalibStatus {
    // SAFETY: the caller's contract.
    status(|| unsafe { access::write(settings, CompensationSettings::default().into()) })
}

/// The default settings in f64: 1e-3 mm and 1e-6 rad, otherwise as
/// [`calib_settings_default_f32`].
///
/// # Safety
/// `settings` points to a writable [`CalibSettings`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_settings_default_f64(
    settings: *mut CalibSettingsF64,
) -> CalibStatus {
    // SAFETY: the caller's contract.
    status(|| unsafe { access::write(settings, CompensationSettings::default().into()) })
}

/// Joint readings that put the identified robot `actual` on `target` (a pose in the base frame),
/// starting from `start` (`CALIB_JOINTS` values, rad: the controller's own inverse kinematics of
/// the target, or [`crate::calib_inverse_kinematics_f32`]). `nominal` is the robot the
/// controller plans with: the correction bounds of `settings` (NULL: the defaults) apply to the
/// difference it predicts between the result and the start, and its joint limits to the result.
/// On success writes `result`.
///
/// # Safety
/// `nominal` and `actual` point to a filled [`CalibRobotF32`] and [`CalibModelF32`], `target` to a
/// readable [`CalibPose`], `start` to `CALIB_JOINTS` readable floats, `settings` is NULL or
/// readable, `result` writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_compensate_joints_f32(
    nominal: *const CalibRobotF32,
    actual: *const CalibModelF32,
    target: *const CalibPoseF32,
    start: *const f32,
    settings: *const CalibSettingsF32,
    result: *mut CalibCompensatedF32,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        let tolerance = CALIB_ROTATION_TOLERANCE_F32;
        joints(
            inputs(nominal, actual, target, tolerance, start, settings)?,
            result,
        )
    })
}

/// [`calib_compensate_joints_f32`] in f64.
///
/// # Safety
/// As [`calib_compensate_joints_f32`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_compensate_joints_f64(
    nominal: *const CalibRobotF64,
    actual: *const CalibModelF64,
    target: *const CalibPoseF64,
    start: *const f64,
    settings: *const CalibSettingsF64,
    result: *mut CalibCompensatedF64,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        let tolerance = CALIB_ROTATION_TOLERANCE_F64;
        joints(
            inputs(nominal, actual, target, tolerance, start, settings)?,
            result,
        )
    })
}

/// Cartesian pre-distortion: the pose to command so that the controller's nominal inverse
/// kinematics (solved from `start`) puts the identified robot on `target`; writes it to `command`
/// and the joints the controller will use to `result`. Arguments as
/// [`calib_compensate_joints_f32`].
///
/// # Safety
/// As [`calib_compensate_joints_f32`], and `command` points to a writable [`CalibPose`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_predistort_f32(
    nominal: *const CalibRobotF32,
    actual: *const CalibModelF32,
    target: *const CalibPoseF32,
    start: *const f32,
    settings: *const CalibSettingsF32,
    command_pose: *mut CalibPoseF32,
    result: *mut CalibCompensatedF32,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        let tolerance = CALIB_ROTATION_TOLERANCE_F32;
        let inputs = inputs(nominal, actual, target, tolerance, start, settings)?;
        command(inputs, command_pose, result)
    })
}

/// [`calib_predistort_f32`] in f64.
///
/// # Safety
/// As [`calib_predistort_f32`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_predistort_f64(
    nominal: *const CalibRobotF64,
    actual: *const CalibModelF64,
    target: *const CalibPoseF64,
    start: *const f64,
    settings: *const CalibSettingsF64,
    command_pose: *mut CalibPoseF64,
    result: *mut CalibCompensatedF64,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        let tolerance = CALIB_ROTATION_TOLERANCE_F64;
        let inputs = inputs(nominal, actual, target, tolerance, start, settings)?;
        command(inputs, command_pose, result)
    })
}
