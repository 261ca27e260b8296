//! The deflection of gravity compliance ([`Compliance`], the model's parameters): for each joint
//! the gravity moment of what it carries, the small turns it causes and their motion of the end
//! frame (formulas in [`crate::model::compliance`]).

use crate::kinematics::{JointAngles, Kinematics, Pose};
use crate::model::KinematicsError;
use crate::model::compliance::{Compliance, PointMass};
use crate::model::{JointCount, JointTable};
use crate::scalar::Real;
use nalgebra::{Matrix3, Rotation3, Translation3, Vector3};

impl<T: Real, N: JointCount> Compliance<T, N> {
    /// The end pose of `geometry` at kinematic angles `t` (rad) without and with the deflection,
    /// and the deflection. Error: a non-finite angle.
    pub fn deflect(
        &self,
        geometry: &Kinematics<T, N>,
        t: &N::Table<T>,
    ) -> Result<(Pose<T>, Deflection<T>), KinematicsError> {
        // The chain the Jacobians use: frame k's origin and z axis (`before_*[k]`, k < N), its
        // y axis (`y_axis[k - 1]`, k > 0), the flange (k = N); x = y x z.
        let chain = geometry.chain(&JointAngles::new(t)?);
        let base = geometry.base();
        let frame = |k: usize| -> (Matrix3<T>, Vector3<T>) {
            match (
                chain.before_z.as_slice().get(k),
                chain.before_origin.as_slice().get(k),
            ) {
                (Some(z), Some(o)) => {
                    let y = match k
                        .checked_sub(1)
                        .and_then(|i| chain.y_axis.as_slice().get(i))
                    {
                        Some(y) => *y,
                        None => base.rotation.matrix().column(1).into_owned(),
                    };
                    (Matrix3::from_columns(&[y.cross(z), y, *z]), *o)
                }
                _ => (
                    *chain.flange.rotation.matrix(),
                    chain.flange.translation.vector,
                ),
            }
        };
        let end = chain.end.translation.vector;
        let g = base.rotation * Vector3::from(*self.gravity_mps2());
        // From the flange inwards: S = sum m c (kg mm), m = sum m (kg) of what joint j carries.
        let (mut moment_arm, mut mass) = (Vector3::zeros(), T::zero());
        let mut deflection = Deflection::zero();
        // Link j's frame is frame j; joint j turns in frame j - 1.
        let mut after = frame(self.links().len());
        moment_arm.add_mass(&after, self.load());
        mass += self.load().mass_kg;
        let kilo = T::of(1e-3);
        for (j, (link, gains)) in self
            .links()
            .iter()
            .zip(self.gains().iter())
            .enumerate()
            .rev()
        {
            moment_arm.add_mass(&after, link);
            mass += link.mass_kg;
            after = frame(j);
            if gains.iter().all(|k| *k == T::zero()) {
                continue;
            }
            // N m from kg mm m/s^2.
            let (r, o) = &after;
            let moment = (moment_arm - o * mass).cross(&g) * kilo;
            deflection.add_turn(r, o, gains, &moment, &end);
        }
        let pose = chain.end;
        Ok((pose, deflection))
    }

    /// What gain `axis` ([`TILT_X`], [`TILT_Y`], [`TORSION`]) of joint `joint` (0-based)
    /// multiplies: the deflection of `geometry` at kinematic angles `t` (rad) by these masses with
    /// that gain at 1 urad per N m and every other gain zero. The deflection is linear in the
    /// gains ([`Compliance::deflect`]'s is the sum of these columns times the gains, to
    /// rounding), so the host's identification fits the gains on these columns: the
    /// controller's own evaluation, so that what is fitted is what is applied. `None` for a
    /// joint or axis out of range; error: a non-finite angle.
    ///
    /// [`TILT_X`]: crate::model::compliance::TILT_X
    /// [`TILT_Y`]: crate::model::compliance::TILT_Y
    /// [`TORSION`]: crate::model::compliance::TORSION
    pub fn gain_column(
        &self,
        geometry: &Kinematics<T, N>,
        t: &N::Table<T>,
        (joint, axis): (usize, usize),
    ) -> Result<Option<Deflection<T>>, KinematicsError> {
        match self.with_unit_gain(joint, axis) {
            Some(unit) => Ok(Some(unit.deflect(geometry, t)?.1)),
            None => Ok(None),
        }
    }

    /// The deflected end pose of `geometry` at kinematic angles `t` (rad).
    pub fn forward(
        &self,
        geometry: &Kinematics<T, N>,
        t: &N::Table<T>,
    ) -> Result<Pose<T>, KinematicsError> {
        let (pose, deflection) = self.deflect(geometry, t)?;
        Ok(deflection.apply(&pose))
    }
}

