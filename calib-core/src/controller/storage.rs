//! The persistent parameter block of the controller, and two-slot (A/B) storage that survives a
//! power loss during an update.
//!
//! Two versions, explicit little-endian, the same on every target (offsets in bytes; `S` = 4 for
//! f32, 8 for f64). Version 1 holds the geometry ([`encode`], [`decode`]); version 2 the geometry,
//! each joint's angle-error map and, when the model has it, the gravity compliance
//! ([`encode_model`]; [`decode_model`] reads both versions, a version 1 block as maps that are
//! zero and no compliance):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `CALB` (0x42 4C 41 43 read as u32 LE: 0x424C_4143) |
//! | 4 | 2 | format version (1 or 2) |
//! | 6 | 1 | scalar type: 4 = f32, 8 = f64 |
//! | 7 | 1 | joint count N |
//! | 8 | 4 | sequence number (wrapping; the newer of two blocks has the larger one) |
//! | 12 | 4 | version 2 only: harmonics per map `H` (u16), then the sections (u16): bit 0 set when the compliance section follows the maps, the other bits 0 |
//! | 12 or 16 | S (7N + 12) | the geometry: per joint a, alpha, theta_offset, d, beta (mm, rad), then per joint lower, upper limit (rad), then base xyz (mm) rpy (rad), then tool xyz rpy |
//! | then | S 2NH | version 2 only: per joint the map's `a_1..a_H` (sin) then `b_1..b_H` (cos), rad |
//! | then | S (7N + 7) | version 2 with bit 0 only: gravity xyz (m/s^2, base frame), per link mass (kg) and centre xyz (mm), the flange load's mass and centre, per joint the gains tilt x, tilt y, torsion (urad per N m) ([`Compliance`]) |
//! | end - 4 | 4 | CRC-32 (IEEE 802.3, reflected, as zlib) of all bytes before it |
//!
//! A block's length is fixed by its scalar, joint count, `H` and the sections ([`block_len`],
//! [`model_block_len`]); a controller built with room for `C` harmonics reads blocks with any
//! `H <= C`. Six joints in f32 with 64 harmonics: 3,308 bytes, 3,504 with compliance.
//!
//! Two slots: [`store`] writes to the slot that does not hold the newest valid block, with the
//! next sequence number, so an interrupted write can only damage the older copy. [`load`] takes the
//! newest valid slot, falls back to the other, then to the nominal model, and says which it used.
//! Both work with either content ([`Stored`]: a [`Robot`] or a [`ControllerModel`]).

use crate::KinematicsError;
use crate::kinematics::MappedKinematics;
use crate::model::compliance::Compliance;
use crate::model::joint_maps::JointMaps;
use crate::model::parameters::ParameterErrors;
use crate::model::{JointCount, JointTable};
use crate::model::{MdhJoint, Robot};
use crate::scalar::Real;
use core::fmt;

/// `CALB` as a little-endian u32.
pub const MAGIC: u32 = u32::from_le_bytes(*b"CALB");
/// Format version of a geometry block ([`encode`]).
pub const VERSION: u16 = 1;
/// Format version of a block with angle-error maps ([`encode_model`]).
pub const VERSION_MAPS: u16 = 2;
const HEADER: usize = 12;
/// Version 2's header: [`HEADER`], harmonics (u16) and sections (u16).
const HEADER_MAPS: usize = 16;
/// Version 2's sections bit: the compliance section follows the maps.
const SECTION_COMPLIANCE: u16 = 1;

/// Bytes of a version 1 (geometry) block for scalar `T` and `joints` joints.
pub const fn block_len<T: Real>(joints: usize) -> usize {
    HEADER + (7 * joints + 12) * T::BYTES + 4
}

/// Bytes of a version 2 block (geometry, maps of `harmonics` harmonics and, if `compliance`, the
/// compliance section) for scalar `T` and `joints` joints.
pub const fn model_block_len<T: Real>(joints: usize, harmonics: usize, compliance: bool) -> usize {
    let compliance_values = if compliance { 7 * joints + 7 } else { 0 };
    HEADER_MAPS + (7 * joints + 12 + 2 * joints * harmonics + compliance_values) * T::BYTES + 4
}

/// What the controller compensates with: the identified geometry, each joint's angle-error map
/// (`C` harmonics of room) and the gravity compliance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControllerModel<T: Real, N: JointCount, const C: usize> {
    /// The geometry (nominal values with the identified errors applied, limits, frames).
    pub robot: Robot<T, N>,
    /// The angle-error maps (zero for a geometric calibration).
    pub maps: JointMaps<T, N, C>,
    /// The gravity compliance (no gains for a model without it).
    pub compliance: Compliance<T, N>,
}

impl<T: Real, N: JointCount, const C: usize> ControllerModel<T, N, C> {
    /// A model without maps.
    pub fn geometric(robot: Robot<T, N>) -> Self {
        let joints = robot.joint_count();
        Self {
            robot,
            maps: JointMaps::zeros_for(joints),
            compliance: Compliance::none_for(joints),
        }
    }

    /// Makes this the model without maps of `robot`, in place ([`ControllerModel::geometric`]
    /// without a temporary of the model's size on the stack).
    pub fn set_geometric(&mut self, robot: &Robot<T, N>) {
        self.robot = *robot;
        self.maps.clear();
        self.compliance = Compliance::none_for(robot.joint_count());
    }

    /// The model ready to evaluate and compensate with (borrowing the maps and compliance).
    /// Error: an invalid geometry or compliance.
    pub fn kinematics(&self) -> Result<MappedKinematics<'_, T, N, C>, KinematicsError> {
        let errors = ParameterErrors::zeros_for(self.robot.joint_count());
        MappedKinematics::new(&self.robot, &errors, &self.maps)?.with_compliance(&self.compliance)
    }
}

