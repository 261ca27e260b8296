//! `(sin x, cos x)` in single precision without any f64 arithmetic: the `f32` scalar's
//! [`Real::sin_cos_fast`](super::Real::sin_cos_fast).

/// Largest |x| (rad) for which [`sin_cos_f32`]'s error bound holds; beyond it the argument is
/// first reduced by `fmod(x, fl(2 pi))`.
pub const F32_REDUCTION_LIMIT: f32 = 8192.0;

/// `(sin x, cos x)` in single precision without any f64 arithmetic (the Cortex-M4F has no
/// double-precision FPU, and libm's `sincosf` computes in f64: about 2,100 instructions per call
/// there). Cephes' `sinf`/`cosf`: reduction by the octant `j = round-to-even-octant(x 4/pi)` with
/// pi/4 split in three parts (exact products up to |x| = 8192), then minimax polynomials of degree
/// 7 (sine) and 8 (cosine) on [-pi/4, pi/4]. Beyond |x| = 8192 rad the argument is first reduced
/// by `fmod(x, fl(2 pi))`, whose error grows as |x| * 1.7e-7; non-finite x gives NaN.
///
/// Error bound, measured against f64 libm over 2,000,001 points in [-8, 8] rad and 200,001 in
/// [-8192, 8192] (unit test `f32_sine_and_cosine_are_within_one_ulp`): at most 7.8e-8 absolute
/// (0.65 ulp of 1.0; libm's `sincosf`, correctly rounded from f64, 3.0e-8). The test asserts
/// 1e-7.
pub fn sin_cos_f32(x: f32) -> (f32, f32) {
    const FOUR_OVER_PI: f32 = 1.273_239_5;
    // pi/4 = DP1 + DP2 + DP3, DP1 and DP2 with few significant bits so that y * DP1, y * DP2
    // are exact for the octants up to 8192 rad.
    const DP1: f32 = 0.785_156_25;
    const DP2: f32 = 2.418_756_5e-4;
    const DP3: f32 = 3.774_895e-8;
    let ax = x.abs();
    if !ax.is_finite() {
        return (f32::NAN, f32::NAN);
    }
    if ax > F32_REDUCTION_LIMIT {
        // No joint turns 1300 times: reduce by fl(2 pi) (fmod is exact; the error grows as
        // |x| * 1.7e-7) rather than link libm's 7 KB multi-precision reduction.
        return sin_cos_f32(fmod_tau(x));
    }
    // Octant; move odd octants up by one so that the remainder lies in [-pi/4, pi/4].
    let mut j = (ax * FOUR_OVER_PI) as u32;
    if j & 1 == 1 {
        j += 1;
    }
    let y = j as f32;
    let z = ((ax - y * DP1) - y * DP2) - y * DP3;
    let z2 = z * z;
    let sin_poly = ((-1.951_529_6e-4 * z2 + 8.332_161e-3) * z2 - 1.666_665_5e-1) * z2 * z + z;
    let cos_poly =
        ((2.443_315_7e-5 * z2 - 1.388_731_6e-3) * z2 + 4.166_664_6e-2) * z2 * z2 - 0.5 * z2 + 1.0;
    // j mod 8 is 0, 2, 4 or 6: rotate by j * pi/4.
    let (s, c) = match j & 7 {
        0 => (sin_poly, cos_poly),
        2 => (cos_poly, -sin_poly),
        4 => (-sin_poly, -cos_poly),
        _ => (-cos_poly, sin_poly),
    };
    (if x.is_sign_negative() { -s } else { s }, c)
}

