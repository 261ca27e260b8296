//! Compensation of target poses with an identified robot, off line: for each target, the joints
//! that put the actual (identified) robot on it, started from the controller's nominal joints:
//! given, or the nominal inverse kinematics, in closed form on a branch where the structure allows
//! (spherical wrist, UR-type offset wrist), numerical otherwise
//! ([`calib_core::controller::numerical_ik`], from the middle of the joint limits).

use crate::tracker_data::TrackerData;
use anyhow::Context;
use calib_core::controller::compensate::{
    ActualRobot, Compensated, CompensationError, CompensationSettings, compensate_joints_from,
    solve_joints,
};
use calib_core::controller::numerical_ik::{NumericalIkSettings, numerical_inverse_kinematics};
use calib_core::kinematics::ik::{IkError, inverse_kinematics};
use calib_core::kinematics::pose_error::PoseError;
use calib_core::{Kinematics, Robot};

/// A target pose in the base frame (mm).
type Pose = calib_core::Pose<f64>;
use nalgebra::{Rotation3, Translation3};

/// The outcome for one target of an `N`-joint robot.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetOutcome<const N: usize> {
    /// The target's id.
    pub id: String,
    /// Where the start joints came from: `given`, `closed form, branch B` or `numerical, seed S`
    /// (empty when none was found).
    pub start: String,
    /// The compensated joints (rad) and predicted residuals, or why the target was refused.
    pub result: Result<Compensated<f64, N>, String>,
}

/// Counts of a compensation run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Summary {
    /// Targets compensated.
    pub ok: usize,
    /// Targets refused with an error.
    pub failed: usize,
}

impl Summary {
    /// The counts of `outcomes`.
    pub fn of<const N: usize>(outcomes: &[TargetOutcome<N>]) -> Self {
        let ok = outcomes.iter().filter(|o| o.result.is_ok()).count();
        Self {
            ok,
            failed: outcomes.len() - ok,
        }
    }
}

/// Compensates every target of `targets` (base frame, with orientation; joints, when the file
/// has `q1_deg..qN_deg`, are the start): `nominal` is the model the controller plans with,
/// `actual` the identified robot. `branch` (0-7) picks the closed-form inverse kinematics
/// solution for targets without joints. One outcome per target, in file order.
pub fn compensate_targets<const N: usize>(
    nominal: &Robot<f64, N>,
    actual: &Robot<f64, N>,
    targets: &TrackerData,
    settings: &CompensationSettings<f64>,
    branch: usize,
) -> anyhow::Result<Vec<TargetOutcome<N>>> {
    let real = Kinematics::nominal(actual).context("identified robot")?;
    compensate_targets_of(nominal, &real, targets, settings, branch)
}

/// [`compensate_targets`] for any actual robot: the geometry alone ([`Kinematics`]) or with
/// angle-error maps ([`calib_core::kinematics::MappedKinematics`]).
pub fn compensate_targets_of<const N: usize>(
    nominal: &Robot<f64, N>,
    real: &impl ActualRobot<f64, N>,
    targets: &TrackerData,
    settings: &CompensationSettings<f64>,
    branch: usize,
) -> anyhow::Result<Vec<TargetOutcome<N>>> {
    let planned = Kinematics::nominal(nominal).context("nominal robot")?;
    let outcomes = targets
        .records
        .iter()
        .map(|record| {
            let rotation = record.rotation.unwrap_or_else(nalgebra::Matrix3::identity);
            let target = Pose::from_parts(
                Translation3::from(nalgebra::Vector3::from(record.position)),
                Rotation3::from_matrix_unchecked(rotation),
            );
            let (start, method) =
                match planned_start(nominal, &planned, &target, record, targets.joints, branch) {
                    Ok((q, method)) => (Ok(q), method),
                    Err(e) => (Err(e), String::new()),
                };
            let result = start.and_then(|start| {
                compensate_target(&planned, real, &nominal.limits, &target, &start, settings)
            });
            TargetOutcome {
                id: record.id.clone(),
                start: method,
                result,
            }
        })
        .collect();
    Ok(outcomes)
}

