//! The nominal robot: N joints of Hayati MDH parameters, joint limits, base and tool frames.

use crate::model::KinematicsError;
use crate::model::joint_count::{JointCount, JointTable, recount};
use crate::model::parameters::{FrameParameter, JointParameter, Parameter};
use crate::scalar::Real;
use core::cmp::Ordering;
use nalgebra::{IsometryMatrix3, Translation3};

/// Nominal MDH parameters of one joint (paper eq. 1). Lengths in mm, angles in rad.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MdhJoint<T> {
    /// Link length `a` along the rotated x axis, mm.
    pub a: T,
    /// Link twist `alpha` about x, rad.
    pub alpha: T,
    /// Joint zero offset, rad: `theta = q + theta_offset`.
    pub theta_offset: T,
    /// Link offset `d` along z, mm.
    pub d: T,
    /// Hayati's extra twist `beta` about y, rad (0 in standard DH).
    pub beta: T,
}

/// Range of a joint reading, rad. Infinite bounds mean "no limit"; NaN is invalid.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointLimits<T> {
    /// Lowest allowed joint reading, rad.
    pub lower: T,
    /// Highest allowed joint reading, rad.
    pub upper: T,
}

impl<T: Real> JointLimits<T> {
    /// No limit: `(-inf, +inf)`.
    pub fn unlimited() -> Self {
        let inf = T::of(f64::INFINITY);
        Self {
            lower: -inf,
            upper: inf,
        }
    }

    /// `true` when `q` (rad) lies within `[lower, upper]`.
    pub fn contains(&self, q: T) -> bool {
        q >= self.lower && q <= self.upper
    }
}

/// A rigid frame given as translation (mm) and roll, pitch, yaw (rad) with
/// `R = Rz(yaw) Ry(pitch) Rx(roll)` (the URDF convention), `T = Trans(xyz) * R`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FramePose<T> {
    /// Translation `[x, y, z]`, mm.
    pub xyz: [T; 3],
    /// `[roll, pitch, yaw]`, rad.
    pub rpy: [T; 3],
}

impl<T: Real> FramePose<T> {
    /// The identity frame.
    pub fn identity() -> Self {
        Self {
            xyz: [T::zero(); 3],
            rpy: [T::zero(); 3],
        }
    }

    /// The frame as an isometry (rotation matrix and translation).
    pub fn isometry(&self) -> IsometryMatrix3<T> {
        let [x, y, z] = self.xyz;
        let [roll, pitch, yaw] = self.rpy;
        // nalgebra applies roll, then pitch, then yaw: R = Rz(yaw) Ry(pitch) Rx(roll).
        IsometryMatrix3::from_parts(
            Translation3::new(x, y, z),
            crate::math::so3::rotation_rpy(roll, pitch, yaw),
        )
    }
}

/// The nominal model of an N-joint serial robot.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Robot<T: Real, N: JointCount> {
    /// Nominal MDH parameters, joint 1 first.
    pub joints: N::Table<MdhJoint<T>>,
    /// Joint limits, rad, joint 1 first.
    pub limits: N::Table<JointLimits<T>>,
    /// Base frame: pose of the frame of joint 1 in the measurement (world) frame.
    pub base: FramePose<T>,
    /// Tool frame: pose of the measured point or probe in the flange frame of joint N.
    pub tool: FramePose<T>,
}

impl<T: Real, N: JointCount> Robot<T, N> {
    /// A robot with the given joints, no joint limits, and identity base and tool frames.
    pub fn from_joints(joints: N::Table<MdhJoint<T>>) -> Self {
        Self {
            limits: N::of(&joints).table(JointLimits::unlimited()),
            joints,
            base: FramePose::identity(),
            tool: FramePose::identity(),
        }
    }

    /// The joint count.
    pub fn joint_count(&self) -> N {
        N::of(&self.joints)
    }

    /// The same robot with the joint count as the type `M` (`Dyn` for a controller's robot on a
    /// host, `Const<N>` back): `None` when `M` cannot hold its count.
    pub fn recount<M: JointCount>(&self) -> Option<Robot<T, M>> {
        Some(Robot {
            joints: recount::<_, N, M>(&self.joints)?,
            limits: recount::<_, N, M>(&self.limits)?,
            base: self.base,
            tool: self.tool,
        })
    }

    /// Checks that every nominal value is finite and every limit pair is ordered.
    pub fn validate(&self) -> Result<(), KinematicsError> {
        let limits = self.limits.as_slice();
        check_count(self.joints.as_slice().len(), limits.len())?;
        for (j, (joint, limits)) in self.joints.as_slice().iter().zip(limits).enumerate() {
            let number = joint_number(j);
            let values = [
                (JointParameter::A, joint.a),
                (JointParameter::D, joint.d),
                (JointParameter::Alpha, joint.alpha),
                (JointParameter::Beta, joint.beta),
                (JointParameter::Theta, joint.theta_offset),
            ];
            for (kind, value) in values {
                if !value.finite() {
                    return Err(KinematicsError::NonFiniteNominal(Parameter::Joint {
                        joint: number,
                        kind,
                    }));
                }
            }
            // NaN compares as `None`.
            if !matches!(
                limits.lower.partial_cmp(&limits.upper),
                Some(Ordering::Less | Ordering::Equal)
            ) {
                return Err(KinematicsError::InvalidLimits { joint: number });
            }
        }
        check_frame(&self.base, Parameter::Base)?;
        check_frame(&self.tool, Parameter::Tool)
    }
}

fn check_frame<T: Real>(
    frame: &FramePose<T>,
    which: fn(FrameParameter) -> Parameter,
) -> Result<(), KinematicsError> {
    let values = frame.xyz.iter().chain(&frame.rpy);
    for (kind, value) in FrameParameter::ALL.iter().zip(values) {
        if !value.finite() {
            return Err(KinematicsError::NonFiniteNominal(which(*kind)));
        }
    }
    Ok(())
}

/// `Ok` when an input of `found` joint values fits a robot of `expected` joints (always, for a
/// count fixed at compile time).
#[inline(always)]
pub(crate) fn check_count(expected: usize, found: usize) -> Result<(), KinematicsError> {
    if expected == found {
        return Ok(());
    }
    Err(KinematicsError::JointCount {
        expected: u8::try_from(expected).unwrap_or(u8::MAX),
        found: u8::try_from(found).unwrap_or(u8::MAX),
    })
}

/// 1-based joint number of the 0-based index `j`, saturating at 255 (no robot has that many joints).
pub(crate) fn joint_number(j: usize) -> u8 {
    u8::try_from(j + 1).unwrap_or(u8::MAX)
}
