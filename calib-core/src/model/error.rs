//! The error of the kinematics layer: what is wrong with a model, a parameter set or a joint input.

use crate::model::parameters::Parameter;
use core::fmt;

/// Why a kinematic model or input was refused. Every variant names the offending item.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum KinematicsError {
    /// A nominal model value (the named parameter's nominal counterpart) is NaN or infinite.
    NonFiniteNominal(Parameter),
    /// A parameter error is NaN or infinite.
    NonFiniteError(Parameter),
    /// A joint reading (1-based joint number) is NaN or infinite.
    NonFiniteJoint {
        /// Joint number, 1-based.
        joint: u8,
    },
    /// The limits of a joint (1-based) are NaN or have `lower > upper`.
    InvalidLimits {
        /// Joint number, 1-based.
        joint: u8,
    },
    /// A joint's angle-error map (1-based joint number) holds a coefficient that is not finite,
    /// beyond 10 mrad or beyond the harmonics used, or changes faster than its inverse allows
    /// (slope bound above 0.5, see `model::joint_maps`).
    InvalidJointMap {
        /// Joint number, 1-based.
        joint: u8,
    },
    /// The maps use more harmonics than the capacity they were built with.
    TooManyHarmonics,
    /// The gravity-compliance model holds a value that is not finite or out of range (see
    /// `model::compliance`).
    InvalidCompliance,
    /// A per-joint input holds another joint count than the robot (only a count known at run
    /// time, `nalgebra::Dyn`, can differ).
    JointCount {
        /// The robot's joint count.
        expected: u8,
        /// The input's joint count.
        found: u8,
    },
    /// The identification mask selects a different number of parameters than the vector holds.
    ParameterCount {
        /// Number of parameters the packed vector holds (the fixed dimension `D`).
        expected: u16,
        /// Number of parameters the mask selects.
        found: u16,
    },
}

impl fmt::Display for KinematicsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFiniteNominal(p) => write!(f, "nominal value of {p} is not finite"),
            Self::NonFiniteError(p) => write!(f, "parameter error {p} is not finite"),
            Self::NonFiniteJoint { joint } => write!(f, "joint reading q{joint} is not finite"),
            Self::InvalidLimits { joint } => {
                write!(f, "limits of joint {joint} are NaN or lower > upper")
            }
            Self::InvalidJointMap { joint } => write!(
                f,
                "the angle-error map of joint {joint} is not finite, beyond 10 mrad per coefficient or too steep to invert (slope bound above 0.5)"
            ),
            Self::JointCount { expected, found } => write!(
                f,
                "{found} joint values given for a robot of {expected} joints"
            ),
            Self::TooManyHarmonics => {
                f.write_str("the angle-error maps use more harmonics than this build holds")
            }
            Self::InvalidCompliance => f.write_str(
                "the gravity-compliance model has a value that is not finite or out of range (mass 0-1000 kg, centre within 5000 mm, gain within 1000 urad/(N m), gravity 9-10.5 m/s^2)",
            ),
            Self::ParameterCount { expected, found } => write!(
                f,
                "the identification mask selects {found} parameters, the vector holds {expected}"
            ),
        }
    }
}

impl core::error::Error for KinematicsError {}