/// The controller's joints for `target` and how they were found: the record's joints when the
/// file has them; otherwise the nominal inverse kinematics, in closed form on `branch` where the
/// robot's structure has one (6 joints: spherical or UR-type offset wrist), else numerical from
/// the middle of the joint limits (each limit taken within one turn of zero).
fn planned_start<const N: usize>(
    nominal: &Robot<f64, N>,
    planned: &Kinematics<f64, N>,
    target: &Pose,
    record: &crate::tracker_data::Record,
    joints_in_file: usize,
    branch: usize,
) -> Result<([f64; N], String), String> {
    if joints_in_file == N {
        let q = std::array::from_fn(|i| record.q.get(i).copied().unwrap_or(0.0));
        return Ok((q, "given".into()));
    }
    match closed_form(nominal, target, branch) {
        Some(Ok(q)) => return Ok((q, format!("closed form, branch {branch}"))),
        Some(Err(e)) => return Err(e),
        None => {}
    }
    let pi = std::f64::consts::PI;
    let reference = nominal
        .limits
        .map(|l| 0.5 * (l.lower.max(-pi) + l.upper.min(pi)));
    numerical_inverse_kinematics(
        planned,
        &nominal.limits,
        target,
        &reference,
        &NumericalIkSettings::default(),
    )
    .map(|s| (s.q, format!("numerical, seed {}", s.seed)))
    .map_err(|e| e.to_string())
}

/// The closed-form inverse kinematics on `branch` when the robot has one (`None`: no closed
/// form for this structure or joint count).
fn closed_form<const N: usize>(
    nominal: &Robot<f64, N>,
    target: &Pose,
    branch: usize,
) -> Option<Result<[f64; N], String>> {
    // Only 6-joint robots have one: the same robot as a Robot<f64, 6>.
    let six = Robot::<f64, 6> {
        joints: nominal.joints.as_slice().try_into().ok()?,
        limits: nominal.limits.as_slice().try_into().ok()?,
        base: nominal.base,
        tool: nominal.tool,
    };
    match inverse_kinematics(&six, target) {
        Ok(solutions) => Some(
            solutions
                .get(branch)
                .copied()
                .flatten()
                .and_then(|q| q.as_slice().try_into().ok())
                .ok_or_else(|| format!("target out of reach on branch {branch}")),
        ),
        Err(IkError::UnsupportedGeometry) => None,
        Err(e) => Some(Err(e.to_string())),
    }
}

/// Retries after the first run from the controller's joints: the iteration cap is multiplied by
/// this, and the start moved by up to [`RETRY_SPREAD_RAD`] in [`RETRIES`] fixed directions.
pub const RETRY_ITERATION_FACTOR: u32 = 4;

/// Number of retries from points near the controller's joints.
pub const RETRIES: usize = 12;

/// Largest move of a joint for a retry's start, rad.
pub const RETRY_SPREAD_RAD: f64 = 0.02;

