//! Parameter blocks: decoding, loading the newest valid block of two slots (A/B), and writing a
//! model to the older slot through the caller's flash driver (the rule of
//! `calib_core::controller::storage`: an interrupted write can only damage the older copy).

use crate::access;
use crate::model::{
    CALIB_JOINTS, CalibModelF32, CalibModelF64, CalibRobotF32, CalibRobotF64, IdentifiedModel,
    NominalRobot, Opaque,
};
use crate::status::{CalibStatus, status};
use calib_core::Real;
use calib_core::controller::storage::{
    FlashSlots, Slot, Source, StorageError, decode, decode_model_into, load_model_into, store,
};
use core::ffi::c_void;
use nalgebra::Const;

/// A parameter slot, or the nominal model when no slot holds a valid block.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CalibSlot {
    /// No slot: the nominal robot without maps.
    Nominal = 0,
    /// Slot A.
    A = 1,
    /// Slot B.
    B = 2,
}

/// Where a loaded model came from, or where a model was written.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CalibSource {
    /// The slot.
    pub slot: CalibSlot,
    /// `true` when the other slot holds a newer block that is damaged (its write did not
    /// complete): the model is the previous one. Report it; store again.
    pub fallback: bool,
    /// The block's sequence number (0 for the nominal model).
    pub sequence: u32,
}

impl From<Source> for CalibSource {
    fn from(source: Source) -> Self {
        let slot = |s| match s {
            Slot::A => CalibSlot::A,
            Slot::B => CalibSlot::B,
        };
        match source {
            Source::Newest(s, sequence) => Self {
                slot: slot(s),
                fallback: false,
                sequence,
            },
            Source::Fallback(s, sequence) => Self {
                slot: slot(s),
                fallback: true,
                sequence,
            },
            Source::Nominal => Self {
                slot: CalibSlot::Nominal,
                fallback: false,
                sequence: 0,
            },
        }
    }
}

/// The caller's flash driver: writes `len` bytes of `data` to the start of `slot` (erasing it as
/// the flash needs) and returns 0 on success, anything else on failure. `context` is the pointer
/// the caller passed to [`calib_model_store_f32`].
pub type CalibFlashWrite = Option<
    unsafe extern "C" fn(context: *mut c_void, slot: CalibSlot, data: *const u8, len: usize) -> i32,
>;

/// The caller's two slots, read through raw pointers so that no borrow of them is alive while
/// the caller's driver writes one.
struct CallerSlots {
    a: (*const u8, usize),
    b: (*const u8, usize),
    write: CalibFlashWrite,
    context: *mut c_void,
}

impl CallerSlots {
    /// # Safety
    /// Each slot pointer is NULL or points to its length of readable bytes.
    unsafe fn new(
        a: (*const u8, usize),
        b: (*const u8, usize),
        write: CalibFlashWrite,
        context: *mut c_void,
    ) -> Result<Self, CalibStatus> {
        // SAFETY: the caller's contract; the borrows end here.
        unsafe {
            access::bytes(a.0, a.1)?;
            access::bytes(b.0, b.1)?;
        }
        Ok(Self {
            a,
            b,
            write,
            context,
        })
    }
}

impl FlashSlots for CallerSlots {
    fn read(&self, slot: Slot) -> &[u8] {
        let (p, len) = match slot {
            Slot::A => self.a,
            Slot::B => self.b,
        };
        // SAFETY: checked non-NULL in `new`; readable by the caller's contract, and only the
        // caller's driver (never during this borrow) writes it.
        unsafe { core::slice::from_raw_parts(p, len) }
    }

    fn write(&mut self, slot: Slot, data: &[u8]) -> Result<(), StorageError> {
        let Some(write) = self.write else {
            return Err(StorageError::Flash);
        };
        let slot = match slot {
            Slot::A => CalibSlot::A,
            Slot::B => CalibSlot::B,
        };
        // SAFETY: the caller's driver, given the caller's context and our scratch buffer.
        match unsafe { write(self.context, slot, data.as_ptr(), data.len()) } {
            0 => Ok(()),
            _ => Err(StorageError::Flash),
        }
    }
}

