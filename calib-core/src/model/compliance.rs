//! Gravity compliance: joints and bearings that yield under the weight of the links
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
//! `(p + v, exp(w) R)` ([`Deflection::apply`](crate::kinematics::deflection::Deflection::apply), computed in
//! [`crate::kinematics::deflection`]); the host's identification (`calib calibrate
//! --model joint-maps+compliance`) fits the gains with this model and checks this module's
//! evaluation against its own.
//!
//! The deflection is a function of the kinematic joint angles (after the joint maps), computed
//! from the frames of the geometry there: one more forward pass (no trigonometry beyond the
//! joints' sines and cosines) and about 40 multiplications per joint.

use crate::model::KinematicsError;
use crate::model::{JointCount, JointTable, check_count};
use crate::scalar::Real;
use nalgebra::Const;

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
pub struct Compliance<T: Real, N: JointCount> {
    gravity_mps2: [T; 3],
    links: N::Table<PointMass<T>>,
    load: PointMass<T>,
    gains: N::Table<[T; 3]>,
}

/// Which gain of a joint: index into a joint's `[tilt x, tilt y, torsion]`.
pub const TILT_X: usize = 0;
/// See [`TILT_X`].
pub const TILT_Y: usize = 1;
/// See [`TILT_X`].
pub const TORSION: usize = 2;

impl<T: Real, const N: usize> Compliance<T, Const<N>> {
    /// No compliance: every gain zero (the deflection is exactly zero; a joint count fixed at
    /// compile time, [`Compliance::none_for`] takes any).
    pub fn none() -> Self {
        Self::none_for(Const)
    }
}

impl<T: Real, N: JointCount> Compliance<T, N> {
    /// No compliance of a robot of `joints` joints: every gain zero.
    pub fn none_for(joints: N) -> Self {
        Self {
            gravity_mps2: [T::zero(); 3],
            links: joints.table(PointMass::none()),
            load: PointMass::none(),
            gains: joints.table([T::zero(); 3]),
        }
    }

    /// The joint count.
    pub fn joint_count(&self) -> N {
        N::of(&self.links)
    }

    /// The model: gravity in the robot's base frame (before the base transform, m/s^2; upright
    /// `[0, 0, -9.81]`), link `j`'s mass (link 1 is moved by joint 1), the flange's load, and per
    /// joint the gains `[tilt x, tilt y, torsion]` (urad per N m) about the axes of the frame the
    /// joint turns in. Error [`KinematicsError::InvalidCompliance`]: a value not finite, a mass
    /// beyond [`MAX_MASS_KG`] or negative, a centre beyond [`MAX_CENTRE_MM`], a gain beyond
    /// [`MAX_GAIN_URAD_PER_NM`], or a gravity outside [`GRAVITY_RANGE_MPS2`] when a gain is set.
    pub fn new(
        gravity_mps2: [T; 3],
        links: N::Table<PointMass<T>>,
        load: PointMass<T>,
        gains: N::Table<[T; 3]>,
    ) -> Result<Self, KinematicsError> {
        check_count(links.len(), gains.len()).map_err(|_| KinematicsError::InvalidCompliance)?;
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
        for link in self.links.iter() {
            ok &= link.valid();
        }
        let mut active = false;
        for gain in self.gains.as_slice().as_flattened() {
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

    /// Every value in the parameter block's order (`controller::storage`): gravity, per link
    /// mass and centre, the load's mass and centre, per joint the three gains.
    pub(crate) fn values_mut(&mut self) -> impl Iterator<Item = &mut T> {
        let masses = self
            .links
            .iter_mut()
            .chain(core::iter::once(&mut self.load));
        self.gravity_mps2
            .iter_mut()
            .chain(
                masses.flat_map(|m| core::iter::once(&mut m.mass_kg).chain(m.centre_mm.iter_mut())),
            )
            .chain(self.gains.as_mut_slice().as_flattened_mut().iter_mut())
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
    pub fn links(&self) -> &N::Table<PointMass<T>> {
        &self.links
    }

    /// The flange's load.
    pub fn load(&self) -> &PointMass<T> {
        &self.load
    }

    /// Per joint `[tilt x, tilt y, torsion]`, urad per N m.
    pub fn gains(&self) -> &N::Table<[T; 3]> {
        &self.gains
    }

    /// These masses with one gain of 1 urad per N m, gain `axis` ([`TILT_X`], [`TILT_Y`],
    /// [`TORSION`]) of joint `joint` (0-based), and every other gain zero; `None` for a joint or
    /// axis out of range, or a gravity outside [`GRAVITY_RANGE_MPS2`].
    pub fn with_unit_gain(&self, joint: usize, axis: usize) -> Option<Self> {
        let mut gains = self.joint_count().table([T::zero(); 3]);
        *gains.as_mut_slice().get_mut(joint)?.get_mut(axis)? = T::one();
        Self::new(self.gravity_mps2, self.links, self.load, gains).ok()
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use nalgebra::U6;
    extern crate std;

    pub(crate) fn ur_like() -> Compliance<f64, U6> {
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

    #[test]
    fn values_out_of_range_are_refused() {
        let good = ur_like();
        let mut gains = *good.gains();
        gains[1][2] = 1001.0;
        let refuse = |g: [f64; 3], l: [PointMass<f64>; 6], t: PointMass<f64>, k| {
            assert_eq!(
                Compliance::<f64, U6>::new(g, l, t, k),
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
        assert!(
            Compliance::<f64, U6>::new([0.0; 3], *good.links(), *good.load(), [[0.0; 3]; 6])
                .is_ok()
        );
    }
}
