//! Compensation of target poses with an identified robot, off line: for each target, the joints
//! that put the actual (identified) robot on it, started from the controller's nominal joints:
//! given, or the nominal inverse kinematics, in closed form on a branch where the structure allows
//! (spherical wrist, UR-type offset wrist), numerical otherwise
//! ([`calib_core::controller::numerical_ik`] from the caller's posture: the first solution in the
//! posture's configuration, [`super::configuration`]). Where that fails or the nominal robot cannot reach the target
//! (within mm of a workspace boundary or singularity, where the two robots part ways), the
//! identified robot is solved from the nominal (or nearest) configuration, under the same bounds.
//! The output's `start` column says which way each row went.
//!
//! The arm configuration is never chosen silently: targets without joints are compensated in the
//! configuration the caller names ([`Configuration`]: a closed-form branch, or the configuration
//! of a reference posture), every row states the configuration its joints are in, and a solution
//! in another configuration than asked is refused with the reason. Joint maps are identified on a
//! range of readings; a target whose joints leave a map's range is refused unless extrapolation is
//! allowed ([`Request`]), and counted.

use super::configuration::{
    ConfigurationBounds, ConfigurationJoints, PostureConfiguration, wrapped,
};
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
    /// The arm configuration of the compensated joints: `branch B` (the closed-form branch, for
    /// robots that have one), `at a singularity` (no branch reproduces them), or `near the
    /// posture` / `from the given joints` for robots without a closed form; empty when refused.
    pub configuration: String,
    /// Whether a joint of the compensated joints lies outside the range of readings its map was
    /// identified on (compensated only when the request allows extrapolation).
    pub extrapolated: bool,
    /// For a target compensated from the controller's joints (given, or a program's joint
    /// targets): the joint (0-based) that moves most from them and by how much, rad.
    pub largest_move: Option<(usize, f64)>,
}

/// A joint move from the controller's joints above which the summary names the target, deg: a
/// mm-level correction moves a joint by hundredths of a degree away from singularities; near the
/// shoulder or wrist singularity by degrees, which the program's author should see.
pub const LARGE_MOVE_DEG: f64 = 5.0;

/// The arm configuration of targets that carry no joints.
#[derive(Clone, Debug, PartialEq)]
pub enum Configuration {
    /// The closed-form inverse kinematics branch, 0-7: bit 4 shoulder back, bit 2 elbow down,
    /// bit 1 wrist flipped (robots with a spherical or UR-type offset wrist).
    Branch(usize),
    /// The configuration of this posture (joint readings, rad): its closed-form branch, with
    /// each joint turned by whole turns toward the posture where the limits allow; for robots
    /// without a closed form, the numerical inverse kinematics started from the posture.
    Near(JointVec<f64>),
}

/// What a compensation run asks for besides the bounds.
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    /// The configuration of targets without joints; `None` refuses such targets.
    pub configuration: Option<Configuration>,
    /// `true` when `configuration` is the robot file's default (`[compensation]`), which a
    /// target file's configuration column overrides; an option given for the run does not.
    pub configuration_is_default: bool,
    /// Per joint, the range of readings (rad) its map was identified on; `None`: no map (or a
    /// map that is zero), any reading.
    pub map_ranges: Vec<Option<[f64; 2]>>,
    /// Compensate targets whose joints leave a map's range (counted) instead of refusing them.
    pub allow_extrapolation: bool,
    /// On robots without a closed form, how far a solution may be from the posture (or the
    /// given joints) and stay in its configuration ([`configuration`](super::configuration)).
    pub bounds: ConfigurationBounds,
    /// The bounds stated for this run, by their flags (`--near-within-deg`,
    /// `--max-arm-angle-deg`): refused for a robot they do not apply to.
    pub stated_bounds: Vec<&'static str>,
}

