//! Checked access to the caller's memory: every pointer is tested for NULL and alignment before
//! it is read or written, and an opaque robot or model only after it was filled.

use crate::model::{Opaque, Tagged};
use crate::status::CalibStatus;
use calib_core::Real;
use calib_core::kinematics::Pose;
use nalgebra::{Matrix3, Rotation3, Translation3};

fn check<T>(p: *const T) -> Result<(), CalibStatus> {
    if p.is_null() {
        Err(CalibStatus::NullPointer)
    } else if !p.addr().is_multiple_of(core::mem::align_of::<T>()) {
        Err(CalibStatus::Misaligned)
    } else {
        Ok(())
    }
}

/// Reads a plain value the caller passed by pointer.
///
/// # Safety
/// `p` is NULL or points to a readable `T` (checked here: NULL and alignment).
pub(crate) unsafe fn read<T: Copy>(p: *const T) -> Result<T, CalibStatus> {
    check(p)?;
    // SAFETY: not NULL, aligned, readable by the caller's contract.
    Ok(unsafe { p.read() })
}

/// Writes a plain value to the caller's pointer.
///
/// # Safety
/// `p` is NULL or points to writable memory for a `T` (checked here: NULL and alignment).
pub(crate) unsafe fn write<T>(p: *mut T, value: T) -> Result<(), CalibStatus> {
    check(p)?;
    // SAFETY: not NULL, aligned, writable by the caller's contract.
    unsafe { p.write(value) };
    Ok(())
}

/// The caller's bytes `[p, p + len)`.
///
/// # Safety
/// `p` is NULL or points to `len` readable bytes that are not written during the call.
pub(crate) unsafe fn bytes<'a>(p: *const u8, len: usize) -> Result<&'a [u8], CalibStatus> {
    check(p)?;
    // SAFETY: not NULL, readable for `len` bytes by the caller's contract.
    Ok(unsafe { core::slice::from_raw_parts(p, len) })
}

/// The caller's writable bytes `[p, p + len)`.
///
/// # Safety
/// `p` is NULL or points to `len` writable bytes no other argument points into.
pub(crate) unsafe fn bytes_mut<'a>(p: *mut u8, len: usize) -> Result<&'a mut [u8], CalibStatus> {
    check(p)?;
    // SAFETY: not NULL, writable for `len` bytes by the caller's contract.
    Ok(unsafe { core::slice::from_raw_parts_mut(p, len) })
}

/// The value of a filled opaque robot or model.
///
/// # Safety
/// `p` is NULL or points to the caller's `O` (its bytes initialised: static or written by us).
pub(crate) unsafe fn filled<'a, O: Opaque>(p: *const O) -> Result<&'a O::Value, CalibStatus> {
    check(p)?;
    let tagged = p.cast::<Tagged<O::Value>>();
    // SAFETY: `O` holds a `Tagged<O::Value>` (size and alignment asserted in `model`); the tag is
    // a plain u64.
    if unsafe { (*tagged).tag } != O::TAG {
        return Err(CalibStatus::NotInitialised);
    }
    // SAFETY: a matching tag is written only after the value (plain numbers, every bit pattern
    // valid) was.
    Ok(unsafe { &(*tagged).value })
}

/// Clears an opaque robot or model to zero (marked not filled) and lends its value for filling;
/// [`mark_filled`] marks it filled afterwards.
///
/// # Safety
/// `p` is NULL or points to the caller's writable `O` that no other argument points into.
pub(crate) unsafe fn cleared<'a, O: Opaque>(p: *mut O) -> Result<&'a mut O::Value, CalibStatus> {
    check(p.cast_const())?;
    // As 32-bit words: the compiler clears them with `__aeabi_memclr4`, which the library links
    // anyway, instead of linking `__aeabi_memclr8` as well for the 8-aligned `O` (174 bytes).
    let words = core::mem::size_of::<O>() / 4;
    // SAFETY: writable `O`, at least 4-aligned and a whole number of 32-bit words (asserted for
    // every opaque type in `model`), so `words` aligned u32 cover it exactly; all-zero bytes are
    // a valid value (plain numbers) and no valid tag.
    unsafe { p.cast::<u32>().write_bytes(0, words) };
    let tagged = p.cast::<Tagged<O::Value>>();
    // SAFETY: as in `filled`; the value's bytes are now initialised.
    Ok(unsafe { &mut (*tagged).value })
}

/// Marks a value lent by [`cleared`] as filled.
///
/// # Safety
/// `p` was passed to [`cleared`] and the value was completely written.
pub(crate) unsafe fn mark_filled<O: Opaque>(p: *mut O) {
    // SAFETY: checked by `cleared`.
    unsafe { (*p.cast::<Tagged<O::Value>>()).tag = O::TAG };
}

/// Joint values, `CALIB_JOINTS` of them, checked finite.
///
/// # Safety
/// As [`read`], for `CALIB_JOINTS` values.
pub(crate) unsafe fn joints<T: Real, const N: usize>(p: *const T) -> Result<[T; N], CalibStatus> {
    // SAFETY: the caller's contract.
    let q = unsafe { read(p.cast::<[T; N]>()) }?;
    if q.iter().all(|v| v.finite()) {
        Ok(q)
    } else {
        Err(CalibStatus::NonFinite)
    }
}

/// A pose from the caller's [`crate::CalibPose`], checked finite and a rotation within
/// `tolerance` (largest element of `R^T R - I`; determinant positive).
pub(crate) fn pose<T: Real>(
    pose: &crate::CalibPose<T>,
    tolerance: T,
) -> Result<Pose<T>, CalibStatus> {
    if !pose
        .position_mm
        .iter()
        .chain(&pose.rotation)
        .all(|v| v.finite())
    {
        return Err(CalibStatus::NonFinite);
    }
    let m = Matrix3::from_row_slice(&pose.rotation);
    let deviation = (m.transpose() * m - Matrix3::identity()).amax();
    if deviation > tolerance || m.determinant() <= T::zero() {
        return Err(CalibStatus::NotARotation);
    }
    let [x, y, z] = pose.position_mm;
    Ok(Pose::from_parts(
        Translation3::new(x, y, z),
        Rotation3::from_matrix_unchecked(m),
    ))
}

/// The caller's [`crate::CalibPose`] of a pose.
pub(crate) fn to_c<T: Real>(pose: &Pose<T>) -> crate::CalibPose<T> {
    let m = pose.rotation.matrix();
    crate::CalibPose {
        position_mm: [pose.translation.x, pose.translation.y, pose.translation.z],
        rotation: [
            m.m11, m.m12, m.m13, m.m21, m.m22, m.m23, m.m31, m.m32, m.m33,
        ],
    }
}
