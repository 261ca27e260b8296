//! The Halton low-discrepancy sequence of the paper's eq. (8)-(9), in integer arithmetic.
//!
//! Point `k` of the D-dimensional sequence has coordinate `i` equal to the radical inverse of `k`
//! in the i-th prime base: write `k = d_j b^j + ... + d_1 b + d_0` (eq. 8), then
//! `phi_b(k) = d_0 / b + d_1 / b^2 + ... + d_j / b^(j+1)` (eq. 9). The digits are accumulated as an
//! exact integer fraction `numerator / b^(j+1)` and divided once, so every value is the correctly
//! rounded `f64` of the exact fraction and lies in `[0, 1)`.
//!
//! Our index is the paper's `k` itself: `k = 0` is the all-zero point. The swarm starts at
//! `k = 1` by default (the zero point would put the first particle on the corner of the range).
//!
//! [`Scrambling::Reverse`] is the deterministic "reverse Halton" digit permutation of
//! Vandewoestyne and Cools (2006): every digit `d != 0` becomes `b - d`. It breaks the strong
//! correlation between the first points of neighbouring large bases (for D = 24 the bases reach 89).

/// The first 64 primes: the bases of dimensions 1 to 64.
pub const PRIMES: [u32; 64] = [
    2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89, 97,
    101, 103, 107, 109, 113, 127, 131, 137, 139, 149, 151, 157, 163, 167, 173, 179, 181, 191, 193,
    197, 199, 211, 223, 227, 229, 233, 239, 241, 251, 257, 263, 269, 271, 277, 281, 283, 293, 307,
    311,
];

/// Largest supported dimension of a Halton point.
pub const MAX_DIMENSION: usize = PRIMES.len();

/// Digit permutation applied to the radical inverse.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Scrambling {
    /// Plain Halton, as in the paper.
    #[default]
    None,
    /// Reverse Halton (Vandewoestyne and Cools 2006): digit `d != 0` becomes `b - d`.
    Reverse,
}

/// Radical inverse `phi_b(k)` of eq. (9) in `[0, 1)`; `base` must be at least 2 (smaller bases
/// give 0).
pub fn radical_inverse(index: u64, base: u32, scrambling: Scrambling) -> f64 {
    if base < 2 {
        return 0.0;
    }
    let b = u128::from(base);
    let mut k = u128::from(index);
    let mut numerator: u128 = 0;
    let mut denominator: u128 = 1;
    // index < 2^64 has at most 64 digits, so denominator <= base * index < 2^(64 + 32): no overflow.
    while k > 0 {
        let mut digit = k % b;
        if scrambling == Scrambling::Reverse && digit != 0 {
            digit = b - digit;
        }
        numerator = numerator * b + digit;
        denominator *= b;
        k /= b;
    }
    // The digits were pushed most-significant-last: numerator holds d_0 b^j + ... + d_j, which over
    // b^(j+1) is exactly eq. (9).
    let value = numerator as f64 / denominator as f64;
    // Fractions within 2^-54 of 1 (indices near 2^64) would round up to 1.
    if value < 1.0 { value } else { ONE_BELOW }
}

/// The largest `f64` below 1.
const ONE_BELOW: f64 = 1.0 - f64::EPSILON / 2.0;

/// Writes Halton point `index` (the paper's k) into `point`, coordinate i in base `PRIMES[i]`.
/// Dimensions beyond [`MAX_DIMENSION`] are set to 0.5 (they never occur with the swarm's const
/// check).
// One copy for the swarm's two calls (positions and velocities: controller flash; it runs only
// at the start).
#[cfg_attr(target_arch = "arm", inline(never))]
pub fn halton_point(index: u64, scrambling: Scrambling, point: &mut [f64]) {
    for (i, value) in point.iter_mut().enumerate() {
        *value = PRIMES
            .get(i)
            .map_or(0.5, |&base| radical_inverse(index, base, scrambling));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_values_in_bases_2_3_5_are_exact() {
        let expect = |base, values: &[f64]| {
            for (k, v) in values.iter().enumerate() {
                assert_eq!(
                    radical_inverse(k as u64, base, Scrambling::None),
                    *v,
                    "base {base} k {k}"
                );
            }
        };
        expect(
            2,
            &[0.0, 0.5, 0.25, 0.75, 0.125, 0.625, 0.375, 0.875, 0.0625],
        );
        expect(
            3,
            &[
                0.0,
                1.0 / 3.0,
                2.0 / 3.0,
                1.0 / 9.0,
                4.0 / 9.0,
                7.0 / 9.0,
                2.0 / 9.0,
            ],
        );
        expect(5, &[0.0, 0.2, 0.4, 0.6, 0.8, 0.04, 0.24, 0.44]);
    }

    #[test]
    fn reverse_scrambling_permutes_nonzero_digits() {
        // Base 3: k = 1 -> digit 1 -> 2 -> 2/3; k = 3 = (10)_3 -> digits 0, 1 -> 0/3 + 2/9.
        assert_eq!(radical_inverse(1, 3, Scrambling::Reverse), 2.0 / 3.0);
        assert_eq!(radical_inverse(3, 3, Scrambling::Reverse), 2.0 / 9.0);
        assert_eq!(radical_inverse(0, 89, Scrambling::Reverse), 0.0);
        // Base 2 has the identity as its only permutation fixing 0.
        for k in 0..100 {
            assert_eq!(
                radical_inverse(k, 2, Scrambling::Reverse),
                radical_inverse(k, 2, Scrambling::None)
            );
        }
    }

    #[test]
    fn values_stay_in_unit_interval_for_huge_indices() {
        for base in PRIMES {
            for index in [u64::MAX, u64::MAX - 1, 1 << 63, 123_456_789_012_345] {
                let v = radical_inverse(index, base, Scrambling::None);
                assert!((0.0..1.0).contains(&v), "base {base} index {index}: {v}");
            }
        }
        assert_eq!(radical_inverse(5, 1, Scrambling::None), 0.0);
    }
}
