//! Compensation of target poses with an identified robot, off line: for each target, the joints
//! that put the actual (identified) robot on it, started from the controller's nominal joints:
//! given, or the nominal inverse kinematics, in closed form on a branch where the structure allows
//! (spherical wrist, UR-type offset wrist), numerical otherwise
//! ([`calib_core::controller::numerical_ik`], from the middle of the joint limits, up to
//! [`NUMERICAL_STARTS`] solutions). Where that fails or the nominal robot cannot reach the target
//! (within mm of a workspace boundary or singularity, where the two robots part ways), the
//! identified robot is solved from the nominal (or nearest) configuration, under the same bounds.
//! The output's `start` column says which way each row went.

use crate::error::Context;
use crate::io::tracker_data::TrackerData;
use calib_core::controller::compensate::{
    ActualRobot, Compensated, CompensationError, CompensationSettings, compensate_joints_from,
    solve_joints,
};
use calib_core::controller::numerical_ik::{
    NumericalIkSettings, numerical_inverse_kinematics_from_seed,
};
use calib_core::kinematics::ik::{BRANCHES, IkError, inverse_kinematics, nearest_configurations};
use calib_core::kinematics::pose_error::PoseError;
use calib_core::model::JointVec;
use calib_core::{Kinematics, Robot};
use nalgebra::Dyn;

/// A target pose in the base frame (mm).
type Pose = calib_core::Pose<f64>;
use nalgebra::{Rotation3, Translation3};

/// The outcome for one target.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetOutcome {
    /// The target's id.
    pub id: String,
    /// Where the start joints came from: `given`, `closed form, branch B` (with `nearest
    /// configuration (X mm beyond the nominal workspace)` for a target the nominal robot cannot
    /// reach on that branch) or `numerical, seed S` (empty when none was found).
    pub start: String,
    /// The compensated joints (rad) and predicted residuals, or why the target was refused.
    pub result: Result<Compensated<f64, Dyn>, String>,
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
    pub fn of(outcomes: &[TargetOutcome]) -> Self {
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
pub fn compensate_targets(
    nominal: &Robot<f64, Dyn>,
    actual: &Robot<f64, Dyn>,
    targets: &TrackerData,
    settings: &CompensationSettings<f64>,
    branch: usize,
) -> crate::Result<Vec<TargetOutcome>> {
    let real = Kinematics::nominal(actual).context("identified robot")?;
    compensate_targets_of(nominal, &real, targets, settings, branch)
}

/// [`compensate_targets`] for any actual robot: the geometry alone ([`Kinematics`]) or with
/// angle-error maps ([`calib_core::kinematics::MappedKinematics`]).
pub(crate) fn compensate_targets_of(
    nominal: &Robot<f64, Dyn>,
    real: &impl ActualRobot<f64, Dyn>,
    targets: &TrackerData,
    settings: &CompensationSettings<f64>,
    branch: usize,
) -> crate::Result<Vec<TargetOutcome>> {
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
            let (result, method) = compensate_record(
                nominal,
                &planned,
                real,
                &target,
                record,
                targets.joints,
                branch,
                settings,
            );
            TargetOutcome {
                id: record.id.clone(),
                start: method,
                result,
            }
        })
        .collect();
    Ok(outcomes)
}

/// Most nominal numerical solutions a target without joints is compensated from: when the
/// compensation from one fails (it lies near a singularity where the actual robot turns away, or
/// needs a joint beyond its limit), the next seed's solution is tried.
pub const NUMERICAL_STARTS: usize = 8;