impl Request {
    /// Refuses bounds stated for a robot they do not bound: any on a robot with a closed form
    /// (its configuration is the branch), the arm angle on arms other than 7 joints.
    fn check_bounds(&self, nominal: &Robot<f64, Dyn>) -> crate::Result<()> {
        if self.stated_bounds.is_empty() {
            return Ok(());
        }
        if has_closed_form(nominal) {
            return Err(crate::refused!(option self.stated_bounds.join(" and ");
                "{} bound the numerical inverse kinematics of robots without a closed form, and this robot has one (its configuration is the branch): drop {}",
                self.stated_bounds.join(" and "),
                if self.stated_bounds.len() == 1 {
                    "it"
                } else {
                    "them"
                }
            ));
        }
        let joints = nominal.joints.len();
        if joints != 7 && self.stated_bounds.contains(&"--max-arm-angle-deg") {
            return Err(crate::refused!(option "--max-arm-angle-deg";
                "--max-arm-angle-deg bounds the arm angle of a 7-joint arm, and this robot has {joints} joints: drop it"
            ));
        }
        Ok(())
    }
    /// Targets in the closed-form `branch`, no joint maps.
    pub fn branch(branch: usize) -> Self {
        Self {
            configuration: Some(Configuration::Branch(branch)),
            configuration_is_default: false,
            map_ranges: Vec::new(),
            allow_extrapolation: false,
            bounds: ConfigurationBounds::default(),
            stated_bounds: Vec::new(),
        }
    }
}

/// Counts of a compensation run.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// Targets compensated.
    pub ok: usize,
    /// Targets refused with an error.
    pub failed: usize,
    /// Targets compensated with a joint outside its map's identified range.
    pub extrapolated: usize,
    /// Targets compensated from the controller's joints with a joint moved by more than
    /// [`LARGE_MOVE_DEG`].
    pub large_moves: usize,
    /// The largest such move: the target's id, the joint (1-based) and the move, deg.
    pub largest_move: Option<(String, usize, f64)>,
}

impl Summary {
    /// The counts of `outcomes`.
    pub fn of(outcomes: &[TargetOutcome]) -> Self {
        let ok = outcomes.iter().filter(|o| o.result.is_ok()).count();
        let moves = outcomes.iter().filter_map(|o| {
            let (joint, rad) = o.largest_move.filter(|_| o.result.is_ok())?;
            (rad.to_degrees() > LARGE_MOVE_DEG).then(|| (o.id.clone(), joint + 1, rad.to_degrees()))
        });
        let (mut large_moves, mut largest_move) = (0, None::<(String, usize, f64)>);
        for m in moves {
            large_moves += 1;
            if largest_move.as_ref().is_none_or(|l| m.2 > l.2) {
                largest_move = Some(m);
            }
        }
        Self {
            ok,
            failed: outcomes.len() - ok,
            extrapolated: outcomes.iter().filter(|o| o.extrapolated).count(),
            large_moves,
            largest_move,
        }
    }
}

/// Compensates every target of `targets` (base frame, with orientation; joints, when the file
/// has `q1_deg..qN_deg`, are the start and name the configuration): `nominal` is the model the
/// controller plans with, `actual` the identified robot; `request` names the configuration of
/// targets without joints. One outcome per target, in file order. Error: targets without joints
/// and no configuration, or a configuration the robot cannot take.
pub fn compensate_targets(
    nominal: &Robot<f64, Dyn>,
    actual: &Robot<f64, Dyn>,
    targets: &TrackerData,
    settings: &CompensationSettings<f64>,
    request: &Request,
) -> crate::Result<Vec<TargetOutcome>> {
    let real = Kinematics::nominal(actual).context("identified robot")?;
    compensate_targets_of(nominal, &real, targets, settings, request)
}