/// Why a block could not be written or read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum StorageError {
    /// The buffer is shorter than [`block_len`].
    BufferTooSmall,
    /// The bytes do not start with the magic number (empty or foreign flash).
    BadMagic,
    /// The block was written by an unknown format version.
    UnsupportedVersion(u16),
    /// The block holds another scalar type (4 = f32, 8 = f64).
    WrongScalar(u8),
    /// The block is for a robot with another joint count.
    WrongJointCount(u8),
    /// The block's maps have more harmonics than this build has room for.
    TooManyHarmonics(u16),
    /// The block holds sections (bits of its header) this build does not know.
    UnknownSections(u16),
    /// The checksum does not match: the block is damaged or was not completely written.
    BadChecksum,
    /// The model is invalid (non-finite value or reversed limits; the cause names it).
    InvalidModel(KinematicsError),
    /// The flash driver reported a failure.
    Flash,
}

impl fmt::Display for StorageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::BufferTooSmall => f.write_str("buffer shorter than a parameter block"),
            Self::BadMagic => f.write_str("no parameter block (bad magic number)"),
            Self::UnsupportedVersion(v) => write!(f, "unsupported block format version {v}"),
            Self::WrongScalar(s) => write!(f, "block holds {s}-byte scalars"),
            Self::WrongJointCount(n) => write!(f, "block is for a {n}-joint robot"),
            Self::TooManyHarmonics(h) => {
                write!(
                    f,
                    "block holds maps of {h} harmonics, more than this build holds"
                )
            }
            Self::UnknownSections(s) => {
                write!(f, "block holds sections {s:#06x} this build does not know")
            }
            Self::BadChecksum => f.write_str("block checksum mismatch (damaged or incomplete)"),
            Self::InvalidModel(e) => write!(f, "block holds an invalid model: {e}"),
            Self::Flash => f.write_str("flash write failed"),
        }
    }
}

impl core::error::Error for StorageError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::InvalidModel(e) => Some(e),
            _ => None,
        }
    }
}

/// CRC-32 (IEEE 802.3, reflected polynomial 0xEDB88320, init and final xor 0xFFFFFFFF), bitwise.
pub(crate) fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for byte in bytes {
        crc ^= u32::from(*byte);
        for _ in 0..8 {
            let mask = (crc & 1).wrapping_neg();
            crc = (crc >> 1) ^ (0xEDB8_8320 & mask);
        }
    }
    !crc
}

/// Writes `robot` with `sequence` as a version 1 block into `out`; returns the number of bytes
/// written. A model that [`decode`] would reject (a value not finite, such as an f64 value beyond
/// the f32 range rounded to infinity) is refused with [`StorageError::InvalidModel`] and nothing is
/// written.
pub fn encode<T: Real, N: JointCount>(
    robot: &Robot<T, N>,
    sequence: u32,
    out: &mut [u8],
) -> Result<usize, StorageError> {
    write_block(robot, sequence, None, out, |_| {})
}

/// Writes `model` (geometry and maps) with `sequence` as a version 2 block into `out`, with the
/// maps' used harmonics ([`model_block_len`] bytes); returns the number of bytes written. Refused
/// as [`encode`] refuses.
pub fn encode_model<T: Real, N: JointCount, const C: usize>(
    model: &ControllerModel<T, N, C>,
    sequence: u32,
    out: &mut [u8],
) -> Result<usize, StorageError> {
    let harmonics = model.maps.harmonics();
    let stored = u16::try_from(harmonics).map_err(|_| StorageError::TooManyHarmonics(u16::MAX))?;
    model
        .compliance
        .validate()
        .map_err(StorageError::InvalidModel)?;
    let compliance = model.compliance.is_active();
    let sections = if compliance { SECTION_COMPLIANCE } else { 0 };
    write_block(
        &model.robot,
        sequence,
        Some((stored, sections)),
        out,
        |writer| {
            for j in 0..model.robot.joints.len() {
                let (Some(sin), Some(cos)) = (
                    model.maps.sin_coefficients(j),
                    model.maps.cos_coefficients(j),
                ) else {
                    continue;
                };
                for v in sin.iter().take(harmonics).chain(cos.iter().take(harmonics)) {
                    writer.put(*v);
                }
            }
            if compliance {
                let mut copy = model.compliance;
                for v in copy.values_mut() {
                    writer.put(*v);
                }
            }
        },
    )
}

/// Header, geometry, what `write_maps` writes, CRC; version 2 when `harmonics` and sections are
/// given.
fn write_block<T: Real, N: JointCount>(
    robot: &Robot<T, N>,
    sequence: u32,
    harmonics: Option<(u16, u16)>,
    out: &mut [u8],
    write_maps: impl FnOnce(&mut Cursor<&mut [u8]>),
) -> Result<usize, StorageError> {
    robot.validate().map_err(StorageError::InvalidModel)?;
    let (len, version) = match harmonics {
        None => (block_len::<T>(robot.joints.len()), VERSION),
        Some((h, sections)) => (
            model_block_len::<T>(
                robot.joints.len(),
                usize::from(h),
                sections & SECTION_COMPLIANCE != 0,
            ),
            VERSION_MAPS,
        ),
    };
    let block = out.get_mut(..len).ok_or(StorageError::BufferTooSmall)?;
    let joints =
        u8::try_from(robot.joints.len()).map_err(|_| StorageError::WrongJointCount(u8::MAX))?;
    let mut writer = Cursor {
        bytes: &mut *block,
        at: 0,
    };
    writer.put_bytes(&MAGIC.to_le_bytes());
    writer.put_bytes(&version.to_le_bytes());
    writer.put_bytes(&[T::BYTES as u8, joints]);
    writer.put_bytes(&sequence.to_le_bytes());
    if let Some((h, sections)) = harmonics {
        writer.put_bytes(&h.to_le_bytes());
        writer.put_bytes(&sections.to_le_bytes());
    }
    for_each_value(robot, |v| writer.put(v));
    write_maps(&mut writer);
    let body = writer.at;
    let crc = crc32(block.get(..body).unwrap_or(&[]));
    block
        .get_mut(body..body + 4)
        .ok_or(StorageError::BufferTooSmall)?
        .copy_from_slice(&crc.to_le_bytes());
    Ok(len)
}

