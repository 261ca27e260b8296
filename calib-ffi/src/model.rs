//! The caller-owned memory of a robot and a model, sizes as compile-time constants, and the
//! plain-data types of poses, settings and results.

use calib_core::controller::compensate::CompensationSettings;
use calib_core::controller::storage::{ControllerModel, model_block_len};
use calib_core::kinematics::MappedKinematics;
use calib_core::{Kinematics, Real, Robot};
use nalgebra::Const;

/// Joint count of this build (the blocks it reads must have it).
pub const CALIB_JOINTS: usize = 6;
/// Harmonics per joint map this build holds (blocks with up to this many are read).
pub const CALIB_HARMONICS: usize = 32;

/// 64-bit words of a [`CalibRobotF32`].
pub const CALIB_ROBOT_F32_WORDS: usize = 98;
/// 64-bit words of a [`CalibRobotF64`].
pub const CALIB_ROBOT_F64_WORDS: usize = 194;
/// 64-bit words of a [`CalibModelF32`].
pub const CALIB_MODEL_F32_WORDS: usize = 321;
/// 64-bit words of a [`CalibModelF64`].
pub const CALIB_MODEL_F64_WORDS: usize = 640;
/// Bytes of the largest f32 block this build reads or writes (maps of [`CALIB_HARMONICS`] and the
/// compliance section): the size of a slot and of the scratch buffer of [`crate::calib_model_store_f32`].
pub const CALIB_BLOCK_MAX_BYTES_F32: usize = 1968;
/// [`CALIB_BLOCK_MAX_BYTES_F32`] for f64 blocks.
pub const CALIB_BLOCK_MAX_BYTES_F64: usize = 3916;

/// Largest deviation of `R^T R` from the identity accepted in an f32 pose's rotation.
pub const CALIB_ROTATION_TOLERANCE_F32: f32 = 1e-4;
/// Largest deviation of `R^T R` from the identity accepted in an f64 pose's rotation.
pub const CALIB_ROTATION_TOLERANCE_F64: f64 = 1e-9;

/// The nominal robot the controller plans with (geometry, joint limits, base and tool frames),
/// f32. Caller-owned, filled by [`crate::calib_robot_decode_f32`]; the content is private.
#[repr(C)]
pub struct CalibRobotF32 {
    opaque: [u64; CALIB_ROBOT_F32_WORDS],
}

/// [`CalibRobotF32`] in f64, filled by [`crate::calib_robot_decode_f64`].
#[repr(C)]
pub struct CalibRobotF64 {
    opaque: [u64; CALIB_ROBOT_F64_WORDS],
}

/// The identified model the controller compensates with (geometry, angle-error maps, gravity
/// compliance), f32. Caller-owned, filled by [`crate::calib_model_decode_f32`] or
/// [`crate::calib_model_load_f32`]; the content is private.
#[repr(C)]
pub struct CalibModelF32 {
    opaque: [u64; CALIB_MODEL_F32_WORDS],
}

/// [`CalibModelF32`] in f64.
#[repr(C)]
pub struct CalibModelF64 {
    opaque: [u64; CALIB_MODEL_F64_WORDS],
}

/// A pose: position of the tool point in the robot's base frame (mm) and the rotation of the tool
/// frame as a row-major 3x3 matrix (`rotation[3 * row + column]`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibPose<T> {
    /// x, y, z, mm.
    pub position_mm: [T; 3],
    /// Row-major rotation matrix.
    pub rotation: [T; 9],
}

/// [`CalibPose`] in f32.
pub type CalibPoseF32 = CalibPose<f32>;
/// [`CalibPose`] in f64.
pub type CalibPoseF64 = CalibPose<f64>;

