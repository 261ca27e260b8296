//! The persistent parameter block of the controller, and two-slot (A/B) storage that survives a
//! power loss during an update.
//!
//! Block layout, explicit little-endian, the same on every target (offsets in bytes):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `CALB` (0x42 4C 41 43 read as u32 LE: 0x424C_4143) |
//! | 4 | 2 | format version (1) |
//! | 6 | 1 | scalar type: 4 = f32, 8 = f64 |
//! | 7 | 1 | joint count N |
//! | 8 | 4 | sequence number (wrapping; the newer of two blocks has the larger one) |
//! | 12 | S (7N + 12) | the model: per joint a, alpha, theta_offset, d, beta (mm, rad), then per joint lower, upper limit (rad), then base xyz (mm) rpy (rad), then tool xyz rpy; S = 4 or 8 |
//! | 12 + S (7N + 12) | 4 | CRC-32 (IEEE 802.3, reflected, as zlib) of all bytes before it |
//!
//! Two slots: [`store`] writes to the slot that does not hold the newest valid block, with the
//! next sequence number, so an interrupted write can only damage the older copy. [`load`] takes the
//! newest valid slot, falls back to the other, then to the nominal model, and says which it used.

use crate::KinematicsError;
use crate::model::{MdhJoint, Robot};
use crate::scalar::Real;
use core::fmt;

/// `CALB` as a little-endian u32.
pub const MAGIC: u32 = u32::from_le_bytes(*b"CALB");
/// Format version written by this code.
pub const VERSION: u16 = 1;
const HEADER: usize = 12;

