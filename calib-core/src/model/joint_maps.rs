//! Per-joint angle-error maps: what a geometric calibration leaves on a real robot.
//!
//! Joint `j`'s map is a Fourier series of its own reading `q_j` (rad),
//!
//! `dq_j(q_j) = sum_{h=1..H} a_jh sin(h q_j) + b_jh cos(h q_j)`,
//!
//! added to the reading before the forward kinematics: the robot's kinematic joint angle is
//! `q_j + dq_j(q_j)`. `H` is used harmonics, at most the compile-time capacity `C`. The series is
//! evaluated with one sine and cosine of `q_j` and the angle-addition recurrence
//! `sin((h+1)q) = sin(hq) cos q + cos(hq) sin q`, `cos((h+1)q) = cos(hq) cos q - sin(hq) sin q`
//! (4 multiplications and 2 additions per harmonic; the rounding error grows linearly with `h`,
//! `h * 6e-8` relative in f32 at most, below 1e-8 rad on a map of 1 mrad with 64 harmonics).
//!
//! A map is stored as coefficients rather than as a lookup table: a table that interpolates
//! linearly to 1 % of a harmonic of order 60 needs about 22 samples per period, 1,320 per
//! revolution, so 2 revolutions for 6 joints in f32 take 63 KiB against 2.9 KiB of coefficients
//! (6 joints x 120 x 4 bytes) and the parameter block's budget of 8 KiB.
//!
//! # The bounds the controller relies on
//!
//! For each map, [`JointMaps::new`] computes `M_j = sum_h sqrt(a_jh^2 + b_jh^2)` (no reading has
//! `|dq_j| > M_j`) and `L_j = sum_h h sqrt(a_jh^2 + b_jh^2)` (no two readings have
//! `|dq_j(x) - dq_j(y)| > L_j |x - y|`, since `|d/dq (a sin hq + b cos hq)| <= h sqrt(a^2 + b^2)`),
//! and refuses maps with `L_j >` [`MAX_SLOPE`]. Then `q -> q + dq(q)` is strictly increasing and
//! the reading `q*` for a kinematic angle `t` is the unique fixed point of `F(q) = t - dq(q)`, a
//! contraction with constant `L_j`: from `q_0 = t - dq(t)`, which is within `L_j M_j` of `q*`
//! (`|q_0 - q*| = |dq(q*) - dq(t)| <= L_j |q* - t| = L_j |dq(q*)|`), iteration `k` is within
//! `L_j^(k+1) M_j` ([`JointMaps::readings`]). Identified UR10 maps have `M_j` near 1 mrad and
//! `L_j` of a few hundredths: two iterations bring the reading within 1e-7 rad.

use crate::model::KinematicsError;
use crate::model::joint_number;
use crate::model::{JointCount, JointTable};
use crate::scalar::Real;
use nalgebra::Const;

/// Largest accepted slope bound `L_j` of a map (dimensionless): the fixed point of the inverse
/// halves its error at least every iteration. Identified maps are below 0.1.
pub const MAX_SLOPE: f64 = 0.5;

/// Largest accepted magnitude of one coefficient, rad (10 mrad; identified maps are below 1 mrad).
pub const MAX_COEFFICIENT: f64 = 0.01;

/// Iterations [`JointMaps::readings`] runs at most (with `L_j <=` [`MAX_SLOPE`] and `M_j <= L_j`,
/// 24 iterations reach `0.5^25 < 3e-8` rad in the worst accepted case).
pub const MAX_FIXED_POINT_ITERATIONS: u32 = 24;

/// `(sin(h q), cos(h q))` for `h = 1, 2, ...` without end, by the angle-addition recurrence from
/// one `sin_cos` of `q` (rad): the one evaluation of a map's harmonics, on the controller
/// ([`JointMaps::error`]) and in the host's identification (its basis), so that both see the same
/// numbers to the last bit.
pub fn harmonics<T: Real>(q: T) -> Harmonics<T> {
    let (s1, c1) = q.sin_cos_fast();
    Harmonics {
        first: (s1, c1),
        next: (s1, c1),
    }
}

/// The iterator of [`harmonics`].
#[derive(Clone, Copy, Debug)]
pub struct Harmonics<T> {
    first: (T, T),
    next: (T, T),
}

impl<T: Real> Iterator for Harmonics<T> {
    type Item = (T, T);

    #[inline]
    fn next(&mut self) -> Option<(T, T)> {
        let (s1, c1) = self.first;
        let (s, c) = self.next;
        self.next = (s * c1 + c * s1, c * c1 - s * s1);
        Some((s, c))
    }
}

