//! Bounded numerical inverse kinematics for any serial robot: redundant arms (7 joints: KUKA
//! iiwa, Franka Panda, Barrett WAM) and geometries without a closed form.
//!
//! The method is the compensation's damped least squares ([`solve_joints`]: minimum-norm steps
//! `dq = J^T (J J^T + lambda^2 I)^-1 e`, Levenberg-Marquardt damping) started from a fixed
//! sequence of seeds: the caller's reference posture first, then the points of a Halton sequence
//! over the joint limits (one turn where a joint is unlimited). A converged solution is moved by
//! whole turns into the joint limits where a joint allows it; the first seed whose solution lies
//! within every limit is returned. The choice for redundant arms is therefore documented and
//! deterministic: the solution reached from the reference posture when that one converges within
//! the limits (the damped steps are minimum-norm, so it stays near the reference), otherwise the
//! one from the first Halton seed that does. The work is bounded: at most `seeds` runs of at most
//! `max_iterations` iterations each.

use crate::controller::compensate::{CompensationError, CompensationSettings, solve_joints};
use crate::identify::halton::{Scrambling, halton_point};
use crate::kinematics::{Kinematics, Pose};
use crate::model::JointLimits;
use crate::model::{JointCount, JointTable};
use crate::scalar::Real;
use core::fmt;

/// Settings of [`numerical_inverse_kinematics`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NumericalIkSettings<T> {
    /// Position tolerance, mm.
    pub position_tolerance_mm: T,
    /// Orientation tolerance, rad.
    pub rotation_tolerance_rad: T,
    /// Iteration cap of one run from one seed.
    pub max_iterations: u32,
    /// Seeds tried at most: the reference posture and `seeds - 1` Halton points.
    pub seeds: u32,
    /// Smallest manipulability of the scaled Jacobian a run may pass (a run that meets a
    /// singularity ends and the next seed is tried).
    pub min_manipulability: T,
}

impl<T: Real> Default for NumericalIkSettings<T> {
    /// 1e-4 mm and 1e-7 rad in f64 (1e-2 mm and 1e-5 rad in f32), 100 iterations per run, 128
    /// seeds (the Franka Panda's narrow limits needed up to 102 for 1,000 random targets:
    /// `host-tools/tests/integration/numerical_ik.rs`), manipulability at least 1e-9.
    fn default() -> Self {
        let f64_scalar = T::BYTES >= 8;
        Self {
            position_tolerance_mm: T::of(if f64_scalar { 1e-4 } else { 1e-2 }),
            rotation_tolerance_rad: T::of(if f64_scalar { 1e-7 } else { 1e-5 }),
            max_iterations: 100,
            seeds: 128,
            min_manipulability: T::of(1e-9),
        }
    }
}

/// A solution of [`numerical_inverse_kinematics`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NumericalIk<T: Real, N: JointCount> {
    /// Joint readings, rad, within the limits.
    pub q: N::Table<T>,
    /// The seed it came from: 0 the reference posture, k > 0 Halton point k.
    pub seed: u32,
    /// Remaining position error, mm.
    pub residual_mm: T,
    /// Remaining orientation error, rad.
    pub residual_rad: T,
}

/// Why no solution was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum NumericalIkError {
    /// The target or the reference posture is not finite.
    NonFinite,
    /// No seed converged to the tolerances within the joint limits (the target is out of reach,
    /// or reachable only near a singularity or outside the limits).
    NotFound {
        /// Seeds tried.
        seeds: u32,
    },
}

impl fmt::Display for NumericalIkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite => f.write_str("target or reference posture is not finite"),
            Self::NotFound { seeds } => write!(
                f,
                "numerical inverse kinematics found no solution within the joint limits from {seeds} \
                 starts: the target is out of reach, near a singularity or reachable only outside \
                 the limits"
            ),
        }
    }
}

impl core::error::Error for NumericalIkError {}

/// Runs from one seed at most: the first, then again from its solution clamped into the limits.
const LIMIT_ROUNDS: usize = 3;

/// `q` moved by whole turns into `limits` if possible.
fn into_limits<T: Real>(q: T, limits: &JointLimits<T>) -> Option<T> {
    if limits.contains(q) {
        return Some(q);
    }
    let two_pi = T::two_pi();
    // The turn count that brings q just above the lower limit.
    let turns = libm::ceil(((limits.lower - q) / two_pi).to_f64());
    let moved = q + two_pi * T::of(turns);
    limits.contains(moved).then_some(moved)
}

