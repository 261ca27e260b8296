//! Calibration as a library: a [`Session`] (a [`Dataset`] of the robot and its measurements, from
//! files or memory, a [`HoldOut`] rule and a [`CalibrationConfig`]) in, a [`Calibrated`] out: the
//! identified robot as a model, the typed [`CalibrationResult`] and the provenance. No file is
//! read or written here; the `calib calibrate` command is a thin layer over [`Session::run`].
//!
//! The stages: the frames are registered and fitted ([`crate::measurement::frames::prepare`]); the
//! identifiability of the parameters is checked and, with `auto_mask`, what the data cannot
//! determine is dropped ([`select_parameters`]); the swarm and/or least squares identify the
//! errors; Table 3 is evaluated on the calibration and the held-out poses.
//!
//! ```
//! use host_tools::calibration::{CalibrationConfig, Method, calibrate};
//! use host_tools::measurement::dataset::Dataset;
//! use host_tools::io::robot_file::RobotFile;
//! use host_tools::io::tracker_data::Record;
//! use calib_core::{Kinematics, ParameterErrors};
//! use calib_core::model::JointVec;
//! use calib_core::model::paper;
//! use std::path::Path;
//!
//! // The nominal ER10L-C10, and the same robot with the paper's Table 2 errors as "the real one".
//! let robot = RobotFile::parse(host_tools::io::robot_file::ER10L_C10_TOML, Path::new("er10l-c10.toml"))?;
//! // The file's robot has its joint count at run time (`nalgebra::Dyn`), as the host has it.
//! let nominal = robot.to_model(Path::new("er10l-c10.toml"))?.robot;
//! let table2 = paper::table2::<f64>().recount().expect("6 joints");
//! let real = Kinematics::new(&nominal, &table2)?;
//! // 32 measured poses (joints in rad, positions in mm), in the robot's base frame.
//! let records: Vec<Record> = (0..32)
//!     .map(|i| {
//!         let q = JointVec::<f64>::from_fn(6, |j| ((i * 7 + j * 3) % 11) as f64 * 0.5 - 2.5);
//!         let pose = real.forward(&q).unwrap();
//!         Record {
//!             line: i as u64 + 1,
//!             id: format!("p{i}"),
//!             q: q.to_vec(),
//!             position: pose.translation.vector.into(),
//!             rotation: Some(*pose.rotation.matrix()),
//!             weight: 1.0,
//!             role: None,
//!             configuration: None,
//!             time_s: None,
//!             temperature_c: None,
//!         }
//!     })
//!     .collect();
//! let dataset = Dataset::from_records(robot, records, true)?;
//! let config = CalibrationConfig { method: Method::Lm, ..CalibrationConfig::default() };
//! let calibrated = calibrate(dataset, None, &config)?;
//! // Least squares recovers Table 2 from exact data: da2 = 0.2565 mm.
//! let da2 = calibrated.result.parameter("da2").unwrap();
//! assert!((da2.value - 0.2565).abs() < 1e-9);
//! assert!(calibrated.result.calibration.after.position_mm.max < 1e-9);
//! // The identified robot is a model: its forward kinematics are the real robot's.
//! let q = JointVec::<f64>::from_fn(6, |j| 0.3 * j as f64 - 0.7);
//! let zero = ParameterErrors::zeros_for(nalgebra::Dyn(6));
//! let identified = Kinematics::new(&calibrated.model.model.robot, &zero)?;
//! let miss = identified.forward(&q).unwrap().translation.vector - real.forward(&q).unwrap().translation.vector;
//! assert!(miss.norm() < 1e-9);
//! # Ok::<(), anyhow::Error>(())
//! ```

mod config;
pub mod cross_validation;
pub mod maps;
pub mod plausibility;
mod result;
mod session;

pub(crate) use config::swarm_without_swarm;
pub use config::{
    CalibrationConfig, Cancel, ErrorModel, Identify, LossChoice, Method, SWARM_SIZES,
    ScramblingChoice, SwarmConfig,
};
pub use session::{Calibrated, HoldOut, Provenance, Session, Truth};

pub use result::{
    CalibrationResult, HoldOutSettings, IdentifiedParameter, LeastSquaresReport, ObjectiveValues,
    Outlier, Parameters, PerPose, PoseReport, Report, Settings, Stage, SwarmSummary, lm_stop,
    swarm_stop,
};

use crate::analysis::identifiability::{IdentifiabilityReport, analyse};
use crate::io::robot_file::RobotFile;
use crate::kinematics::actual::ActualRobot;
use crate::measurement::dataset::{Dataset, Seen};
use crate::measurement::frames::{Frames, FramesReport};
use crate::runtime::swarm_team::{LaneObjective, SwarmTeam};

use calib_core::identify::ipso::{self, Control, IpsoSettings, SearchSpace};
use calib_core::identify::lm::{LeastSquares, LmError, LmResult, LmSettings};
use calib_core::identify::objective::Objective;
use calib_core::{Kinematics, Parameter, ParameterErrors, ParameterMask, ParameterSet, Problem};
use nalgebra::{DVector, Dyn};
use std::io::IsTerminal;
use std::time::Instant;

/// Fits of the geometry with a robot file's gravity compliance taken off the measurements, each
/// at the previous fit's geometry (see [`calibrate`]).
const COMPLIANCE_ROUNDS: usize = 2;

/// Calibrates `dataset` (its robot's identification mask plus the frames of `config`), validating
/// on `validation` when given (poses in the same tracker frame, not used to identify): a
/// [`Session`] with those poses held out ([`HoldOut::poses`]), no provenance and no truth.
pub fn calibrate(
    dataset: Dataset,
    validation: Option<Dataset>,
    config: &CalibrationConfig,
) -> crate::Result<Calibrated> {
    Session {
        hold_out: validation.map_or(HoldOut::None, HoldOut::poses),
        ..Session::new(dataset, config.clone())
    }
    .run()
}

