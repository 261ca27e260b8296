//! The scalar type of every computation: `f64` on a PC, `f32` on the controller.
//!
//! [`Real`] adds to nalgebra's `RealField` the few operations the core needs with a fixed
//! implementation: the sine and cosine come from `libm` (never from the host's C library) so that
//! x86_64 and Cortex-M compute the same bits for the same input.

mod sin_cos_f32;

use nalgebra::RealField;

/// What the controller's logs can print: `defmt::Format` with the `defmt` feature, anything
/// without it.
#[cfg(feature = "defmt")]
pub trait Loggable: defmt::Format {}
#[cfg(feature = "defmt")]
impl<X: defmt::Format> Loggable for X {}
/// What the controller's logs can print: `defmt::Format` with the `defmt` feature, anything
/// without it.
#[cfg(not(feature = "defmt"))]
pub trait Loggable {}
#[cfg(not(feature = "defmt"))]
impl<X> Loggable for X {}

/// A floating-point scalar usable by the core (`f32` or `f64`).
pub trait Real: RealField + Copy + Loggable {
    /// Sine and cosine of `self` (radians) in one call, from `libm`.
    fn sin_cos_libm(self) -> (Self, Self);
    /// Sine and cosine of `self` (radians) as the core computes them: `libm` for `f64`, the
    /// single-precision routine `scalar::sin_cos_f32` for `f32` (no f64 arithmetic, which
    /// the Cortex-M4F emulates in software). Identical bits on every target.
    fn sin_cos_fast(self) -> (Self, Self);
    /// The correctly rounded square root (IEEE 754): the SSE2 intrinsic on x86-64, the FPU's
    /// `VSQRT.F32` on a Cortex-M with a single-precision FPU (libm's software `sqrtf` costs far
    /// more there), libm elsewhere. All are exact to the last bit, so they agree bit for bit.
    fn sqrt_ieee(self) -> Self;
    /// Converts an `f64` constant or input to this scalar (rounding to nearest for `f32`).
    fn of(value: f64) -> Self;
    /// Widens this scalar to `f64` (exact for both `f32` and `f64`).
    fn to_f64(self) -> f64;
    /// `true` when the value is neither infinite nor NaN.
    fn finite(self) -> bool;
    /// A uniform value in `[0, 1)` from 64 random bits (the top 53 bits for `f64`, 24 for `f32`).
    fn unit_from_bits(bits: u64) -> Self;
    /// Two independent uniform values in `[0, 1)` from a generator of 64-bit words: two words
    /// for `f64` (53 bits each), one word split into two 24-bit halves for `f32`.
    fn unit_pair(next: &mut impl FnMut() -> u64) -> (Self, Self);
    /// Size of the scalar in bytes (4 or 8).
    const BYTES: usize;
    /// Writes the little-endian IEEE 754 bytes into `out[..BYTES]`; `false` if `out` is too short.
    fn write_le(self, out: &mut [u8]) -> bool;
    /// Reads a value from little-endian IEEE 754 bytes; `None` if `bytes` is too short.
    fn read_le(bytes: &[u8]) -> Option<Self>;
}