/// [`compensate_targets`] for any actual robot: the geometry alone ([`Kinematics`]) or with
/// angle-error maps ([`calib_core::kinematics::MappedKinematics`]).
pub(crate) fn compensate_targets_of(
    nominal: &Robot<f64, Dyn>,
    real: &impl ActualRobot<f64, Dyn>,
    targets: &TrackerData,
    settings: &CompensationSettings<f64>,
    request: &Request,
) -> crate::Result<Vec<TargetOutcome>> {
    request.check_bounds(nominal)?;
    let planned = Kinematics::nominal(nominal).context("nominal robot")?;
    let start = Start::of_rows(nominal, &planned, targets, request)?;
    let outcomes = targets
        .records
        .iter()
        .map(|record| {
            // A row's own configuration (the `configuration` column) before the file's.
            let own = record
                .configuration
                .map(|branch| Start::Branch(usize::from(branch), None));
            let Some(start) = own.as_ref().or(start.as_ref()) else {
                return TargetOutcome {
                    id: record.id.clone(),
                    start: String::new(),
                    result: Err("no arm configuration named for this target".to_string()),
                    configuration: String::new(),
                    extrapolated: false,
                    largest_move: None,
                };
            };
            let rotation = record.rotation.unwrap_or_else(nalgebra::Matrix3::identity);
            let target = Pose::from_parts(
                Translation3::from(nalgebra::Vector3::from(record.position)),
                Rotation3::from_matrix_unchecked(rotation),
            );
            let (result, method) =
                compensate_record(nominal, &planned, real, &target, record, start, settings);
            checked(
                settings, nominal, &planned, record, start, request, result, method,
            )
        })
        .collect();
    Ok(outcomes)
}

/// Compensates one record: from the controller's joints when the file has them; otherwise from
/// the nominal inverse kinematics, in closed form on `branch` where the robot's structure has
/// one (6 joints: spherical or UR-type offset wrist), else numerical from the middle of the joint
/// limits (each limit taken within one turn of zero): the first solution in the posture's
/// configuration. Returns the outcome and where the start came from (empty when none was found).
fn compensate_record(
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    real: &impl ActualRobot<f64, Dyn>,
    target: &Pose,
    record: &crate::io::tracker_data::Record,
    start: &Start,
    settings: &CompensationSettings<f64>,
) -> (Result<Compensated<f64, Dyn>, String>, String) {
    let from = |start: &JointVec<f64>| {
        compensate_target(planned, real, &nominal.limits, target, start, settings)
    };
    let (branch, posture) = match start {
        Start::Given(_) => return (from(&given_joints(record, nominal)), "given".into()),
        Start::Numerical(configuration) => {
            return from_numerical_starts(nominal, planned, real, target, configuration, settings);
        }
        Start::Branch(branch, posture) => (*branch, posture.as_ref()),
    };
    match closed_form(nominal, planned, target, branch, posture) {
        Some(Ok(ClosedForm::Exact(q, method))) => match from(&q) {
            Ok(c) => (Ok(c), method),
            Err(e) => {
                on_identified_robot(planned, real, &nominal.limits, target, &q, true, settings)
                    .map_or_else(
                        |f| (Err(format!("{e}; then {f}")), method.clone()),
                        |(c, m)| (Ok(c), format!("{method}; {m}")),
                    )
            }
        },
        Some(Ok(ClosedForm::Nearest(q, method))) => {
            match on_identified_robot(planned, real, &nominal.limits, target, &q, true, settings) {
                Ok((c, m)) => (Ok(c), format!("{method}; {m}")),
                Err(e) => (Err(e), method),
            }
        }
        Some(Err(e)) => (Err(e), String::new()),
        None => (
            Err(format!(
                "branch {branch} names a closed-form configuration, and this robot has no closed form; name a posture instead (--near-deg)"
            )),
            String::new(),
        ),
    }
}