/// A checked block: its harmonics (0 for version 1), sections (0 for version 1), sequence number
/// and the bytes of its values (between the header and the CRC).
struct OpenBlock<'a, N> {
    joints: N,
    harmonics: u16,
    sections: u16,
    sequence: u32,
    values: &'a [u8],
}

/// Checks magic, version, scalar, joint count, length and CRC of the block at the start of
/// `bytes`; version 2 only with room for its harmonics (`capacity`, `None`: version 1 only).
#[inline(always)]
fn open_block<T: Real, N: JointCount>(
    bytes: &[u8],
    capacity: Option<usize>,
) -> Result<OpenBlock<'_, N>, StorageError> {
    let u16_at = |at: usize| -> Option<u16> {
        Some(u16::from_le_bytes(bytes.get(at..at + 2)?.try_into().ok()?))
    };
    let u32_at = |at: usize| -> Option<u32> {
        Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
    };
    let too_small = StorageError::BufferTooSmall;
    if u32_at(0).ok_or(too_small)? != MAGIC {
        return Err(StorageError::BadMagic);
    }
    let version = u16_at(4).ok_or(too_small)?;
    if version != VERSION && (version != VERSION_MAPS || capacity.is_none()) {
        return Err(StorageError::UnsupportedVersion(version));
    }
    let scalar = bytes.get(6).copied().ok_or(too_small)?;
    if usize::from(scalar) != T::BYTES {
        return Err(StorageError::WrongScalar(scalar));
    }
    let stored_joints = bytes.get(7).copied().ok_or(too_small)?;
    let joints = N::checked(usize::from(stored_joints))
        .ok_or(StorageError::WrongJointCount(stored_joints))?;
    // The count as the type has it: a constant where it is fixed (so are the lengths below).
    let count = joints.value();
    let (harmonics, sections, header, len) = if version == VERSION {
        (0, 0, HEADER, block_len::<T>(count))
    } else {
        let h = u16_at(12).ok_or(too_small)?;
        if capacity.is_none_or(|c| usize::from(h) > c) {
            return Err(StorageError::TooManyHarmonics(h));
        }
        let sections = u16_at(14).ok_or(too_small)?;
        if sections & !SECTION_COMPLIANCE != 0 {
            return Err(StorageError::UnknownSections(sections));
        }
        let compliance = sections & SECTION_COMPLIANCE != 0;
        let len = model_block_len::<T>(count, usize::from(h), compliance);
        (h, sections, HEADER_MAPS, len)
    };
    let body = len - 4;
    let stored_crc = u32_at(body).ok_or(too_small)?;
    let block = bytes.get(..body).ok_or(too_small)?;
    if crc32(block) != stored_crc {
        return Err(StorageError::BadChecksum);
    }
    Ok(OpenBlock {
        joints,
        harmonics,
        sections,
        sequence: u32_at(8).ok_or(too_small)?,
        values: block.get(header..).ok_or(too_small)?,
    })
}

/// Reads a version 1 block: the robot and its sequence number. A version 2 block is
/// [`StorageError::UnsupportedVersion`] here: read it with [`decode_model`].
pub fn decode<T: Real, N: JointCount>(bytes: &[u8]) -> Result<(Robot<T, N>, u32), StorageError> {
    let block = open_block::<T, N>(bytes, None)?;
    let mut reader = Cursor {
        bytes: block.values,
        at: 0,
    };
    Ok((read_robot(block.joints, &mut reader)?, block.sequence))
}

/// Reads a block of either version: the model (zero maps from a version 1 block) and its sequence
/// number. A block whose maps have more than `C` harmonics is
/// [`StorageError::TooManyHarmonics`]; maps that [`JointMaps::new`] or compliance that
/// [`Compliance::new`] refuses are [`StorageError::InvalidModel`]. On a controller prefer [`decode_model_into`] (no copies of
/// the maps on the stack).
pub fn decode_model<T: Real, N: JointCount, const C: usize>(
    bytes: &[u8],
) -> Result<(ControllerModel<T, N, C>, u32), StorageError> {
    let block = open_block::<T, N>(bytes, Some(C))?;
    let mut model = ControllerModel::geometric(zero_robot(block.joints));
    let sequence = read_model(&block, &mut model)?;
    Ok((model, sequence))
}

/// [`decode_model`] into `model`, in place; returns the sequence number. On an error `model` is
/// unchanged unless the block passed its checksum and its maps or compliance were refused (then
/// its maps are zero or its compliance none, and its geometry the block's).
pub fn decode_model_into<T: Real, N: JointCount, const C: usize>(
    bytes: &[u8],
    model: &mut ControllerModel<T, N, C>,
) -> Result<u32, StorageError> {
    read_model(&open_block::<T, N>(bytes, Some(C))?, model)
}

