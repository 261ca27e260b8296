//! Rotation group helpers: the exact log map of a rotation matrix and the inverse of its right
//! Jacobian. Both are exact for every angle in `[0, pi]` (series near 0, the symmetric part near pi).

use crate::scalar::Real;
use nalgebra::{Matrix3, Rotation3, Vector3};

/// `R = Rz(yaw) Ry(pitch) Rx(roll)` (rad): nalgebra's `Rotation3::from_euler_angles`, term for
/// term, but with the core's sine and cosine ([`Real::sin_cos_fast`]), so that f32 needs no f64
/// arithmetic and f64 gives the same bits as nalgebra with libm.
pub fn rotation_rpy<T: Real>(roll: T, pitch: T, yaw: T) -> Rotation3<T> {
    let (sr, cr) = roll.sin_cos_fast();
    let (sp, cp) = pitch.sin_cos_fast();
    let (sy, cy) = yaw.sin_cos_fast();
    Rotation3::from_matrix_unchecked(Matrix3::new(
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    ))
}

/// Below this angle (rad) the small-angle series are used.
const SMALL_ANGLE: f64 = 1e-4;
/// Below this angle (rad) the right-Jacobian coefficient uses its series (avoids cancellation).
const JACOBIAN_SERIES_ANGLE: f64 = 0.1;

/// `[v]x`, the cross-product matrix of `v`.
pub fn skew<T: Real>(v: &Vector3<T>) -> Matrix3<T> {
    let z = T::zero();
    #[rustfmt::skip]
    let m = Matrix3::new(
        z,     -v.z,  v.y,
        v.z,   z,     -v.x,
        -v.y,  v.x,   z,
    );
    m
}

/// The rotation vector `phi` (rad) with `exp([phi]x) = r`, `|phi| <= pi`; exact log map.
///
/// `r` must be a rotation matrix (orthonormal, det +1) up to rounding.
pub fn log<T: Real>(r: &Matrix3<T>) -> Vector3<T> {
    let two = T::of(2.0);
    // v = 2 sin(theta) n, trace - 1 = 2 cos(theta).
    let v = Vector3::new(r.m32 - r.m23, r.m13 - r.m31, r.m21 - r.m12);
    let two_sin = super::norm(&v);
    let two_cos = r.m11 + r.m22 + r.m33 - T::one();
    let theta = two_sin.atan2(two_cos);
    if theta < T::of(SMALL_ANGLE) {
        // theta / sin(theta) = 1 + theta^2/6 + 7 theta^4/360.
        let t2 = theta * theta;
        return v * ((T::one() + t2 / T::of(6.0) + t2 * t2 * T::of(7.0 / 360.0)) / two);
    }
    let cos = two_cos / two;
    if cos > T::of(-0.9) {
        return v * (theta / two_sin);
    }
    // Near pi: n n^T = (S - cos I) / (1 - cos) with S the symmetric part; take the column of the
    // largest diagonal entry, and the sign that agrees with v = 2 sin(theta) n.
    let one_minus_cos = T::one() - cos;
    let s = (r + r.transpose()) / two;
    // (column of S, its diagonal entry, unit vector of that axis) for the largest diagonal entry.
    let (column, diagonal, axis) = if s.m11 >= s.m22 && s.m11 >= s.m33 {
        (s.column(0), s.m11, Vector3::x())
    } else if s.m22 >= s.m33 {
        (s.column(1), s.m22, Vector3::y())
    } else {
        (s.column(2), s.m33, Vector3::z())
    };
    let nk = ((diagonal - cos) / one_minus_cos)
        .max(T::zero())
        .sqrt_ieee();
    // Off-diagonal entries give n_j = S_kj / ((1 - cos) n_k); the k-th entry is n_k itself.
    let off_diagonal = column.into_owned() - axis * diagonal;
    let mut n = off_diagonal / (one_minus_cos * nk) + axis * nk;
    if n.dot(&v) < T::zero() {
        n = -n;
    }
    n * theta
}

/// Rotation angle (rad) between two rotation matrices, `|log(a b^T)|`, without forming the product
/// and, for angles up to 0.1 rad, without any libm call: `|a - b|_F^2 = 8 sin^2(angle / 2)`, then
/// `angle = 2 asin(x)` by its series (first omitted term below 2e-19 for x <= 0.05), libm beyond.
pub fn angle_between<T: Real>(a: &Matrix3<T>, b: &Matrix3<T>) -> T {
    let x = ((a - b).norm_squared() / T::of(8.0)).sqrt_ieee();
    if x > T::of(0.05) {
        return T::of(2.0) * x.min(T::one()).asin();
    }
    let x2 = x * x;
    // asin x = x (1 + x^2/6 + 3x^4/40 + 5x^6/112 + 35x^8/1152 + 63x^10/2816).
    let series = T::one()
        + x2 * (T::of(1.0 / 6.0)
            + x2 * (T::of(3.0 / 40.0)
                + x2 * (T::of(5.0 / 112.0)
                    + x2 * (T::of(35.0 / 1152.0) + x2 * T::of(63.0 / 2816.0)))));
    T::of(2.0) * x * series
}

