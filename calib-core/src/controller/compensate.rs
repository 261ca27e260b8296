//! On-line pose compensation: joint readings that put the actual robot (the identified model) on
//! a target pose, and Cartesian pre-distortion for controllers that accept only Cartesian targets.
//!
//! Joint-space compensation iterates damped least squares (Levenberg-Marquardt in joint space) with
//! the actual model's geometric Jacobian: `dq = J^T (J J^T + lambda^2 W)^-1 e`, where `e` is the pose
//! error of the target against the actual pose (`[dp (mm); dr (rad)]`) and `W` puts millimetres and
//! radians on one scale (1 rad ~ [`CHARACTERISTIC_LENGTH`] mm). Each iteration costs one forward
//! kinematics with Jacobian and one 6x6 Cholesky solve; the iteration cap bounds the worst case.
//!
//! A robot with angle-error maps ([`MappedKinematics`]) is solved in two steps: the damped least
//! squares above finds the kinematic joint angles that put its geometry on the target, then the
//! maps' fixed-point inverse (`model::joint_maps`, error bound proved there) gives the readings
//! to command, and the pose of the whole model at those readings is checked against the
//! tolerance. The inverse costs one sine and cosine and `2 C` harmonic terms per joint and
//! iteration, against a forward kinematics with Jacobian and a 6x6 solve for another Newton step.
//!
//! Every run ends in a result or an error, never a silent failure: no convergence within the cap,
//! a joint outside its limits, a correction larger than the configured bound (compared with the
//! pose the nominal model gives for the start joints), or a near-singular configuration
//! (manipulability of the scaled Jacobian below a threshold).

use crate::KinematicsError;
use crate::kinematics::pose_error::PoseError;
use crate::kinematics::{Kinematics, MappedKinematics, Pose};
use crate::math::{cholesky, norm};
use crate::model::JointLimits;
use crate::model::{JacobianColumns, JointCount, JointTable};
use crate::scalar::Real;
use core::borrow::Borrow;
use core::fmt;
use nalgebra::{SMatrix, SVector};

/// Length that makes one radian comparable to millimetres in the Jacobian scaling, mm (the
/// ER10L-C10's reach is about 1.4 m).
pub const CHARACTERISTIC_LENGTH: f64 = 1000.0;

/// Geometry solves at most per compensation of a model with gravity compliance (typically 1 or
/// 2 are used).
pub const COMPLIANCE_ROUNDS: u32 = 4;

/// Settings of a compensation.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CompensationSettings<T> {
    /// Position tolerance, mm.
    pub position_tolerance: T,
    /// Orientation tolerance, rad.
    pub rotation_tolerance: T,
    /// Iteration cap (each iteration: one forward kinematics with Jacobian, one 6x6 solve).
    pub max_iterations: u32,
    /// Damping `lambda` of the damped least-squares step (scaled units).
    pub damping: T,
    /// Largest allowed correction of the commanded pose, mm.
    pub max_correction_mm: T,
    /// Largest allowed correction of the commanded orientation, rad.
    pub max_correction_rad: T,
    /// Largest allowed change of any joint from the start, rad: away from singularities a mm-level
    /// correction needs hundredths of a radian; near the wrist singularity joints 4 and 6 may
    /// need tenths; more is a wrist flip, never commanded.
    pub max_joint_correction_rad: T,
    /// Smallest allowed manipulability `sqrt(det(J_s J_s^T))` of the scaled Jacobian.
    pub min_manipulability: T,
}

impl<T: Real> Default for CompensationSettings<T> {
    /// 1e-3 mm and 1e-6 rad in f64 (1e-2 mm and 1e-5 rad in f32, its rounding floor), 60
    /// iterations (typically 2 to 5 are used; the slow ones are near singularities), corrections up
    /// to 5 mm and 0.5 deg and 0.5 rad per joint, manipulability at least 1e-6.
    fn default() -> Self {
        let f64_scalar = T::BYTES >= 8;
        Self {
            position_tolerance: T::of(if f64_scalar { 1e-3 } else { 1e-2 }),
            rotation_tolerance: T::of(if f64_scalar { 1e-6 } else { 1e-5 }),
            max_iterations: 60,
            damping: T::of(1e-6),
            max_correction_mm: T::of(5.0),
            max_correction_rad: T::of(0.5f64.to_radians()),
            max_joint_correction_rad: T::of(0.5),
            min_manipulability: T::of(1e-6),
        }
    }
}