/// Compensates one record: from the controller's joints when the file has them; otherwise from
/// the nominal inverse kinematics, in closed form on `branch` where the robot's structure has
/// one (6 joints: spherical or UR-type offset wrist), else numerical from the middle of the joint
/// limits (each limit taken within one turn of zero), up to [`NUMERICAL_STARTS`] solutions in
/// seed order. Returns the outcome and where the start came from (empty when none was found).
#[allow(clippy::too_many_arguments)]
fn compensate_record(
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    real: &impl ActualRobot<f64, Dyn>,
    target: &Pose,
    record: &crate::io::tracker_data::Record,
    joints_in_file: usize,
    branch: usize,
    settings: &CompensationSettings<f64>,
) -> (Result<Compensated<f64, Dyn>, String>, String) {
    let from = |start: &JointVec<f64>| {
        compensate_target(planned, real, &nominal.limits, target, start, settings)
    };
    if joints_in_file == nominal.joints.len() {
        let q = JointVec::from_fn(joints_in_file, |i| record.q.get(i).copied().unwrap_or(0.0));
        return (from(&q), "given".into());
    }
    match closed_form(nominal, planned, target, branch) {
        Some(Ok(ClosedForm::Exact(q, method))) => {
            return match from(&q) {
                Ok(c) => (Ok(c), method),
                Err(e) => {
                    on_identified_robot(planned, real, &nominal.limits, target, &q, true, settings)
                        .map_or_else(
                            |f| (Err(format!("{e}; then {f}")), method.clone()),
                            |(c, m)| (Ok(c), format!("{method}; {m}")),
                        )
                }
            };
        }
        Some(Ok(ClosedForm::Nearest(q, method))) => {
            return match on_identified_robot(
                planned,
                real,
                &nominal.limits,
                target,
                &q,
                true,
                settings,
            ) {
                Ok((c, m)) => (Ok(c), format!("{method}; {m}")),
                Err(e) => (Err(e), method),
            };
        }
        Some(Err(e)) => return (Err(e), String::new()),
        None => {}
    }
    from_numerical_starts(nominal, planned, real, target, settings)
}

/// Compensates `target` from the nominal robot's numerical inverse kinematics, from the middle
/// of the joint limits (each limit taken within one turn of zero), up to [`NUMERICAL_STARTS`]
/// solutions in seed order; where none works, the identified robot is solved from the first
/// start (or the middle of the limits). Returns the outcome and where the start came from.
fn from_numerical_starts(
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    real: &impl ActualRobot<f64, Dyn>,
    target: &Pose,
    settings: &CompensationSettings<f64>,
) -> (Result<Compensated<f64, Dyn>, String>, String) {
    let pi = std::f64::consts::PI;
    let reference = nominal
        .limits
        .map(|l| 0.5 * (l.lower.max(-pi) + l.upper.min(pi)));
    // The first failure: its error, method and start.
    let mut first: Option<(String, String, JointVec<f64>)> = None;
    let mut not_found = None;
    let mut seed = 0;
    for _ in 0..NUMERICAL_STARTS {
        let start = match numerical_inverse_kinematics_from_seed(
            planned,
            &nominal.limits,
            target,
            &reference,
            &NumericalIkSettings::default(),
            seed,
        ) {
            Ok(start) => start,
            Err(e) => {
                not_found = Some(e.to_string());
                break;
            }
        };
        let method = format!("numerical, seed {}", start.seed);
        match compensate_target(planned, real, &nominal.limits, target, &start.q, settings) {
            Ok(c) => return (Ok(c), method),
            Err(e) => {
                first.get_or_insert((e, method, start.q));
            }
        }
        seed = start.seed.saturating_add(1);
    }
    let (from_planned, planned_start) = match &first {
        Some((_, _, q)) => (true, *q),
        None => (false, reference),
    };
    let fallback = on_identified_robot(
        planned,
        real,
        &nominal.limits,
        target,
        &planned_start,
        from_planned,
        settings,
    );
    match (fallback, first, not_found) {
        (Ok((c, m)), Some((_, method, _)), _) => (Ok(c), format!("{method}; {m}")),
        (Ok((c, m)), None, _) => (Ok(c), m),
        (Err(_), Some((error, method, _)), _) => (Err(error), method),
        (Err(_), None, Some(e)) => (Err(e), String::new()),
        (Err(e), None, None) => (Err(e), String::new()),
    }
}

/// A closed-form start and how it was found.
enum ClosedForm {
    /// The nominal robot reaches the target there.
    Exact(JointVec<f64>, String),
    /// The target is beyond the nominal workspace on the branch: its nearest configuration.
    Nearest(JointVec<f64>, String),
}