impl Real for f64 {
    #[inline]
    fn sin_cos_libm(self) -> (Self, Self) {
        libm::sincos(self)
    }
    #[inline]
    fn sin_cos_fast(self) -> (Self, Self) {
        libm::sincos(self)
    }
    #[inline]
    fn sqrt_ieee(self) -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            x86_64_sqrt::sqrt_f64(self)
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            libm::sqrt(self)
        }
    }
    #[inline]
    fn of(value: f64) -> Self {
        value
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline]
    fn unit_from_bits(bits: u64) -> Self {
        (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    #[inline]
    fn unit_pair(next: &mut impl FnMut() -> u64) -> (Self, Self) {
        let first = Self::unit_from_bits(next());
        (first, Self::unit_from_bits(next()))
    }
    const BYTES: usize = 8;
    fn write_le(self, out: &mut [u8]) -> bool {
        match out.get_mut(..8) {
            Some(slot) => {
                slot.copy_from_slice(&self.to_le_bytes());
                true
            }
            None => false,
        }
    }
    fn read_le(bytes: &[u8]) -> Option<Self> {
        let array: [u8; 8] = bytes.get(..8)?.try_into().ok()?;
        Some(Self::from_le_bytes(array))
    }
}

/// The square root on x86-64 by the compiler's SSE2 intrinsic, not by libm.
///
/// libm's x86 `sqrt` and `sqrtf` are inline assembly (`sqrtsd`, `sqrtss`), which the assembler
/// emits in the legacy SSE encoding even inside code compiled for AVX2 or AVX-512 (the swarm's
/// lanes, `host_tools::runtime::lanes`). A legacy SSE instruction while the upper halves of the
/// vector registers are in use costs a state transition on some processors; on one of this
/// project's machines the paper's swarm ran several times slower, nearly all of it at the
/// square roots of the objective (docs/RESULTS.md, "The swarm's runtime"). The intrinsic is an
/// ordinary floating-point square root to the compiler, encoded as `vsqrtsd` in AVX code and
/// `sqrtsd` elsewhere; it is the same correctly rounded operation, so the bits do not change.
#[cfg(target_arch = "x86_64")]
mod x86_64_sqrt {
    use core::arch::x86_64::{
        _mm_cvtsd_f64, _mm_cvtss_f32, _mm_set_sd, _mm_set_ss, _mm_sqrt_pd, _mm_sqrt_ps,
    };

    /// `sqrt(x)` of an `f64`, correctly rounded.
    #[inline(always)]
    pub(super) fn sqrt_f64(x: f64) -> f64 {
        // SAFETY: the intrinsics need SSE2, which every x86-64 processor has (the target's
        // baseline); they touch no memory.
        unsafe { _mm_cvtsd_f64(_mm_sqrt_pd(_mm_set_sd(x))) }
    }

    /// `sqrt(x)` of an `f32`, correctly rounded.
    #[inline(always)]
    pub(super) fn sqrt_f32(x: f32) -> f32 {
        // SAFETY: the intrinsics need SSE, part of the x86-64 baseline; they touch no memory.
        unsafe { _mm_cvtss_f32(_mm_sqrt_ps(_mm_set_ss(x))) }
    }
}

/// `VSQRT.F32 s0, s0`, then return: the FPU's correctly rounded square root as a function of
/// its own. The hard-float procedure call standard passes the argument and the result in `s0`,
/// so a call is the whole cost (an inline sequence would move the value through a core register
/// and save `s0` around it: 20 bytes at every use instead of 4).
// SAFETY (the naked body): it keeps the procedure call standard for `extern "C" fn(f32) -> f32`
// on eabihf: it reads its argument from `s0`, leaves the result in `s0`, touches no other
// register, no memory and no flags but the FPU's status, and returns with `bx lr`.
#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[unsafe(naked)]
extern "C" fn vsqrt_f32(_x: f32) -> f32 {
    // The instruction is given as its encoding because rustc does not enable the `vfp2` feature
    // for the assembler on thumbv7em-none-eabihf, although the target has the FPU on.
    core::arch::naked_asm!(
        ".inst.w 0xEEB10AC0", // vsqrt.f32 s0, s0
        "bx lr",
    )
}

impl Real for f32 {
    #[inline]
    fn sin_cos_libm(self) -> (Self, Self) {
        libm::sincosf(self)
    }
    #[inline]
    fn sin_cos_fast(self) -> (Self, Self) {
        sin_cos_f32::sin_cos_f32(self)
    }
    #[inline]
    fn sqrt_ieee(self) -> Self {
        #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
        {
            vsqrt_f32(self)
        }
        #[cfg(target_arch = "x86_64")]
        {
            x86_64_sqrt::sqrt_f32(self)
        }
        #[cfg(not(any(
            all(target_arch = "arm", target_abi = "eabihf"),
            target_arch = "x86_64"
        )))]
        {
            libm::sqrtf(self)
        }
    }
    #[inline]
    fn of(value: f64) -> Self {
        value as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline]
    fn unit_from_bits(bits: u64) -> Self {
        // Through u32: the 24-bit value converts exactly either way, and a u64 -> f32 conversion
        // is a software routine on a 32-bit controller.
        ((bits >> 40) as u32) as f32 * (1.0 / (1u32 << 24) as f32)
    }
    #[inline]
    fn unit_pair(next: &mut impl FnMut() -> u64) -> (Self, Self) {
        let bits = next();
        (Self::unit_from_bits(bits), Self::unit_from_bits(bits << 24))
    }
    const BYTES: usize = 4;
    fn write_le(self, out: &mut [u8]) -> bool {
        match out.get_mut(..4) {
            Some(slot) => {
                slot.copy_from_slice(&self.to_le_bytes());
                true
            }
            None => false,
        }
    }
    fn read_le(bytes: &[u8]) -> Option<Self> {
        let array: [u8; 4] = bytes.get(..4)?.try_into().ok()?;
        Some(Self::from_le_bytes(array))
    }
}

