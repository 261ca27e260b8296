//! Gravity compliance (issue 14): joints and bearings that yield under the weight of the links
//! beyond them.
//!
//! For joint `j`, the gravity moment of everything it carries (links `j..N` and the flange's
//! load, masses and centres of mass given) about the origin `o_{j-1}` of the frame it turns in is
//!
//! `M_j = sum_{k >= j} m_k (c_k - o_{j-1}) x g = (S_j - m_j' o_{j-1}) x g` (N m),
//!
//! with `S_j = sum_{k >= j} m_k c_k` and `m_j' = sum_{k >= j} m_k` accumulated from the flange
//! inwards (one pass). That frame's axes `x`, `y`, `z` (`z` the joint's axis) turn the distal
//! chain by the small rotation
//!
//! `phi_j = 1e-6 (k_x (x . M_j) x + k_y (y . M_j) y + k_z (z . M_j) z)` (rad),
//!
//! with gains `k` in urad per N m: `k_z` a torsion of the joint, `k_x`, `k_y` tilts of its
//! bearing. The end point `p` moves by `v = sum_j phi_j x (p - o_{j-1})` (mm) and the end frame
//! turns by `w = sum_j phi_j` (first order: identified deflections are below 1 mrad, the neglected
//! second-order terms below 1e-5 mm on a UR10). The deflected end pose is
//! `(p + v, exp(w) R)` ([`Deflection::apply`]); the host's identification (`calib calibrate
//! --model joint-maps+compliance`) fits the gains with this model and checks this module's
//! evaluation against its own.
//!
//! The deflection is a function of the kinematic joint angles (after the joint maps), computed
//! from the frames of the geometry there: one more forward pass (no trigonometry beyond the
//! joints' sines and cosines) and about 40 multiplications per joint.

use crate::kinematics::{JointAngles, Kinematics, Pose};
use crate::model::KinematicsError;
use crate::scalar::Real;
use nalgebra::{Matrix3, Rotation3, Translation3, Vector3};

/// Largest accepted mass of a link or load, kg.
pub const MAX_MASS_KG: f64 = 1000.0;
/// Largest accepted distance of a centre of mass from its frame's origin per axis, mm.
pub const MAX_CENTRE_MM: f64 = 5000.0;
/// Largest accepted magnitude of a gain, urad per N m (a 100 N m moment would turn a joint by
/// 0.1 rad).
pub const MAX_GAIN_URAD_PER_NM: f64 = 1000.0;
/// Accepted magnitudes of gravity, m/s^2.
pub const GRAVITY_RANGE_MPS2: (f64, f64) = (9.0, 10.5);

/// A point mass: a link's or the flange load's mass and centre.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PointMass<T> {
    /// Mass, kg.
    pub mass_kg: T,
    /// Centre of mass, mm: for a link in the frame after its joint's transform, for the flange's
    /// load in the flange frame.
    pub centre_mm: [T; 3],
}

impl<T: Real> PointMass<T> {
    /// No mass.
    pub fn none() -> Self {
        Self {
            mass_kg: T::zero(),
            centre_mm: [T::zero(); 3],
        }
    }

    #[inline(never)]
    fn valid(&self) -> bool {
        let limit = T::of(MAX_CENTRE_MM);
        self.mass_kg.finite()
            && self.mass_kg >= T::zero()
            && self.mass_kg <= T::of(MAX_MASS_KG)
            && self
                .centre_mm
                .iter()
                .all(|c| c.finite() && c.abs() <= limit)
    }
}

/// The gravity-compliance model of an `N`-joint robot: gravity, masses and gains.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compliance<T, const N: usize> {
    gravity_mps2: [T; 3],
    links: [PointMass<T>; N],
    load: PointMass<T>,
    gains: [[T; 3]; N],
}

/// Which gain of a joint: index into a joint's `[tilt x, tilt y, torsion]`.
pub const TILT_X: usize = 0;
/// See [`TILT_X`].
pub const TILT_Y: usize = 1;
/// See [`TILT_X`].
pub const TORSION: usize = 2;

impl<T: Real, const N: usize> Compliance<T, N> {
    /// No compliance: every gain zero (the deflection is exactly zero).
    pub fn none() -> Self {
        Self {
            gravity_mps2: [T::zero(); 3],
            links: [PointMass::none(); N],
            load: PointMass::none(),
            gains: [[T::zero(); 3]; N],
        }
    }