/// # Safety
/// See [`calib_robot_decode_f32`].
unsafe fn decode_robot<T: Real, O: Opaque<Value = NominalRobot<T>>>(
    robot: *mut O,
    block: *const u8,
    len: usize,
) -> Result<(), CalibStatus> {
    // SAFETY: the caller's contract (cleared first: on an error the robot is not filled).
    let value = unsafe { access::cleared(robot) }?;
    // SAFETY: the caller's contract.
    let (decoded, _) = decode::<T, Const<CALIB_JOINTS>>(unsafe { access::bytes(block, len) }?)?;
    value.set(&decoded)?;
    // SAFETY: filled above.
    unsafe { access::mark_filled(robot) };
    Ok(())
}

/// # Safety
/// See [`calib_model_decode_f32`].
unsafe fn decode_model<T: Real, O>(
    model: *mut O,
    block: *const u8,
    len: usize,
    sequence: *mut u32,
) -> Result<(), CalibStatus>
where
    O: Opaque<Value = IdentifiedModel<T>>,
{
    // SAFETY: the caller's contract.
    let bytes = unsafe { access::bytes(block, len) }?;
    // SAFETY: the caller's contract.
    let value = unsafe { access::cleared(model) }?;
    let s = decode_model_into(bytes, &mut value.model)?;
    value.prepare()?;
    // SAFETY: filled above.
    unsafe { access::mark_filled(model) };
    if !sequence.is_null() {
        // SAFETY: the caller's contract.
        unsafe { access::write(sequence, s) }?;
    }
    Ok(())
}

/// # Safety
/// See [`calib_model_load_f32`].
unsafe fn load<T: Real, O, R>(
    model: *mut O,
    slots: &CallerSlots,
    nominal: *const R,
    source: *mut CalibSource,
) -> Result<(), CalibStatus>
where
    O: Opaque<Value = IdentifiedModel<T>>,
    R: Opaque<Value = NominalRobot<T>>,
{
    // SAFETY: the caller's contract (a copy: `model` may not point into `nominal`).
    let nominal = unsafe { access::filled(nominal) }?.robot;
    // SAFETY: the caller's contract.
    let value = unsafe { access::cleared(model) }?;
    let loaded = load_model_into(slots, &nominal, &mut value.model);
    value.prepare()?;
    // SAFETY: filled above (by a block or the nominal robot).
    unsafe { access::mark_filled(model) };
    if !source.is_null() {
        // SAFETY: the caller's contract.
        unsafe { access::write(source, loaded.into()) }?;
    }
    Ok(())
}

/// # Safety
/// See [`calib_model_store_f32`].
unsafe fn store_model<T: Real, O>(
    model: *const O,
    slots: &mut CallerSlots,
    scratch: *mut u8,
    scratch_len: usize,
    written: *mut CalibSource,
) -> Result<(), CalibStatus>
where
    O: Opaque<Value = IdentifiedModel<T>>,
{
    // SAFETY: the caller's contract.
    let value = unsafe { access::filled(model) }?;
    // SAFETY: the caller's contract.
    let buffer = unsafe { access::bytes_mut(scratch, scratch_len) }?;
    if slots.write.is_none() {
        return Err(CalibStatus::NullPointer);
    }
    let (slot, sequence) = store(slots, &value.model, buffer)?;
    if !written.is_null() {
        // SAFETY: the caller's contract.
        unsafe { access::write(written, Source::Newest(slot, sequence).into()) }?;
    }
    Ok(())
}

/// Fills `robot` with the nominal robot of a version 1 block (`calib export --format block
/// --scalar f32` of the robot file) of `len` bytes at `block`.
///
/// # Safety
/// `robot` points to a writable [`CalibRobotF32`]; `block` to `len` readable bytes; they do not
/// overlap. On an error `robot` is left not filled.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_robot_decode_f32(
    robot: *mut CalibRobotF32,
    block: *const u8,
    len: usize,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe { decode_robot(robot, block, len) })
}

/// [`calib_robot_decode_f32`] for an f64 block.
///
/// # Safety
/// As [`calib_robot_decode_f32`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_robot_decode_f64(
    robot: *mut CalibRobotF64,
    block: *const u8,
    len: usize,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe { decode_robot(robot, block, len) })
}

/// Fills `model` from a block of `len` bytes at `block` (version 1: geometry; version 2: with
/// angle-error maps of up to `CALIB_HARMONICS` harmonics and gravity compliance), for a block
/// received from the host before it is stored; writes its sequence number to `sequence` unless
/// that is NULL.
///
/// # Safety
/// `model` points to a writable [`CalibModelF32`]; `block` to `len` readable bytes; `sequence` is
/// NULL or writable; none overlap. On an error `model` is left not filled.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_model_decode_f32(
    model: *mut CalibModelF32,
    block: *const u8,
    len: usize,
    sequence: *mut u32,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe { decode_model(model, block, len, sequence) })
}