/// Compensates `target` from the nominal robot's numerical inverse kinematics in the posture's
/// `configuration`: the first nominal solution in that configuration, from the posture first,
/// then in seed order (solutions in another configuration are passed over; once one in the
/// configuration is found, no other is sought: a later seed's solution would be another arm
/// configuration the test does not tell, such as joints 1 and 3 trading half a turn near the
/// shoulder's alignment). Where its compensation fails, the identified robot is solved from it
/// under the bounds (or from the posture when none was found). Returns the outcome and where the
/// start came from.
fn from_numerical_starts(
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    real: &impl ActualRobot<f64, Dyn>,
    target: &Pose,
    configuration: &PostureConfiguration,
    settings: &CompensationSettings<f64>,
) -> (Result<Compensated<f64, Dyn>, String>, String) {
    let reference = configuration.posture;
    // The first failure: its error, method and start.
    let mut first: Option<(String, String, JointVec<f64>)> = None;
    // The first nominal solution passed over, and why.
    let mut elsewhere: Option<String> = None;
    let mut not_found = None;
    let mut seed = 0;
    while first.is_none() {
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
        seed = start.seed.saturating_add(1);
        if let Some(why) = configuration.departure(planned, &start.q) {
            elsewhere.get_or_insert(format!("seed {}: {why}", start.seed));
            continue;
        }
        let method = format!("numerical, seed {}", start.seed);
        match compensate_target(planned, real, &nominal.limits, target, &start.q, settings) {
            Ok(c) => return (Ok(c), method),
            Err(e) => {
                first.get_or_insert((e, method, start.q));
            }
        }
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
    // A fallback from the posture itself may land in another configuration: refused here, with
    // the reason the nominal solutions gave.
    let fallback = fallback.and_then(|(c, m)| match configuration.departure(planned, &c.q) {
        Some(why) if !from_planned => Err(format!("on the identified robot: {why}")),
        _ => Ok((c, m)),
    });
    let first = first.map(|(error, method, _)| (error, method));
    numerical_outcome(fallback, first, (elsewhere, not_found), configuration)
}

/// The outcome of [`from_numerical_starts`]: the fallback's result, or the first nominal
/// solution's refusal (`first`: its error and method), or why no nominal solution was found in
/// the configuration (`elsewhere`: the first found outside it; `not_found`: the search's error).
fn numerical_outcome(
    fallback: Result<(Compensated<f64, Dyn>, String), String>,
    first: Option<(String, String)>,
    (elsewhere, not_found): (Option<String>, Option<String>),
    configuration: &PostureConfiguration,
) -> (Result<Compensated<f64, Dyn>, String>, String) {
    match (fallback, first) {
        (Ok((c, m)), Some((_, method))) => (Ok(c), format!("{method}; {m}")),
        (Ok((c, m)), None) => (Ok(c), format!("numerical, the posture; {m}")),
        (Err(_), Some((error, method))) => (Err(error), method),
        (Err(e), None) => {
            let found = match (elsewhere, not_found) {
                (Some(why), _) => {
                    format!("the nominal robot's solutions are in another configuration ({why})")
                }
                (None, Some(e)) => e,
                (None, None) => e,
            };
            let within = configuration.describe();
            (
                Err(format!("no solution in {within}: {found}")),
                String::new(),
            )
        }
    }
}

/// Each joint of `q` turned by whole turns toward `reference` where the limits allow.
fn turned_toward(
    q: &mut JointVec<f64>,
    reference: &JointVec<f64>,
    limits: &JointVec<calib_core::JointLimits<f64>>,
) {
    for ((q, r), l) in q.iter_mut().zip(reference).zip(limits) {
        let turned = *q + std::f64::consts::TAU * ((r - *q) / std::f64::consts::TAU).round();
        if l.contains(turned) {
            *q = turned;
        }
    }
}

/// The nominal robot as a 6-joint robot, for the closed-form inverse kinematics (`None`: it has
/// another joint count).
fn as_six(nominal: &Robot<f64, Dyn>) -> Option<Robot<f64, nalgebra::U6>> {
    Some(Robot::<f64, nalgebra::U6> {
        joints: <[_; 6]>::try_from(&nominal.joints[..]).ok()?,
        limits: <[_; 6]>::try_from(&nominal.limits[..]).ok()?,
        base: nominal.base,
        tool: nominal.tool,
    })
}

/// How far a joint reading may be from a closed-form solution (whole turns aside) and still be
/// in its configuration, rad: far above the closed form's rounding, far below any other
/// configuration's distance.
const SAME_CONFIGURATION_RAD: f64 = 1e-6;

/// The closed-form branches (0-7) of the nominal robot whose solution for its own pose at `q`
/// is `q` in the joints that tell the configurations apart (1, 3 and 5: shoulder, elbow, wrist;
/// whole turns aside): the configurations `q` is in, two or more at a singularity, none where
/// the closed form is indeterminate (a wrist centre on the first axis). `None`: the robot has no
/// closed form.
pub(crate) fn branches_of(
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    q: &JointVec<f64>,
) -> Option<Vec<usize>> {
    branch_distances(nominal, planned, q).map(|d| exact_branches(&d))
}

/// The branches whose solution is `q` itself, of the per-branch distances of [`branch_distances`].
fn exact_branches(distances: &[Option<f64>; BRANCHES]) -> Vec<usize> {
    (0..BRANCHES)
        .filter(|b| distances[*b].is_some_and(|d| d < SAME_CONFIGURATION_RAD))
        .collect()
}

/// Per closed-form branch, how far its solution for the nominal robot's pose at `q` is from `q`
/// in joints 1, 3 and 5 (the largest difference, whole turns aside), rad; `None` where the branch
/// does not reach that pose. `None` for a robot without a closed form.
fn branch_distances(
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    q: &JointVec<f64>,
) -> Option<[Option<f64>; BRANCHES]> {
    let six = as_six(nominal)?;
    let pose = planned.forward(q).ok()?;
    let solutions = inverse_kinematics(&six, &pose).ok()?;
    Some(solutions.map(|solution| {
        let s = solution?;
        Some(
            [0, 2, 4]
                .iter()
                .map(|&j| wrapped(s[j] - q[j]).abs())
                .fold(0.0, f64::max),
        )
    }))
}

/// Where the nominal start of targets without their own joints comes from.
enum Start {
    /// Every target has the controller's joints; for a robot without a closed form, its
    /// configuration joints (the compensated joints keep the given joints' configuration).
    Given(Option<ConfigurationJoints>),
    /// The closed-form branch, with the posture whose configuration it is (whole turns toward it).
    Branch(usize, Option<JointVec<f64>>),
    /// The numerical inverse kinematics from this posture, in its configuration (robots without
    /// a closed form).
    Numerical(Box<PostureConfiguration>),
}

impl Start {
    /// The start of the rows of `targets` without a configuration of their own; `None` when
    /// every row names its own (the `configuration` column). Errors: as [`Start::of`]; a file
    /// with both joints and a configuration column, or a configuration column and a
    /// configuration option.
    fn of_rows(
        nominal: &Robot<f64, Dyn>,
        planned: &Kinematics<f64, Dyn>,
        targets: &TrackerData,
        request: &Request,
    ) -> crate::Result<Option<Self>> {
        let named = targets
            .records
            .iter()
            .filter(|r| r.configuration.is_some())
            .count();
        if named == 0 {
            return Self::of(nominal, planned, targets, request).map(Some);
        }
        let path = targets.path.display();
        if targets.joints == nominal.joints.len() {
            return Err(crate::refused!(input path;
                "{path}: has both the controller's joints, which name each target's configuration, and a configuration column; give one of them"
            ));
        }
        if request.configuration.is_some() && !request.configuration_is_default {
            return Err(crate::refused!(input path;
                "{path}: its configuration column names the targets' configurations, and so does --branch or --near-deg; give one of them (leave the option out)"
            ));
        }
        if let Some(r) = targets.records.iter().find(|r| r.configuration.is_none()) {
            if request.configuration.is_some() {
                // The robot file's default for the rows that name none.
                return Self::of(nominal, planned, targets, request).map(Some);
            }
            return Err(crate::refused!(input path;
                "{path}:{}: target {} names no configuration while others do: fill its configuration column",
                r.line,
                r.id
            ));
        }
        Ok(None)
    }

    /// The start of `targets` under `request`. Errors: no joints and no configuration named; a
    /// branch out of range; a posture of another joint count, outside the limits, or in no
    /// configuration of the closed form.
    fn of(
        nominal: &Robot<f64, Dyn>,
        planned: &Kinematics<f64, Dyn>,
        targets: &TrackerData,
        request: &Request,
    ) -> crate::Result<Self> {
        let joints = nominal.joints.len();
        if targets.joints == joints {
            if request.configuration.is_some() {
                return Err(crate::refused!(input targets.path.display();
                    "{}: the targets carry the controller's joints (q1_deg..q{joints}_deg), which name their configuration; give either the joints or a configuration (--branch, --near-deg), not both",
                    targets.path.display()
                ));
            }
            let joints = (!has_closed_form(nominal))
                .then(|| ConfigurationJoints::of(planned, &nominal.limits));
            return Ok(Self::Given(joints));
        }
        match &request.configuration {
            None => Err(crate::refused!(option "--near-deg";
                "{}: the targets carry no joints, so the arm configuration to reach them in must be named: --near-deg q1,...,q{joints} (the configuration of that posture, e.g. the robot's home), or --branch 0-7 (closed form: bit 4 shoulder back, bit 2 elbow down, bit 1 wrist flipped); or give the controller's joints as q1_deg..q{joints}_deg; or state the robot's default in its file: [compensation] near_deg = [...]",
                targets.path.display()
            )),
            Some(Configuration::Branch(branch)) if *branch >= BRANCHES => {
                Err(crate::refused!(option "--branch";
                    "--branch must be 0 to {}, got {branch}",
                    BRANCHES - 1
                ))
            }
            Some(Configuration::Branch(branch)) => Ok(Self::Branch(*branch, None)),
            Some(Configuration::Near(posture)) => {
                if posture.len() != joints {
                    return Err(crate::refused!(option "--near-deg";
                        "--near-deg has {} values; the robot has {joints} joints",
                        posture.len()
                    ));
                }
                if let Some((j, q)) = posture
                    .iter()
                    .zip(&nominal.limits)
                    .enumerate()
                    .find(|(_, (q, l))| !l.contains(**q))
                    .map(|(j, (q, _))| (j, q))
                {
                    return Err(crate::refused!(option "--near-deg";
                        "--near-deg: q{} = {:.3} deg is outside the joint limits of the robot",
                        j + 1,
                        q.to_degrees()
                    ));
                }
                match branches_of(nominal, planned, posture) {
                    None => PostureConfiguration::of(
                        planned,
                        ConfigurationJoints::of(planned, &nominal.limits),
                        *posture,
                        request.bounds,
                        true,
                    )
                    .map(|c| Self::Numerical(Box::new(c)))
                    .map_err(|e| crate::refused!(option "--near-deg"; "--near-deg: {e}")),
                    Some(branches) => match branches.first() {
                        Some(branch) => Ok(Self::Branch(*branch, Some(*posture))),
                        None => Err(crate::refused!(option "--near-deg";
                            "--near-deg: the posture is at a singularity where the closed form cannot tell its configuration (the wrist centre on the first axis); name a posture away from it, or --branch"
                        )),
                    },
                }
            }
        }
    }
}

/// A record's joints as a joint vector (rad).
fn given_joints(
    record: &crate::io::tracker_data::Record,
    nominal: &Robot<f64, Dyn>,
) -> JointVec<f64> {
    JointVec::from_fn(nominal.joints.len(), |i| {
        record.q.get(i).copied().unwrap_or(0.0)
    })
}

/// The outcome of one record, with the configuration checks: the compensated joints must be in
/// the configuration asked for (the branch, or the given joints' configuration), and within the
/// range each joint map was identified on unless extrapolation is allowed.
#[allow(clippy::too_many_arguments)]
fn checked(
    settings: &CompensationSettings<f64>,
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    record: &crate::io::tracker_data::Record,
    start: &Start,
    request: &Request,
    result: Result<Compensated<f64, Dyn>, String>,
    method: String,
) -> TargetOutcome {
    let mut outcome = TargetOutcome {
        id: record.id.clone(),
        start: method,
        result,
        configuration: String::new(),
        extrapolated: false,
        largest_move: None,
    };
    let Ok(compensated) = &outcome.result else {
        return outcome;
    };
    if let Start::Given(_) = start {
        outcome.largest_move = largest_move(&compensated.q, &given_joints(record, nominal));
    }
    let (configuration, refusal) = configuration_against_start(
        settings,
        nominal,
        planned,
        record,
        start,
        request,
        &compensated.q,
    );
    outcome.configuration = configuration;
    let outside = outside_map_range(request, &compensated.q);
    if let Some(reason) = refusal {
        outcome.result = Err(reason);
    } else if let Some((j, q, lo, hi)) = outside {
        if request.allow_extrapolation {
            outcome.extrapolated = true;
        } else {
            outcome.result = Err(format!(
                "joint {} at {:.3} deg is outside [{:.3}, {:.3}] deg, the readings its map was identified on: the map would be extrapolated (pass --allow-extrapolation to compensate anyway)",
                j + 1,
                q.to_degrees(),
                lo.to_degrees(),
                hi.to_degrees()
            ));
        }
    }
    if outcome.result.is_err() {
        outcome.configuration.clear();
    }
    outcome
}

/// The joint (0-based) of `q` that moves most from `from`, and by how much (rad).
fn largest_move(q: &JointVec<f64>, from: &JointVec<f64>) -> Option<(usize, f64)> {
    q.iter()
        .zip(from)
        .map(|(q, g)| (q - g).abs())
        .enumerate()
        .fold(None, |m: Option<(usize, f64)>, (j, d)| match m {
            Some((_, best)) if best >= d => m,
            _ => Some((j, d)),
        })
}

/// The configuration of the compensated joints `q` as the output states it, and the refusal when
/// it is not the one asked for: the branch, the given joints' (by branch on closed-form robots,
/// by [`PostureConfiguration`] on the others) or the posture's.
fn configuration_against_start(
    settings: &CompensationSettings<f64>,
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    record: &crate::io::tracker_data::Record,
    start: &Start,
    request: &Request,
    q: &JointVec<f64>,
) -> (String, Option<String>) {
    match start {
        Start::Numerical(posture) => numerical_configuration(planned, posture, q),
        Start::Given(Some(joints)) => {
            let given = PostureConfiguration::of(
                planned,
                joints.clone(),
                given_joints(record, nominal),
                request.bounds,
                false,
            );
            match given {
                Ok(given) => numerical_configuration(planned, &given, q),
                Err(e) => (String::new(), Some(e)),
            }
        }
        Start::Given(None) => {
            let asked = branches_of(nominal, planned, &given_joints(record, nominal));
            configuration_of(settings, nominal, planned, q, start, asked.as_deref())
        }
        Start::Branch(branch, _) => {
            configuration_of(settings, nominal, planned, q, start, Some(&[*branch]))
        }
    }
}

/// The arm configuration of the compensated joints `q` as the output states it, and the
/// refusal when they are in another configuration than `asked` (the branches of the start).
fn configuration_of(
    settings: &CompensationSettings<f64>,
    nominal: &Robot<f64, Dyn>,
    planned: &Kinematics<f64, Dyn>,
    q: &JointVec<f64>,
    start: &Start,
    asked: Option<&[usize]>,
) -> (String, Option<String>) {
    // In a configuration asked for: exactly, or within the joint bound of its solution (at the
    // boundary of two configurations, where a correction may cross it by a fraction of a
    // degree), or where it does not reach (the start was its nearest configuration). One
    // closed-form solution of the pose at `q` serves both.
    let distances = branch_distances(nominal, planned, q);
    let reached = distances.as_ref().map(exact_branches);
    let near_asked = |asked: &[usize]| {
        asked.iter().any(|b| {
            distances
                .and_then(|d| d[*b])
                .is_none_or(|d| d <= settings.max_joint_correction_rad)
        })
    };
    let refusal = match (asked, &reached) {
        (Some(asked), Some(reached))
            if !asked.is_empty() && !reached.is_empty() && !near_asked(asked) =>
        {
            Some(format!(
                "the compensated joints are in another arm configuration (branch {}) than {} (branch {}): refused, as the robot would move through the workspace another way",
                list(reached),
                match start {
                    Start::Given(_) => "the given joints",
                    _ => "asked for",
                },
                list(asked)
            ))
        }
        _ => None,
    };
    let configuration = match (&reached, start) {
        (Some(b), _) if b.is_empty() => "at a singularity".into(),
        (Some(b), _) => match asked {
            Some(asked) if !asked.is_empty() && !asked.iter().any(|a| b.contains(a)) => format!(
                "branch {}, at the boundary of branch {} (within the joint bound)",
                list(b),
                list(asked)
            ),
            _ => format!("branch {}", list(b)),
        },
        (None, Start::Given(_)) => "from the given joints".into(),
        (None, _) => "near the posture".into(),
    };
    (configuration, refusal)
}

/// The configuration of joints `q` on a robot without a closed form as the output states it (the
/// posture's), and the refusal when they are in another one.
fn numerical_configuration(
    planned: &Kinematics<f64, Dyn>,
    posture: &PostureConfiguration,
    q: &JointVec<f64>,
) -> (String, Option<String>) {
    let refusal = posture.departure(planned, q).map(|why| {
        format!(
            "the compensated joints are in another arm configuration than {}: {why}; refused, as the robot would move through the workspace another way",
            posture.describe()
        )
    });
    (posture.describe(), refusal)
}

/// Whether the nominal robot has a closed-form inverse kinematics (6 joints, a spherical or
/// UR-type offset wrist).
fn has_closed_form(nominal: &Robot<f64, Dyn>) -> bool {
    as_six(nominal).is_some_and(|six| {
        !matches!(
            inverse_kinematics(&six, &Pose::identity()),
            Err(IkError::UnsupportedGeometry)
        )
    })
}

/// The first joint of `q` outside the readings its map was identified on: (joint, reading,
/// lowest, highest), rad.
fn outside_map_range(request: &Request, q: &JointVec<f64>) -> Option<(usize, f64, f64, f64)> {
    request
        .map_ranges
        .iter()
        .zip(q.iter())
        .enumerate()
        .find_map(|(j, (range, q))| {
            let [lo, hi] = (*range)?;
            (*q < lo || *q > hi).then_some((j, *q, lo, hi))
        })
}

/// Branch numbers as text: `3`, or `1 or 3`.
fn list(branches: &[usize]) -> String {
    branches
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(" or ")
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
                turned_toward(&mut start.q, reference, limits);
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
        let (joint, joint_change_rad) = largest_move(q, reference).unwrap_or((0, 0.0));
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
    posture: Option<&JointVec<f64>>,
) -> Option<Result<ClosedForm, String>> {
    let six = as_six(nominal)?;
    let on_branch = |solutions: [Option<[f64; 6]>; BRANCHES]| -> Option<JointVec<f64>> {
        let mut q = solutions
            .get(branch)
            .copied()
            .flatten()
            .and_then(|q| JointVec::from_slice(&q))?;
        if let Some(posture) = posture {
            turned_toward(&mut q, posture, &nominal.limits);
        }
        Some(q)
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
pub fn to_csv(outcomes: &[TargetOutcome], joints: usize) -> crate::Result<Vec<u8>> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["id".to_string()];
    header.extend((1..=joints).map(|i| format!("q{i}_deg")));
    header.extend(
        [
            "residual_mm",
            "residual_deg",
            "status",
            "start",
            "configuration",
        ]
        .map(String::from),
    );
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
        row.push(outcome.configuration.clone());
        writer.write_record(&row)?;
    }
    Ok(writer.into_inner().map_err(|e| e.into_error())?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The UR10 at (0, -90, 90, -90, -90, 0) deg is in exactly one closed-form branch (the
    /// nominal robot's own solution of its pose there); joints in that branch pass, and asked for
    /// any other branch, whose solution of the same pose is more than the joint bound away, they
    /// are refused with both branches named.
    #[test]
    fn joints_in_another_configuration_than_asked_are_refused() {
        let path = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml"));
        let model = crate::io::robot_file::RobotModel::load(path).unwrap();
        let planned = Kinematics::nominal(&model.robot).unwrap();
        let q =
            JointVec::from_slice(&[0.0f64, -90.0, 90.0, -90.0, -90.0, 0.0].map(f64::to_radians))
                .unwrap();
        let branches = branches_of(&model.robot, &planned, &q).unwrap();
        assert_eq!(branches.len(), 1, "{branches:?}");
        let own = branches[0];
        let settings = CompensationSettings::default();
        let start = Start::Branch(own, None);
        let (label, refusal) =
            configuration_of(&settings, &model.robot, &planned, &q, &start, Some(&[own]));
        assert_eq!((label, refusal), (format!("branch {own}"), None));
        for other in (0..BRANCHES).filter(|b| *b != own) {
            let (_, refusal) = configuration_of(
                &settings,
                &model.robot,
                &planned,
                &q,
                &start,
                Some(&[other]),
            );
            let refusal = refusal.expect("another configuration is refused");
            assert!(
                refusal.contains(&format!("(branch {own}) than asked for (branch {other})")),
                "{refusal}"
            );
        }
    }
}