/// Why a compensation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum CompensationError {
    /// The target or start joints are not finite.
    NonFinite,
    /// A model could not be evaluated at the joints (the cause names the joint or parameter).
    Kinematics(KinematicsError),
    /// The tolerance was not reached within the iteration cap.
    NoConvergence,
    /// The solution puts this joint (1-based) outside its limits.
    JointLimit(u8),
    /// The correction exceeds the configured bound.
    CorrectionTooLarge,
    /// The configuration is too close to a singularity.
    NearSingular,
}

impl fmt::Display for CompensationError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NonFinite => f.write_str("target or start joints are not finite"),
            Self::Kinematics(e) => write!(f, "kinematics: {e}"),
            Self::NoConvergence => f.write_str("no convergence within the iteration cap"),
            Self::JointLimit(j) => write!(f, "joint {j} would leave its limits"),
            Self::CorrectionTooLarge => f.write_str("correction larger than the configured bound"),
            Self::NearSingular => f.write_str("configuration too close to a singularity"),
        }
    }
}

impl core::error::Error for CompensationError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Kinematics(e) => Some(e),
            _ => None,
        }
    }
}

/// A successful compensation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compensated<T: Real, N: JointCount> {
    /// Joint readings to command, rad.
    pub q: N::Table<T>,
    /// Predicted remaining position error of the actual robot, mm.
    pub residual_mm: T,
    /// Predicted remaining orientation error, rad.
    pub residual_rad: T,
    /// Iterations used.
    pub iterations: u32,
}

fn finite<T: Real>(values: &[T]) -> bool {
    values.iter().all(|v| v.finite())
}

/// The actual robot the compensation drives: a geometric model, possibly with maps from joint
/// readings to its kinematic angles.
pub trait ActualRobot<T: Real, N: JointCount> {
    /// The geometric model, evaluated at kinematic angles.
    fn geometry(&self) -> &Kinematics<T, N>;
    /// The kinematic angles of joint readings `q`, rad.
    fn angles(&self, q: &N::Table<T>) -> N::Table<T>;
    /// End pose (mm) for joint readings `q` (rad).
    fn forward(&self, q: &N::Table<T>) -> Result<Pose<T>, KinematicsError>;
    /// The settings for solving the geometry alone: tighter where the readings step adds an error.
    fn geometry_settings(&self, settings: &CompensationSettings<T>) -> CompensationSettings<T>;
    /// The pose the geometry must reach at kinematic angles near `angles` for the whole model to
    /// reach `target` (the target itself unless the model deflects the end pose).
    fn geometric_target(
        &self,
        target: &Pose<T>,
        _angles: &N::Table<T>,
    ) -> Result<Pose<T>, KinematicsError> {
        Ok(*target)
    }
    /// How many times the geometry is solved at most, each time for the geometric target at the
    /// previous solution (1 unless the geometric target depends on the joints).
    fn rounds(&self) -> u32 {
        1
    }
    /// The readings for `solution`, kinematic angles that put the geometry on `target`, with the
    /// residual of the whole model there.
    fn readings(
        &self,
        solution: Compensated<T, N>,
        target: &Pose<T>,
        settings: &CompensationSettings<T>,
    ) -> Result<Compensated<T, N>, CompensationError>;
}

impl<T: Real, N: JointCount> ActualRobot<T, N> for Kinematics<T, N> {
    fn geometry(&self) -> &Kinematics<T, N> {
        self
    }
    fn angles(&self, q: &N::Table<T>) -> N::Table<T> {
        *q
    }
    fn forward(&self, q: &N::Table<T>) -> Result<Pose<T>, KinematicsError> {
        Kinematics::forward(self, q)
    }
    fn geometry_settings(&self, settings: &CompensationSettings<T>) -> CompensationSettings<T> {
        *settings
    }
    fn readings(
        &self,
        solution: Compensated<T, N>,
        _: &Pose<T>,
        _: &CompensationSettings<T>,
    ) -> Result<Compensated<T, N>, CompensationError> {
        Ok(solution)
    }
}