/// The stages of a calibration of `dataset` validated on `validation`: the typed result and the
/// identified robot file.
///
/// The stages, each taking the model of the robot ([`ActualRobot`]) the one before returned:
/// the measurement setup (an identified probe kept with `--frames base`), the frames
/// ([`crate::measurement::frames::prepare`]), the selection ([`select_parameters`]), the stored
/// probe's parameters the data cannot determine held (`frames::hold_dropped_probe_parameters`),
/// the solve (`solve_geometry`), the joint maps (`maps::add_joint_maps`), the held-out accuracy
/// and the plausibility (`accuracy_and_plausibility`). The datasets are read once and not
/// changed: each stage sees their poses through its model ([`Dataset::seen_by`]).
pub(crate) fn stages(
    dataset: Dataset,
    validation: Option<Dataset>,
    config: &CalibrationConfig,
) -> crate::Result<(CalibrationResult, RobotFile)> {
    config.check()?;
    if !config.acceptance.is_empty() && validation.is_none() {
        return Err(crate::Error::NoHeldOut(format!(
            "--accept {}: an acceptance criterion is judged on held-out poses, and none are held out: give --validate FRACTION \
             or --holdout FILE (or measure a plan with verification poses)",
            config.acceptance[0]
        )));
    }
    if config.model.maps() {
        maps::check_robot_file(&dataset.robot, config)?;
    }
    let conditions = crate::measurement::conditions::MeasurementConditions::of(
        &dataset,
        validation.as_ref(),
        config.payload_kg,
    )?;
    let frames = Frames::chosen(config.frames, &dataset.data);
    // With only the base fitted, the probe identified with the file's model stays the tool (as in
    // `evaluate --fit-frames base`); the file written keeps the given controller frames and
    // records the probe in its measurement setup.
    let given = &dataset.robot;
    let probe = given.identified_probe().cloned();
    let setup = crate::measurement::frames::with_identified_probe(given, frames)?;
    let probe_kept = setup.is_some();
    let setup = setup.unwrap_or_else(|| given.clone());
    let (robot, mut frames_report, mask) =
        crate::measurement::frames::prepare(frames, &dataset.seen_by(&setup)?, config.k)?;
    let mask = identified_mask(mask, frames, config)?;
    let seen = dataset.seen_by(&robot)?;
    let selection = select_parameters(&seen, mask, config)?;
    let held = match probe.as_ref().filter(|_| frames.tool()) {
        Some(stored) => crate::measurement::frames::hold_dropped_probe_parameters(
            &seen,
            (&selection.dropped, &selection.mask),
            stored,
            config.k,
        )?,
        None => None,
    };
    let robot = match held {
        Some((held_robot, held)) => {
            frames_report.held_at_stored_probe = held.iter().map(ToString::to_string).collect();
            held_robot
        }
        None => robot,
    };
    let inputs = (&dataset, validation.as_ref());
    let mut solved = solve_geometry(&robot, inputs, config, &selection, &frames_report)?;
    if config.model.maps() {
        solved = maps::add_joint_maps(solved, &robot, inputs, config)?;
    }
    let (mut result, mut file) = solved;
    if probe_kept {
        (file.base, file.tool) = (given.file.base.clone(), given.file.tool.clone());
        if let Some(m) = file.measurement.as_mut() {
            m.flange_tool = probe;
        }
    }
    if config.cancel.is_cancelled() {
        return Err(crate::Error::Cancelled);
    }
    result.conditions = Some(conditions);
    let calibration_joints: Vec<Vec<f64>> =
        dataset.data.records.iter().map(|r| r.q.clone()).collect();
    let held_out = validation.as_ref().map(|v| v.seen_by(&robot)).transpose()?;
    accuracy_and_plausibility(
        (result, file),
        (&calibration_joints, held_out.as_ref()),
        config,
    )
}

/// The caveats of the certificate ([`crate::analysis::caveats`]; `calib calibrate` adds the plan
/// check's gap, [`crate::planning::PlanCheck::caveat`]): a cross-validation worse than nominal, held-out poses outside the joint ranges of the
/// calibration poses (`calibration_joints`, rad), held-out errors beyond the predicted band, an
/// implausible result kept.
fn caveats(
    result: &CalibrationResult,
    calibration_joints: &[Vec<f64>],
    validation: Option<&Seen<'_>>,
) -> Vec<crate::analysis::caveats::Caveat> {
    use crate::analysis::caveats::{
        COVERAGE_BELOW_PERCENT, Caveat, CaveatKind, extrapolation, joint_ranges,
    };
    let whole = |kind, text: String| Caveat {
        kind,
        text,
        lines: Vec::new(),
    };
    let mut out = Vec::new();
    // A re-registration keeps a geometry identified from other data: the geometry's
    // cross-validation and the joint ranges of these (registration) poses say nothing of it.
    let geometry_identified = result.config.identify == Identify::Geometry;
    if let Some(cv) =
        (result.cross_validation).filter(|cv| geometry_identified && cv.worse_than_nominal())
    {
        out.push(whole(
            CaveatKind::CrossValidation,
            format!(
                "cross-validation: the model identified from these poses predicts new ones worse ({:.4} mm) than the nominal model ({:.4} mm)",
                cv.calibrated_mean_mm, cv.nominal_mean_mm
            ),
        ));
    }
    if let Some(v) = validation.filter(|_| geometry_identified) {
        let held_out: Vec<Vec<f64>> = v.data.records.iter().map(|r| r.q.clone()).collect();
        let lines: Vec<u64> = v.data.records.iter().map(|r| r.line).collect();
        out.extend(extrapolation(
            &joint_ranges(calibration_joints),
            &held_out,
            &lines,
        ));
    }
    if let Some(u) = result
        .uncertainty
        .as_ref()
        .filter(|u| u.percent_inside_95 < COVERAGE_BELOW_PERCENT)
    {
        out.push(whole(
            CaveatKind::Uncertainty,
            format!(
                "only {:.1} % of the held-out errors lie inside their predicted 95 % band: the model or the stated instrument misses an error",
                u.percent_inside_95
            ),
        ));
    }
    if !result.implausible.is_empty() {
        out.push(whole(
            CaveatKind::Implausible,
            format!(
                "the result is not plausible and was kept (--accept-implausible): {}",
                result.implausible.join("; ")
            ),
        ));
    }
    out
}