/// The model of an opened block into `model`, in place; its sequence number. Inlined: on a
/// controller it is [`decode_model_into`]'s body.
#[inline(always)]
fn read_model<T: Real, N: JointCount, const C: usize>(
    block: &OpenBlock<'_, N>,
    model: &mut ControllerModel<T, N, C>,
) -> Result<u32, StorageError> {
    let harmonics = usize::from(block.harmonics);
    let mut reader = Cursor {
        bytes: block.values,
        at: 0,
    };
    model.robot = read_robot(block.joints, &mut reader)?;
    // Per joint: a_1..a_H, then b_1..b_H.
    let maps_at = reader.at;
    let value = |joint: usize, index: usize| -> Option<T> {
        let at = maps_at + (joint * 2 * harmonics + index) * T::BYTES;
        T::read_le(block.values.get(at..)?)
    };
    model
        .maps
        .set(block.joints, harmonics, |j, h| {
            Some((value(j, h - 1)?, value(j, harmonics + h - 1)?))
        })
        .map_err(StorageError::InvalidModel)?;
    model.compliance = Compliance::none_for(block.joints);
    if block.sections & SECTION_COMPLIANCE != 0 {
        reader.at = maps_at + 2 * block.joints.value() * harmonics * T::BYTES;
        model.compliance = read_compliance(block.joints, &mut reader)?;
    }
    Ok(block.sequence)
}

/// The compliance section from `reader`'s position, validated.
fn read_compliance<T: Real, N: JointCount>(
    joints: N,
    reader: &mut Cursor<&[u8]>,
) -> Result<Compliance<T, N>, StorageError> {
    let mut compliance = Compliance::none_for(joints);
    for slot in compliance.values_mut() {
        *slot = reader.get().ok_or(StorageError::BufferTooSmall)?;
    }
    compliance.validate().map_err(StorageError::InvalidModel)?;
    Ok(compliance)
}

/// A robot of zeros, to be overwritten by a block's values.
fn zero_robot<T: Real, N: JointCount>(joints: N) -> Robot<T, N> {
    Robot::from_joints(joints.table(MdhJoint {
        a: T::zero(),
        alpha: T::zero(),
        theta_offset: T::zero(),
        d: T::zero(),
        beta: T::zero(),
    }))
}

/// The geometry from the start of `reader`, validated.
fn read_robot<T: Real, N: JointCount>(
    joints: N,
    reader: &mut Cursor<&[u8]>,
) -> Result<Robot<T, N>, StorageError> {
    let mut robot = zero_robot(joints);
    let mut ok = true;
    for_each_slot(&mut robot, |slot| match reader.get::<T>() {
        Some(v) => *slot = v,
        None => ok = false,
    });
    if !ok {
        return Err(StorageError::BufferTooSmall);
    }
    robot.validate().map_err(StorageError::InvalidModel)?;
    Ok(robot)
}

/// What a block holds: a geometry ([`Robot`], version 1) or geometry and maps
/// ([`ControllerModel`], version 2, which also reads version 1).
pub trait Stored: Sized + Copy {
    /// Checks that the content can be encoded and decoded again.
    fn validate(&self) -> Result<(), StorageError>;
    /// Writes the block; returns its length.
    fn encode_block(&self, sequence: u32, out: &mut [u8]) -> Result<usize, StorageError>;
    /// Reads a block: the content and its sequence number.
    fn decode_block(bytes: &[u8]) -> Result<(Self, u32), StorageError>;
}

impl<T: Real, N: JointCount> Stored for Robot<T, N> {
    fn validate(&self) -> Result<(), StorageError> {
        Robot::validate(self).map_err(StorageError::InvalidModel)
    }
    fn encode_block(&self, sequence: u32, out: &mut [u8]) -> Result<usize, StorageError> {
        encode(self, sequence, out)
    }
    fn decode_block(bytes: &[u8]) -> Result<(Self, u32), StorageError> {
        decode(bytes)
    }
}

impl<T: Real, N: JointCount, const C: usize> Stored for ControllerModel<T, N, C> {
    fn validate(&self) -> Result<(), StorageError> {
        self.robot.validate().map_err(StorageError::InvalidModel)?;
        self.compliance
            .validate()
            .map_err(StorageError::InvalidModel)
    }
    fn encode_block(&self, sequence: u32, out: &mut [u8]) -> Result<usize, StorageError> {
        encode_model(self, sequence, out)
    }
    fn decode_block(bytes: &[u8]) -> Result<(Self, u32), StorageError> {
        decode_model(bytes)
    }
}

/// The model's values in block order.
fn for_each_value<T: Real, N: JointCount>(robot: &Robot<T, N>, mut f: impl FnMut(T)) {
    let mut copy = *robot;
    for_each_slot(&mut copy, |slot| f(*slot));
}

/// The model's fields in block order, mutable.
fn for_each_slot<T: Real, N: JointCount>(robot: &mut Robot<T, N>, mut f: impl FnMut(&mut T)) {
    for j in robot.joints.iter_mut() {
        for v in [
            &mut j.a,
            &mut j.alpha,
            &mut j.theta_offset,
            &mut j.d,
            &mut j.beta,
        ] {
            f(v);
        }
    }
    for l in robot.limits.iter_mut() {
        f(&mut l.lower);
        f(&mut l.upper);
    }
    for frame in [&mut robot.base, &mut robot.tool] {
        for v in frame.xyz.iter_mut().chain(frame.rpy.iter_mut()) {
            f(v);
        }
    }
}

struct Cursor<B> {
    bytes: B,
    at: usize,
}

impl Cursor<&mut [u8]> {
    fn put_bytes(&mut self, data: &[u8]) {
        if let Some(dst) = self.bytes.get_mut(self.at..self.at + data.len()) {
            dst.copy_from_slice(data);
        }
        self.at += data.len();
    }
    fn put<T: Real>(&mut self, v: T) {
        if let Some(dst) = self.bytes.get_mut(self.at..) {
            v.write_le(dst);
        }
        self.at += T::BYTES;
    }
}

impl Cursor<&[u8]> {
    fn get<T: Real>(&mut self) -> Option<T> {
        let v = T::read_le(self.bytes.get(self.at..)?)?;
        self.at += T::BYTES;
        Some(v)
    }
}

/// One of the two storage slots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Slot {
    /// Slot A.
    A,
    /// Slot B.
    B,
}