impl<T: Real, N: JointCount, const C: usize, G: Borrow<Kinematics<T, N>>> ActualRobot<T, N>
    for MappedKinematics<'_, T, N, C, G>
{
    fn geometry(&self) -> &Kinematics<T, N> {
        self.geometry.borrow()
    }
    fn angles(&self, q: &N::Table<T>) -> N::Table<T> {
        self.maps.apply(q)
    }
    fn forward(&self, q: &N::Table<T>) -> Result<Pose<T>, KinematicsError> {
        MappedKinematics::forward(self, q)
    }
    /// `target` with the compliance's deflection at `angles` taken off.
    #[inline(never)]
    fn geometric_target(
        &self,
        target: &Pose<T>,
        angles: &N::Table<T>,
    ) -> Result<Pose<T>, KinematicsError> {
        match self.compliance {
            None => Ok(*target),
            Some(compliance) => {
                let (_, deflection) = compliance.deflect(self.geometry.borrow(), angles)?;
                Ok(deflection.remove(target))
            }
        }
    }
    /// With compliance, up to [`COMPLIANCE_ROUNDS`]: the deflection at the solution differs from
    /// the one at the start by its change over the correction (about 1e-3 of it per mrad).
    fn rounds(&self) -> u32 {
        if self.compliance.is_some() {
            COMPLIANCE_ROUNDS
        } else {
            1
        }
    }
    /// Half the tolerances: the other half is left for the readings' inverse and, with
    /// compliance, for the change of the deflection between the geometry's start and solution.
    fn geometry_settings(&self, settings: &CompensationSettings<T>) -> CompensationSettings<T> {
        let half = T::of(0.5);
        CompensationSettings {
            position_tolerance: settings.position_tolerance * half,
            rotation_tolerance: settings.rotation_tolerance * half,
            ..*settings
        }
    }
    /// The fixed point of the maps' inverse to a tenth of the tolerances (a joint error of `e`
    /// rad moves the end by at most `e` times the reach, taken as [`CHARACTERISTIC_LENGTH`]), then
    /// the whole model's pose at the readings against the target.
    fn readings(
        &self,
        solution: Compensated<T, N>,
        target: &Pose<T>,
        settings: &CompensationSettings<T>,
    ) -> Result<Compensated<T, N>, CompensationError> {
        let tolerance = settings
            .rotation_tolerance
            .min(settings.position_tolerance / T::of(CHARACTERISTIC_LENGTH))
            * T::of(0.1);
        let (q, _) = self.maps.readings(&solution.q, tolerance);
        let pose = self.forward(&q).map_err(CompensationError::Kinematics)?;
        let error = PoseError::between(target, &pose);
        let (dp, dr) = (norm(&error.position), norm(&error.rotation));
        if !(dp <= settings.position_tolerance && dr <= settings.rotation_tolerance) {
            return Err(CompensationError::NoConvergence);
        }
        Ok(Compensated {
            q,
            residual_mm: dp,
            residual_rad: dr,
            iterations: solution.iterations,
        })
    }
}

/// Joint readings that put the `actual` robot on `target`, starting from `start` (the nominal
/// controller's inverse kinematics of the target). `nominal` is the model the controller plans
/// with: the correction bound applies to the difference between the pose it predicts for the
/// result and for the start.
pub fn compensate_joints<T: Real, N: JointCount>(
    nominal: &Kinematics<T, N>,
    actual: &impl ActualRobot<T, N>,
    limits: &N::Table<JointLimits<T>>,
    target: &Pose<T>,
    start: &N::Table<T>,
    settings: &CompensationSettings<T>,
) -> Result<Compensated<T, N>, CompensationError> {
    compensate_joints_from(nominal, actual, limits, target, start, start, settings)
}