/// The seed `index` (1-based Halton point) within the limits (one turn around zero where a joint
/// is unlimited on a side).
fn halton_seed<T: Real, N: JointCount>(
    index: u32,
    limits: &N::Table<JointLimits<T>>,
) -> N::Table<T> {
    let joints = N::of(limits);
    let mut unit = joints.table(0.5f64);
    halton_point(u64::from(index), Scrambling::None, unit.as_mut_slice());
    let pi = core::f64::consts::PI;
    let mut seed = joints.table(T::zero());
    for ((q, l), u) in seed.iter_mut().zip(limits.iter()).zip(unit.iter()) {
        let (lower, upper) = (l.lower.to_f64().max(-pi), l.upper.to_f64().min(pi));
        *q = T::of(lower + (upper - lower) * u);
    }
    seed
}

/// Joint readings that put `model` on `target` (base frame, mm) within `limits`, from
/// `reference` (rad) first, then from Halton seeds (see the module documentation).
pub fn numerical_inverse_kinematics<T: Real, N: JointCount>(
    model: &Kinematics<T, N>,
    limits: &N::Table<JointLimits<T>>,
    target: &Pose<T>,
    reference: &N::Table<T>,
    settings: &NumericalIkSettings<T>,
) -> Result<NumericalIk<T, N>, NumericalIkError> {
    numerical_inverse_kinematics_from_seed(model, limits, target, reference, settings, 0)
}

/// [`numerical_inverse_kinematics`] with the search begun at seed `first_seed` (0: the
/// reference posture; `k >= 1`: the k-th Halton point): the next solution after one found at
/// seed `k - 1` that did not serve (a compensation from it failed, say), in the same order.
pub fn numerical_inverse_kinematics_from_seed<T: Real, N: JointCount>(
    model: &Kinematics<T, N>,
    limits: &N::Table<JointLimits<T>>,
    target: &Pose<T>,
    reference: &N::Table<T>,
    settings: &NumericalIkSettings<T>,
    first_seed: u32,
) -> Result<NumericalIk<T, N>, NumericalIkError> {
    let solve = CompensationSettings {
        position_tolerance: settings.position_tolerance_mm,
        rotation_tolerance: settings.rotation_tolerance_rad,
        max_iterations: settings.max_iterations,
        min_manipulability: settings.min_manipulability,
        ..CompensationSettings::default()
    };
    for seed in first_seed..settings.seeds {
        let mut start = if seed == 0 {
            *reference
        } else {
            halton_seed::<T, N>(seed, limits)
        };
        // A solution outside the limits is clamped into them and solved again from there (the
        // other joints take over the motion the clamped ones cannot make), a few times.
        for _ in 0..LIMIT_ROUNDS {
            // The first run checks the target and the reference: not finite is an error at once.
            let solution = match solve_joints(model, target, &start, &solve) {
                Ok(s) => s,
                Err(CompensationError::NonFinite) => return Err(NumericalIkError::NonFinite),
                Err(_) => break,
            };
            let mut q = solution.q;
            let within = q
                .iter_mut()
                .zip(limits.iter())
                .all(|(qj, l)| into_limits(*qj, l).map(|v| *qj = v).is_some());
            if within {
                return Ok(NumericalIk {
                    q,
                    seed,
                    residual_mm: solution.residual_mm,
                    residual_rad: solution.residual_rad,
                });
            }
            for ((s, v), l) in start.iter_mut().zip(q.iter()).zip(limits.iter()) {
                *s = v.max(l.lower).min(l.upper);
            }
        }
    }
    Err(NumericalIkError::NotFound {
        seeds: settings.seeds,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turns_bring_a_joint_into_its_limits_or_refuse() {
        let limits = JointLimits {
            lower: -1.0f64,
            upper: 3.0,
        };
        let two_pi = core::f64::consts::TAU;
        assert_eq!(into_limits(2.0, &limits), Some(2.0));
        assert!((into_limits(2.0 - two_pi, &limits).unwrap() - 2.0).abs() < 1e-12);
        assert!((into_limits(-0.5 + 3.0 * two_pi, &limits).unwrap() + 0.5).abs() < 1e-12);
        // 4 rad is not within [-1, 3] after any whole turn (4 - 2 pi = -2.28).
        assert_eq!(into_limits(4.0, &limits), None);
        assert_eq!(
            into_limits(1e300, &JointLimits::unlimited()),
            Some(1e300),
            "an unlimited joint keeps its value"
        );
    }
}
