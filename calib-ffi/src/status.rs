//! Status codes of every call and their messages.

use calib_core::controller::compensate::CompensationError;
use calib_core::controller::storage::StorageError;
use calib_core::kinematics::ik::IkError;
use core::ffi::c_char;

/// What a call did: [`CalibStatus::Ok`] or why it did nothing useful. Outputs are written only on
/// `Ok` (except where a function says otherwise).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CalibStatus {
    /// Success.
    Ok = 0,
    /// A required pointer argument is NULL.
    NullPointer = 1,
    /// A pointer argument is not aligned for its type.
    Misaligned = 2,
    /// A model or robot argument was not filled by a successful decode or load.
    NotInitialised = 3,
    /// A joint value or pose is not finite.
    NonFinite = 4,
    /// A pose's rotation matrix is not a rotation (orthonormal, determinant +1) within tolerance.
    NotARotation = 5,
    /// A buffer is shorter than the block.
    BufferTooSmall = 10,
    /// No parameter block (bad magic number: empty or foreign flash).
    BadMagic = 11,
    /// The block was written by an unknown format version.
    UnsupportedVersion = 12,
    /// The block holds the other scalar type (f32 against f64).
    WrongScalar = 13,
    /// The block is for a robot with another joint count than `CALIB_JOINTS`.
    WrongJointCount = 14,
    /// The block's maps have more harmonics than `CALIB_HARMONICS`.
    TooManyHarmonics = 15,
    /// The block holds sections this library does not know.
    UnknownSections = 16,
    /// The block's checksum does not match (damaged or incompletely written).
    BadChecksum = 17,
    /// The block or model holds an invalid model (a value not finite, reversed limits).
    InvalidModel = 18,
    /// The caller's flash driver reported a failure.
    FlashWrite = 19,
    /// The compensation did not reach its tolerance within the iteration cap.
    NoConvergence = 20,
    /// The compensated joints would leave a joint's limits (the result names the joint).
    JointLimit = 21,
    /// The correction is larger than the settings allow.
    CorrectionTooLarge = 22,
    /// The configuration is too close to a singularity.
    NearSingular = 23,
    /// The model could not be evaluated at the joints.
    Kinematics = 24,
    /// Closed-form inverse kinematics does not cover this robot's geometry.
    UnsupportedGeometry = 30,
    /// No inverse kinematics branch reaches the target.
    Unreachable = 31,
}

impl CalibStatus {
    /// Every status, for the message table.
    const ALL: [CalibStatus; 23] = [
        Self::Ok,
        Self::NullPointer,
        Self::Misaligned,
        Self::NotInitialised,
        Self::NonFinite,
        Self::NotARotation,
        Self::BufferTooSmall,
        Self::BadMagic,
        Self::UnsupportedVersion,
        Self::WrongScalar,
        Self::WrongJointCount,
        Self::TooManyHarmonics,
        Self::UnknownSections,
        Self::BadChecksum,
        Self::InvalidModel,
        Self::FlashWrite,
        Self::NoConvergence,
        Self::JointLimit,
        Self::CorrectionTooLarge,
        Self::NearSingular,
        Self::Kinematics,
        Self::UnsupportedGeometry,
        Self::Unreachable,
    ];

    /// A sentence saying what went wrong and what to do.
    pub fn message(self) -> &'static core::ffi::CStr {
        match self {
            Self::Ok => c"success",
            Self::NullPointer => c"a required pointer argument is NULL",
            Self::Misaligned => c"a pointer argument is not aligned for its type",
            Self::NotInitialised => {
                c"the model or robot was not filled by a successful decode or load call"
            }
            Self::NonFinite => c"a joint value or pose is not finite",
            Self::NotARotation => {
                c"the pose's rotation is not a rotation matrix (row-major, orthonormal, determinant +1)"
            }
            Self::BufferTooSmall => c"the buffer is shorter than the parameter block",
            Self::BadMagic => c"no parameter block here (bad magic number: empty or foreign flash)",
            Self::UnsupportedVersion => c"the block was written by an unknown format version",
            Self::WrongScalar => c"the block holds the other scalar type (f32 against f64)",
            Self::WrongJointCount => c"the block is for a robot with another joint count",
            Self::TooManyHarmonics => {
                c"the block's maps have more harmonics than this library holds (CALIB_HARMONICS)"
            }
            Self::UnknownSections => c"the block holds sections this library does not know",
            Self::BadChecksum => c"the block's checksum does not match (damaged or incomplete)",
            Self::InvalidModel => c"the block holds an invalid model (value not finite or limits reversed)",
            Self::FlashWrite => c"the flash driver reported a write failure",
            Self::NoConvergence => c"compensation did not converge within the iteration cap",
            Self::JointLimit => c"the compensated joints would leave a joint's limits",
            Self::CorrectionTooLarge => c"the correction is larger than the settings allow",
            Self::NearSingular => c"the configuration is too close to a singularity",
            Self::Kinematics => c"the model could not be evaluated at these joints",
            Self::UnsupportedGeometry => {
                c"closed-form inverse kinematics covers spherical-wrist and UR-type 6-joint robots only"
            }
            Self::Unreachable => c"no inverse kinematics branch reaches the target",
        }
    }
}

impl From<StorageError> for CalibStatus {
    fn from(e: StorageError) -> Self {
        match e {
            StorageError::BufferTooSmall => Self::BufferTooSmall,
            StorageError::BadMagic => Self::BadMagic,
            StorageError::UnsupportedVersion(_) => Self::UnsupportedVersion,
            StorageError::WrongScalar(_) => Self::WrongScalar,
            StorageError::WrongJointCount(_) => Self::WrongJointCount,
            StorageError::TooManyHarmonics(_) => Self::TooManyHarmonics,
            StorageError::UnknownSections(_) => Self::UnknownSections,
            StorageError::BadChecksum => Self::BadChecksum,
            StorageError::Flash => Self::FlashWrite,
            _ => Self::InvalidModel,
        }
    }
}

impl From<CompensationError> for CalibStatus {
    fn from(e: CompensationError) -> Self {
        match e {
            CompensationError::NonFinite => Self::NonFinite,
            CompensationError::NoConvergence => Self::NoConvergence,
            CompensationError::JointLimit(_) => Self::JointLimit,
            CompensationError::CorrectionTooLarge => Self::CorrectionTooLarge,
            CompensationError::NearSingular => Self::NearSingular,
            _ => Self::Kinematics,
        }
    }
}

impl From<IkError> for CalibStatus {
    fn from(e: IkError) -> Self {
        match e {
            IkError::UnsupportedGeometry => Self::UnsupportedGeometry,
            IkError::NonFinite => Self::NonFinite,
            _ => Self::InvalidModel,
        }
    }
}

/// The message of `status` (a NUL-terminated sentence in static memory; "unknown status" for a
/// value that is no [`CalibStatus`]). Never NULL.
#[unsafe(no_mangle)]
pub extern "C" fn calib_status_message(status: i32) -> *const c_char {
    CalibStatus::ALL
        .iter()
        .find(|s| **s as i32 == status)
        .map_or(c"unknown status", |s| s.message())
        .as_ptr()
}

/// Runs a call's body and turns its result into the status it returns.
pub(crate) fn status(body: impl FnOnce() -> Result<(), CalibStatus>) -> CalibStatus {
    match body() {
        Ok(()) => CalibStatus::Ok,
        Err(e) => e,
    }
}