/// Settings of a compensation ([`crate::calib_settings_default_f32`] gives the defaults).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibSettings<T> {
    /// Position tolerance, mm.
    pub position_tolerance_mm: T,
    /// Orientation tolerance, rad.
    pub rotation_tolerance_rad: T,
    /// Iteration cap (each iteration: one forward kinematics with Jacobian, one 6x6 solve).
    pub max_iterations: u32,
    /// Damping of the damped least-squares step (scaled units).
    pub damping: T,
    /// Largest allowed correction of the commanded position, mm.
    pub max_correction_mm: T,
    /// Largest allowed correction of the commanded orientation, rad.
    pub max_correction_rad: T,
    /// Largest allowed change of any joint from the start, rad.
    pub max_joint_correction_rad: T,
    /// Smallest allowed manipulability of the scaled Jacobian.
    pub min_manipulability: T,
}

/// [`CalibSettings`] in f32.
pub type CalibSettingsF32 = CalibSettings<f32>;
/// [`CalibSettings`] in f64.
pub type CalibSettingsF64 = CalibSettings<f64>;

impl<T: Copy> From<CompensationSettings<T>> for CalibSettings<T> {
    fn from(s: CompensationSettings<T>) -> Self {
        Self {
            position_tolerance_mm: s.position_tolerance,
            rotation_tolerance_rad: s.rotation_tolerance,
            max_iterations: s.max_iterations,
            damping: s.damping,
            max_correction_mm: s.max_correction_mm,
            max_correction_rad: s.max_correction_rad,
            max_joint_correction_rad: s.max_joint_correction_rad,
            min_manipulability: s.min_manipulability,
        }
    }
}

impl<T: Copy> From<CalibSettings<T>> for CompensationSettings<T> {
    fn from(s: CalibSettings<T>) -> Self {
        Self {
            position_tolerance: s.position_tolerance_mm,
            rotation_tolerance: s.rotation_tolerance_rad,
            max_iterations: s.max_iterations,
            damping: s.damping,
            max_correction_mm: s.max_correction_mm,
            max_correction_rad: s.max_correction_rad,
            max_joint_correction_rad: s.max_joint_correction_rad,
            min_manipulability: s.min_manipulability,
        }
    }
}

/// The outcome of a compensation.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibCompensated<T> {
    /// Joint readings to command, rad (`CALIB_JOINTS` values).
    pub q: [T; CALIB_JOINTS],
    /// Predicted remaining position error of the identified robot, mm.
    pub residual_mm: T,
    /// Predicted remaining orientation error, rad.
    pub residual_rad: T,
    /// Damped least-squares iterations used.
    pub iterations: u32,
    /// With [`crate::CalibStatus::JointLimit`]: the joint (1-based) that would leave its limits;
    /// 0 otherwise. The only field written on that status.
    pub limit_joint: u32,
}

/// [`CalibCompensated`] in f32.
pub type CalibCompensatedF32 = CalibCompensated<f32>;
/// [`CalibCompensated`] in f64.
pub type CalibCompensatedF64 = CalibCompensated<f64>;

/// The nominal robot as held in a [`CalibRobotF32`]: the robot and its kinematics, prepared once
/// when the block is decoded (the constant trigonometry of every call saved).
pub(crate) struct NominalRobot<T: Real> {
    pub(crate) robot: Robot<T, Const<CALIB_JOINTS>>,
    pub(crate) kinematics: Kinematics<T, Const<CALIB_JOINTS>>,
}

impl<T: Real> NominalRobot<T> {
    /// Holds `robot` and prepares its kinematics, in place; error: an invalid robot.
    pub(crate) fn set(
        &mut self,
        robot: &Robot<T, Const<CALIB_JOINTS>>,
    ) -> Result<(), crate::CalibStatus> {
        self.robot = *robot;
        self.kinematics =
            Kinematics::nominal(&self.robot).map_err(|_| crate::CalibStatus::InvalidModel)?;
        Ok(())
    }
}