/// The fallback where a compensation from the controller's nominal joints fails or there are
/// none (the target lies beyond the nominal workspace, or near a singularity where the nominal
/// and the identified robot part ways): the numerical inverse kinematics of the identified
/// robot's geometry from `reference` (the planned or nearest nominal configuration, or, with
/// `planned_reference` false, the middle of the limits), then the compensation from there. The
/// bounds still hold: the correction is the nominal pose at the result against the target, and,
/// with `planned_reference`, no joint moves from `reference` by more than the joint bound.
/// Returns the result and how it was found.
fn on_identified_robot(
    planned: &Kinematics<f64, Dyn>,
    real: &impl ActualRobot<f64, Dyn>,
    limits: &JointVec<calib_core::JointLimits<f64>>,
    target: &Pose,
    reference: &JointVec<f64>,
    planned_reference: bool,
    settings: &CompensationSettings<f64>,
) -> Result<(Compensated<f64, Dyn>, String), String> {
    let unbounded = CompensationSettings {
        max_correction_mm: f64::INFINITY,
        max_correction_rad: f64::INFINITY,
        ..*settings
    };
    let (solution, method) =
        match compensate_target(planned, real, limits, target, reference, &unbounded) {
            Ok(solution) => (solution, "the identified robot from there".to_string()),
            Err(_) => {
                let mut start = numerical_inverse_kinematics_from_seed(
                    real.geometry(),
                    limits,
                    target,
                    reference,
                    &NumericalIkSettings::default(),
                    0,
                )
                .map_err(|e| format!("on the identified robot: {e}"))?;
                // Whole turns toward the reference where the limits allow.
                for ((q, r), l) in start.q.iter_mut().zip(reference).zip(limits) {
                    let turned =
                        *q + std::f64::consts::TAU * ((r - *q) / std::f64::consts::TAU).round();
                    if l.contains(turned) {
                        *q = turned;
                    }
                }
                let solution =
                    compensate_target(planned, real, limits, target, &start.q, &unbounded)?;
                (
                    solution,
                    format!("numerical on the identified robot, seed {}", start.seed),
                )
            }
        };
    let nominal_pose = planned.forward(&solution.q).map_err(|e| e.to_string())?;
    let needed = Needed::between(target, &nominal_pose, &solution.q, reference);
    if (planned_reference && needed.joint_change_rad > settings.max_joint_correction_rad)
        || needed.correction.position.norm() > settings.max_correction_mm
        || needed.correction.rotation.norm() > settings.max_correction_rad
    {
        return Err(needed.refusal(
            "the identified robot reaches the target with",
            "from the nominal configuration",
            settings,
        ));
    }
    Ok((solution, method))
}

/// What a compensation needs: the change of the commanded pose and the largest joint move.
struct Needed {
    /// The commanded pose's change (mm, rad).
    correction: PoseError<f64>,
    /// The joint that moves most, 0-based.
    joint: usize,
    /// Its move, rad.
    joint_change_rad: f64,
}

impl Needed {
    /// The change from pose `from` to pose `to`, and joints `q` against `reference`.
    fn between(from: &Pose, to: &Pose, q: &JointVec<f64>, reference: &JointVec<f64>) -> Self {
        let (joint, joint_change_rad) = q
            .iter()
            .zip(reference)
            .map(|(q, r)| (q - r).abs())
            .enumerate()
            .fold((0, 0.0f64), |m, (j, c)| if c > m.1 { (j, c) } else { m });
        Self {
            correction: PoseError::between(to, from),
            joint,
            joint_change_rad,
        }
    }

    /// Why the target was refused, with the numbers against the bounds and the flags that set
    /// them: `{refused}: {needs} X mm and Y deg of correction (bounds ...), moving joint J by Z
    /// deg {from} (bound ...)`.
    fn refusal(&self, needs: &str, from: &str, settings: &CompensationSettings<f64>) -> String {
        format!(
            "{}: {needs} {:.3} mm and {:.3} deg of correction (bounds {} mm, --max-correction-mm, \
             and {} deg, --max-correction-deg), moving joint {} by {:.3} deg {from} (bound {:.3} deg, \
             --max-joint-correction-deg)",
            CompensationError::CorrectionTooLarge,
            self.correction.position.norm(),
            self.correction.rotation.norm().to_degrees(),
            settings.max_correction_mm,
            settings.max_correction_rad.to_degrees(),
            self.joint + 1,
            self.joint_change_rad.to_degrees(),
            settings.max_joint_correction_rad.to_degrees()
        )
    }
}