/// The last stages: the accuracy on the held-out poses of `validation`, the acceptance criteria
/// judged on them, and the plausibility check (an implausible result is refused unless the
/// configuration accepts it).
fn accuracy_and_plausibility(
    (mut result, mut file): (CalibrationResult, RobotFile),
    (calibration_joints, validation): (&[Vec<f64>], Option<&Seen<'_>>),
    config: &CalibrationConfig,
) -> crate::Result<(CalibrationResult, RobotFile)> {
    if let Some(v) = validation {
        let poses: Vec<(String, u64)> = (v.data.records.iter())
            .map(|r| (r.id.clone(), r.line))
            .collect();
        result.per_pose.validation_lines = poses.iter().map(|(_, line)| *line).collect();
        result.held_out = crate::analysis::accuracy::HeldOutAccuracy::of(
            &poses,
            &result.per_pose.validation_before_xyz,
            &result.per_pose.validation_after_xyz,
        );
        if let Some(held) = result.held_out.as_mut() {
            let q: Vec<Vec<f64>> = v.data.records.iter().map(|r| r.q.clone()).collect();
            held.iso9283 = crate::analysis::accuracy::Iso9283::of(
                &q,
                &result.per_pose.validation_lines,
                &result.per_pose.validation_after_xyz,
            );
        }
        map_the_workspace(&mut result, v)?;
    }
    record_covariance(&result, &mut file, config);
    result.acceptance = crate::analysis::accuracy::Acceptance::judge(
        &config.acceptance,
        &result.per_pose.validation_after,
    );
    result.implausible = plausibility::check(&result, &file);
    if !result.implausible.is_empty() && !config.accept_implausible {
        let question = plausibility::question(&result).map_or(String::new(), |q| q + "\n");
        return Err(crate::Error::Implausible {
            problems: result.implausible.clone(),
            message: format!(
                "the calibration is not plausible, nothing was written:\n  - {}\n{question}{}",
                result.implausible.join("\n  - "),
                plausibility::LIKELY_CAUSES
            ),
            result: Box::new(result),
        });
    }
    result.caveats = caveats(&result, calibration_joints, validation);
    Ok((result, file))
}

/// The held-out poses of `validation` placed in the workspace (`per_pose.validation_position_mm`,
/// with the predicted error of each when the covariance is known) and the map of their error
/// after calibration (`held_out.workspace`).
fn map_the_workspace(result: &mut CalibrationResult, validation: &Seen<'_>) -> crate::Result<()> {
    let actual = Kinematics::new(&validation.robot.model.robot, &result.errors)?;
    let per_pose = &mut result.per_pose;
    per_pose.validation_position_mm = crate::measurement::statistics::base_positions(
        &actual,
        &validation.robot.model.robot,
        validation.measurements(),
    );
    per_pose.validation_predicted_rms_mm = (result.uncertainty.as_ref())
        .map(|u| u.model_rms_mm.clone())
        .unwrap_or_default();
    if let Some(held) = result.held_out.as_mut() {
        held.workspace = crate::analysis::workspace::WorkspaceMap::of(
            &per_pose.validation_position_mm,
            &per_pose.validation_after,
            &per_pose.validation_lines,
            Some(&per_pose.validation_predicted_rms_mm)
                .filter(|p| !p.is_empty())
                .map(|p| p.as_slice()),
        );
    }
    Ok(())
}

/// Records the identified parameters' covariance (the frames of the measurement setup included:
/// the joint parameters are determined relative to them) in the identified file's
/// `[calibration]` of `file`, for a calibration of the geometry.
fn record_covariance(result: &CalibrationResult, file: &mut RobotFile, config: &CalibrationConfig) {
    let (Some(covariance), Identify::Geometry) = (&result.covariance, config.identify) else {
        return;
    };
    let entry = crate::io::robot_file::CovarianceEntry {
        parameters: result.names(),
        matrix: (covariance.row_iter())
            .map(|r| r.iter().copied().collect())
            .collect(),
    };
    if let Some(c) = file.calibration.as_mut() {
        c.covariance = Some(entry);
    }
}

/// The parameters to identify of `mask` (the robot's and the frames'): all of them, or with
/// `--identify frames` only the frames' (which needs data in a tracker's frame).
fn identified_mask(
    mask: ParameterMask<Dyn>,
    frames: Frames,
    config: &CalibrationConfig,
) -> crate::Result<ParameterMask<Dyn>> {
    match config.identify {
        Identify::Geometry => Ok(mask),
        Identify::Frames => {
            if !frames.base() {
                return Err(crate::refused!(
                    "--identify frames re-registers the frames of a measurement setup: the data must be in a tracker's frame (--frames base or base+tool), not in the base frame"
                ));
            }
            let mut only_frames = ParameterMask::empty_for(mask.joint_count());
            for p in mask.iter() {
                only_frames.set(p, matches!(p, Parameter::Base(_) | Parameter::Tool(_)));
            }
            Ok(only_frames)
        }
    }
}

/// The solve stage: the errors of `selection` identified for the geometry of `robot` (its frames
/// registered) from the poses of `dataset`, evaluated there and on `validation`. A robot's
/// gravity compliance is part of the model and held fixed: the geometry is fitted to the measured
/// poses with its deflection taken off, evaluated at the registered frames, then again at the
/// first fit's errors (the deflection depends on the geometry only through its small change).
fn solve_geometry(
    robot: &ActualRobot,
    (dataset, validation): (&Dataset, Option<&Dataset>),
    config: &CalibrationConfig,
    selection: &Selection,
    frames: &FramesReport,
) -> crate::Result<(CalibrationResult, RobotFile)> {
    let solved = |calibration: &Seen<'_>, held_out: Option<&Seen<'_>>| {
        solve(
            calibration,
            held_out,
            config,
            selection.clone(),
            frames.clone(),
        )
    };
    if robot.compliance.is_none() {
        let held_out = validation.map(|v| v.seen_by(robot)).transpose()?;
        return solved(&dataset.seen_by(robot)?, held_out.as_ref());
    }
    // The rounds before the last only move the geometry the deflection is evaluated at: their
    // errors are all that is kept, so they are identified and nothing else (no evaluation, no
    // covariance, no cross-validation); the last round is the calibration.
    let mut errors = ParameterErrors::zeros_for(robot.model.robot.joint_count());
    for _ in 1..COMPLIANCE_ROUNDS {
        let calibration = dataset.seen_by_geometry(robot, &errors)?;
        errors = identified_errors(&calibration, config, selection)?;
    }
    let calibration = dataset.seen_by_geometry(robot, &errors)?;
    let held_out = (validation.map(|v| v.seen_by_geometry(robot, &errors))).transpose()?;
    solved(&calibration, held_out.as_ref())
}

/// The errors of the parameters of `selection` identified from `dataset`, as [`solve`]
/// identifies them, without evaluating them.
fn identified_errors(
    dataset: &Seen<'_>,
    config: &CalibrationConfig,
    selection: &Selection,
) -> crate::Result<ParameterErrors<f64, Dyn>> {
    let set = crate::model::counts::solvable_set(&selection.mask)?;
    let problem = dataset.problem(set, config.k)?;
    let objective = Objective::new(&problem);
    let (_, _, best) = identify_errors(config, &problem, &objective, dataset)?;
    Ok(problem.set().unpack(&best)?)
}

/// The parameters to identify and why.
#[derive(Clone, Debug)]
pub struct Selection {
    /// The identified parameters.
    pub mask: ParameterMask<Dyn>,
    /// The analysis of the parameters asked for (with the condition number reached after
    /// dropping, when parameters were dropped).
    pub identifiability: IdentifiabilityReport,
    /// Parameters dropped by `auto_mask`, in the order dropped.
    pub dropped: Vec<Parameter>,
}

/// Checks that the data determine the parameters of `mask`: refuses what they cannot determine,
/// or with `auto_mask` drops it; then, unless `keep_ill_conditioned`, drops while the pose set is
/// ill-conditioned the parameter with the largest share of the least determined direction.
pub fn select_parameters(
    dataset: &Seen<'_>,
    mask: ParameterMask<Dyn>,
    config: &CalibrationConfig,
) -> crate::Result<Selection> {
    let analysed = |mask: &ParameterMask<Dyn>| analyse(dataset, mask, config.k);
    let (mut mask, reflector) =
        crate::analysis::identifiability::default_mask(dataset, mask, config.k)?;
    let mut initial = analysed(&mask)?;
    initial.reflector_on_last_axis = reflector;
    let mut identifiability = initial.clone();
    let mut dropped = Vec::new();
    if identifiability.rank < identifiability.parameters {
        if !config.auto_mask {
            return Err(crate::Error::Unidentifiable {
                rank: identifiability.rank,
                parameters: identifiability.parameters,
                undetermined: (identifiability.to_drop().iter())
                    .map(ToString::to_string)
                    .collect(),
                message: format!(
                    "the data cannot determine every identified parameter (rank {} of {}): {}. \
                     Drop them with --auto-mask, or set identify = [...] in the robot file; `calib check` shows the analysis",
                    identifiability.rank,
                    identifiability.parameters,
                    identifiability.problem()
                ),
            });
        }
        for parameter in identifiability.to_drop() {
            mask.set(parameter, false);
            dropped.push(parameter);
        }
        identifiability = analysed(&mask)?;
    }
    if !config.keep_ill_conditioned {
        while identifiability.ill_conditioned && mask.count() > 1 {
            let Some(parameter) = identifiability.weakest_direction.first().map(|(p, _)| *p) else {
                break;
            };
            mask.set(parameter, false);
            dropped.push(parameter);
            identifiability = analysed(&mask)?;
        }
    }
    // Report the analysis of the full set (it says why parameters were dropped), with the
    // condition number reached.
    if !dropped.is_empty() {
        let reached = identifiability.condition_number;
        identifiability = initial;
        identifiability.condition_number_after_drop = reached;
    }
    Ok(Selection {
        mask,
        identifiability,
        dropped,
    })
}

/// The errors identified by the method of `config`: the swarm from zero errors, then least
/// squares from its best (or from zero); returns both runs (where they ran) and the best errors.
fn identify_errors(
    config: &CalibrationConfig,
    problem: &Problem<'_, f64, Dyn, Dyn>,
    objective: &Objective<'_, f64, Dyn, Dyn>,
    dataset: &Seen<'_>,
) -> crate::Result<(Option<SwarmRun>, Option<Fit>, DVector<f64>)> {
    let swarm = if config.method.swarm() {
        Some(run_swarm(config, objective, problem.set())?)
    } else {
        None
    };
    let start = swarm
        .as_ref()
        .map_or_else(|| problem.set().zeros(), |s| s.best.clone());
    let fit = if config.method.least_squares() {
        Some(least_squares(
            config,
            &LeastSquares::new(problem),
            &start,
            dataset,
        )?)
    } else {
        None
    };
    let best = fit.as_ref().map_or(start, |f| f.result.x.clone());
    Ok((swarm, fit, best))
}

/// Identifies the parameters of `selection` and evaluates the result.
fn solve(
    dataset: &Seen<'_>,
    validation: Option<&Seen<'_>>,
    config: &CalibrationConfig,
    selection: Selection,
    mut frames: FramesReport,
) -> crate::Result<(CalibrationResult, RobotFile)> {
    let set = crate::model::counts::solvable_set(&selection.mask)?;
    let problem = dataset.problem(set, config.k)?;
    let set = problem.set();
    let objective = Objective::new(&problem);
    let zero = set.zeros();
    let started = Instant::now();
    let (swarm, fit, best) = identify_errors(config, &problem, &objective, dataset)?;
    let seconds = started.elapsed().as_secs_f64();
    let standard_errors = fit.as_ref().and_then(|f| f.result.standard_errors());
    let parameters = identified_parameters(set, &best, standard_errors.as_ref());
    let errors = set.unpack(&best)?;
    let (covariance, uncertainty, significance) =
        covariance_findings((dataset, validation), set, fit.as_ref(), &best, &errors)?;
    let (calibration, validation, per_pose, poses) =
        evaluate(dataset, validation, &errors, fit.as_ref())?;
    let identified_robot = identified_robot(dataset, config, &parameters, &errors, &mut frames);
    // Cross-validation with the loss scale of the fit (estimated or given).
    let cv_config = CalibrationConfig {
        loss_scale_mm: fit
            .as_ref()
            .and_then(|f| f.report.loss_scale_mm)
            .or(config.loss_scale_mm),
        ..config.clone()
    };
    let cross_validation = cross_validation::cross_validate(dataset, set, &cv_config);
    let initial = objective.value(&zero);
    let result = CalibrationResult {
        robot: dataset.robot.model.name.clone(),
        robot_path: dataset.robot.model.path.clone(),
        data_path: dataset.data.path.clone(),
        config: config.clone(),
        objective: ObjectiveValues {
            initial,
            r#final: objective.value(&best),
            initial_swarm_best: swarm.as_ref().map_or(initial, |s| s.initial_cost),
            after_swarm: swarm.as_ref().map_or(initial, |s| s.best_cost),
            k: config.k,
        },
        parameters,
        errors,
        swarm: swarm.map(|s| s.summary),
        least_squares: fit.as_ref().map(|f| f.report.clone()),
        identifiability: selection.identifiability,
        dropped: selection.dropped,
        frames,
        outliers: fit.map(|f| f.outliers).unwrap_or_default(),
        poses,
        calibration,
        validation,
        per_pose,
        seconds,
        calibrated_at: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
        implausible: Vec::new(),
        cross_validation,
        joint_maps: None,
        plan_check: None,
        held_out: None,
        acceptance: None,
        uncertainty,
        significance,
        conditions: None,
        caveats: Vec::new(),
        covariance,
    };
    Ok((result, identified_robot))
}

/// What the fit's covariance says (least squares only): the covariance itself, the held-out poses
/// of `validation` against their predicted band, and the parameters' significance.
type CovarianceFindings = (
    Option<nalgebra::DMatrix<f64>>,
    Option<crate::analysis::uncertainty::Coverage>,
    Option<crate::analysis::uncertainty::Significance>,
);

/// [`CovarianceFindings`] of the fit of `set` (values `best`, errors `errors`) on `dataset`.
fn covariance_findings(
    (dataset, validation): (&Seen<'_>, Option<&Seen<'_>>),
    set: &ParameterSet<Dyn, Dyn>,
    fit: Option<&Fit>,
    best: &DVector<f64>,
    errors: &ParameterErrors<f64, Dyn>,
) -> crate::Result<CovarianceFindings> {
    let (Some(fit), Some(covariance)) = (fit, fit.and_then(|f| f.result.covariance())) else {
        return Ok((None, None, None));
    };
    let uncertainty = match validation {
        Some(v) => held_out_coverage((dataset, v), set, &covariance, errors, fit.report.sigma_mm)?,
        None => None,
    };
    let significance = crate::analysis::uncertainty::Significance::of(
        &set.parameters()
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>(),
        best.as_slice(),
        &covariance,
    );
    Ok((Some(covariance), uncertainty, Some(significance)))
}

/// The held-out poses of `validation` against the 95 % band of the model `errors` predicted from
/// the parameters' `covariance` (in the order of `set`) and the instrument's noise: the one the data
/// profile states (`[instrument]`, at each point's distance from the tracker; the covariance then
/// scaled from the fit's residual sigma to the instrument's noise on the calibration poses of
/// `dataset`), else the fit's residual sigma.
fn held_out_coverage(
    (dataset, validation): (&Seen<'_>, &Seen<'_>),
    set: &ParameterSet<Dyn, Dyn>,
    covariance: &nalgebra::DMatrix<f64>,
    errors: &ParameterErrors<f64, Dyn>,
    sigma_mm: f64,
) -> crate::Result<Option<crate::analysis::uncertainty::Coverage>> {
    let instrument = validation.data.instrument.as_ref();
    // Distances from the instrument are known in its own frame only.
    let noise = |data: &Seen<'_>, m: &calib_core::identify::objective::Measurement<f64, Dyn>| {
        instrument.map_or(sigma_mm, |i| {
            i.sigma_mm(if data.data.base_frame {
                0.0
            } else {
                m.position.norm()
            })
        })
    };
    let (covariance, source) = match instrument {
        None => (
            covariance.clone(),
            "from the fit's residual sigma".to_string(),
        ),
        Some(i) => {
            let n = dataset.measurements().len().max(1) as f64;
            let rms = (dataset.measurements().iter())
                .map(|m| noise(dataset, m).powi(2))
                .sum::<f64>()
                / n;
            (
                covariance * (rms / (sigma_mm * sigma_mm).max(f64::MIN_POSITIVE)),
                format!(
                    "from the instrument ({}: MPE {} um + {} um/m, read as 2 sigma)",
                    i.name.as_deref().unwrap_or("data profile"),
                    i.mpe_um,
                    i.mpe_um_per_m
                ),
            )
        }
    };
    let actual = Kinematics::new(&validation.robot.model.robot, errors)?;
    let poses: Vec<_> = (validation.measurements().iter())
        .zip(&validation.data.records)
        .map(|(m, r)| {
            let error = m.error_of(&actual.forward_angles(&m.angles)).position;
            (m.angles, error, r.line, noise(validation, m))
        })
        .collect();
    Ok(crate::analysis::uncertainty::coverage(
        (&actual, set, &covariance),
        &poses,
        source,
    ))
}