/// One map's value at reading `q` (rad): `sum_h sin[h-1] sin(h q) + cos[h-1] cos(h q)` over the
/// shorter of the two coefficient slices (rad), summed from `h = 1` up, each term `a s + b c`.
pub fn series<T: Real>(sin: &[T], cos: &[T], q: T) -> T {
    if sin.is_empty() || cos.is_empty() {
        return T::zero();
    }
    (sin.iter().zip(cos).zip(harmonics(q))).fold(T::zero(), |error, ((a, b), (s, c))| {
        error + (*a * s + *b * c)
    })
}

/// The angle-error maps of `N` joints with room for `C` harmonics each.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointMaps<T: Real, N: JointCount, const C: usize> {
    harmonics: u16,
    sin: N::Table<[T; C]>,
    cos: N::Table<[T; C]>,
    amplitude_bound: N::Table<T>,
    slope_bound: N::Table<T>,
}

impl<T: Real, const N: usize, const C: usize> JointMaps<T, Const<N>, C> {
    /// Maps that are zero everywhere (a geometric model; a joint count fixed at compile time,
    /// [`JointMaps::zeros_for`] takes any).
    pub fn zero() -> Self {
        Self::zeros_for(Const)
    }
}

impl<T: Real, N: JointCount, const C: usize> JointMaps<T, N, C> {
    /// Maps of a robot of `joints` joints that are zero everywhere (a geometric model).
    pub fn zeros_for(joints: N) -> Self {
        Self {
            harmonics: 0,
            sin: joints.table([T::zero(); C]),
            cos: joints.table([T::zero(); C]),
            amplitude_bound: joints.table(T::zero()),
            slope_bound: joints.table(T::zero()),
        }
    }

    /// The joint count.
    pub fn joint_count(&self) -> N {
        N::of(&self.amplitude_bound)
    }

    /// Sets the maps to zero everywhere in place ([`JointMaps::zero`] without a temporary: a
    /// controller with little stack resets its model's storage).
    pub fn clear(&mut self) {
        self.harmonics = 0;
        for row in self.sin.iter_mut().chain(self.cos.iter_mut()) {
            row.fill(T::zero());
        }
        self.amplitude_bound.fill(T::zero());
        self.slope_bound.fill(T::zero());
    }

    /// The maps with `harmonics` used harmonics: `sin[j][h-1] = a_jh`, `cos[j][h-1] = b_jh` (rad);
    /// coefficients beyond `harmonics` must be zero. Refused, naming the joint, when a
    /// coefficient is not finite or beyond [`MAX_COEFFICIENT`], when a map's slope bound exceeds
    /// [`MAX_SLOPE`], or when `harmonics > C`.
    pub fn new(
        harmonics: usize,
        sin: N::Table<[T; C]>,
        cos: N::Table<[T; C]>,
    ) -> Result<Self, KinematicsError> {
        crate::model::check_count(sin.len(), cos.len())?;
        let mut maps = Self::zeros_for(N::of(&sin));
        maps.sin = sin;
        maps.cos = cos;
        maps.settle(harmonics)?;
        Ok(maps)
    }

    /// Sets the maps of a robot of `joints` joints in place (no copy of the coefficient arrays,
    /// for a controller's stack): `coefficient(j, h)` gives `(a_jh, b_jh)` for joint `j` (0-based) and harmonic `h`
    /// (1-based) up to `harmonics`, or `None` to stop. Refused as [`new`](Self::new) refuses,
    /// and then the maps are zero.
    // Inlined on a controller into the block reader, its one caller there (less flash).
    #[cfg_attr(target_arch = "arm", inline(always))]
    pub fn set(
        &mut self,
        joints: N,
        harmonics: usize,
        mut coefficient: impl FnMut(usize, usize) -> Option<(T, T)>,
    ) -> Result<(), KinematicsError> {
        *self = Self::zeros_for(joints);
        if harmonics > C {
            return Err(KinematicsError::TooManyHarmonics);
        }
        for (j, (a, b)) in self.sin.iter_mut().zip(self.cos.iter_mut()).enumerate() {
            for (h, (a, b)) in a.iter_mut().zip(b.iter_mut()).take(harmonics).enumerate() {
                let Some(pair) = coefficient(j, h + 1) else {
                    *self = Self::zeros_for(self.joint_count());
                    return Err(KinematicsError::InvalidJointMap {
                        joint: joint_number(j),
                    });
                };
                (*a, *b) = pair;
            }
        }
        self.settle(harmonics)
    }

    /// Checks the coefficients and computes the bounds; zero maps on refusal.
    #[cfg_attr(target_arch = "arm", inline(always))]
    fn settle(&mut self, harmonics: usize) -> Result<(), KinematicsError> {
        let result = self.check_and_bound(harmonics);
        if result.is_err() {
            *self = Self::zeros_for(self.joint_count());
        }
        result
    }