/// The identified model as held in a [`CalibModelF32`]: the model and its geometry, prepared
/// once when the block is decoded or loaded.
pub(crate) struct IdentifiedModel<T: Real> {
    pub(crate) model: ControllerModel<T, Const<CALIB_JOINTS>, CALIB_HARMONICS>,
    pub(crate) geometry: Kinematics<T, Const<CALIB_JOINTS>>,
}

impl<T: Real> IdentifiedModel<T> {
    /// Prepares the geometry of the model just written to `self.model` (it also validates the
    /// compliance). Error: an invalid model.
    pub(crate) fn prepare(&mut self) -> Result<(), crate::CalibStatus> {
        let invalid = |_| crate::CalibStatus::InvalidModel;
        self.model.compliance.validate().map_err(invalid)?;
        self.geometry = Kinematics::nominal(&self.model.robot).map_err(invalid)?;
        Ok(())
    }

    /// The model's kinematics (readings through the maps, the geometry, the compliance) from the
    /// prepared parts.
    pub(crate) fn kinematics(
        &self,
    ) -> MappedKinematics<
        '_,
        T,
        Const<CALIB_JOINTS>,
        CALIB_HARMONICS,
        &Kinematics<T, Const<CALIB_JOINTS>>,
    > {
        let compliance = &self.model.compliance;
        MappedKinematics {
            geometry: &self.geometry,
            maps: &self.model.maps,
            compliance: compliance.is_active().then_some(compliance),
        }
    }
}

/// What lives in the caller's memory: a tag saying it was filled, then the value.
#[repr(C)]
pub(crate) struct Tagged<V> {
    pub(crate) tag: u64,
    pub(crate) value: V,
}

/// A caller-owned opaque type and the value it holds.
pub(crate) trait Opaque {
    /// The value held.
    type Value;
    /// The tag of a filled value (distinct per type, so a robot is not taken for a model).
    const TAG: u64;
}

impl Opaque for CalibRobotF32 {
    type Value = NominalRobot<f32>;
    const TAG: u64 = u64::from_le_bytes(*b"CALBR32\0");
}
impl Opaque for CalibRobotF64 {
    type Value = NominalRobot<f64>;
    const TAG: u64 = u64::from_le_bytes(*b"CALBR64\0");
}
impl Opaque for CalibModelF32 {
    type Value = IdentifiedModel<f32>;
    const TAG: u64 = u64::from_le_bytes(*b"CALBM32\0");
}
impl Opaque for CalibModelF64 {
    type Value = IdentifiedModel<f64>;
    const TAG: u64 = u64::from_le_bytes(*b"CALBM64\0");
}

/// Each opaque type holds its tagged value, exactly (the header's sizes are not larger than
/// needed by more than one word), and is aligned for it and cleared as whole 32-bit words
/// (`access::cleared`).
const fn fits<O, V>() -> bool {
    let need = core::mem::size_of::<Tagged<V>>();
    let have = core::mem::size_of::<O>();
    need <= have
        && have < need + 8
        && core::mem::align_of::<Tagged<V>>() <= core::mem::align_of::<O>()
        && have.is_multiple_of(4)
        && core::mem::align_of::<O>() >= 4
}
const _: () = assert!(fits::<CalibRobotF32, <CalibRobotF32 as Opaque>::Value>());
const _: () = assert!(fits::<CalibRobotF64, <CalibRobotF64 as Opaque>::Value>());
const _: () = assert!(fits::<CalibModelF32, <CalibModelF32 as Opaque>::Value>());
const _: () = assert!(fits::<CalibModelF64, <CalibModelF64 as Opaque>::Value>());
const _: () = assert!(
    CALIB_BLOCK_MAX_BYTES_F32 == model_block_len::<f32>(CALIB_JOINTS, CALIB_HARMONICS, true)
);
const _: () = assert!(
    CALIB_BLOCK_MAX_BYTES_F64 == model_block_len::<f64>(CALIB_JOINTS, CALIB_HARMONICS, true)
);