/// The closed-form inverse kinematics on `branch` when the robot has one (`None`: no closed
/// form for this structure or joint count), and how it was found. A target beyond the nominal
/// workspace on `branch` (within a few mm of a stretched elbow or of the shoulder's cylinder, where
/// the actual robot's workspace differs from the nominal one by its errors) starts from the
/// nearest configuration on the workspace boundary
/// ([`calib_core::kinematics::ik::nearest_configurations`]): the method says how far it is from
/// the target, and the compensation finds out whether the actual robot reaches it.
fn closed_form(
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    target: &Pose,
    branch: usize,
) -> Option<Result<ClosedForm, String>> {
    // Only 6-joint robots have one: the same robot as a Robot<f64, 6>.
    let six = Robot::<f64, nalgebra::U6> {
        joints: <[_; 6]>::try_from(&nominal.joints[..]).ok()?,
        limits: <[_; 6]>::try_from(&nominal.limits[..]).ok()?,
        base: nominal.base,
        tool: nominal.tool,
    };
    let on_branch = |solutions: [Option<[f64; 6]>; BRANCHES]| -> Option<JointVec<f64>> {
        solutions
            .get(branch)
            .copied()
            .flatten()
            .and_then(|q| JointVec::from_slice(&q))
    };
    match inverse_kinematics(&six, target) {
        Ok(solutions) => {
            if let Some(q) = on_branch(solutions) {
                return Some(Ok(ClosedForm::Exact(
                    q,
                    format!("closed form, branch {branch}"),
                )));
            }
        }
        Err(IkError::UnsupportedGeometry) => return None,
        Err(e) => return Some(Err(e.to_string())),
    }
    let out_of_reach = format!("target out of reach on branch {branch}");
    let nearest = nearest_configurations(&six, target)
        .ok()
        .and_then(on_branch)
        .and_then(|q| Some((q, planned.forward(&q).ok()?)));
    Some(match nearest {
        Some((q, pose)) => {
            let miss = PoseError::between(target, &pose).position.norm();
            Ok(ClosedForm::Nearest(
                q,
                format!(
                    "closed form, branch {branch}, nearest configuration ({miss:.3} mm beyond the nominal workspace)"
                ),
            ))
        }
        None => Err(out_of_reach),
    })
}

/// Retries after the first run from the controller's joints: the iteration cap is multiplied by
/// this, and the start moved by up to [`RETRY_SPREAD_RAD`] in [`RETRIES`] fixed directions.
pub(crate) const RETRY_ITERATION_FACTOR: u32 = 4;

/// Number of retries from points near the controller's joints.
pub(crate) const RETRIES: usize = 12;

/// Largest move of a joint for a retry's start, rad.
pub(crate) const RETRY_SPREAD_RAD: f64 = 0.02;

/// Compensates one target from the controller's joints `start`: the core's
/// [`compensate_joints_from`] from `start`, then, if that fails, with a longer iteration cap and
/// from [`RETRIES`] points near `start` (the bounds always apply to the change from `start`).
/// A refusal says why; for a correction beyond the bounds, how large it is and which flag raises
/// the bound.
pub(crate) fn compensate_target(
    planned: &Kinematics<f64, Dyn>,
    real: &impl ActualRobot<f64, Dyn>,
    limits: &JointVec<calib_core::JointLimits<f64>>,
    target: &Pose,
    start: &JointVec<f64>,
    settings: &CompensationSettings<f64>,
) -> Result<Compensated<f64, Dyn>, String> {
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
        let initial = JointVec::<f64>::from_fn(start.len(), |j| {
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
fn needed_correction(
    planned: &Kinematics<f64, Dyn>,
    real: &impl ActualRobot<f64, Dyn>,
    target: &Pose,
    start: &JointVec<f64>,
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
    Needed::between(&before, &after, &solution.q, start).refusal(
        "the actual robot needs",
        "from the planned joints",
        settings,
    )
}

/// The outcomes of a robot of `joints` joints as CSV: `id, q1_deg..qN_deg, residual_mm, residual_deg, status, start` (`ok` or
/// the error; a refused target leaves the joints and residuals empty).
pub(crate) fn to_csv(outcomes: &[TargetOutcome], joints: usize) -> crate::Result<Vec<u8>> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["id".to_string()];
    header.extend((1..=joints).map(|i| format!("q{i}_deg")));
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
                row.extend(std::iter::repeat_n(String::new(), joints + 2));
                row.push(e.clone());
            }
        }
        row.push(outcome.start.clone());
        writer.write_record(&row)?;
    }
    Ok(writer.into_inner().map_err(|e| e.into_error())?)
}