/// [`compensate_joints`] with the iteration started at `initial` instead of `start` (a retry from
/// a neighbouring point when the first run does not converge); the bounds still apply to the
/// change from `start`, the controller's joints.
pub fn compensate_joints_from<T: Real, N: JointCount>(
    nominal: &Kinematics<T, N>,
    actual: &impl ActualRobot<T, N>,
    limits: &N::Table<JointLimits<T>>,
    target: &Pose<T>,
    start: &N::Table<T>,
    initial: &N::Table<T>,
    settings: &CompensationSettings<T>,
) -> Result<Compensated<T, N>, CompensationError> {
    if !finite(start.as_slice()) {
        return Err(CompensationError::NonFinite);
    }
    let geometry_settings = actual.geometry_settings(settings);
    let mut from = actual.angles(initial);
    let mut round = 1;
    let solution = loop {
        let goal = actual
            .geometric_target(target, &from)
            .map_err(CompensationError::Kinematics)?;
        let angles = solve_joints(actual.geometry(), &goal, &from, &geometry_settings)?;
        match actual.readings(angles, target, settings) {
            Err(CompensationError::NoConvergence) if round < actual.rounds() => {
                from = angles.q;
                round += 1;
            }
            result => break result?,
        }
    };
    if solution
        .q
        .iter()
        .zip(start.iter())
        .any(|(q, s)| (*q - *s).abs() > settings.max_joint_correction_rad)
    {
        return Err(CompensationError::CorrectionTooLarge);
    }
    for (j, (q, l)) in solution.q.iter().zip(limits.iter()).enumerate() {
        if !l.contains(*q) {
            return Err(CompensationError::JointLimit(crate::model::joint_number(j)));
        }
    }
    let before = nominal
        .forward(start)
        .map_err(CompensationError::Kinematics)?;
    let after = nominal
        .forward(&solution.q)
        .map_err(CompensationError::Kinematics)?;
    let correction = PoseError::between(&after, &before);
    if norm(&correction.position) > settings.max_correction_mm
        || norm(&correction.rotation) > settings.max_correction_rad
    {
        return Err(CompensationError::CorrectionTooLarge);
    }
    Ok(solution)
}

/// Damped least-squares inverse kinematics of `model` for `target` from `start`, with
/// Levenberg-Marquardt damping: a step that does not reduce the scaled pose error is rejected and
/// the damping raised tenfold; an accepted step lowers it tenfold (not below `settings.damping`).
pub fn solve_joints<T: Real, N: JointCount>(
    model: &Kinematics<T, N>,
    target: &Pose<T>,
    start: &N::Table<T>,
    settings: &CompensationSettings<T>,
) -> Result<Compensated<T, N>, CompensationError> {
    if !finite(start.as_slice())
        || !finite(target.translation.vector.as_slice())
        || !finite(target.rotation.matrix().as_slice())
    {
        return Err(CompensationError::NonFinite);
    }
    let length = T::of(CHARACTERISTIC_LENGTH);
    let scaled_error = |e: &PoseError<T>| -> SVector<T, 6> {
        SVector::<T, 6>::new(
            e.position.x / length,
            e.position.y / length,
            e.position.z / length,
            e.rotation.x,
            e.rotation.y,
            e.rotation.z,
        )
    };
    let mut q = *start;
    let (pose, mut jacobian) = model
        .geometric_jacobian(&q)
        .map_err(CompensationError::Kinematics)?;
    let mut error = PoseError::between(target, &pose);
    let mut lambda = settings.damping;
    let mut iterations = 0;
    loop {
        let (dp, dr) = (norm(&error.position), norm(&error.rotation));
        if dp <= settings.position_tolerance && dr <= settings.rotation_tolerance {
            return Ok(Compensated {
                q,
                residual_mm: dp,
                residual_rad: dr,
                iterations,
            });
        }
        if iterations >= settings.max_iterations || !dp.finite() || !dr.finite() {
            return Err(CompensationError::NoConvergence);
        }
        iterations += 1;
        // Scale position rows to the characteristic length so both halves are comparable.
        let mut scaled = jacobian;
        scaled.divide_position_rows(length);
        let jjt = scaled.outer_product_sum();
        // Manipulability sqrt(det(J J^T)) = product of the Cholesky factor's diagonal (no LU,
        // whose pivoting code has panicking bounds checks).
        let Some(factor) = cholesky::factor(&jjt) else {
            return Err(CompensationError::NearSingular);
        };
        let manipulability = factor.diagonal_product();
        if !manipulability.finite() || manipulability < settings.min_manipulability {
            return Err(CompensationError::NearSingular);
        }
        let damped = jjt + SMatrix::<T, 6, 6>::identity() * (lambda * lambda);
        let Some(cholesky) = cholesky::factor(&damped) else {
            return Err(CompensationError::NearSingular);
        };
        let mut dq = q;
        scaled.transpose_times(&cholesky.solve(&scaled_error(&error)), dq.as_mut_slice());
        let mut candidate = q;
        for (qi, d) in candidate.iter_mut().zip(dq.iter()) {
            *qi += *d;
        }
        // The candidate's Jacobian comes with its pose, so an accepted step (the usual case)
        // needs no second forward kinematics.
        let (candidate_pose, candidate_jacobian) = model
            .geometric_jacobian(&candidate)
            .map_err(|_| CompensationError::NoConvergence)?;
        let candidate_error = PoseError::between(target, &candidate_pose);
        if scaled_error(&candidate_error).norm_squared() < scaled_error(&error).norm_squared() {
            q = candidate;
            jacobian = candidate_jacobian;
            error = candidate_error;
            lambda = (lambda / T::of(10.0)).max(settings.damping);
        } else {
            lambda *= T::of(10.0);
        }
    }
}