/// Compensates one target from the controller's joints `start`: the core's
/// [`compensate_joints_from`] from `start`, then, if that fails, with a longer iteration cap and
/// from [`RETRIES`] points near `start` (the bounds always apply to the change from `start`).
/// A refusal says why; for a correction beyond the bounds, how large it is and which flag raises
/// the bound.
pub fn compensate_target<const N: usize>(
    planned: &Kinematics<f64, N>,
    real: &impl ActualRobot<f64, N>,
    limits: &[calib_core::JointLimits<f64>; N],
    target: &Pose,
    start: &[f64; N],
    settings: &CompensationSettings<f64>,
) -> Result<Compensated<f64, N>, String> {
    let first = match compensate_joints_from(planned, real, limits, target, start, start, settings)
    {
        Ok(c) => return Ok(c),
        Err(e) => e,
    };
    if matches!(
        first,
        CompensationError::NonFinite | CompensationError::Kinematics(_)
    ) {
        return Err(first.to_string());
    }
    let longer = CompensationSettings {
        max_iterations: settings
            .max_iterations
            .saturating_mul(RETRY_ITERATION_FACTOR),
        ..*settings
    };
    for retry in 0..=RETRIES {
        // Retry 0: the start itself with the longer cap; then fixed spread directions.
        let initial: [f64; N] = std::array::from_fn(|j| {
            let direction = ((retry * 7 + j * 3) % 5) as f64 / 2.0 - 1.0;
            start[j] + RETRY_SPREAD_RAD * direction * retry as f64 / RETRIES as f64
        });
        if let Ok(c) =
            compensate_joints_from(planned, real, limits, target, start, &initial, &longer)
        {
            return Ok(c);
        }
    }
    if first == CompensationError::CorrectionTooLarge {
        return Err(needed_correction(
            planned, real, target, start, &longer, settings,
        ));
    }
    Err(first.to_string())
}

/// The refusal of a correction beyond the bounds: the correction the actual robot needs, the
/// bounds, and the flags that raise them.
fn needed_correction<const N: usize>(
    planned: &Kinematics<f64, N>,
    real: &impl ActualRobot<f64, N>,
    target: &Pose,
    start: &[f64; N],
    longer: &CompensationSettings<f64>,
    settings: &CompensationSettings<f64>,
) -> String {
    let refused = CompensationError::CorrectionTooLarge.to_string();
    let geometric = real.geometry_settings(longer);
    let Ok(solution) = solve_joints(real.geometry(), target, &real.angles(start), &geometric)
        .and_then(|angles| real.readings(angles, target, longer))
    else {
        return refused;
    };
    let (Ok(before), Ok(after)) = (planned.forward(start), planned.forward(&solution.q)) else {
        return refused;
    };
    let correction = PoseError::between(&after, &before);
    let (joint, change) = solution
        .q
        .iter()
        .zip(start)
        .map(|(q, s)| (q - s).abs())
        .enumerate()
        .fold((0, 0.0f64), |m, (j, c)| if c > m.1 { (j, c) } else { m });
    format!(
        "{refused}: the actual robot needs {:.3} mm and {:.3} deg of correction (bounds {} mm, --max-correction-mm, \
         and {} deg, --max-correction-deg) and moves joint {} by {:.3} deg (bound {:.3} deg, --max-joint-correction-deg)",
        correction.position.norm(),
        correction.rotation.norm().to_degrees(),
        settings.max_correction_mm,
        settings.max_correction_rad.to_degrees(),
        joint + 1,
        change.to_degrees(),
        settings.max_joint_correction_rad.to_degrees()
    )
}

/// The outcomes as CSV: `id, q1_deg..qN_deg, residual_mm, residual_deg, status, start` (`ok` or
/// the error; a refused target leaves the joints and residuals empty).
pub fn to_csv<const N: usize>(outcomes: &[TargetOutcome<N>]) -> anyhow::Result<Vec<u8>> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["id".to_string()];
    header.extend((1..=N).map(|i| format!("q{i}_deg")));
    header.extend(["residual_mm", "residual_deg", "status", "start"].map(String::from));
    writer.write_record(&header)?;
    for outcome in outcomes {
        let mut row = vec![outcome.id.clone()];
        match &outcome.result {
            Ok(c) => {
                row.extend(c.q.iter().map(|q| q.to_degrees().to_string()));
                row.push(format!("{:.6e}", c.residual_mm));
                row.push(format!("{:.6e}", c.residual_rad.to_degrees()));
                row.push("ok".into());
            }
            Err(e) => {
                row.extend(std::iter::repeat_n(String::new(), N + 2));
                row.push(e.clone());
            }
        }
        row.push(outcome.start.clone());
        writer.write_record(&row)?;
    }
    Ok(writer.into_inner()?)
}