/// `fmod(x, fl(2 pi))` for finite `|x| >= fl(2 pi)`, exact (the remainder of two floats is a
/// float), by shift-and-subtract on the 24-bit significands in 32-bit integers: the same result
/// as `libm::fmodf` without its 64-bit integer division (about 1.3 KB of flash on the M4F).
fn fmod_tau(x: f32) -> f32 {
    const SIGNIFICAND: u32 = (1 << 23) - 1;
    let significand = |v: f32| (v.to_bits() & SIGNIFICAND) | (1 << 23);
    let exponent = |v: f32| (v.to_bits() >> 23) & 0xff;
    let tau = core::f32::consts::TAU;
    let divisor = significand(tau);
    // x = mx 2^(ex - 150) and tau = my 2^(ey - 150) with ex >= ey (both normal: |x| >= tau).
    let mut remainder = significand(x);
    for _ in 0..exponent(x).saturating_sub(exponent(tau)) {
        if remainder >= divisor {
            remainder -= divisor;
        }
        remainder <<= 1; // below 2^25
    }
    if remainder >= divisor {
        remainder -= divisor;
    }
    // remainder < 2^24 is exact in f32; scaling by tau's power of two is exact.
    let magnitude = remainder as f32 * f32::from_bits((exponent(tau) - 23) << 23);
    if x.is_sign_negative() {
        -magnitude
    } else {
        magnitude
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn reduction_by_two_pi_is_libm_fmodf_bit_for_bit() {
        let tau = core::f32::consts::TAU;
        let mut checked = 0;
        // Every exponent from tau's up to the largest finite float, many significands each.
        let mut bits = tau.to_bits();
        while bits < f32::MAX.to_bits() {
            for x in [f32::from_bits(bits), -f32::from_bits(bits)] {
                assert_eq!(
                    fmod_tau(x).to_bits(),
                    libm::fmodf(x, tau).to_bits(),
                    "{x:e}"
                );
                checked += 1;
            }
            bits += 9_973;
        }
        for x in [
            tau,
            8192.5f32,
            1e5,
            -3.3e4,
            f32::MAX,
            -f32::MAX,
            2.0 * tau,
            4096.0 * tau,
        ] {
            assert_eq!(
                fmod_tau(x).to_bits(),
                libm::fmodf(x, tau).to_bits(),
                "{x:e}"
            );
        }
        assert!(checked > 200_000, "{checked}");
    }

    fn worst_f32(points: impl Iterator<Item = f32>) -> (f64, f64) {
        let (mut ours, mut libm32) = (0.0f64, 0.0f64);
        for x in points {
            let (s, c) = sin_cos_f32(x);
            let (ls, lc) = libm::sincosf(x);
            let (es, ec) = libm::sincos(f64::from(x));
            ours = ours
                .max((f64::from(s) - es).abs())
                .max((f64::from(c) - ec).abs());
            libm32 = libm32
                .max((f64::from(ls) - es).abs())
                .max((f64::from(lc) - ec).abs());
        }
        (ours, libm32)
    }

    #[test]
    fn f32_sine_and_cosine_are_within_one_ulp() {
        let near = worst_f32((-1_000_000..=1_000_000).map(|i| i as f32 * 8e-6));
        let far = worst_f32((-100_000..=100_000).map(|i| i as f32 * 0.081_92));
        // Exactly representable special points.
        for x in [
            0.0f32,
            -0.0,
            core::f32::consts::FRAC_PI_4,
            core::f32::consts::PI,
            1e-30,
        ] {
            let (s, c) = sin_cos_f32(x);
            let (es, ec) = libm::sincos(f64::from(x));
            assert!(
                (f64::from(s) - es).abs() <= 1.2e-7 && (f64::from(c) - ec).abs() <= 1.2e-7,
                "{x}"
            );
        }
        assert_eq!(sin_cos_f32(-0.0).0.to_bits(), (-0.0f32).to_bits());
        std::println!(
            "worst |error| in [-8, 8]: ours {:e}, libm sincosf {:e}; in [-8192, 8192]: ours {:e}, libm {:e}",
            near.0,
            near.1,
            far.0,
            far.1
        );
        assert!(near.0 <= 1e-7, "[-8, 8]: {:e} (libm {:e})", near.0, near.1);
        assert!(
            far.0 <= 1e-7,
            "[-8192, 8192]: {:e} (libm {:e})",
            far.0,
            far.1
        );
        // Beyond the reduction limit: within |x| * 2e-7 of the truth; non-finite input: NaN.
        for x in [1e4f32, -3.3e4, 1e5] {
            let (s, c) = sin_cos_f32(x);
            let (es, ec) = libm::sincos(f64::from(x));
            let bound = f64::from(x.abs()) * 2e-7;
            assert!(
                (f64::from(s) - es).abs() < bound && (f64::from(c) - ec).abs() < bound,
                "{x}"
            );
        }
        assert!(sin_cos_f32(f32::NAN).0.is_nan() && sin_cos_f32(f32::INFINITY).1.is_nan());
    }
}