/// The identified values of `set` with their standard errors, when least squares gave them.
fn identified_parameters(
    set: &ParameterSet<Dyn, Dyn>,
    best: &DVector<f64>,
    standard_errors: Option<&DVector<f64>>,
) -> Vec<IdentifiedParameter> {
    set.parameters()
        .iter()
        .zip(best.iter())
        .enumerate()
        .map(|(i, (p, v))| IdentifiedParameter {
            parameter: *p,
            value: *v,
            std_error: standard_errors.and_then(|s| s.get(i).copied()),
        })
        .collect()
}

/// The identified robot file and the identified frames in the report. The file is the robot
/// file given plus the identified joint errors, with the controller's base and tool (those of the
/// robot file given); frames identified from tracker data are the measurement setup and go to
/// its `[measurement]` section and the report, never into `[base]` and `[tool]`.
pub(crate) fn identified_robot(
    dataset: &Seen<'_>,
    config: &CalibrationConfig,
    parameters: &[IdentifiedParameter],
    errors: &ParameterErrors<f64, Dyn>,
    frames: &mut FramesReport,
) -> crate::io::robot_file::RobotFile {
    let std_errors: Vec<(Parameter, f64)> = parameters
        .iter()
        .filter_map(|p| p.std_error.map(|s| (p.parameter, s)))
        .collect();
    let method = config.method.name();
    let nominal = dataset.robot.model.path.display().to_string();
    let mut file = dataset.robot.file.with_errors(
        errors,
        parameters.iter().map(|p| p.parameter),
        &std_errors,
        method,
        &nominal,
    );
    if !frames.identified.base() {
        return file;
    }
    // The measurement frames: the fitted start plus their identified errors.
    frames.base = file.base.clone();
    if frames.identified.tool() {
        frames.tool = file.tool.clone();
    }
    let is_joint = |p: &Parameter| matches!(p, Parameter::Joint { .. });
    let mut joint_errors = *errors;
    joint_errors.base = calib_core::FrameErrors::default();
    joint_errors.tool = calib_core::FrameErrors::default();
    file = dataset.robot.file.with_errors(
        &joint_errors,
        parameters.iter().map(|p| p.parameter).filter(is_joint),
        &std_errors
            .into_iter()
            .filter(|(p, _)| is_joint(p))
            .collect::<Vec<_>>(),
        method,
        &nominal,
    );
    (file.base, file.tool) = (frames.given.base.clone(), frames.given.tool.clone());
    if config.identify == Identify::Frames {
        // Re-registration: the geometry and its calibration record are the given file's.
        file.calibration = frames.given.calibration.clone();
    }
    file.measurement =
        frames
            .base
            .clone()
            .map(|tracker_base| crate::io::robot_file::MeasurementSection {
                frames: frames.identified.name().to_string(),
                tracker_base,
                flange_tool: frames.tool.clone(),
                registered_at: None,
                geometry_from: None,
                inputs: Vec::new(),
            });
    file
}