/// Two flash regions of at least [`block_len`] bytes each, as the controller's driver offers them.
pub trait FlashSlots {
    /// The current content of a slot.
    fn read(&self, slot: Slot) -> &[u8];
    /// Erases and programs a slot with `data` (from its first byte). A power loss may leave any
    /// prefix of `data` written and the rest erased or old.
    fn write(&mut self, slot: Slot, data: &[u8]) -> Result<(), StorageError>;
}

/// Where [`load`] found the parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Source {
    /// The newest valid block, in this slot, with this sequence number.
    Newest(Slot, u32),
    /// The newest block was invalid; this older valid block was used.
    Fallback(Slot, u32),
    /// No valid block: the nominal model.
    Nominal,
}

/// `true` when sequence `a` is newer than `b` (wrapping comparison).
fn newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// The sequence number in a slot's header, if the slot starts with the magic number (whether or
/// not the rest of the block is intact).
fn header_sequence(bytes: &[u8]) -> Option<u32> {
    let magic = u32::from_le_bytes(bytes.get(0..4)?.try_into().ok()?);
    if magic != MAGIC {
        return None;
    }
    Some(u32::from_le_bytes(bytes.get(8..12)?.try_into().ok()?))
}

/// The slot and sequence number of the newest block header in the two slots, intact or not.
fn newest_header(flash: &impl FlashSlots) -> Option<(Slot, u32)> {
    let mut newest: Option<(Slot, u32)> = None;
    for slot in [Slot::A, Slot::B] {
        if let Some(s) = header_sequence(flash.read(slot))
            && newest.is_none_or(|(_, n)| newer(s, n))
        {
            newest = Some((slot, s));
        }
    }
    newest
}

/// Where loaded parameters come from: `chosen`, the slot and sequence number of the newest valid
/// block (`None`: the nominal model), a fallback when a newer header stands in the other slot.
fn source_of(chosen: Option<(Slot, u32)>, flash: &impl FlashSlots) -> Source {
    match (chosen, newest_header(flash)) {
        (None, _) => Source::Nominal,
        // A damaged block with a newer sequence number: its write did not complete.
        (Some((slot, s)), Some((other, n))) if other != slot && newer(n, s) => {
            Source::Fallback(slot, s)
        }
        (Some((slot, s)), _) => Source::Newest(slot, s),
    }
}

/// Loads the newest valid parameters, falling back to the other slot and then to `nominal`.
pub fn load<M: Stored>(flash: &impl FlashSlots, nominal: &M) -> (M, Source) {
    let mut best: Option<(Slot, M, u32)> = None;
    for slot in [Slot::A, Slot::B] {
        if let Ok((robot, s)) = M::decode_block(flash.read(slot))
            && best.as_ref().is_none_or(|(_, _, n)| newer(s, *n))
        {
            best = Some((slot, robot, s));
        }
    }
    let source = source_of(best.as_ref().map(|(slot, _, s)| (*slot, *s)), flash);
    (best.map_or(*nominal, |(_, robot, _)| robot), source)
}

/// [`load`] of a [`ControllerModel`] into `model` in place, with the same rule (the newest valid
/// slot, then the other, then `nominal`'s geometry without maps) and the same [`Source`]: no copy
/// of the model is made on the stack (a controller with little RAM decodes each slot into its own
/// model storage, and the chosen one a second time if the other was decoded last).
pub fn load_model_into<T: Real, N: JointCount, const C: usize>(
    flash: &impl FlashSlots,
    nominal: &Robot<T, N>,
    model: &mut ControllerModel<T, N, C>,
) -> Source {
    let mut best: Option<(Slot, u32)> = None;
    let mut last_decoded = None;
    for slot in [Slot::A, Slot::B] {
        if let Ok(s) = decode_model_into(flash.read(slot), model) {
            last_decoded = Some(slot);
            if best.is_none_or(|(_, n)| newer(s, n)) {
                best = Some((slot, s));
            }
        }
    }
    let reloaded = match best {
        Some((slot, _)) if last_decoded != Some(slot) => {
            // Fails only for a flash that changed since it was decoded a moment ago.
            decode_model_into(flash.read(slot), model).is_ok()
        }
        chosen => chosen.is_some(),
    };
    if !reloaded {
        model.set_geometric(nominal);
        return Source::Nominal;
    }
    source_of(best, flash)
}