/// Accumulating `sum m c` (kg mm) of point masses given in a frame.
trait MassSum<T: Real> {
    /// Adds `mass` whose centre is given in `frame` (rotation, origin in mm).
    fn add_mass(&mut self, frame: &(Matrix3<T>, Vector3<T>), mass: &PointMass<T>);
}

impl<T: Real> MassSum<T> for Vector3<T> {
    #[inline(never)]
    fn add_mass(&mut self, (r, o): &(Matrix3<T>, Vector3<T>), mass: &PointMass<T>) {
        *self += (o + r * Vector3::from(mass.centre_mm)) * mass.mass_kg;
    }
}

/// A small motion of the end frame: the end point moves by `translation`, the frame turns by the
/// rotation vector `rotation` (world axes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Deflection<T: Real> {
    /// End point motion, mm.
    pub translation: Vector3<T>,
    /// Rotation vector, rad.
    pub rotation: Vector3<T>,
}

impl<T: Real> Deflection<T> {
    /// No motion.
    pub fn zero() -> Self {
        Self {
            translation: Vector3::zeros(),
            rotation: Vector3::zeros(),
        }
    }

    /// Adds the turn of a joint whose frame has axes `axes` (columns) and origin `origin` (mm),
    /// loaded by `moment` (N m) with `gains` (urad per N m about the frame's x, y, z), seen at
    /// the end point `end` (mm). Not inlined: one copy serves every joint (controller flash).
    #[inline(never)]
    fn add_turn(
        &mut self,
        axes: &Matrix3<T>,
        origin: &Vector3<T>,
        gains: &[T; 3],
        moment: &Vector3<T>,
        end: &Vector3<T>,
    ) {
        let micro = T::of(1e-6);
        let mut phi = Vector3::zeros();
        for (axis, k) in axes.column_iter().zip(gains) {
            phi += axis * (axis.dot(moment) * *k * micro);
        }
        self.rotation += phi;
        self.translation += phi.cross(&(end - origin));
    }

    /// `exp([rotation]x)` by Rodrigues' formula `I + a K + b K^2` with `a = sin(t)/t` and
    /// `b = (1 - cos t)/t^2` written as `2 (sin(t/2)/t)^2` (no cancellation for small angles).
    fn turn(&self) -> Matrix3<T> {
        let w = self.rotation;
        let theta = w.norm_squared().sqrt_ieee();
        let (a, b) = if theta > T::zero() {
            let (s, c) = (theta * T::of(0.5)).sin_cos_fast();
            let half = s / theta;
            (T::of(2.0) * half * c, T::of(2.0) * half * half)
        } else {
            (T::one(), T::of(0.5))
        };
        let k = crate::math::so3::skew(&w);
        Matrix3::identity() + k * a + k * k * b
    }

    /// The deflected pose `(p + translation, exp(rotation) R)`.
    pub fn apply(&self, pose: &Pose<T>) -> Pose<T> {
        self.moved(pose, false)
    }

    /// The pose this deflection takes to `pose`: `(p - translation, exp(-rotation) R)`.
    pub fn remove(&self, pose: &Pose<T>) -> Pose<T> {
        self.moved(pose, true)
    }