/// The cores this process may run on ([`std::thread::available_parallelism`], 1 when unknown),
/// asked once per process: every asking reads the cgroup's CPU quota files (25-60 us each,
/// measured on this machine), and a calibration asks for the swarm and the cross-validation.
pub(crate) fn cores() -> usize {
    static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, std::num::NonZero::get))
}

/// The swarm's outcome.
struct SwarmRun {
    summary: SwarmSummary,
    /// The best point found.
    best: DVector<f64>,
    /// The best objective of the initial swarm.
    initial_cost: f64,
    /// The best objective found.
    best_cost: f64,
}

fn run_swarm(
    config: &CalibrationConfig,
    objective: &Objective<'_, f64, Dyn, Dyn>,
    set: &ParameterSet<Dyn, Dyn>,
) -> crate::Result<SwarmRun> {
    let swarm = &config.swarm;
    let space = SearchSpace::for_parameters(
        set,
        swarm.init_angle_rad,
        swarm.init_length_mm,
        swarm.bound_factor,
    );
    let settings = IpsoSettings {
        c1: swarm.c1,
        c2: swarm.c2,
        max_generations: swarm.generations,
        target_cost: swarm.target,
        stall_generations: swarm.stall_generations,
        halton_start: swarm.halton_start,
        scrambling: swarm.scrambling.into(),
        seed: swarm.seed,
    };
    let bar = if config.progress && std::io::stderr().is_terminal() {
        indicatif::ProgressBar::new(u64::from(swarm.generations))
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "IPSO {bar:40} {pos}/{len} generations, best f = {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut history = Vec::with_capacity(swarm.generations as usize + 1);
    let mut observer = |generation: u32, best: f64| {
        history.push((generation, best));
        if generation.is_multiple_of(20) {
            bar.set_position(u64::from(generation));
            bar.set_message(format!("{best:.6e}"));
        }
        if config.cancel.is_cancelled() {
            return Control::Cancel;
        }
        Control::Continue
    };
    let particles = swarm.particles;
    let mut positions = vec![set.zeros::<f64>(); particles];
    let mut velocities = positions.clone();
    let mut best_positions = positions.clone();
    let (mut costs, mut best_costs) = (vec![0.0; particles], vec![0.0; particles]);
    let memory = ipso::SwarmMemory::new(
        &mut positions,
        &mut velocities,
        &mut best_positions,
        &mut costs,
        &mut best_costs,
    )?;
    let lanes = LaneObjective::new(objective);
    let threads = cores().min(particles);
    let result = SwarmTeam::run(&lanes, threads, settings.seed, |team, pairs| {
        team.optimize(memory, pairs, &space, &settings, &mut observer)
    })?;
    bar.finish_and_clear();
    let summary = SwarmSummary {
        generations: result.generations,
        evaluations: result.evaluations,
        stop: result.stop,
        history,
    };
    Ok(SwarmRun {
        summary,
        best: result.best,
        initial_cost: result.initial_cost,
        best_cost: result.best_cost,
    })
}

/// The least-squares stage: its result, report, robust weights and outliers.
struct Fit {
    result: LmResult<f64, Dyn>,
    report: LeastSquaresReport,
    weights: Vec<f64>,
    outliers: Vec<Outlier>,
}

fn least_squares(
    config: &CalibrationConfig,
    least_squares: &LeastSquares<'_, f64, Dyn, Dyn>,
    start: &DVector<f64>,
    dataset: &Seen<'_>,
) -> crate::Result<Fit> {
    let set = least_squares.problem().set();
    let settings = LmSettings {
        max_iterations: config.lm_iterations,
        ..LmSettings::default()
    };
    let mut weights = vec![1.0; dataset.measurements().len()];
    let estimated = match (config.loss, config.loss_scale_mm) {
        (LossChoice::L2, _) | (_, Some(_)) => None,
        (_, None) => Some(robust_scale(least_squares, start, &settings, config.k)?),
    };
    let scale = match config.loss {
        LossChoice::L2 => None,
        _ => config.loss_scale_mm.or(estimated.map(|e| e.loss_scale_mm)),
    };
    let loss = config.loss.with_scale(scale.unwrap_or(1.0));
    let robust = least_squares
        .solve_robust(start, &settings, loss, &mut weights)
        .map_err(|e| lm_error(e, set))?;
    let mut outliers = Vec::new();
    if config.loss != LossChoice::L2 {
        let mut norms = vec![0.0; dataset.measurements().len()];
        least_squares.pose_residual_norms(&robust.result.x, &mut norms)?;
        let fitted = least_squares.problem().kinematics(&robust.result.x)?;
        let poses = dataset.data.records.iter().zip(&norms).zip(&weights);
        for (((record, norm), weight), m) in poses.zip(dataset.measurements()) {
            let outlier = match &estimated {
                Some(thresholds) => {
                    let error = m.error_of(&fitted.forward_angles(&m.angles));
                    let rotation = if m.rotation.is_some() {
                        error.rotation.norm()
                    } else {
                        0.0
                    };
                    thresholds.is_outlier(error.position.norm(), rotation)
                }
                None => *norm > scale.unwrap_or(f64::INFINITY),
            };
            if outlier {
                outliers.push(Outlier {
                    id: record.id.clone(),
                    line: record.line,
                    residual_mm: *norm,
                    weight: *weight,
                });
            }
        }
    }
    let l = &robust.result;
    let report = LeastSquaresReport {
        iterations: l.iterations,
        evaluations: l.evaluations,
        stop: lm_stop(l.stop),
        cost_initial: l.initial_cost,
        cost_final: l.cost,
        rows: l.rows,
        sigma_mm: l.sigma(),
        loss_scale_mm: scale,
        loss_scale_estimated: estimated.is_some(),
        outlier_position_mm: estimated.map(|e| e.position_mm),
        outlier_rotation_deg: estimated
            .map(|e| e.rotation_rad.to_degrees())
            .filter(|d| d.is_finite()),
    };
    Ok(Fit {
        result: robust.result,
        report,
        weights,
        outliers,
    })
}

/// Robust standard deviations beyond the median at which a pose is an outlier (for position and
/// orientation residuals separately). On the real UR10 Series B (1495 poses), the three known stale
/// measurements lie 7.7 to 9.5 robust standard deviations out and the largest clean pose 5.1 to
/// 5.3: the threshold sits between them.
pub const OUTLIER_DEVIATIONS: f64 = 6.0;

/// Outlier thresholds and the robust loss scale, estimated from the data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RobustScale {
    /// A pose whose position residual exceeds this is an outlier, mm.
    pub position_mm: f64,
    /// A pose whose orientation residual exceeds this is an outlier, rad (without orientations:
    /// infinite).
    pub rotation_rad: f64,
    /// The loss scale on the pose residual `sqrt(|dp|^2 + k |dr|^2)`, mm: the two thresholds
    /// combined.
    pub loss_scale_mm: f64,
}