/// Cartesian pre-distortion: a commanded pose such that the nominal controller's joints for it
/// put the actual robot on `target`. Iterates `C <- C (+) (target (-) actual(nominal_ik(C)))`,
/// with the nominal inverse kinematics solved from `start` by [`solve_joints`]. Returns the
/// commanded pose and the joints the controller will use.
pub fn predistort<T: Real, N: JointCount>(
    nominal: &Kinematics<T, N>,
    actual: &impl ActualRobot<T, N>,
    limits: &N::Table<JointLimits<T>>,
    target: &Pose<T>,
    start: &N::Table<T>,
    settings: &CompensationSettings<T>,
) -> Result<(Pose<T>, Compensated<T, N>), CompensationError> {
    // The joint-space solution is the fixed point: command the pose the nominal model gives it.
    let solution = compensate_joints(nominal, actual, limits, target, start, settings)?;
    let mut command = nominal
        .forward(&solution.q)
        .map_err(CompensationError::Kinematics)?;
    let mut q = *start;
    let mut iterations = 0;
    loop {
        // What the controller does with the command: its own (nominal) inverse kinematics.
        let planned = solve_joints(
            nominal,
            &command,
            &q,
            &CompensationSettings {
                position_tolerance: settings.position_tolerance / T::of(10.0),
                rotation_tolerance: settings.rotation_tolerance / T::of(10.0),
                ..*settings
            },
        )?;
        q = planned.q;
        let reached = actual.forward(&q).map_err(CompensationError::Kinematics)?;
        let error = PoseError::between(target, &reached);
        let (dp, dr) = (norm(&error.position), norm(&error.rotation));
        if dp <= settings.position_tolerance && dr <= settings.rotation_tolerance {
            return Ok((
                command,
                Compensated {
                    q,
                    residual_mm: dp,
                    residual_rad: dr,
                    iterations,
                },
            ));
        }
        if iterations >= settings.max_iterations {
            return Err(CompensationError::NoConvergence);
        }
        iterations += 1;
        // Shift the command by the remaining error (in the base frame).
        command.translation.vector += error.position;
        let delta = nalgebra::Rotation3::new(error.rotation);
        command.rotation = delta * command.rotation;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::paper::{er10l_c10, table2};
    use nalgebra::U6;
    use rand_core::{Rng, SeedableRng};
    extern crate std;

    /// Table 2 makes corrections of up to about 35 mm, beyond the 5 mm default meant for
    /// calibrated production robots, and near the wrist singularity its 0.009 rad twist errors need
    /// wrist turns beyond the 0.5 rad default, so these tests allow 50 mm, 5 deg and any joint
    /// change: they check that every target is either reached or refused with an error.
    fn settings<T: Real>() -> CompensationSettings<T> {
        CompensationSettings {
            max_correction_mm: T::of(50.0),
            max_correction_rad: T::of(5f64.to_radians()),
            max_joint_correction_rad: T::of(10.0),
            ..CompensationSettings::default()
        }
    }

    struct Outcome {
        ok: usize,
        errors: [usize; 5],
        uncompensated_mean_mm: f64,
        worst_mm: f64,
        worst_rad: f64,
    }

    /// Random targets reachable by the actual robot (its pose at random joints) that the
    /// nominal controller can plan (its inverse kinematics converges from those joints): the
    /// controller's joints are the start. Compensation must put the actual robot on the target;
    /// the check uses the actual model independently of the solver's residual.
    fn run<T: Real>(count: usize, predistortion: bool) -> Outcome {
        let actual = Kinematics::new(&er10l_c10::<T>(), &table2::<T>()).unwrap();
        run_with(
            &actual,
            |q| actual.forward(q).unwrap(),
            count,
            predistortion,
        )
    }

    /// [`run`] for any actual robot; `truth` evaluates the actual robot's pose independently of
    /// the solver.
    fn run_with<T: Real>(
        actual: &impl ActualRobot<T, U6>,
        truth: impl Fn(&[T; 6]) -> Pose<T>,
        count: usize,
        predistortion: bool,
    ) -> Outcome {
        let nominal = Kinematics::nominal(&er10l_c10::<T>()).unwrap();
        let limits = [JointLimits::unlimited(); 6];
        let settings = settings::<T>();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(5);
        let mut out = Outcome {
            ok: 0,
            errors: [0; 5],
            uncompensated_mean_mm: 0.0,
            worst_mm: 0.0,
            worst_rad: 0.0,
        };
        let mut tried = 0;
        while tried < count {
            let q_true: [T; 6] = core::array::from_fn(|_| {
                T::of(core::f64::consts::PI * (2.0 * f64::unit_from_bits(rng.next_u64()) - 1.0))
            });
            let target = truth(&q_true);
            // The controller's plan: nominal inverse kinematics of the target, on the branch of
            // the true joints (a closed-form IK picks the branch; a plan that wandered to another
            // branch is not what a controller would command).
            let Ok(plan) =
                solve_joints(&nominal, &target, &q_true, &CompensationSettings::default())
            else {
                continue;
            };
            if plan
                .q
                .iter()
                .zip(q_true.iter())
                .any(|(a, b)| (*a - *b).abs() > T::of(0.5))
            {
                continue;
            }
            tried += 1;
            let start = plan.q;
            let off = PoseError::between(&target, &truth(&start));
            out.uncompensated_mean_mm += off.position.norm().to_f64() / count as f64;
            let result = if predistortion {
                predistort(&nominal, actual, &limits, &target, &start, &settings).map(|(_, c)| c)
            } else {
                compensate_joints(&nominal, actual, &limits, &target, &start, &settings)
            };
            match result {
                Ok(c) => {
                    let e = PoseError::between(&target, &truth(&c.q));
                    out.worst_mm = out.worst_mm.max(e.position.norm().to_f64());
                    out.worst_rad = out.worst_rad.max(e.rotation.norm().to_f64());
                    out.ok += 1;
                }
                Err(e) => {
                    let i = match e {
                        CompensationError::NonFinite | CompensationError::Kinematics(_) => 0,
                        CompensationError::NoConvergence => 1,
                        CompensationError::JointLimit(_) => 2,
                        CompensationError::CorrectionTooLarge => 3,
                        CompensationError::NearSingular => 4,
                    };
                    out.errors[i] += 1;
                }
            }
        }
        out
    }

    fn report(name: &str, o: &Outcome) {
        std::println!(
            "{name}: ok {} errors [non-finite, no convergence, limit, too large, singular] {:?}; uncompensated mean {:.3} mm; worst {:.2e} mm {:.2e} rad",
            o.ok,
            o.errors,
            o.uncompensated_mean_mm,
            o.worst_mm,
            o.worst_rad
        );
    }

    #[test]
    fn joint_space_compensation_of_10000_targets_in_f64() {
        let o = run::<f64>(10_000, false);
        report("f64 joint space", &o);
        assert!(o.ok >= 9_990, "only {} of 10000", o.ok);
        assert!(o.worst_mm <= 1e-3 && o.worst_rad <= 1e-6);
        assert!((10.0..16.0).contains(&o.uncompensated_mean_mm));
    }

    #[test]
    fn predistortion_of_10000_targets_in_f64() {
        let o = run::<f64>(10_000, true);
        report("f64 pre-distortion", &o);
        assert!(o.ok >= 9_990, "only {} of 10000", o.ok);
        assert!(o.worst_mm <= 1e-3 && o.worst_rad <= 1e-6);
    }

    #[test]
    fn joint_space_compensation_in_f32() {
        let o = run::<f32>(10_000, false);
        report("f32 joint space", &o);
        assert!(o.ok >= 9_990, "only {} of 10000", o.ok);
        assert!(o.worst_mm <= 1e-2, "{}", o.worst_mm);
    }

    /// Table 2's geometry with maps of 8 harmonics, up to about 1 mrad per joint (the UR10's are
    /// 0.15-0.33 mrad RMS).
    fn mapped_maps<T: Real>() -> crate::model::joint_maps::JointMaps<T, U6, 8> {
        let mut sin = [[T::zero(); 8]; 6];
        let mut cos = [[T::zero(); 8]; 6];
        for j in 0..6 {
            for h in 0..8 {
                let sign = if (j + h) % 2 == 0 { 1.0 } else { -1.0 };
                sin[j][h] = T::of(3e-4 / (1.0 + h as f64) * sign);
                cos[j][h] = T::of(1e-4 * ((j * 3 + h) % 5) as f64 / 5.0);
            }
        }
        crate::model::joint_maps::JointMaps::new(8, sin, cos).unwrap()
    }

    fn mapped<T: Real>(
        maps: &crate::model::joint_maps::JointMaps<T, U6, 8>,
    ) -> MappedKinematics<'_, T, U6, 8> {
        MappedKinematics::new(&er10l_c10(), &table2(), maps).unwrap()
    }

    /// The mapped robot's pose from the series summed with libm's sine and cosine of `h q` in
    /// f64, independently of the recurrence and the fixed point.
    fn mapped_truth<T: Real>(model: &MappedKinematics<'_, T, U6, 8>, q: &[T; 6]) -> Pose<T> {
        let angles: [T; 6] = core::array::from_fn(|j| {
            let x = q[j].to_f64();
            let (a, b) = (
                model.maps.sin_coefficients(j).unwrap(),
                model.maps.cos_coefficients(j).unwrap(),
            );
            let dq: f64 = (0..8)
                .map(|h| {
                    let (s, c) = libm::sincos((h + 1) as f64 * x);
                    a[h].to_f64() * s + b[h].to_f64() * c
                })
                .sum();
            T::of(x + dq)
        });
        model.geometry.forward(&angles).unwrap()
    }

    #[test]
    fn joint_space_compensation_with_maps_in_f64_and_f32() {
        let maps = mapped_maps::<f64>();
        let model = mapped(&maps);
        let o = run_with(&model, |q| mapped_truth(&model, q), 2_000, false);
        report("f64 joint space with maps", &o);
        assert!(o.ok >= 1_996, "only {} of 2000", o.ok);
        assert!(o.worst_mm <= 1e-3 && o.worst_rad <= 1e-6, "{}", o.worst_mm);
        let maps = mapped_maps::<f32>();
        let model = mapped(&maps);
        let o = run_with(&model, |q| mapped_truth(&model, q), 2_000, false);
        report("f32 joint space with maps", &o);
        assert!(o.ok >= 1_996, "only {} of 2000", o.ok);
        assert!(o.worst_mm <= 1e-2, "{}", o.worst_mm);
    }

    /// UR10-like masses on Table 2's robot with gains of 3-12 urad/(N m) on joints 1-4: deflections
    /// of about 0.1-1 mm.
    fn compliance<T: Real>() -> crate::model::compliance::Compliance<T, U6> {
        use crate::model::compliance::{Compliance, PointMass};
        let mass = |m: f64, c: [f64; 3]| PointMass {
            mass_kg: T::of(m),
            centre_mm: c.map(T::of),
        };
        let gains = [
            [12.0, -7.0, 0.0],
            [3.0, 0.0, 6.0],
            [-4.0, 2.0, 9.0],
            [5.0, 1.0, 8.0],
            [0.0; 3],
            [0.0; 3],
        ];
        Compliance::new(
            [T::zero(), T::zero(), T::of(-9.81)],
            [
                mass(20.0, [-100.0, 0.0, 50.0]),
                mass(15.0, [-300.0, 0.0, 0.0]),
                mass(8.0, [0.0, 0.0, 300.0]),
                mass(3.0, [0.0, 10.0, 0.0]),
                mass(2.0, [0.0, 0.0, 10.0]),
                mass(0.5, [0.0, 0.0, -20.0]),
            ],
            mass(1.5, [0.0, 0.0, 60.0]),
            gains.map(|g| g.map(T::of)),
        )
        .unwrap()
    }

    #[test]
    fn joint_space_compensation_with_maps_and_compliance_in_f64_and_f32() {
        fn check<T: Real>(count: usize, predistortion: bool, worst: (f64, f64)) {
            let maps = mapped_maps::<T>();
            let compliance = compliance::<T>();
            let model = mapped(&maps).with_compliance(&compliance).unwrap();
            // Independently of the solver: the maps summed in f64, then the deflection there.
            let truth = |q: &[T; 6]| {
                let plain = mapped_truth(&model, q);
                let t = model.maps.apply(q);
                let (geometric, deflection) = compliance.deflect(&model.geometry, &t).unwrap();
                // The maps' truth and the recurrence agree far below the tolerance.
                assert!(
                    (plain.translation.vector - geometric.translation.vector)
                        .norm()
                        .to_f64()
                        < worst.0 / 10.0
                );
                deflection.apply(&plain)
            };
            // The compliance moves the robot by a tenth of a millimetre or more here.
            let q = [0.3, -0.4, 0.5, 0.2, 0.9, -0.3].map(T::of);
            let moved = truth(&q).translation.vector - mapped_truth(&model, &q).translation.vector;
            assert!(moved.norm().to_f64() > 0.1, "{}", moved.norm());
            let o = run_with(&model, truth, count, predistortion);
            report(
                &std::format!("{}-byte joint space with maps and compliance", T::BYTES),
                &o,
            );
            assert!(o.ok * 1000 >= count * 998, "only {} of {count}", o.ok);
            assert!(
                o.worst_mm <= worst.0 && o.worst_rad <= worst.1,
                "{}",
                o.worst_mm
            );
        }
        check::<f64>(2_000, false, (1e-3, 1e-6));
        check::<f32>(2_000, false, (1e-2, 1e-5));
        check::<f64>(500, true, (1e-3, 1e-6));
    }

    #[test]
    fn predistortion_with_maps_in_f64() {
        let maps = mapped_maps::<f64>();
        let model = mapped(&maps);
        let o = run_with(&model, |q| mapped_truth(&model, q), 2_000, true);
        report("f64 pre-distortion with maps", &o);
        assert!(o.ok >= 1_996, "only {} of 2000", o.ok);
        assert!(o.worst_mm <= 1e-3 && o.worst_rad <= 1e-6, "{}", o.worst_mm);
    }

    #[test]
    fn errors_instead_of_wild_poses() {
        let nominal = Kinematics::nominal(&er10l_c10::<f64>()).unwrap();
        let actual = Kinematics::new(&er10l_c10::<f64>(), &table2::<f64>()).unwrap();
        let q = [0.3, -0.4, 0.5, 0.6, -0.7, 0.8];
        let target = nominal.forward(&q).unwrap();
        let unlimited = [JointLimits::unlimited(); 6];
        // The default 5 mm bound refuses the large Table 2 correction at this pose.
        let off = PoseError::between(&target, &actual.forward(&q).unwrap())
            .position
            .norm();
        assert!(off > 5.0, "{off}");
        assert_eq!(
            compensate_joints(
                &nominal,
                &actual,
                &unlimited,
                &target,
                &q,
                &CompensationSettings::default()
            ),
            Err(CompensationError::CorrectionTooLarge)
        );
        // A limit that the solution must cross.
        let mut limits = unlimited;
        limits[0] = JointLimits {
            lower: 0.29,
            upper: 0.3,
        };
        let solved =
            compensate_joints(&nominal, &actual, &unlimited, &target, &q, &settings()).unwrap();
        if !limits[0].contains(solved.q[0]) {
            assert_eq!(
                compensate_joints(&nominal, &actual, &limits, &target, &q, &settings()),
                Err(CompensationError::JointLimit(1))
            );
        }
        // Wrist singularity of the model being solved (q5 = 0), target 1 mm away.
        let singular = [0.3, -0.4, 0.5, 0.6, 0.0, 0.8];
        let mut target = nominal.forward(&singular).unwrap();
        target.translation.vector.z += 1.0;
        assert_eq!(
            compensate_joints(
                &nominal,
                &nominal,
                &unlimited,
                &target,
                &singular,
                &settings()
            ),
            Err(CompensationError::NearSingular)
        );
        // A wrist flip is refused by the joint bound.
        let near = [0.525, 0.687, -1.11, -1.765, -3.122, -0.565];
        let target = nominal.forward(&near).unwrap();
        let wide = CompensationSettings {
            max_joint_correction_rad: 0.5,
            ..settings()
        };
        match compensate_joints(&nominal, &actual, &unlimited, &target, &near, &wide) {
            Ok(c) => assert!(
                c.q.iter()
                    .zip(near.iter())
                    .all(|(a, b)| (a - b).abs() <= 0.5)
            ),
            Err(e) => assert!(
                matches!(
                    e,
                    CompensationError::CorrectionTooLarge | CompensationError::NoConvergence
                ),
                "{e:?}"
            ),
        }
        // Garbage in.
        let mut bad = q;
        bad[2] = f64::NAN;
        assert_eq!(
            compensate_joints(&nominal, &actual, &unlimited, &target, &bad, &settings()),
            Err(CompensationError::NonFinite)
        );
        // An unreachable target (2 m beyond the reach).
        let mut far = target;
        far.translation.vector.x += 2000.0;
        assert!(compensate_joints(&nominal, &actual, &unlimited, &far, &q, &settings()).is_err());
    }
}