/// Squared rotation angle (rad^2) between two rotation matrices, `|log(a b^T)|^2`, with no square
/// root and, up to 0.1 rad, no libm call: with `x^2 = |a - b|_F^2 / 8 = sin^2(angle / 2)`,
/// `angle^2 = 4 asin^2(x) = 4 x^2 (1 + x^2/3 + 8x^4/45 + 4x^6/35 + 128x^8/1575 + 256x^10/4158)`;
/// the first omitted term is below 2e-17 relative for x <= 0.05.
pub fn angle_squared_between<T: Real>(a: &Matrix3<T>, b: &Matrix3<T>) -> T {
    angle_squared_from_chord((a - b).norm_squared())
}

/// [`angle_squared_between`] from the squared chord `|a - b|_F^2` of the two rotations.
pub fn angle_squared_from_chord<T: Real>(chord_squared: T) -> T {
    let x2 = chord_squared / T::of(8.0);
    if x2 > T::of(0.05 * 0.05) {
        let angle = T::of(2.0) * x2.sqrt_ieee().min(T::one()).asin();
        return angle * angle;
    }
    let series = T::one()
        + x2 * (T::of(1.0 / 3.0)
            + x2 * (T::of(8.0 / 45.0)
                + x2 * (T::of(4.0 / 35.0)
                    + x2 * (T::of(128.0 / 1575.0) + x2 * T::of(256.0 / 4158.0)))));
    T::of(4.0) * x2 * series
}

/// Inverse of the right Jacobian of SO(3) at `phi` (rad):
/// `Jr^-1 = I + [phi]x / 2 + (1/theta^2 - (1 + cos theta) / (2 theta sin theta)) [phi]x^2`.
///
/// With it, `log(E exp([eta]x)) = log(E) + Jr^-1(log E) eta + O(eta^2)`.
pub fn right_jacobian_inverse<T: Real>(phi: &Vector3<T>) -> Matrix3<T> {
    let theta = super::norm(phi);
    let k = skew(phi);
    let coefficient = if theta < T::of(JACOBIAN_SERIES_ANGLE) {
        // 1/12 + theta^2/720 + theta^4/30240; the next term is below 1e-12 here.
        let t2 = theta * theta;
        T::of(1.0 / 12.0) + t2 / T::of(720.0) + t2 * t2 / T::of(30240.0)
    } else {
        let (s, c) = theta.sin_cos_fast();
        T::one() / (theta * theta) - (T::one() + c) / (T::of(2.0) * theta * s)
    };
    Matrix3::identity() + k * T::of(0.5) + k * k * coefficient
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_rpy_is_nalgebras_euler_angles_bit_for_bit_in_f64() {
        for i in 0..200 {
            let v = |k: f64| (f64::from(i) * 0.731 + k).sin() * 3.0;
            let (r, p, y) = (v(0.0), v(1.0), v(2.0));
            assert_eq!(rotation_rpy(r, p, y), Rotation3::from_euler_angles(r, p, y));
        }
    }

    fn exp(phi: &Vector3<f64>) -> Matrix3<f64> {
        *Rotation3::new(*phi).matrix()
    }

    #[test]
    fn log_inverts_exp_over_the_whole_range() {
        let axes = [
            Vector3::new(0.3, -0.5, 0.8).normalize(),
            Vector3::new(-0.9, 0.1, 0.2).normalize(),
            Vector3::z(),
        ];
        let angles = [
            0.0,
            1e-9,
            1e-5,
            0.03,
            1.0,
            2.0,
            2.9,
            3.1,
            core::f64::consts::PI - 1e-7,
        ];
        for axis in &axes {
            for &angle in &angles {
                let phi = axis * angle;
                let back = log(&exp(&phi));
                assert!(
                    (back - phi).norm() < 1e-14,
                    "angle {angle}: {back} vs {phi}"
                );
            }
        }
    }

    #[test]
    fn log_at_exactly_pi_gives_a_half_turn() {
        let r = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
        let phi: Vector3<f64> = log(&r);
        assert!((phi.norm() - core::f64::consts::PI).abs() < 1e-15);
        assert!((phi.normalize().x.abs() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn angle_between_equals_the_norm_of_the_log() {
        let a = exp(&Vector3::new(0.4, -1.0, 2.0));
        for angle in [0.0, 1e-10, 1e-6, 1e-3, 0.03, 0.0999, 0.1001, 0.5, 3.0] {
            let delta = exp(&(Vector3::new(1.0, 2.0, -0.5).normalize() * angle));
            let b = delta * a;
            let got = angle_between(&b, &a);
            assert!(
                (got - angle).abs() <= 2e-15 * (1.0 + angle),
                "{angle}: {got}"
            );
            assert!((got - log(&(b * a.transpose())).norm()).abs() <= 2e-15 * (1.0 + angle));
            let squared = angle_squared_between(&b, &a);
            assert!(
                (squared.sqrt() - angle).abs() <= 2e-15 * (1.0 + angle),
                "{angle}"
            );
        }
    }

    #[test]
    fn right_jacobian_inverse_matches_finite_differences() {
        for phi in [
            Vector3::new(0.01, -0.02, 0.015),
            Vector3::new(0.5, 0.3, -0.4),
            Vector3::new(1.5, -1.0, 1.2),
        ] {
            let e = exp(&phi);
            let j = right_jacobian_inverse(&phi);
            let h = 1e-6;
            for k in 0..3 {
                let mut eta = Vector3::zeros();
                eta[k] = h;
                let fd = (log(&(e * exp(&eta))) - log(&(e * exp(&-eta)))) / (2.0 * h);
                assert!((fd - j.column(k)).norm() < 1e-8, "{fd} vs {}", j.column(k));
            }
        }
    }
}