    #[cfg_attr(target_arch = "arm", inline(always))]
    fn check_and_bound(&mut self, harmonics: usize) -> Result<(), KinematicsError> {
        self.harmonics = u16::try_from(harmonics)
            .ok()
            .filter(|_| harmonics <= C)
            .ok_or(KinematicsError::TooManyHarmonics)?;
        let limit = T::of(MAX_COEFFICIENT);
        let joints = self.sin.iter().zip(self.cos.iter());
        let bounds = self
            .amplitude_bound
            .iter_mut()
            .zip(self.slope_bound.iter_mut());
        for (j, ((sin, cos), (amplitude_bound, slope_bound))) in joints.zip(bounds).enumerate() {
            let invalid = KinematicsError::InvalidJointMap {
                joint: joint_number(j),
            };
            let (mut amplitude, mut slope, mut order) = (T::zero(), T::zero(), T::zero());
            for (h, (a, b)) in sin.iter().zip(cos).enumerate() {
                order += T::one();
                if !(a.finite() && b.finite() && a.abs() <= limit && b.abs() <= limit) {
                    return Err(invalid);
                }
                if h >= harmonics && (*a != T::zero() || *b != T::zero()) {
                    return Err(invalid);
                }
                let magnitude = (*a * *a + *b * *b).sqrt_ieee();
                amplitude += magnitude;
                slope += magnitude * order;
            }
            if slope > T::of(MAX_SLOPE) {
                return Err(invalid);
            }
            *amplitude_bound = amplitude;
            *slope_bound = slope;
        }
        Ok(())
    }

    /// Harmonics used (at most `C`).
    pub fn harmonics(&self) -> usize {
        usize::from(self.harmonics)
    }

    /// Coefficients of `sin(h q)` of joint `joint` (0-based), `h = 1..C`, rad.
    pub fn sin_coefficients(&self, joint: usize) -> Option<&[T; C]> {
        self.sin.as_slice().get(joint)
    }

    /// Coefficients of `cos(h q)` of joint `joint` (0-based), `h = 1..C`, rad.
    pub fn cos_coefficients(&self, joint: usize) -> Option<&[T; C]> {
        self.cos.as_slice().get(joint)
    }

    /// `M_j`: no reading has a larger angle error on joint `joint` (0-based), rad.
    pub fn amplitude_bound(&self, joint: usize) -> T {
        self.amplitude_bound
            .as_slice()
            .get(joint)
            .copied()
            .unwrap_or(T::zero())
    }

    /// `L_j`: the map of joint `joint` (0-based) changes at most this much per radian.
    pub fn slope_bound(&self, joint: usize) -> T {
        self.slope_bound
            .as_slice()
            .get(joint)
            .copied()
            .unwrap_or(T::zero())
    }

    /// Whether every map is zero everywhere.
    pub fn is_zero(&self) -> bool {
        self.amplitude_bound.iter().all(|m| *m == T::zero())
    }

    /// The angle error of joint `joint` (0-based) at reading `q` and its slope `d dq / dq`:
    /// `(rad, dimensionless)`.
    pub fn error_and_slope(&self, joint: usize, q: T) -> (T, T) {
        self.fold_harmonics(
            joint,
            q,
            (T::zero(), T::zero()),
            |(error, slope), h, a, b, s, c| (error + (a * s + b * c), slope + h * (a * c - b * s)),
        )
    }

    /// The angle error of joint `joint` (0-based) at reading `q`, rad (the value alone: the
    /// compensation's hot path). The [`series`] of the joint's used coefficients.
    pub fn error(&self, joint: usize, q: T) -> T {
        let used = self.harmonics().min(C);
        let (Some(a), Some(b)) = (
            (self.sin.as_slice().get(joint)).and_then(|a| a.get(..used)),
            (self.cos.as_slice().get(joint)).and_then(|b| b.get(..used)),
        ) else {
            return T::zero();
        };
        series(a, b, q)
    }

    /// Folds `step(acc, h, a_h, b_h, sin(h q), cos(h q))` over the used harmonics of joint
    /// `joint`, the sines and cosines by the angle-addition recurrence from one `sin_cos` of `q`.
    fn fold_harmonics<A>(
        &self,
        joint: usize,
        q: T,
        init: A,
        mut step: impl FnMut(A, T, T, T, T, T) -> A,
    ) -> A {
        let (Some(a), Some(b)) = (
            self.sin.as_slice().get(joint),
            self.cos.as_slice().get(joint),
        ) else {
            return init;
        };
        let used = self.harmonics().min(C);
        if used == 0 {
            return init;
        }
        let (mut acc, mut order) = (init, T::zero());
        for ((a, b), (s, c)) in a.iter().zip(b).take(used).zip(harmonics(q)) {
            order += T::one();
            acc = step(acc, order, *a, *b, s, c);
        }
        acc
    }

