//! The Hayati modified DH joint transform of the paper's eq. (1):
//! `A = Rz(theta) Tz(d) Tx(a) Rx(alpha) Ry(beta)`.

use crate::scalar::Real;
#[cfg(test)]
use nalgebra::{IsometryMatrix3, Rotation3, Translation3};
use nalgebra::{Matrix3, SVector, Vector3};

/// Number of poses evaluated side by side by [`PreparedJoint::append_lanes`]: 4 on a PC, where
/// the compiler turns the lanes into SIMD, 1 on a 32-bit ARM controller, which has no SIMD for
/// floats and where four poses' worth of lanes spill registers (the objective costs 925
/// instructions per pose with 4 lanes on the Cortex-M4F). Every lane is computed with the same
/// element-wise operations, and the objective sums its terms in groups of [`GROUP`] either way,
/// so the results are bit-identical.
pub const LANES: usize = if cfg!(target_arch = "arm") { 1 } else { 4 };

/// Poses whose objective terms are summed together before the group is added to the total
/// (the summation order that makes every [`LANES`] give the same bits).
pub const GROUP: usize = 4;

/// One value for each of `L` poses, [`LANES`] unless said otherwise (structure of arrays, so the
/// compiler vectorises).
pub type Lanes<T, const L: usize = LANES> = SVector<T, L>;

/// A frame for `L` poses at once ([`LANES`] unless said otherwise): the columns of the rotation
/// and the origin, each coordinate as lanes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaneFrame<T: Real, const L: usize = LANES> {
    /// Columns x, y, z of the rotation; `columns[j][i]` is entry (i, j) in every lane.
    pub columns: [[Lanes<T, L>; 3]; 3],
    /// Origin, mm.
    pub origin: [Lanes<T, L>; 3],
}

/// `a * ca + b * cb` for three lane coordinates.
#[inline(always)]
fn combine<T: Real, const L: usize>(
    a: &[Lanes<T, L>; 3],
    ca: &Lanes<T, L>,
    b: &[Lanes<T, L>; 3],
    cb: &Lanes<T, L>,
) -> [Lanes<T, L>; 3] {
    let [a0, a1, a2] = a;
    let [b0, b1, b2] = b;
    [
        a0.component_mul(ca) + b0.component_mul(cb),
        a1.component_mul(ca) + b1.component_mul(cb),
        a2.component_mul(ca) + b2.component_mul(cb),
    ]
}

/// `a * ca + b * cb` for three lane coordinates and scalar factors.
#[inline(always)]
fn combine_scalar<T: Real, const L: usize>(
    a: &[Lanes<T, L>; 3],
    ca: T,
    b: &[Lanes<T, L>; 3],
    cb: T,
) -> [Lanes<T, L>; 3] {
    let [a0, a1, a2] = a;
    let [b0, b1, b2] = b;
    [a0 * ca + b0 * cb, a1 * ca + b1 * cb, a2 * ca + b2 * cb]
}

/// A joint of the actual model prepared for fast evaluation: the constant trigonometry of
/// `alpha`, `beta` and `theta_offset` is computed once, so a pose needs only `sin q`, `cos q`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PreparedJoint<T: Real> {
    /// Link length `a`, mm.
    pub a: T,
    /// Link offset `d`, mm.
    pub d: T,
    /// `(cos, sin)` of the joint zero offset `theta_offset + dtheta`.
    pub offset: (T, T),
    /// `Rx(alpha) Ry(beta)`, the constant right factor of the joint rotation.
    pub twist: Matrix3<T>,
    /// `(cos alpha, sin alpha)`, and whether `beta` is exactly zero (then `twist = Rx(alpha)`,
    /// which [`PreparedJoint::append`] applies with 12 instead of 27 multiplications).
    alpha_only: Option<(T, T)>,
}

impl<T: Real> PreparedJoint<T> {
    /// Prepares a joint from its actual MDH values (mm, rad).
    #[cfg(test)]
    pub fn new(a: T, alpha: T, theta_offset: T, d: T, beta: T) -> Self {
        let cos_sin = |x: T| {
            let (s, c) = x.sin_cos_fast();
            (c, s)
        };
        Self::from_trig(a, d, cos_sin(alpha), cos_sin(beta), cos_sin(theta_offset))
    }

    /// Prepares a joint from `a`, `d` (mm) and `(cos, sin)` of `alpha`, `beta`, `theta_offset`.
    pub fn from_trig(a: T, d: T, (ca, sa): (T, T), (cb, sb): (T, T), offset: (T, T)) -> Self {
        // Rx(alpha) Ry(beta) in closed form.
        #[rustfmt::skip]
        let twist = Matrix3::new(
            cb,       T::zero(), sb,
            sa * sb,  ca,        -sa * cb,
            -ca * sb, sa,        ca * cb,
        );
        let alpha_only = (sb == T::zero() && cb == T::one()).then_some((ca, sa));
        Self {
            a,
            d,
            offset,
            twist,
            alpha_only,
        }
    }

    /// `(cos theta, sin theta)` for a joint reading with `(cos q, sin q)`, by angle addition.
    #[inline(always)]
    pub fn theta(&self, cos_q: T, sin_q: T) -> (T, T) {
        let (co, so) = self.offset;
        (cos_q * co - sin_q * so, sin_q * co + cos_q * so)
    }

