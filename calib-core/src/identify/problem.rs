//! A calibration problem, checked once and borrowed by both solvers (the swarm's [`Objective`]
//! and [`LeastSquares`]): the nominal robot (prepared once), the errors of the parameters that are
//! not identified, the identified parameter set, the measurements, and the orientation weight `k`.
//!
//! [`Objective`]: crate::identify::objective::Objective
//! [`LeastSquares`]: crate::identify::lm::LeastSquares

use crate::identify::objective::Measurement;
use crate::kinematics::{Kinematics, PreparedRobot};
use crate::model::Robot;
use crate::model::parameters::{ParameterErrors, ParameterSet, ShapeError};
use crate::model::{JointCount, JointTable};
use crate::model::{KinematicsError, check_count};
use crate::scalar::Real;
use core::fmt;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OVector};

/// Why a calibration problem was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ProblemError {
    /// The nominal model or the fixed errors are invalid.
    Model(KinematicsError),
    /// The orientation weight `k` is negative or not finite.
    InvalidK,
}

impl fmt::Display for ProblemError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Model(e) => write!(f, "model: {e}"),
            Self::InvalidK => f.write_str("the orientation weight k must be finite and >= 0"),
        }
    }
}

impl core::error::Error for ProblemError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Model(e) => Some(e),
            Self::InvalidK => None,
        }
    }
}

impl From<KinematicsError> for ProblemError {
    fn from(e: KinematicsError) -> Self {
        Self::Model(e)
    }
}

/// The data and model of one calibration, checked once.
#[derive(Clone, Debug)]
pub struct Problem<'a, T: Real, N: JointCount, D: Dim>
where
    DefaultAllocator: Allocator<D>,
{
    robot: PreparedRobot<T, N>,
    fixed: ParameterErrors<T, N>,
    set: ParameterSet<N, D>,
    measurements: &'a [Measurement<T, N>],
    k: T,
}

impl<'a, T: Real, N: JointCount, D: Dim> Problem<'a, T, N, D>
where
    DefaultAllocator: Allocator<D>,
{
    /// The problem of identifying the parameters of `set`; the others keep the values of `fixed`
    /// (usually zero). `k` weights orientation, mm^2/rad^2 (eq. 7).
    pub fn new(
        robot: &Robot<T, N>,
        fixed: &ParameterErrors<T, N>,
        set: ParameterSet<N, D>,
        measurements: &'a [Measurement<T, N>],
        k: T,
    ) -> Result<Self, ProblemError> {
        robot.validate()?;
        fixed.validate()?;
        let joints = robot.joints.len();
        check_count(joints, fixed.joints.len())?;
        check_count(joints, set.joint_count().value())?;
        for m in measurements {
            check_count(joints, m.angles.cos.len())?;
        }
        if !k.finite() || k < T::zero() {
            return Err(ProblemError::InvalidK);
        }
        Ok(Self {
            robot: PreparedRobot::new(robot),
            fixed: *fixed,
            set,
            measurements,
            k,
        })
    }

    /// The joint count.
    pub fn joint_count(&self) -> N {
        self.set.joint_count()
    }

    /// The identified parameters.
    pub fn set(&self) -> &ParameterSet<N, D> {
        &self.set
    }

    /// The orientation weight `k`, mm^2/rad^2.
    pub fn k(&self) -> T {
        self.k
    }

    /// The measurements.
    pub fn measurements(&self) -> &'a [Measurement<T, N>] {
        self.measurements
    }

    /// All errors for the packed vector `x`: the fixed values with the identified ones replaced;
    /// a vector of another length than the set is refused.
    pub fn errors(&self, x: &OVector<T, D>) -> Result<ParameterErrors<T, N>, ShapeError> {
        self.set.check_shape(x)?;
        Ok(self.errors_unchecked(x))
    }

    /// [`Self::errors`] of a vector whose length was checked where it entered (the objective's
    /// and the solver's inner loops).
    #[cfg_attr(not(target_arch = "arm"), inline(always))]
    pub(crate) fn errors_unchecked(&self, x: &OVector<T, D>) -> ParameterErrors<T, N> {
        let mut errors = self.fixed;
        self.set.write_into(x, &mut errors);
        errors
    }

    /// The actual model at the packed errors `x`; a vector of another length than the set is
    /// refused.
    pub fn kinematics(&self, x: &OVector<T, D>) -> Result<Kinematics<T, N>, ShapeError> {
        self.set.check_shape(x)?;
        Ok(self.kinematics_unchecked(x))
    }

    /// [`Self::kinematics`] of a vector whose length was checked where it entered.
    #[cfg_attr(not(target_arch = "arm"), inline(always))]
    pub(crate) fn kinematics_unchecked(&self, x: &OVector<T, D>) -> Kinematics<T, N> {
        self.robot.actual(&self.errors_unchecked(x))
    }
}