#[cfg(test)]
mod tests {
    use super::Real;

    /// Values that exercise every case of a square root: signed zeros, subnormals, the extremes,
    /// exact squares, values between squares, infinities, NaN and negatives (NaN results).
    fn f64_cases() -> impl Iterator<Item = f64> {
        let special = [
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            f64::MIN_POSITIVE / 3.0,
            5e-324,
            f64::MAX,
            f64::EPSILON,
            1.0,
            2.0,
            4.0,
            1e-300,
            1e300,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -1.0,
            -5e-324,
        ];
        // A deterministic spread over every binade from the subnormals to the largest values (a
        // multiplicative walk whose factor is not a power of two, so the mantissas vary).
        let walk = (0..5000).scan(1e-310_f64, |x, _| {
            *x *= 1.37_f64 + 1e-9;
            Some(*x)
        });
        special
            .into_iter()
            .chain(walk.take_while(|x| x.is_finite()))
    }

    /// Checks `sqrt_ieee` against `reference` on every value of `cases`: the same bits (compared
    /// widened to `f64`, which is exact), NaN where the reference gives NaN. Returns the count.
    fn check_against<T: Real + core::fmt::LowerExp>(
        cases: impl Iterator<Item = T>,
        reference: fn(T) -> T,
    ) -> usize {
        let mut count = 0;
        for x in cases {
            let (ours, expected) = (x.sqrt_ieee().to_f64(), reference(x).to_f64());
            if expected.is_nan() {
                assert!(ours.is_nan(), "sqrt({x:e}) = {ours:e}, expected NaN");
            } else {
                assert_eq!(ours.to_bits(), expected.to_bits(), "sqrt({x:e})");
            }
            count += 1;
        }
        count
    }

    /// `sqrt_ieee` is the correctly rounded square root: bit for bit libm's (the implementation
    /// it replaces on x86-64) for every case, NaN for NaN.
    #[test]
    fn f64_square_root_equals_libm_bit_for_bit() {
        let count = check_against(f64_cases(), libm::sqrt);
        assert!(count > 1000, "only {count} cases");
        assert_eq!(9.0_f64.sqrt_ieee(), 3.0);
        assert_eq!((-0.0_f64).sqrt_ieee().to_bits(), (-0.0_f64).to_bits());
    }

    /// The same for `f32`, against libm's `sqrtf`, over the `f64` cases rounded to `f32` and
    /// every 4099th bit pattern of the positive `f32`s.
    #[test]
    fn f32_square_root_equals_libm_bit_for_bit() {
        let patterns = (0..0x7f80_0000_u32).step_by(4099).map(f32::from_bits);
        let count = check_against(f64_cases().map(|x| x as f32).chain(patterns), libm::sqrtf);
        assert!(count > 500_000, "only {count} cases");
        assert_eq!(2.25_f32.sqrt_ieee(), 1.5);
    }
}