    /// The joint transform `A` (eq. 1) in closed form for `(cos theta, sin theta)` (tests check
    /// the chained form against it).
    #[cfg(test)]
    pub fn transform(&self, cos_theta: T, sin_theta: T) -> IsometryMatrix3<T> {
        let (c, s) = (cos_theta, sin_theta);
        #[rustfmt::skip]
        let rz = Matrix3::new(
            c,         -s,        T::zero(),
            s,         c,         T::zero(),
            T::zero(), T::zero(), T::one(),
        );
        IsometryMatrix3::from_parts(
            Translation3::new(self.a * c, self.a * s, self.d),
            Rotation3::from_matrix_unchecked(rz * self.twist),
        )
    }

    /// Appends this joint to the frame `(rotation, origin)` of the previous joint, in place:
    /// `F <- F * A`. Returns the x axis of `F_prev Rz(theta)` (the axis of `a` and `alpha`).
    ///
    /// Cost: 30 multiplications when `beta = 0`, 45 otherwise (63 for a general rigid product).
    #[inline(always)]
    pub fn append(
        &self,
        rotation: &mut Matrix3<T>,
        origin: &mut Vector3<T>,
        cos_theta: T,
        sin_theta: T,
    ) -> Vector3<T> {
        let (c, s) = (cos_theta, sin_theta);
        let r1 = rotation.column(0).into_owned();
        let r2 = rotation.column(1).into_owned();
        let z = rotation.column(2).into_owned();
        // Columns of F_prev Rz(theta).
        let x = r1 * c + r2 * s;
        let y = r2 * c - r1 * s;
        *origin += x * self.a + z * self.d;
        *rotation = match self.alpha_only {
            // [x, y, z] Rx(alpha) = [x, c y + s z, c z - s y].
            Some((ca, sa)) => Matrix3::from_columns(&[x, y * ca + z * sa, z * ca - y * sa]),
            None => Matrix3::from_columns(&[x, y, z]) * self.twist,
        };
        x
    }
}

impl<T: Real> PreparedJoint<T> {
    /// [`PreparedJoint::append`] for `L` poses at once, with `cos q` and `sin q` as lanes.
    #[inline(always)]
    pub fn append_lanes<const L: usize>(
        &self,
        frame: &mut LaneFrame<T, L>,
        cos_q: &Lanes<T, L>,
        sin_q: &Lanes<T, L>,
    ) {
        let (co, so) = self.offset;
        let ct = cos_q * co - sin_q * so;
        let st = sin_q * co + cos_q * so;
        let neg_st = -st;
        let [r1, r2, z] = &frame.columns;
        let x = combine(r1, &ct, r2, &st);
        let y = combine(r2, &ct, r1, &neg_st);
        let [o0, o1, o2] = &mut frame.origin;
        let [x0, x1, x2] = &x;
        let [z0, z1, z2] = z;
        *o0 += x0 * self.a + z0 * self.d;
        *o1 += x1 * self.a + z1 * self.d;
        *o2 += x2 * self.a + z2 * self.d;
        frame.columns = match self.alpha_only {
            Some((ca, sa)) => {
                let new_y = combine_scalar(&y, ca, z, sa);
                let new_z = combine_scalar(z, ca, &y, -sa);
                [x, new_y, new_z]
            }
            None => {
                let t = &self.twist;
                let column = |j: usize| {
                    let (t0, t1, t2) = (t[(0, j)], t[(1, j)], t[(2, j)]);
                    let xy = combine_scalar(&x, t0, &y, t1);
                    let [a0, a1, a2] = xy;
                    let [z0, z1, z2] = z;
                    [a0 + z0 * t2, a1 + z1 * t2, a2 + z2 * t2]
                };
                [column(0), column(1), column(2)]
            }
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq. (1) from the elementary transforms, as nalgebra products.
    fn elementary(a: f64, alpha: f64, theta: f64, d: f64, beta: f64) -> IsometryMatrix3<f64> {
        let rz = IsometryMatrix3::rotation(Vector3::z() * theta);
        let tz = IsometryMatrix3::translation(0.0, 0.0, d);
        let tx = IsometryMatrix3::translation(a, 0.0, 0.0);
        let rx = IsometryMatrix3::rotation(Vector3::x() * alpha);
        let ry = IsometryMatrix3::rotation(Vector3::y() * beta);
        rz * tz * tx * rx * ry
    }

    #[test]
    fn closed_form_equals_the_product_of_elementary_transforms() {
        for beta in [0.02, 0.0] {
            check_joint(170.0, -1.3, 0.4, 55.0, beta);
        }
    }

    fn check_joint(a: f64, alpha: f64, offset: f64, d: f64, beta: f64) {
        let joint = PreparedJoint::new(a, alpha, offset, d, beta);
        assert_eq!(joint.alpha_only.is_some(), beta == 0.0);
        for q in [-3.0, -0.5, 0.0, 1.0, 2.5] {
            let (s, c) = libm::sincos(q);
            let (ct, st) = joint.theta(c, s);
            let closed = joint.transform(ct, st);
            let expected = elementary(a, alpha, q + offset, d, beta);
            assert!((closed.to_homogeneous() - expected.to_homogeneous()).norm() < 1e-12);

            let previous = elementary(10.0, 0.3, -0.2, 20.0, 0.1);
            let mut rotation = *previous.rotation.matrix();
            let mut origin = previous.translation.vector;
            let x = joint.append(&mut rotation, &mut origin, ct, st);
            let composed = previous * expected;
            assert!((rotation - composed.rotation.matrix()).norm() < 1e-12);
            assert!((origin - composed.translation.vector).norm() < 1e-12);
            let x_expected = (previous * IsometryMatrix3::rotation(Vector3::z() * (q + offset)))
                .rotation
                * Vector3::x();
            assert!((x - x_expected).norm() < 1e-12);
        }
    }
}