    /// The model: gravity in the robot's base frame (before the base transform, m/s^2; upright
    /// `[0, 0, -9.81]`), link `j`'s mass (link 1 is moved by joint 1), the flange's load, and per
    /// joint the gains `[tilt x, tilt y, torsion]` (urad per N m) about the axes of the frame the
    /// joint turns in. Error [`KinematicsError::InvalidCompliance`]: a value not finite, a mass
    /// beyond [`MAX_MASS_KG`] or negative, a centre beyond [`MAX_CENTRE_MM`], a gain beyond
    /// [`MAX_GAIN_URAD_PER_NM`], or a gravity outside [`GRAVITY_RANGE_MPS2`] when a gain is set.
    pub fn new(
        gravity_mps2: [T; 3],
        links: [PointMass<T>; N],
        load: PointMass<T>,
        gains: [[T; 3]; N],
    ) -> Result<Self, KinematicsError> {
        let model = Self {
            gravity_mps2,
            links,
            load,
            gains,
        };
        model.validate()?;
        Ok(model)
    }

    /// Checks the values as [`Compliance::new`] does.
    pub fn validate(&self) -> Result<(), KinematicsError> {
        // Loops rather than iterator chains: this runs once per block load, and on the
        // controller small code matters more than speed here.
        let limit = T::of(MAX_GAIN_URAD_PER_NM);
        let mut ok = self.load.valid();
        for link in &self.links {
            ok &= link.valid();
        }
        let mut active = false;
        for gain in self.gains.as_flattened() {
            ok &= gain.finite() && gain.abs() <= limit;
            active |= *gain != T::zero();
        }
        let (low, high) = GRAVITY_RANGE_MPS2;
        let mut squared = T::zero();
        for g in &self.gravity_mps2 {
            ok &= g.finite();
            squared += *g * *g;
        }
        ok &= !active || (squared >= T::of(low * low) && squared <= T::of(high * high));
        if ok {
            Ok(())
        } else {
            Err(KinematicsError::InvalidCompliance)
        }
    }

    /// Whether any gain is set (a model without gains deflects nothing).
    pub fn is_active(&self) -> bool {
        self.gains.iter().flatten().any(|g| *g != T::zero())
    }

    /// Gravity in the robot's base frame, m/s^2.
    pub fn gravity_mps2(&self) -> &[T; 3] {
        &self.gravity_mps2
    }

    /// The links' masses, link 1 first.
    pub fn links(&self) -> &[PointMass<T>; N] {
        &self.links
    }

    /// The flange's load.
    pub fn load(&self) -> &PointMass<T> {
        &self.load
    }

    /// Per joint `[tilt x, tilt y, torsion]`, urad per N m.
    pub fn gains(&self) -> &[[T; 3]; N] {
        &self.gains
    }