    /// [`Deflection::apply`], or [`Deflection::remove`] if `back` (one copy on a controller).
    #[inline(never)]
    fn moved(&self, pose: &Pose<T>, back: bool) -> Pose<T> {
        let (translation, turn) = if back {
            (-self.translation, self.turn().transpose())
        } else {
            (self.translation, self.turn())
        };
        Pose::from_parts(
            Translation3::from(pose.translation.vector + translation),
            Rotation3::from_matrix_unchecked(turn * pose.rotation.matrix()),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::compliance::tests::ur_like;
    use crate::model::paper::{er10l_c10, table2};
    use nalgebra::{U2, U6};
    extern crate std;

    /// A point mass on a horizontal arm: the torsion of the joint carrying it turns the end by
    /// `k m g r`, and the end point sinks by that angle times its lever.
    #[test]
    fn a_horizontal_arm_sags_by_the_closed_form() {
        // A planar arm: joint 1 about the vertical z, joint 2 about the horizontal, 1 m link.
        let joint = |a: f64, alpha: f64| crate::model::MdhJoint {
            a,
            alpha,
            theta_offset: 0.0,
            d: 0.0,
            beta: 0.0,
        };
        let robot = crate::model::Robot::from_joints([
            joint(0.0, core::f64::consts::FRAC_PI_2),
            joint(1000.0, 0.0),
        ]);
        let geometry = Kinematics::nominal(&robot).unwrap();
        let mut links = [PointMass::none(); 2];
        // 10 kg at the end of link 2 (its frame's origin).
        links[1] = PointMass {
            mass_kg: 10.0,
            centre_mm: [0.0; 3],
        };
        let k = 5.0;
        let c = Compliance::<f64, U2>::new(
            [0.0, 0.0, -9.81],
            links,
            PointMass::none(),
            [[0.0; 3], [0.0, 0.0, k]],
        )
        .unwrap();
        let (pose, d) = c.deflect(&geometry, &[0.3, 0.0]).unwrap();
        let phi = k * 1e-6 * 10.0 * 9.81 * 1.0;
        assert!((d.rotation.norm() - phi).abs() < 1e-15, "{}", d.rotation);
        // The end point (1 m out, horizontal) sinks by phi * 1000 mm.
        assert!(
            (d.translation.z + phi * 1000.0).abs() < 1e-12,
            "{}",
            d.translation
        );
        assert!(d.translation.xy().norm() < 1e-12);
        assert!((pose.translation.vector.norm() - 1000.0).abs() < 1e-9);
        // Raised to vertical (q2 = 90 deg) the moment vanishes.
        let (_, up) = c
            .deflect(&geometry, &[0.3, core::f64::consts::FRAC_PI_2])
            .unwrap();
        assert!(up.rotation.norm() < 1e-15, "{}", up.rotation);
    }

    #[test]
    fn no_gains_deflect_nothing_and_remove_undoes_apply() {
        let geometry = Kinematics::new(&er10l_c10(), &table2()).unwrap();
        let q = [0.3, -0.4, 0.5, 0.2, 0.9, -0.3];
        let (pose, d) = Compliance::<f64, U6>::none()
            .deflect(&geometry, &q)
            .unwrap();
        assert_eq!(d, Deflection::zero());
        assert_eq!(pose, geometry.forward(&q).unwrap());
        let (pose, d) = ur_like().deflect(&geometry, &q).unwrap();
        // A few hundredths of a millimetre to a few tenths, a fraction of a milliradian.
        let (v, w) = (d.translation.norm(), d.rotation.norm());
        assert!(v > 0.01 && v < 1.0 && w > 1e-6 && w < 1e-3, "{v} {w}");
        let back = d.remove(&d.apply(&pose));
        assert!((back.translation.vector - pose.translation.vector).norm() < 1e-12);
        assert!((back.rotation.matrix() - pose.rotation.matrix()).norm() < 1e-15);
        // The turn is a rotation by |w| about w.
        let moved = d.apply(&pose);
        let turned = moved.rotation.matrix() * pose.rotation.matrix().transpose();
        let expected = Rotation3::new(d.rotation);
        assert!((turned - expected.matrix()).norm() < 1e-15);
    }

    /// The deflection is linear in the gains: the columns times the gains sum to it.
    #[test]
    fn the_gain_columns_sum_to_the_deflection() {
        let geometry = Kinematics::new(&er10l_c10(), &table2()).unwrap();
        let c = ur_like();
        let q = [0.3, -0.4, 0.5, 0.2, 0.9, -0.3];
        let (_, d) = c.deflect(&geometry, &q).unwrap();
        let mut sum = Deflection::zero();
        for (j, gains) in c.gains().iter().enumerate() {
            for (axis, k) in gains.iter().enumerate() {
                let column = c.gain_column(&geometry, &q, (j, axis)).unwrap().unwrap();
                sum.translation += column.translation * *k;
                sum.rotation += column.rotation * *k;
            }
        }
        assert!((sum.translation - d.translation).norm() < 1e-15 * 1e3);
        assert!((sum.rotation - d.rotation).norm() < 1e-18 * 1e3);
        assert!(d.translation.norm() > 0.01);
        assert_eq!(c.gain_column(&geometry, &q, (6, 0)).unwrap(), None);
        assert_eq!(c.gain_column(&geometry, &q, (0, 3)).unwrap(), None);
    }

    #[test]
    fn f32_agrees_with_f64() {
        let geometry = Kinematics::new(&er10l_c10(), &table2()).unwrap();
        let c = ur_like();
        let q = [0.3, -0.4, 0.5, 0.2, 0.9, -0.3];
        let (_, d) = c.deflect(&geometry, &q).unwrap();
        let of = |v: f64| v as f32;
        let c32 = Compliance::<f32, U6>::new(
            c.gravity_mps2().map(of),
            c.links().map(|l| PointMass {
                mass_kg: of(l.mass_kg),
                centre_mm: l.centre_mm.map(of),
            }),
            PointMass {
                mass_kg: of(c.load().mass_kg),
                centre_mm: c.load().centre_mm.map(of),
            },
            c.gains().map(|g| g.map(of)),
        )
        .unwrap();
        let g32 = Kinematics::<f32, U6>::new(&er10l_c10(), &table2()).unwrap();
        let (_, d32) = c32.deflect(&g32, &q.map(of)).unwrap();
        for r in 0..3 {
            assert!((f64::from(d32.translation[r]) - d.translation[r]).abs() < 1e-6);
            assert!((f64::from(d32.rotation[r]) - d.rotation[r]).abs() < 1e-9);
        }
    }
}