    /// The kinematic joint angles for readings `q`: `q_j + dq_j(q_j)`, rad.
    pub fn apply(&self, q: &N::Table<T>) -> N::Table<T> {
        let mut out = *q;
        if self.harmonics == 0 {
            return out;
        }
        for (j, v) in out.iter_mut().enumerate() {
            *v += self.error(j, *v);
        }
        out
    }

    /// The readings that give the kinematic joint angles `angles` (the inverse of [`apply`]),
    /// each within `tolerance` rad by the bound of the module documentation, and the iterations
    /// run (the most over the joints). The count is fixed in advance from `L_j` and `M_j`, at
    /// most [`MAX_FIXED_POINT_ITERATIONS`].
    ///
    /// [`apply`]: Self::apply
    pub fn readings(&self, angles: &N::Table<T>, tolerance: T) -> (N::Table<T>, u32) {
        let mut out = *angles;
        let mut most = 0;
        if self.harmonics == 0 {
            return (out, 0);
        }
        for (j, (q, t)) in out.iter_mut().zip(angles.iter()).enumerate() {
            let slope = self.slope_bound(j);
            let mut bound = slope * self.amplitude_bound(j);
            let mut iterations = 0;
            *q = *t - self.error(j, *t);
            while bound > tolerance && iterations < MAX_FIXED_POINT_ITERATIONS {
                *q = *t - self.error(j, *q);
                bound *= slope;
                iterations += 1;
            }
            most = most.max(iterations);
        }
        (out, most)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{U1, U2};
    extern crate std;

    fn maps() -> JointMaps<f64, U2, 4> {
        let mut sin = [[0.0; 4]; 2];
        let mut cos = [[0.0; 4]; 2];
        sin[0] = [3e-4, 0.0, -1e-4, 0.0];
        cos[0] = [0.0, 2e-4, 0.0, 5e-5];
        sin[1][1] = 1e-3;
        JointMaps::new(4, sin, cos).unwrap()
    }

    #[test]
    fn the_recurrence_equals_the_series() {
        let m = maps();
        for i in 0..50 {
            let q = -6.0 + 0.25 * f64::from(i);
            let direct = 3e-4 * q.sin() + 2e-4 * (2.0 * q).cos() - 1e-4 * (3.0 * q).sin()
                + 5e-5 * (4.0 * q).cos();
            let slope = 3e-4 * q.cos()
                - 4e-4 * (2.0 * q).sin()
                - 3e-4 * (3.0 * q).cos()
                - 2e-4 * (4.0 * q).sin();
            let (e, s) = m.error_and_slope(0, q);
            assert!((e - direct).abs() < 1e-17, "{e} {direct}");
            assert!((s - slope).abs() < 1e-16, "{s} {slope}");
        }
        // M and L of joint 2: 1e-3 and 2e-3.
        assert_eq!(m.amplitude_bound(1), 1e-3);
        assert_eq!(m.slope_bound(1), 2e-3);
    }

    #[test]
    fn readings_invert_apply_within_the_bound() {
        let m = maps();
        for i in 0..40 {
            let q = [-3.0 + 0.15 * f64::from(i), 2.0 - 0.1 * f64::from(i)];
            let angles = m.apply(&q);
            let (back, iterations) = m.readings(&angles, 1e-12);
            assert!(iterations <= 6, "{iterations}");
            for j in 0..2 {
                assert!((back[j] - q[j]).abs() < 1e-12, "{back:?} {q:?}");
            }
        }
    }

    #[test]
    fn implausible_maps_are_refused_with_their_joint() {
        let mut sin = [[0.0; 4]; 2];
        let cos = [[0.0; 4]; 2];
        sin[1][3] = 0.009; // L = 4 * 0.009, fine
        assert!(JointMaps::<f64, U2, 4>::new(4, sin, cos).is_ok());
        sin[1][3] = f64::NAN;
        assert_eq!(
            JointMaps::<f64, U2, 4>::new(4, sin, cos),
            Err(KinematicsError::InvalidJointMap { joint: 2 })
        );
        sin[1][3] = 0.02;
        assert!(JointMaps::<f64, U2, 4>::new(4, sin, cos).is_err());
        // Slope bound beyond 0.5: 64 harmonics of 0.009 rad would be far beyond it.
        let big = JointMaps::<f64, U1, 64>::new(64, [[0.009; 64]], [[0.0; 64]]);
        assert_eq!(big, Err(KinematicsError::InvalidJointMap { joint: 1 }));
        // A coefficient beyond the harmonics used.
        sin[1][3] = 1e-4;
        assert!(JointMaps::<f64, U2, 4>::new(3, sin, cos).is_err());
        assert_eq!(
            JointMaps::<f64, U2, 4>::new(5, [[0.0; 4]; 2], cos),
            Err(KinematicsError::TooManyHarmonics)
        );
    }
}