/// Bytes of a block for scalar `T` and `N` joints.
pub const fn block_len<T: Real, const N: usize>() -> usize {
    HEADER + (7 * N + 12) * T::BYTES + 4
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

/// Writes `robot` with `sequence` as a block into `out`; returns the number of bytes written.
/// A model that [`decode`] would reject (a value not finite, such as an f64 value beyond the f32
/// range rounded to infinity) is refused with [`StorageError::InvalidModel`] and nothing is written.
pub fn encode<T: Real, const N: usize>(
    robot: &Robot<T, N>,
    sequence: u32,
    out: &mut [u8],
) -> Result<usize, StorageError> {
    robot.validate().map_err(StorageError::InvalidModel)?;
    let len = block_len::<T, N>();
    let block = out.get_mut(..len).ok_or(StorageError::BufferTooSmall)?;
    let joints = u8::try_from(N).map_err(|_| StorageError::WrongJointCount(u8::MAX))?;
    let mut header = [0u8; HEADER];
    header[0..4].copy_from_slice(&MAGIC.to_le_bytes());
    header[4..6].copy_from_slice(&VERSION.to_le_bytes());
    header[6] = T::BYTES as u8;
    header[7] = joints;
    header[8..12].copy_from_slice(&sequence.to_le_bytes());
    let mut writer = Cursor {
        bytes: &mut *block,
        at: 0,
    };
    writer.put_bytes(&header);
    for_each_value(robot, |v| writer.put(v));
    let body = writer.at;
    let crc = crc32(block.get(..body).unwrap_or(&[]));
    block
        .get_mut(body..body + 4)
        .ok_or(StorageError::BufferTooSmall)?
        .copy_from_slice(&crc.to_le_bytes());
    Ok(len)
}

/// Reads a block: the robot and its sequence number.
pub fn decode<T: Real, const N: usize>(bytes: &[u8]) -> Result<(Robot<T, N>, u32), StorageError> {
    let len = block_len::<T, N>();
    let block = bytes.get(..len).ok_or(StorageError::BufferTooSmall)?;
    let u32_at = |at: usize| -> u32 {
        let mut word = [0u8; 4];
        if let Some(src) = block.get(at..at + 4) {
            word.copy_from_slice(src);
        }
        u32::from_le_bytes(word)
    };
    if u32_at(0) != MAGIC {
        return Err(StorageError::BadMagic);
    }
    let version = u16::from_le_bytes([
        block.get(4).copied().unwrap_or(0),
        block.get(5).copied().unwrap_or(0),
    ]);
    if version != VERSION {
        return Err(StorageError::UnsupportedVersion(version));
    }
    let scalar = block.get(6).copied().unwrap_or(0);
    if usize::from(scalar) != T::BYTES {
        return Err(StorageError::WrongScalar(scalar));
    }
    let joints = block.get(7).copied().unwrap_or(0);
    if usize::from(joints) != N {
        return Err(StorageError::WrongJointCount(joints));
    }
    let body = len - 4;
    if crc32(block.get(..body).unwrap_or(&[])) != u32_at(body) {
        return Err(StorageError::BadChecksum);
    }
    let sequence = u32_at(8);
    let mut reader = Cursor {
        bytes: block.get(HEADER..body).unwrap_or(&[]),
        at: 0,
    };
    let mut robot = Robot::from_joints(
        [MdhJoint {
            a: T::zero(),
            alpha: T::zero(),
            theta_offset: T::zero(),
            d: T::zero(),
            beta: T::zero(),
        }; N],
    );
    let mut ok = true;
    for_each_slot(&mut robot, |slot| match reader.get::<T>() {
        Some(v) => *slot = v,
        None => ok = false,
    });
    if !ok {
        return Err(StorageError::BufferTooSmall);
    }
    robot.validate().map_err(StorageError::InvalidModel)?;
    Ok((robot, sequence))
}

/// The model's values in block order.
fn for_each_value<T: Real, const N: usize>(robot: &Robot<T, N>, mut f: impl FnMut(T)) {
    let mut copy = *robot;
    for_each_slot(&mut copy, |slot| f(*slot));
}

/// The model's fields in block order, mutable.
fn for_each_slot<T: Real, const N: usize>(robot: &mut Robot<T, N>, mut f: impl FnMut(&mut T)) {
    for j in &mut robot.joints {
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
    for l in &mut robot.limits {
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

/// Loads the newest valid parameters, falling back to the other slot and then to `nominal`.
pub fn load<T: Real, const N: usize>(
    flash: &impl FlashSlots,
    nominal: &Robot<T, N>,
) -> (Robot<T, N>, Source) {
    let mut best: Option<(Slot, Robot<T, N>, u32)> = None;
    let mut newest_header: Option<(Slot, u32)> = None;
    for slot in [Slot::A, Slot::B] {
        let bytes = flash.read(slot);
        if let Some(s) = header_sequence(bytes)
            && newest_header.is_none_or(|(_, n)| newer(s, n))
        {
            newest_header = Some((slot, s));
        }
        if let Ok((robot, s)) = decode::<T, N>(bytes)
            && best.as_ref().is_none_or(|(_, _, n)| newer(s, *n))
        {
            best = Some((slot, robot, s));
        }
    }
    match best {
        None => (*nominal, Source::Nominal),
        Some((slot, robot, s)) => match newest_header {
            // A damaged block with a newer sequence number: its write did not complete.
            Some((other, n)) if other != slot && newer(n, s) => (robot, Source::Fallback(slot, s)),
            _ => (robot, Source::Newest(slot, s)),
        },
    }
}

/// Stores `robot` in the slot that does not hold the newest valid block, with the next sequence
/// number; `buffer` must hold [`block_len`] bytes. Returns the slot and sequence written.
pub fn store<T: Real, const N: usize>(
    flash: &mut impl FlashSlots,
    robot: &Robot<T, N>,
    buffer: &mut [u8],
) -> Result<(Slot, u32), StorageError> {
    robot.validate().map_err(StorageError::InvalidModel)?;
    let (slot, sequence) = match load::<T, N>(flash, robot).1 {
        Source::Newest(Slot::A, s) | Source::Fallback(Slot::A, s) => (Slot::B, s.wrapping_add(1)),
        Source::Newest(Slot::B, s) | Source::Fallback(Slot::B, s) => (Slot::A, s.wrapping_add(1)),
        Source::Nominal => (Slot::A, 1),
    };
    let len = encode(robot, sequence, buffer)?;
    flash.write(slot, buffer.get(..len).ok_or(StorageError::BufferTooSmall)?)?;
    Ok((slot, sequence))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Kinematics;
    use crate::model::paper::{er10l_c10, table2};
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
    fn identified() -> Robot<f64, 6> {
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
        let mut buffer = [0u8; block_len::<f64, 6>()];
        assert_eq!(block_len::<f64, 6>(), 12 + 54 * 8 + 4);
        assert_eq!(encode(&robot, 7, &mut buffer), Ok(448));
        let (back, sequence) = decode::<f64, 6>(&buffer).unwrap();
        assert_eq!(sequence, 7);
        let bits = |r: &Robot<f64, 6>| {
            let mut v = Vec::new();
            for_each_value(r, |x| v.push(x.to_bits()));
            v
        };
        assert_eq!(bits(&back), bits(&robot));
        assert_eq!(&buffer[..4], b"CALB");
        assert_eq!(buffer[6], 8);

        let robot32 = er10l_c10::<f32>();
        let mut small = [0u8; block_len::<f32, 6>()];
        encode(&robot32, 1, &mut small).unwrap();
        assert_eq!(decode::<f32, 6>(&small).unwrap().0, robot32);
        assert_eq!(decode::<f64, 6>(&buffer[..]).map(|r| r.1), Ok(7));
        assert_eq!(
            decode::<f32, 6>(&buffer[..]),
            Err(StorageError::WrongScalar(8))
        );
        assert_eq!(
            decode::<f64, 5>(&buffer[..]),
            Err(StorageError::WrongJointCount(6))
        );
        assert_eq!(
            encode(&robot, 1, &mut [0u8; 100]),
            Err(StorageError::BufferTooSmall)
        );
        assert_eq!(decode::<f64, 6>(&[0xFF; 448]), Err(StorageError::BadMagic));
    }

    #[test]
    fn every_single_bit_flip_is_detected() {
        let mut buffer = [0u8; block_len::<f64, 6>()];
        encode(&identified(), 3, &mut buffer).unwrap();
        for byte in 0..buffer.len() {
            for bit in 0..8 {
                let mut damaged = buffer;
                damaged[byte] ^= 1 << bit;
                assert!(
                    decode::<f64, 6>(&damaged).is_err(),
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
        let len = block_len::<f64, 6>();
        let mut buffer = [0u8; block_len::<f64, 6>()];
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
        let len = block_len::<f64, 6>();
        let mut flash = Flash::new(len);
        assert_eq!(load(&flash, &nominal), (nominal, Source::Nominal));
        let mut buffer = [0u8; block_len::<f64, 6>()];
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
        let mut buffer = [0u8; block_len::<f32, 6>()];
        assert!(matches!(
            encode(&robot, 1, &mut buffer),
            Err(StorageError::InvalidModel(_))
        ));
        assert!(buffer.iter().all(|b| *b == 0));
    }

    #[test]
    fn sequence_numbers_wrap() {
        assert!(newer(0, u32::MAX));
        assert!(newer(5, 3));
        assert!(!newer(3, 5));
    }
}