    /// The end pose of `geometry` at kinematic angles `t` (rad) without and with the deflection,
    /// and the deflection. Error: a non-finite angle.
    pub fn deflect(
        &self,
        geometry: &Kinematics<T, N>,
        t: &[T; N],
    ) -> Result<(Pose<T>, Deflection<T>), KinematicsError> {
        // The chain the Jacobians use: frame k's origin and z axis (`before_*[k]`, k < N), its
        // y axis (`y_axis[k - 1]`, k > 0), the flange (k = N); x = y x z.
        let chain = geometry.chain(&JointAngles::new(t)?);
        let base = geometry.base();
        let frame = |k: usize| -> (Matrix3<T>, Vector3<T>) {
            match (chain.before_z.get(k), chain.before_origin.get(k)) {
                (Some(z), Some(o)) => {
                    let y = match k.checked_sub(1).and_then(|i| chain.y_axis.get(i)) {
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
        let g = base.rotation * Vector3::from(self.gravity_mps2);
        // From the flange inwards: S = sum m c (kg mm), m = sum m (kg) of what joint j carries.
        let (mut moment_arm, mut mass) = (Vector3::zeros(), T::zero());
        let mut deflection = Deflection::zero();
        // Link j's frame is frame j; joint j turns in frame j - 1.
        let mut after = frame(N);
        moment_arm.add_mass(&after, &self.load);
        mass += self.load.mass_kg;
        let kilo = T::of(1e-3);
        for (j, (link, gains)) in self.links.iter().zip(&self.gains).enumerate().rev() {
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

    /// The deflected end pose of `geometry` at kinematic angles `t` (rad).
    pub fn forward(
        &self,
        geometry: &Kinematics<T, N>,
        t: &[T; N],
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

    /// `exp([rotation]x)` by Rodrigues' formula; below 1 mrad by its series (exact to 1e-16).
    fn turn(&self) -> Matrix3<T> {
        let w = self.rotation;
        let theta2 = w.norm_squared();
        let (a, b) = if theta2 < T::of(1e-6) {
            // sin(t)/t and (1 - cos t)/t^2 to t^4.
            (
                T::one() - theta2 / T::of(6.0) + theta2 * theta2 / T::of(120.0),
                T::of(0.5) - theta2 / T::of(24.0) + theta2 * theta2 / T::of(720.0),
            )
        } else {
            let theta = theta2.sqrt_ieee();
            let (s, c) = theta.sin_cos_fast();
            (s / theta, (T::one() - c) / theta2)
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
    use crate::model::paper::{er10l_c10, table2};
    extern crate std;

    fn ur_like() -> Compliance<f64, 6> {
        let link = |m: f64, c: [f64; 3]| PointMass {
            mass_kg: m,
            centre_mm: c,
        };
        Compliance::new(
            [0.0, 0.0, -9.81],
            [
                link(7.1, [21.0, 0.0, 27.0]),
                link(12.7, [380.0, 0.0, 158.0]),
                link(4.27, [240.0, 0.0, 68.0]),
                link(2.0, [0.0, 7.0, 18.0]),
                link(2.0, [0.0, 7.0, 18.0]),
                link(0.365, [0.0, 0.0, -26.0]),
            ],
            link(1.5, [0.0, 0.0, 60.0]),
            [
                [12.0, -7.0, 0.0],
                [3.0, 0.0, 6.0],
                [-4.0, 2.0, 9.0],
                [5.0, 1.0, 8.0],
                [0.0; 3],
                [0.0; 3],
            ],
        )
        .unwrap()
    }

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
        let c = Compliance::new(
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
        let (pose, d) = Compliance::<f64, 6>::none().deflect(&geometry, &q).unwrap();
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

    #[test]
    fn values_out_of_range_are_refused() {
        let good = ur_like();
        let mut gains = *good.gains();
        gains[1][2] = 1001.0;
        let refuse = |g: [f64; 3], l: [PointMass<f64>; 6], t: PointMass<f64>, k| {
            assert_eq!(
                Compliance::new(g, l, t, k),
                Err(KinematicsError::InvalidCompliance)
            );
        };
        refuse(*good.gravity_mps2(), *good.links(), *good.load(), gains);
        refuse([0.0, 0.0, -1.0], *good.links(), *good.load(), *good.gains());
        let mut links = *good.links();
        links[2].mass_kg = f64::NAN;
        refuse(*good.gravity_mps2(), links, *good.load(), *good.gains());
        links[2].mass_kg = -1.0;
        refuse(*good.gravity_mps2(), links, *good.load(), *good.gains());
        let mut load = *good.load();
        load.centre_mm[1] = 6000.0;
        refuse(*good.gravity_mps2(), *good.links(), load, *good.gains());
        // Without gains, gravity does not matter.
        assert!(Compliance::new([0.0; 3], *good.links(), *good.load(), [[0.0; 3]; 6]).is_ok());
    }

    #[test]
    fn f32_agrees_with_f64() {
        let geometry = Kinematics::new(&er10l_c10(), &table2()).unwrap();
        let c = ur_like();
        let q = [0.3, -0.4, 0.5, 0.2, 0.9, -0.3];
        let (_, d) = c.deflect(&geometry, &q).unwrap();
        let of = |v: f64| v as f32;
        let c32 = Compliance::<f32, 6>::new(
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
        let g32 = Kinematics::<f32, 6>::new(&er10l_c10(), &table2()).unwrap();
        let (_, d32) = c32.deflect(&g32, &q.map(of)).unwrap();
        for r in 0..3 {
            assert!((f64::from(d32.translation[r]) - d.translation[r]).abs() < 1e-6);
            assert!((f64::from(d32.rotation[r]) - d.rotation[r]).abs() < 1e-9);
        }
    }
}