/// Stores `robot` (a [`Robot`] or a [`ControllerModel`]) in the slot that does not hold the
/// newest valid block, with the next sequence number; `buffer` must hold the block
/// ([`block_len`] or [`model_block_len`] bytes). Returns the slot and sequence written.
pub fn store<M: Stored>(
    flash: &mut impl FlashSlots,
    robot: &M,
    buffer: &mut [u8],
) -> Result<(Slot, u32), StorageError> {
    robot.validate()?;
    let (slot, sequence) = match load(flash, robot).1 {
        Source::Newest(Slot::A, s) | Source::Fallback(Slot::A, s) => (Slot::B, s.wrapping_add(1)),
        Source::Newest(Slot::B, s) | Source::Fallback(Slot::B, s) => (Slot::A, s.wrapping_add(1)),
        Source::Nominal => (Slot::A, 1),
    };
    let len = robot.encode_block(sequence, buffer)?;
    flash.write(slot, buffer.get(..len).ok_or(StorageError::BufferTooSmall)?)?;
    Ok((slot, sequence))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Kinematics;
    use crate::model::paper::{er10l_c10, table2};
    use nalgebra::U5;
    use nalgebra::U6;
    extern crate std;
    use std::vec;
    use std::vec::Vec;

    /// Simulated flash: two slots; a write may be cut after `budget` bytes (power loss).
    struct Flash {
        slots: [Vec<u8>; 2],
        budget: Option<usize>,
    }

    impl Flash {
        fn new(len: usize) -> Self {
            Self {
                slots: [vec![0xFF; len], vec![0xFF; len]],
                budget: None,
            }
        }
    }

    impl FlashSlots for Flash {
        fn read(&self, slot: Slot) -> &[u8] {
            &self.slots[slot as usize]
        }
        fn write(&mut self, slot: Slot, data: &[u8]) -> Result<(), StorageError> {
            let target = &mut self.slots[slot as usize];
            // Erase, then program byte by byte until the power fails.
            target.fill(0xFF);
            let n = self.budget.map_or(data.len(), |b| b.min(data.len()));
            target[..n].copy_from_slice(&data[..n]);
            if n < data.len() {
                Err(StorageError::Flash)
            } else {
                Ok(())
            }
        }
    }

    /// The ER10L-C10 with Table 2 applied, as an identified model to store.
    fn identified() -> Robot<f64, U6> {
        let mut robot = er10l_c10::<f64>();
        for (j, e) in robot.joints.iter_mut().zip(table2::<f64>().joints) {
            j.a += e.da;
            j.alpha += e.dalpha;
            j.theta_offset += e.dtheta;
            j.d += e.dd;
            j.beta += e.dbeta;
        }
        robot.limits[0] = crate::JointLimits {
            lower: -2.9,
            upper: 2.9,
        };
        robot.tool.xyz = [1.0, -2.0, 150.0];
        robot
    }

    #[test]
    fn crc32_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
    }

    #[test]
    fn round_trip_is_bit_exact_in_f64_and_f32() {
        let robot = identified();
        let mut buffer = [0u8; block_len::<f64>(6)];
        assert_eq!(block_len::<f64>(6), 12 + 54 * 8 + 4);
        assert_eq!(encode(&robot, 7, &mut buffer), Ok(448));
        let (back, sequence) = decode::<f64, U6>(&buffer).unwrap();
        assert_eq!(sequence, 7);
        let bits = |r: &Robot<f64, U6>| {
            let mut v = Vec::new();
            for_each_value(r, |x| v.push(x.to_bits()));
            v
        };
        assert_eq!(bits(&back), bits(&robot));
        assert_eq!(&buffer[..4], b"CALB");
        assert_eq!(buffer[6], 8);

        let robot32 = er10l_c10::<f32>();
        let mut small = [0u8; block_len::<f32>(6)];
        encode(&robot32, 1, &mut small).unwrap();
        assert_eq!(decode::<f32, U6>(&small).unwrap().0, robot32);
        assert_eq!(decode::<f64, U6>(&buffer[..]).map(|r| r.1), Ok(7));
        assert_eq!(
            decode::<f32, U6>(&buffer[..]),
            Err(StorageError::WrongScalar(8))
        );
        assert_eq!(
            decode::<f64, U5>(&buffer[..]),
            Err(StorageError::WrongJointCount(6))
        );
        assert_eq!(
            encode(&robot, 1, &mut [0u8; 100]),
            Err(StorageError::BufferTooSmall)
        );
        assert_eq!(decode::<f64, U6>(&[0xFF; 448]), Err(StorageError::BadMagic));
    }

    #[test]
    fn every_single_bit_flip_is_detected() {
        let mut buffer = [0u8; block_len::<f64>(6)];
        encode(&identified(), 3, &mut buffer).unwrap();
        for byte in 0..buffer.len() {
            for bit in 0..8 {
                let mut damaged = buffer;
                damaged[byte] ^= 1 << bit;
                assert!(
                    decode::<f64, U6>(&damaged).is_err(),
                    "flip of bit {bit} in byte {byte} went unnoticed"
                );
            }
        }
    }

    #[test]
    fn interrupted_write_at_every_byte_keeps_the_previous_parameters() {
        let nominal = er10l_c10::<f64>();
        let first = identified();
        let mut second = first;
        second.joints[3].d += 0.25;
        let len = block_len::<f64>(6);
        let mut buffer = [0u8; block_len::<f64>(6)];
        for cut in 0..len {
            let mut flash = Flash::new(len);
            assert_eq!(store(&mut flash, &first, &mut buffer), Ok((Slot::A, 1)));
            assert_eq!(store(&mut flash, &second, &mut buffer), Ok((Slot::B, 2)));
            // A third write goes to slot A (older) and loses power after `cut` bytes.
            let mut third = second;
            third.joints[0].a += 1.0;
            flash.budget = Some(cut);
            assert_eq!(
                store(&mut flash, &third, &mut buffer),
                Err(StorageError::Flash)
            );
            let (loaded, source) = load(&flash, &nominal);
            assert_eq!(loaded, second, "cut at byte {cut}");
            assert!(
                matches!(
                    source,
                    Source::Newest(Slot::B, 2) | Source::Fallback(Slot::B, 2)
                ),
                "{source:?}"
            );
            // The next complete write succeeds and wins.
            flash.budget = None;
            let (slot, sequence) = store(&mut flash, &third, &mut buffer).unwrap();
            assert_eq!((slot, sequence), (Slot::A, 3));
            assert_eq!(load(&flash, &nominal), (third, Source::Newest(Slot::A, 3)));
        }
    }

    #[test]
    fn empty_flash_gives_nominal_and_a_damaged_newest_block_falls_back() {
        let nominal = er10l_c10::<f64>();
        let len = block_len::<f64>(6);
        let mut flash = Flash::new(len);
        assert_eq!(load(&flash, &nominal), (nominal, Source::Nominal));
        let mut buffer = [0u8; block_len::<f64>(6)];
        store(&mut flash, &identified(), &mut buffer).unwrap();
        let mut newer_model = identified();
        newer_model.joints[5].d += 0.1;
        store(&mut flash, &newer_model, &mut buffer).unwrap();
        flash.slots[1][100] ^= 0x10;
        assert_eq!(
            load(&flash, &nominal),
            (identified(), Source::Fallback(Slot::A, 1))
        );
        // The stored model is usable.
        assert!(Kinematics::nominal(&load(&flash, &nominal).0).is_ok());
    }

    #[test]
    fn a_model_the_decoder_would_reject_is_not_encoded() {
        // Issue 13, defect 10: 1e300 mm rounded to f32 is +inf.
        let mut robot = er10l_c10::<f32>();
        robot.joints[1].a = 1e300f64 as f32;
        let mut buffer = [0u8; block_len::<f32>(6)];
        assert!(matches!(
            encode(&robot, 1, &mut buffer),
            Err(StorageError::InvalidModel(_))
        ));
        assert!(buffer.iter().all(|b| *b == 0));
    }

    /// [`identified`] with maps of 40 harmonics on every joint (about 0.3 mrad RMS).
    fn identified_with_maps<T: Real>() -> ControllerModel<T, U6, 64> {
        let mut sin = [[T::zero(); 64]; 6];
        let mut cos = [[T::zero(); 64]; 6];
        for j in 0..6 {
            for h in 0..40 {
                let x = ((j * 41 + h * 17) % 23) as f64 / 23.0 - 0.5;
                sin[j][h] = T::of(8e-5 * x / (1.0 + 0.05 * h as f64));
                cos[j][h] = T::of(-6e-5 * x * x);
            }
        }
        let robot = identified();
        let mut cast = er10l_c10::<T>();
        for (c, r) in cast.joints.iter_mut().zip(robot.joints.iter()) {
            *c = MdhJoint {
                a: T::of(r.a),
                alpha: T::of(r.alpha),
                theta_offset: T::of(r.theta_offset),
                d: T::of(r.d),
                beta: T::of(r.beta),
            };
        }
        ControllerModel {
            robot: cast,
            maps: JointMaps::new(40, sin, cos).unwrap(),
            compliance: Compliance::none(),
        }
    }

    /// [`identified_with_maps`] with UR10-like masses and 11 gains.
    fn identified_with_compliance<T: Real>() -> ControllerModel<T, U6, 64> {
        let mass = |m: f64, c: [f64; 3]| crate::model::compliance::PointMass {
            mass_kg: T::of(m),
            centre_mm: c.map(T::of),
        };
        let gains = [
            [12.5, -7.25, 0.0],
            [3.0, 0.0, 6.125],
            [-4.0, 2.0, 9.0],
            [5.0, 1.0, 8.0],
            [0.0; 3],
            [0.0; 3],
        ];
        ControllerModel {
            compliance: Compliance::new(
                [0.0, 0.0, -9.81].map(T::of),
                [
                    mass(7.1, [21.0, 0.0, 27.0]),
                    mass(12.7, [380.0, 0.0, 158.0]),
                    mass(4.27, [240.0, 0.0, 68.0]),
                    mass(2.0, [0.0, 7.0, 18.0]),
                    mass(2.0, [0.0, 7.0, 18.0]),
                    mass(0.365, [0.0, 0.0, -26.0]),
                ],
                mass(1.5, [0.0, 0.0, 60.0]),
                gains.map(|g| g.map(T::of)),
            )
            .unwrap(),
            ..identified_with_maps()
        }
    }

    #[test]
    fn a_block_with_compliance_round_trips_bit_exactly() {
        let model = identified_with_compliance::<f32>();
        let len = model_block_len::<f32>(6, 40, true);
        assert_eq!(len, model_block_len::<f32>(6, 40, false) + 49 * 4);
        let mut buffer = [0u8; model_block_len::<f32>(6, 64, true)];
        assert_eq!(encode_model(&model, 9, &mut buffer), Ok(len));
        assert_eq!(&buffer[12..16], &[40, 0, 1, 0]);
        assert_eq!(decode_model::<f32, U6, 64>(&buffer), Ok((model, 9)));
        let model64 = identified_with_compliance::<f64>();
        let mut wide = [0u8; model_block_len::<f64>(6, 64, true)];
        encode_model(&model64, 10, &mut wide).unwrap();
        assert_eq!(decode_model::<f64, U6, 64>(&wide), Ok((model64, 10)));
        // Every bit flip is detected.
        let block = &buffer[..len];
        for byte in 0..len {
            for bit in 0..8 {
                let mut damaged = [0u8; model_block_len::<f32>(6, 64, true)];
                damaged[..len].copy_from_slice(block);
                damaged[byte] ^= 1 << bit;
                assert!(
                    decode_model::<f32, U6, 64>(&damaged).is_err(),
                    "flip of bit {bit} in byte {byte} went unnoticed"
                );
            }
        }
        // A section this build does not know is named, not misread.
        let mut future = buffer;
        future[14] = 3;
        let crc = crc32(&future[..len - 4]);
        future[len - 4..len].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(
            decode_model::<f32, U6, 64>(&future),
            Err(StorageError::UnknownSections(3))
        );
        // A model without gains writes no compliance section (the block of the maps alone).
        let mut plain = model;
        plain.compliance = Compliance::new(
            *model.compliance.gravity_mps2(),
            *model.compliance.links(),
            *model.compliance.load(),
            [[0.0; 3]; 6],
        )
        .unwrap();
        assert_eq!(
            encode_model(&plain, 9, &mut buffer),
            Ok(model_block_len::<f32>(6, 40, false))
        );
    }

    #[test]
    fn a_block_with_maps_round_trips_bit_exactly_within_8_kib() {
        let model = identified_with_maps::<f32>();
        assert_eq!(
            model_block_len::<f32>(6, 40, false),
            16 + (54 + 480) * 4 + 4
        );
        assert!(model_block_len::<f32>(6, 64, false) <= 8192);
        let mut buffer = [0u8; model_block_len::<f32>(6, 64, false)];
        assert_eq!(encode_model(&model, 5, &mut buffer), Ok(2156));
        assert_eq!(&buffer[4..6], &[2, 0]);
        assert_eq!(&buffer[12..14], &[40, 0]);
        let (back, sequence) = decode_model::<f32, U6, 64>(&buffer).unwrap();
        assert_eq!((back, sequence), (model, 5));
        // A build with room for exactly 40 harmonics reads it too; one with 39 says why not.
        let (narrow, _) = decode_model::<f32, U6, 40>(&buffer).unwrap();
        assert_eq!(narrow.maps.error(2, 0.7), model.maps.error(2, 0.7));
        assert_eq!(
            decode_model::<f32, U6, 39>(&buffer),
            Err(StorageError::TooManyHarmonics(40))
        );
        // The geometry-only reader refuses it by version; the f64 reader by scalar.
        assert_eq!(
            decode::<f32, U6>(&buffer),
            Err(StorageError::UnsupportedVersion(2))
        );
        assert_eq!(
            decode_model::<f64, U6, 64>(&buffer),
            Err(StorageError::WrongScalar(4))
        );
        let model64 = identified_with_maps::<f64>();
        let mut wide = [0u8; model_block_len::<f64>(6, 64, false)];
        let len = encode_model(&model64, 6, &mut wide).unwrap();
        assert_eq!(len, model_block_len::<f64>(6, 40, false));
        assert_eq!(decode_model::<f64, U6, 64>(&wide), Ok((model64, 6)));
    }

    #[test]
    fn a_version_1_block_loads_as_a_model_without_maps() {
        let mut buffer = [0u8; block_len::<f64>(6)];
        encode(&identified(), 4, &mut buffer).unwrap();
        let (model, sequence) = decode_model::<f64, U6, 64>(&buffer).unwrap();
        assert_eq!(sequence, 4);
        assert_eq!(model.robot, identified());
        assert!(model.maps.is_zero());
        assert_eq!(model.maps.harmonics(), 0);
    }

    #[test]
    fn every_single_bit_flip_of_a_block_with_maps_is_detected() {
        let mut buffer = [0u8; model_block_len::<f32>(6, 40, false)];
        encode_model(&identified_with_maps::<f32>(), 3, &mut buffer).unwrap();
        for byte in 0..buffer.len() {
            for bit in 0..8 {
                let mut damaged = buffer;
                damaged[byte] ^= 1 << bit;
                assert!(
                    decode_model::<f32, U6, 64>(&damaged).is_err(),
                    "flip of bit {bit} in byte {byte} went unnoticed"
                );
            }
        }
    }

    #[test]
    fn an_interrupted_write_of_a_model_keeps_the_previous_one() {
        let nominal = ControllerModel::<f32, U6, 64>::geometric(er10l_c10());
        let first = identified_with_maps::<f32>();
        let mut second = first;
        second.robot.joints[2].d += 0.5;
        let len = model_block_len::<f32>(6, 64, false);
        let mut buffer = [0u8; model_block_len::<f32>(6, 64, false)];
        for cut in (0..model_block_len::<f32>(6, 40, false)).step_by(7) {
            let mut flash = Flash::new(len);
            store(&mut flash, &first, &mut buffer).unwrap();
            flash.budget = Some(cut);
            assert_eq!(
                store(&mut flash, &second, &mut buffer),
                Err(StorageError::Flash)
            );
            assert_eq!(load(&flash, &nominal).0, first, "cut at byte {cut}");
            flash.budget = None;
            store(&mut flash, &second, &mut buffer).unwrap();
            assert_eq!(load(&flash, &nominal), (second, Source::Newest(Slot::B, 2)));
        }
    }

    #[test]
    fn loading_in_place_chooses_what_load_chooses() {
        let robot = er10l_c10::<f32>();
        let nominal = ControllerModel::<f32, U6, 64>::geometric(robot);
        let first = identified_with_maps::<f32>();
        let mut second = first;
        second.robot.joints[2].d += 0.5;
        let len = model_block_len::<f32>(6, 64, false);
        let mut buffer = [0u8; model_block_len::<f32>(6, 64, false)];
        let mut flash = Flash::new(len);
        let mut model = ControllerModel::<f32, U6, 64>::geometric(er10l_c10());
        let mut check = |flash: &Flash, expected: (ControllerModel<f32, U6, 64>, Source)| {
            assert_eq!(load(flash, &nominal), expected);
            // Start from a model unlike every candidate, so nothing passes by accident.
            model.robot.joints[0].a = 12345.0;
            let source = load_model_into(flash, &robot, &mut model);
            assert_eq!((model, source), expected);
        };
        check(&flash, (nominal, Source::Nominal));
        store(&mut flash, &first, &mut buffer).unwrap();
        check(&flash, (first, Source::Newest(Slot::A, 1)));
        store(&mut flash, &second, &mut buffer).unwrap();
        // B (newer) was decoded last.
        check(&flash, (second, Source::Newest(Slot::B, 2)));
        // A third write to A: A is newest and B was decoded last, so A is decoded again.
        let mut third = second;
        third.robot.joints[0].a += 1.0;
        store(&mut flash, &third, &mut buffer).unwrap();
        check(&flash, (third, Source::Newest(Slot::A, 3)));
        // A damaged, B valid: falls back to B.
        flash.slots[0][40] ^= 0x01;
        check(&flash, (second, Source::Fallback(Slot::B, 2)));
        // Both damaged: the nominal geometry without maps.
        flash.slots[1][40] ^= 0x01;
        check(&flash, (nominal, Source::Nominal));
    }

    #[test]
    fn sequence_numbers_wrap() {
        assert!(newer(0, u32::MAX));
        assert!(newer(5, 3));
        assert!(!newer(3, 5));
    }
}