/// [`calib_model_decode_f32`] for an f64 block.
///
/// # Safety
/// As [`calib_model_decode_f32`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_model_decode_f64(
    model: *mut CalibModelF64,
    block: *const u8,
    len: usize,
    sequence: *mut u32,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe { decode_model(model, block, len, sequence) })
}

/// Fills `model` with the newest valid block of the two slots (`len_a` bytes at `slot_a`,
/// `len_b` at `slot_b`, each at least the block's length), falling back to the other slot and
/// then to `nominal` without maps; writes where it came from to `source` unless that is NULL.
/// Cost on a Cortex-M4F: see the C firmware's table (`firmware-c/README.md`).
///
/// # Safety
/// `model` points to a writable [`CalibModelF32`], `nominal` to a filled [`CalibRobotF32`], the
/// slots to readable bytes, `source` is NULL or writable; none overlap.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_model_load_f32(
    model: *mut CalibModelF32,
    slot_a: *const u8,
    len_a: usize,
    slot_b: *const u8,
    len_b: usize,
    nominal: *const CalibRobotF32,
    source: *mut CalibSource,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        let slots = CallerSlots::new(
            (slot_a, len_a),
            (slot_b, len_b),
            None,
            core::ptr::null_mut(),
        )?;
        load(model, &slots, nominal, source)
    })
}

/// [`calib_model_load_f32`] in f64.
///
/// # Safety
/// As [`calib_model_load_f32`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn calib_model_load_f64(
    model: *mut CalibModelF64,
    slot_a: *const u8,
    len_a: usize,
    slot_b: *const u8,
    len_b: usize,
    nominal: *const CalibRobotF64,
    source: *mut CalibSource,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        let slots = CallerSlots::new(
            (slot_a, len_a),
            (slot_b, len_b),
            None,
            core::ptr::null_mut(),
        )?;
        load(model, &slots, nominal, source)
    })
}

/// Writes `model` as a block to the slot that does not hold the newest valid block, with the
/// next sequence number, through the caller's flash driver `write` (given `context`), encoding it
/// in `scratch` (`scratch_len` bytes, at least `CALIB_BLOCK_MAX_BYTES_F32`); writes the slot and
/// sequence number to `written` unless that is NULL. An interrupted write leaves the previous
/// block loadable.
///
/// # Safety
/// `model` points to a filled [`CalibModelF32`]; the slots to readable bytes that only `write`
/// changes; `scratch` to `scratch_len` writable bytes; `write` is a function of the
/// [`CalibFlashWrite`] contract; `written` is NULL or writable; none overlap.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // the C signature: two slots, scratch, driver, context
pub unsafe extern "C" fn calib_model_store_f32(
    model: *const CalibModelF32,
    slot_a: *const u8,
    len_a: usize,
    slot_b: *const u8,
    len_b: usize,
    scratch: *mut u8,
    scratch_len: usize,
    write: CalibFlashWrite,
    context: *mut c_void,
    written: *mut CalibSource,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        let mut slots = CallerSlots::new((slot_a, len_a), (slot_b, len_b), write, context)?;
        store_model(model, &mut slots, scratch, scratch_len, written)
    })
}

/// [`calib_model_store_f32`] in f64 (`scratch_len` at least `CALIB_BLOCK_MAX_BYTES_F64`).
///
/// # Safety
/// As [`calib_model_store_f32`].
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // the C signature: two slots, scratch, driver, context
pub unsafe extern "C" fn calib_model_store_f64(
    model: *const CalibModelF64,
    slot_a: *const u8,
    len_a: usize,
    slot_b: *const u8,
    len_b: usize,
    scratch: *mut u8,
    scratch_len: usize,
    write: CalibFlashWrite,
    context: *mut c_void,
    written: *mut CalibSource,
) -> CalibStatus {
    // SAFETY: forwarded contract.
    status(|| unsafe {
        let mut slots = CallerSlots::new((slot_a, len_a), (slot_b, len_b), write, context)?;
        store_model(model, &mut slots, scratch, scratch_len, written)
    })
}
