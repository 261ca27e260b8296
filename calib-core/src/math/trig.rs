//! Sine and cosine of small angles: a short polynomial for the small parameter errors
//! (|x| <= 0.1 rad) that every objective evaluation needs, so that preparing a candidate model
//! costs no libm call, and angle addition.
//!
//! Error bound of [`sin_cos_small`] on `|x| <= 0.1`: the first omitted terms are
//! `x^11 / 11! < 2.6e-19` and `x^12 / 12! < 2.1e-21`, far below one ulp; the measured worst
//! difference to `libm` is 1 ulp in f64 and f32 (unit test `small_angle_polynomial_matches_libm`).

use crate::scalar::Real;

/// Largest |x| (rad) for which [`sin_cos_small`] uses its polynomial.
pub const SMALL: f64 = 0.1;

/// `(sin x, cos x)` for any finite `x` (rad): a Taylor polynomial for `|x| <= 0.1`, libm beyond.
#[inline]
pub fn sin_cos_small<T: Real>(x: T) -> (T, T) {
    if x.abs() > T::of(SMALL) {
        return x.sin_cos_fast();
    }
    let x2 = x * x;
    // Horner form of x - x^3/3! + ... + x^9/9! and 1 - x^2/2! + ... + x^10/10!, multiplying by
    // the reciprocals (rounded once, at compile time): a division takes as long as a dozen
    // multiplications, and the swarm prepares 18 of these per candidate model (its eighteen
    // divisions were most of the 167 ns `Problem::kinematics` took on the paper robot).
    let r = |n: f64| T::of(1.0 / n);
    let sin = x
        * (T::one()
            - x2 * r(6.0)
                * (T::one()
                    - x2 * r(20.0) * (T::one() - x2 * r(42.0) * (T::one() - x2 * r(72.0)))));
    let cos = T::one()
        - x2 * r(2.0)
            * (T::one()
                - x2 * r(12.0)
                    * (T::one()
                        - x2 * r(30.0) * (T::one() - x2 * r(56.0) * (T::one() - x2 * r(90.0)))));
    (sin, cos)
}

/// `(cos, sin)` of `a + b` from `(cos a, sin a)` and `(cos b, sin b)` (angle addition).
#[inline(always)]
pub fn add<T: Real>((ca, sa): (T, T), (cb, sb): (T, T)) -> (T, T) {
    (ca * cb - sa * sb, sa * cb + ca * sb)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    #[test]
    fn small_angle_polynomial_matches_libm() {
        let mut worst64 = 0.0f64;
        let mut worst32 = 0.0f32;
        for i in -10_000..=10_000 {
            let x = f64::from(i) * 1e-5;
            let (s, c) = sin_cos_small(x);
            let (ls, lc) = libm::sincos(x);
            worst64 = worst64.max((s - ls).abs()).max((c - lc).abs());
            let xf = x as f32;
            let (s, c) = sin_cos_small(xf);
            let (ls, lc) = libm::sincosf(xf);
            worst32 = worst32.max((s - ls).abs()).max((c - lc).abs());
        }
        // One ulp of 1.0: 2.2e-16 (f64) and 1.2e-7 (f32).
        assert!(worst64 <= f64::EPSILON, "f64 worst {worst64:e}");
        assert!(worst32 <= f32::EPSILON, "f32 worst {worst32:e}");
        // Beyond the polynomial range it is the scalar's own sine and cosine.
        assert_eq!(sin_cos_small(0.7f64), libm::sincos(0.7));
    }
}