impl RobustScale {
    /// `true` when the pose error is beyond either threshold.
    pub(crate) fn is_outlier(&self, position_mm: f64, rotation_rad: f64) -> bool {
        position_mm > self.position_mm || rotation_rad > self.rotation_rad
    }
}

/// Estimates the outlier thresholds from a plain least-squares fit from `start`: for the position
/// and the orientation residuals of the poses separately, `median + OUTLIER_DEVIATIONS * 1.4826 *
/// MAD` (median absolute deviation), so that orientation counted in millimetres never makes clean
/// poses outliers.
pub(crate) fn robust_scale(
    least_squares: &LeastSquares<'_, f64, Dyn, Dyn>,
    start: &DVector<f64>,
    settings: &LmSettings<f64>,
    k: f64,
) -> crate::Result<RobustScale> {
    let set = least_squares.problem().set();
    let fit = least_squares
        .solve(start, settings)
        .map_err(|e| lm_error(e, set))?;
    let model = least_squares.problem().kinematics(&fit.x)?;
    let (mut positions, mut rotations) = (Vec::new(), Vec::new());
    for m in least_squares.problem().measurements() {
        let error = m.error_of(&model.forward_angles(&m.angles));
        positions.push(error.position.norm());
        if m.rotation.is_some() {
            rotations.push(error.rotation.norm());
        }
    }
    let threshold = |mut v: Vec<f64>, floor: f64| -> f64 {
        if v.is_empty() {
            return f64::INFINITY;
        }
        let m = median(&mut v);
        let mut deviations: Vec<f64> = v.iter().map(|r| (r - m).abs()).collect();
        // A floor keeps exact (noise-free) data from a zero threshold.
        (m + OUTLIER_DEVIATIONS * 1.4826 * median(&mut deviations)).max(floor)
    };
    let position_mm = threshold(positions, 1e-9);
    let rotation_rad = threshold(rotations, 1e-12);
    let loss_scale_mm = if rotation_rad.is_finite() {
        (position_mm * position_mm + k * rotation_rad * rotation_rad).sqrt()
    } else {
        position_mm
    };
    Ok(RobustScale {
        position_mm,
        rotation_rad,
        loss_scale_mm,
    })
}

/// The median of `v` (sorted in place; 0 for none).
pub(crate) fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => v[n / 2],
        _ => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

/// A least-squares error in the user's terms (parameter names, not indices).
fn lm_error(error: LmError, set: &ParameterSet<Dyn, Dyn>) -> crate::Error {
    match error {
        LmError::UnobservableParameter(i) => {
            let name = set
                .parameters()
                .get(usize::from(i))
                .map(ToString::to_string)
                .unwrap_or_default();
            crate::refused!(
                "the data cannot determine {name}: it changes no residual; remove it from the identified parameters"
            )
        }
        other => crate::Error::from(other).context("least squares"),
    }
}

/// Table 3 before and after on the calibration and validation poses, per-pose errors, and the
/// calibration poses' report rows.
fn evaluate(
    dataset: &Seen<'_>,
    validation: Option<&Seen<'_>>,
    errors: &ParameterErrors<f64, Dyn>,
    fit: Option<&Fit>,
) -> crate::Result<(Stage, Option<Stage>, PerPose, Vec<PoseReport>)> {
    use crate::measurement::statistics::{orientation_per_pose, table3};
    let nominal = Kinematics::nominal(&dataset.robot.model.robot)?;
    let actual = Kinematics::new(&dataset.robot.model.robot, errors)?;
    let (before, before_poses) = table3(&nominal, dataset.measurements());
    let (after, after_poses) = table3(&actual, dataset.measurements());
    let mut per_pose = PerPose {
        orientation_before: orientation_per_pose(&nominal, dataset),
        orientation_after: orientation_per_pose(&actual, dataset),
        ..PerPose::default()
    };
    let validation_stage = validation.map(|v| {
        let (before, per_pose_before) = table3(&nominal, v.measurements());
        let (after, per_pose_after) = table3(&actual, v.measurements());
        per_pose.validation_before = per_pose_before;
        per_pose.validation_after = per_pose_after;
        per_pose.validation_before_xyz = crate::measurement::statistics::signed_errors(
            &nominal,
            &v.robot.model.robot,
            v.measurements(),
        );
        per_pose.validation_after_xyz = crate::measurement::statistics::signed_errors(
            &actual,
            &v.robot.model.robot,
            v.measurements(),
        );
        Stage {
            poses: v.measurements().len(),
            before,
            after,
        }
    });
    let weights = fit.map(|f| f.weights.as_slice());
    let poses = dataset
        .data
        .records
        .iter()
        .zip(before_poses.iter().zip(&after_poses))
        .enumerate()
        .map(|(i, (r, (b, a)))| PoseReport {
            id: r.id.clone(),
            line: r.line,
            before_mm: *b,
            after_mm: *a,
            robust_weight: weights.and_then(|w| w.get(i).copied()).unwrap_or(1.0),
        })
        .collect();
    per_pose.before = before_poses;
    per_pose.after = after_poses;
    per_pose.lines = dataset.data.records.iter().map(|r| r.line).collect();
    per_pose.orientation_lines = (dataset.data.records.iter())
        .zip(dataset.measurements())
        .filter(|(_, m)| m.rotation.is_some())
        .map(|(r, _)| r.line)
        .collect();
    let calibration = Stage {
        poses: dataset.measurements().len(),
        before,
        after,
    };
    Ok((calibration, validation_stage, per_pose, poses))
}
