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
mod evaluation;
pub mod fit;
mod identified_file;
pub mod maps;
pub mod mixed;
pub mod plausibility;
mod result;
mod session;
mod solve;
pub mod torsion;
pub mod touch_plan;
pub mod touches;
pub mod verify;

pub use config::swarm_without_swarm;
pub use config::{
    CalibrationConfig, Cancel, ErrorModel, Identify, LossChoice, Method, SWARM_SIZES,
    ScramblingChoice, SwarmConfig, SwarmOptions,
};
pub use session::{Calibrated, HoldOut, Provenance, Session, Truth};
pub use solve::OUTLIER_DEVIATIONS;
pub(crate) use solve::{cores, median};

pub use result::{
    CalibrationResult, Covariance, HoldOutSettings, IdentifiedParameter, LeastSquaresReport,
    ObjectiveValues, Outlier, ParameterEntry, Parameters, PerPose, PoseReport, Report, Settings,
    Stage, SwarmSummary, lm_stop, swarm_stop,
};

use crate::analysis::identifiability::IdentifiabilityReport;
use crate::analysis::kind::MeasurementKind;
use crate::analysis::kind::analyse_kind;
use crate::io::robot_file::RobotFile;
use crate::measurement::conditions::MeasurementConditions;
use crate::measurement::dataset::{Dataset, Seen};
use crate::measurement::frames::{Frames, FramesReport};
use crate::planning::Measure;
use calib_core::{Parameter, ParameterMask};
use evaluation::Evaluation;
use nalgebra::Dyn;
use solve::Identification;

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

/// The stages of a calibration of `dataset` validated on `validation` (with `plan`, the
/// held-out poses are a measured plan's verification poses, checked against its prediction):
/// the typed result and the identified robot file.
///
/// The stages, each taking the model of the robot ([`crate::kinematics::actual::ActualRobot`])
/// the one before returned: the measurement setup (an identified probe kept with `--frames
/// base`), the frames ([`crate::measurement::frames::prepare`]), the selection
/// ([`select_parameters`]), the stored probe's parameters the data cannot determine held
/// (`frames::hold_dropped_probe_parameters`), the solve (`solve::solve_geometry`), the joint maps
/// (`maps::add_joint_maps`); then one evaluation of the model found (`evaluation`) and the
/// result built once ([`finish`]). The datasets are read once and not changed: each stage sees
/// their poses through its model ([`Dataset::seen_by`]).
pub(crate) fn stages(
    dataset: Dataset,
    validation: Option<Dataset>,
    config: &CalibrationConfig,
    plan: bool,
) -> crate::Result<(CalibrationResult, RobotFile)> {
    // The settings were checked by `Session::run`, the only caller.
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
    let conditions = MeasurementConditions::of(&dataset, validation.as_ref(), config.payload_kg)?;
    let Registered {
        robot,
        frames: mut frames_report,
        setup,
        selection,
        probe,
    } = register_and_select(&dataset, config)?;
    let inputs = (&dataset, validation.as_ref());
    let (identification, seen, held_out) =
        solve::solve_geometry(&robot, inputs, config, &selection)?;
    let geometric = evaluation::evaluate(
        (&seen, held_out.as_ref()),
        (&seen, held_out.as_ref(), &identification.errors),
        &identification.weights,
    )?;
    let maps = match config.model.maps() {
        true => Some(maps::add_joint_maps(
            &identification,
            &robot,
            &dataset,
            config,
            (geometric.calibration, geometric.validation),
        )?),
        false => None,
    };
    if config.cancel.is_cancelled() {
        return Err(crate::Error::Cancelled);
    }
    // The model found: the geometry, or the geometry with its maps.
    let kept = maps.as_ref().and_then(|(_, kept)| kept.as_ref());
    let (identified, evaluation, file) = identified_model(
        (&identification, kept),
        (&dataset, validation.as_ref()),
        (&seen, held_out.as_ref(), geometric),
        config,
        (&mut frames_report, &setup),
    )?;
    let mut file = file;
    if let Some(probe) = probe {
        let given = &dataset.robot.file;
        (file.base, file.tool) = (given.base.clone(), given.tool.clone());
        if let Some(m) = file.measurement.as_mut() {
            m.flange_tool = probe;
        }
    }
    let registered = validation.as_ref().map(|v| v.seen_by(&robot)).transpose()?;
    let found = Found {
        identification,
        identified,
        evaluation,
        maps: maps.map(|(report, _)| report),
        selection,
        frames: frames_report,
        conditions,
    };
    let views = (&seen, held_out.as_ref(), registered.as_ref());
    let result = finish(found, views, config, plan.then_some(&dataset))?;
    Ok((result, file))
}

/// The model the solve stage starts from and what it identifies.
struct Registered {
    /// The robot with the frames of the measurement setup registered (and a stored probe's
    /// parameters the data cannot determine held).
    robot: crate::kinematics::actual::ActualRobot,
    /// The frames identified with the geometry.
    frames: FramesReport,
    /// The robot file the frames were registered with: its base and tool are the controller's
    /// (the measured frames belong to the measurement setup), kept for the identified file.
    setup: RobotFile,
    /// The parameters to identify.
    selection: Selection,
    /// With only the base fitted: the probe identified with the file's model, kept as the tool
    /// (the file written records it in its measurement setup; `Some(None)`: the file had none).
    probe: Option<Option<crate::io::robot_file::FrameEntry>>,
}

/// The measurement setup, the frames ([`crate::measurement::frames::prepare`]), the selection
/// ([`select_parameters`]) and the stored probe's parameters the data cannot determine held
/// (`frames::hold_dropped_probe_parameters`), for `dataset`.
fn register_and_select(dataset: &Dataset, config: &CalibrationConfig) -> crate::Result<Registered> {
    let frames = Frames::chosen(config.frames, &dataset.data);
    // With only the base fitted, the probe identified with the file's model stays the tool (as in
    // `evaluate --fit-frames base`); the file written keeps the given controller frames and
    // records the probe in its measurement setup.
    let probe = dataset.robot.identified_probe().cloned();
    let crate::measurement::frames::RegisteredSetup {
        setup,
        probe_kept,
        robot,
        report: mut frames_report,
        mask,
    } = crate::measurement::frames::register_setup(&dataset.robot, frames, dataset, config.k)?;
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
    Ok(Registered {
        robot,
        frames: frames_report,
        setup: setup.file,
        selection,
        probe: probe_kept.then_some(probe),
    })
}

/// The model found (the geometry of `identification`, or with the maps `kept`), its evaluation on
/// `dataset` and `validation` (the geometric one, `geometric`, made on the poses as the fit saw
/// them, `seen` and `held_out`) and its identified robot file (the frames identified recorded in
/// `frames`).
fn identified_model(
    (identification, kept): (&Identification, Option<&maps::KeptMaps>),
    (dataset, validation): (&Dataset, Option<&Dataset>),
    (seen, held_out, geometric): (&Seen<'_>, Option<&Seen<'_>>, Evaluation),
    config: &CalibrationConfig,
    frames: (&mut FramesReport, &RobotFile),
) -> crate::Result<(Identified, Evaluation, RobotFile)> {
    let Some(kept) = kept else {
        let mut file = identified_file::identified_robot(
            seen,
            config,
            &identification.parameters,
            &identification.errors,
            (&mut *frames.0, frames.1),
        );
        identified_file::record_covariance(
            &mut file,
            (
                &identification.parameters,
                identification.covariance.as_ref(),
            ),
            config,
        );
        return Ok((Identified::geometric(identification), geometric, file));
    };
    let mapped = dataset.seen_by_geometry(&kept.robot, &kept.errors)?;
    let mapped_out =
        (validation.map(|v| v.seen_by_geometry(&kept.robot, &kept.errors))).transpose()?;
    let evaluation = evaluation::evaluate(
        (seen, held_out),
        (&mapped, mapped_out.as_ref(), &kept.errors),
        &identification.weights,
    )?;
    let identified = Identified::with_maps(identification, kept);
    let mut file = identified_file::identified_robot(
        &mapped,
        config,
        &identified.parameters,
        &kept.errors,
        frames,
    );
    file.joint_maps = Some(kept.maps.clone());
    file.compliance = kept.compliance.clone();
    Ok((identified, evaluation, file))
}

/// The identified model's parameters and errors, and what its covariance says (the geometry's;
/// none for a model with joint maps, which the geometric fit's covariance does not describe).
struct Identified {
    parameters: Vec<IdentifiedParameter>,
    errors: calib_core::ParameterErrors<f64, Dyn>,
    covariance: Option<nalgebra::DMatrix<f64>>,
    significance: Option<crate::analysis::uncertainty::Significance>,
}

impl Identified {
    /// The geometric identification's.
    fn geometric(identification: &Identification) -> Self {
        Self {
            parameters: identification.parameters.clone(),
            errors: identification.errors,
            covariance: identification.covariance.clone(),
            significance: identification.significance.clone(),
        }
    }

    /// The model with the maps `kept`: their errors, with the maps' posterior standard deviations.
    fn with_maps(identification: &Identification, kept: &maps::KeptMaps) -> Self {
        let parameters = (identification.parameters.iter())
            .enumerate()
            .map(|(i, p)| IdentifiedParameter {
                parameter: p.parameter,
                value: kept.errors.get(p.parameter).unwrap_or(0.0),
                std_error: kept.parameter_sd.get(i).copied(),
            })
            .collect();
        Self {
            parameters,
            errors: kept.errors,
            covariance: None,
            significance: None,
        }
    }
}

/// What the stages found, for the result.
struct Found {
    identification: Identification,
    identified: Identified,
    evaluation: Evaluation,
    maps: Option<maps::JointMapsReport>,
    selection: Selection,
    frames: FramesReport,
    conditions: crate::measurement::conditions::MeasurementConditions,
}

/// The result, built once from what the stages `found` on the poses of `calibration` and
/// `held_out` (as the geometric fit saw them: with a robot's compliance, taken off at the fit)
/// and `validation` (the held-out poses as the registered geometry sees them): the held-out accuracy
/// and the band the covariance predicts, the acceptance criteria, a measured plan's check (with
/// `plan`, the dataset it was fitted on), the plausibility check (an implausible result is
/// refused, with the result, unless the configuration accepts it) and the caveats.
fn finish(
    found: Found,
    (calibration, held_out, validation): (&Seen<'_>, Option<&Seen<'_>>, Option<&Seen<'_>>),
    config: &CalibrationConfig,
    plan: Option<&Dataset>,
) -> crate::Result<CalibrationResult> {
    let Found {
        identification,
        identified,
        evaluation,
        maps,
        selection,
        frames,
        conditions,
    } = found;
    let Evaluation {
        calibration: calibration_stage,
        validation: validation_stage,
        mut per_pose,
        poses,
    } = evaluation;
    let (uncertainty, held_out, acceptance, budget) = held_out_statements(
        (held_out, validation),
        (&identification, &identified),
        (calibration, &calibration_stage, &conditions, &mut per_pose),
        config,
    )?;
    let plan_check = match (plan, validation_stage) {
        (Some(fitted), Some(stage)) => plan_check(fitted, &poses, stage, config),
        _ => None,
    };
    let robot = &calibration.robot;
    let implausible = plausibility::check(
        &identified.parameters,
        calibration_stage.after.position_mm.rms,
        &robot.file,
    );
    let caveats = caveats(
        (config.identify, identification.cross_validation),
        (uncertainty.as_ref(), &implausible, plan_check.as_ref()),
        calibration,
        validation,
    );
    let result = CalibrationResult {
        robot: robot.model.name.clone(),
        robot_path: robot.model.path.clone(),
        data_path: calibration.data.path.clone(),
        config: config.clone(),
        objective: identification.objective,
        parameters: identified.parameters,
        errors: identified.errors,
        swarm: identification.swarm,
        least_squares: identification.least_squares,
        identifiability: selection.identifiability,
        dropped: selection.dropped,
        frames,
        outliers: identification.outliers,
        poses,
        calibration: calibration_stage,
        validation: validation_stage,
        per_pose,
        seconds: identification.seconds,
        calibrated_at: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
        implausible,
        cross_validation: identification.cross_validation,
        joint_maps: maps,
        plan_check,
        held_out,
        acceptance,
        uncertainty,
        budget,
        significance: identified.significance,
        conditions: Some(conditions),
        caveats,
        covariance: identified.covariance,
    };
    refused_if_implausible(result, config)
}

/// The uncertainty budget of the accuracy statement ([`crate::analysis::budget`]): from the
/// held-out band's inputs (`uncertainty`), the least squares' rows and parameters, the
/// calibration poses' RMS position residual (`calibration`) and the temperatures seen; `None`
/// without held-out poses or least squares.
fn budget_of(
    uncertainty: Option<&crate::analysis::uncertainty::Coverage>,
    identification: &Identification,
    calibration: &Stage,
    conditions: &MeasurementConditions,
) -> Option<crate::analysis::budget::UncertaintyBudget> {
    let u = uncertainty?;
    let rows = f64::from(identification.least_squares.as_ref()?.rows);
    crate::analysis::budget::UncertaintyBudget::of(&crate::analysis::budget::BudgetInputs {
        model_rms_mm: &u.model_rms_mm,
        held_out_errors_mm: &u.errors_mm,
        reach_mm: &u.reach_mm,
        residual: (
            calibration.after.position_mm.rms,
            rows,
            identification.set.len() as f64,
        ),
        instrument: u.instrument.clone(),
        temperature_c: conditions.temperature.as_ref().map(|t| (t.min_c, t.max_c)),
    })
}

/// `result`, or with problems of plausibility (unless the configuration accepts them) the
/// refusal [`crate::Error::Implausible`] holding it.
fn refused_if_implausible(
    result: CalibrationResult,
    config: &CalibrationConfig,
) -> crate::Result<CalibrationResult> {
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
    Ok(result)
}

/// What the held-out poses say of the model `identified`: against the band its covariance
/// predicts (on the poses as the fit saw them; with the calibration poses for the instrument's
/// noise), its accuracy (on the poses as the registered geometry sees them), the acceptance
/// criteria judged on them, and the uncertainty budget of the accuracy statement (with the
/// calibration poses' residual `stage` and the `conditions`' temperatures).
type HeldOutStatements = (
    Option<crate::analysis::uncertainty::Coverage>,
    Option<crate::analysis::accuracy::HeldOutAccuracy>,
    Option<crate::analysis::accuracy::Acceptance>,
    Option<crate::analysis::budget::UncertaintyBudget>,
);

/// [`HeldOutStatements`] of `identified` on `held_out` (as the fit saw them) and `validation` (as
/// the registered geometry sees them), the poses placed in `per_pose`.
fn held_out_statements(
    (held_out, validation): (Option<&Seen<'_>>, Option<&Seen<'_>>),
    (identification, identified): (&Identification, &Identified),
    (calibration, stage, conditions, per_pose): (
        &Seen<'_>,
        &Stage,
        &MeasurementConditions,
        &mut PerPose,
    ),
    config: &CalibrationConfig,
) -> crate::Result<HeldOutStatements> {
    let uncertainty = match (
        held_out,
        &identified.covariance,
        &identification.least_squares,
    ) {
        (Some(v), Some(covariance), Some(l)) => evaluation::held_out_coverage(
            (calibration, v),
            &identification.set,
            covariance,
            &identified.errors,
            l.sigma_mm,
        )?,
        _ => None,
    };
    let accuracy = match validation {
        Some(v) => {
            let predicted = (uncertainty.as_ref())
                .map(|u| u.model_rms_mm.clone())
                .unwrap_or_default();
            evaluation::held_out_accuracy(per_pose, v, &identified.errors, predicted)?
        }
        None => None,
    };
    let acceptance = crate::analysis::accuracy::Acceptance::judge(
        &config.acceptance,
        &per_pose.validation_after,
    );
    let budget = budget_of(uncertainty.as_ref(), identification, stage, conditions);
    Ok((uncertainty, accuracy, acceptance, budget))
}

/// The check of a measured plan's verification poses (held out, Table 3 `validation`) against
/// the plan's prediction, when the file `fitted` came from kept the plan's prediction line; the
/// fitted poses' errors after calibration (`poses`) name those of largest residual.
fn plan_check(
    fitted: &Dataset,
    poses: &[PoseReport],
    validation: Stage,
    config: &CalibrationConfig,
) -> Option<crate::planning::PlanCheck> {
    let predicted = fitted.data.planned?;
    let measure = if fitted.data.rows_without_orientation() {
        Measure::Position
    } else {
        Measure::Pose
    };
    let poses: Vec<(String, Vec<f64>, f64)> = (fitted.data.records.iter())
        .zip(poses)
        .map(|(r, p)| (r.id.clone(), r.q.clone(), p.after_mm))
        .collect();
    Some(crate::planning::check_plan(
        predicted,
        validation.after.position_mm.mean,
        validation.poses,
        &fitted.robot.file,
        &fitted.robot.model.path,
        &poses,
        measure,
        config.k,
    ))
}

/// The caveats of the certificate ([`crate::analysis::caveats`]): a cross-validation worse than
/// nominal, held-out poses outside the joint ranges of the calibration poses (`calibration`),
/// held-out errors beyond the predicted band, an implausible result kept, a measured plan's
/// verification error beyond its prediction ([`crate::planning::PlanCheck::caveat`]).
fn caveats(
    (identify, cross_validation): (Identify, Option<cross_validation::CrossValidation>),
    (uncertainty, implausible, plan_check): (
        Option<&crate::analysis::uncertainty::Coverage>,
        &[String],
        Option<&crate::planning::PlanCheck>,
    ),
    calibration: &Seen<'_>,
    validation: Option<&Seen<'_>>,
) -> Vec<crate::analysis::caveats::Caveat> {
    let calibration_joints: Vec<Vec<f64>> = calibration
        .data
        .records
        .iter()
        .map(|r| r.q.clone())
        .collect();
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
    let geometry_identified = identify == Identify::Geometry;
    if let Some(cv) = cross_validation.filter(|cv| geometry_identified && cv.worse_than_nominal()) {
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
            &joint_ranges(&calibration_joints),
            &held_out,
            &lines,
        ));
    }
    if let Some(u) = uncertainty.filter(|u| u.percent_inside_95 < COVERAGE_BELOW_PERCENT) {
        out.push(whole(
            CaveatKind::Uncertainty,
            format!(
                "only {:.1} % of the held-out errors lie inside their predicted 95 % band: the model or the stated instrument misses an error",
                u.percent_inside_95
            ),
        ));
    }
    if !implausible.is_empty() {
        out.push(whole(
            CaveatKind::Implausible,
            format!(
                "the result is not plausible and was kept (--accept-implausible): {}",
                implausible.join("; ")
            ),
        ));
    }
    out.extend(plan_check.and_then(crate::planning::PlanCheck::caveat));
    out
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
                return Err(crate::refused!(option "--identify";
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
    let poses = crate::analysis::kind::Poses {
        seen: dataset,
        k: config.k,
    };
    select_parameters_of(&poses, mask, config)
}

/// [`select_parameters`] on measurements of any kind: what the kind leaves free whatever the
/// data's spread taken out first (and reported), then the analysis of the kind's Jacobian.
pub fn select_parameters_of<K: MeasurementKind>(
    kind: &K,
    mut mask: ParameterMask<Dyn>,
    config: &CalibrationConfig,
) -> crate::Result<Selection> {
    let analysed = |mask: &ParameterMask<Dyn>| analyse_kind(kind, mask);
    let left_free = kind.left_free(&mask, config.k)?;
    for parameter in left_free.all() {
        mask.set(parameter, false);
    }
    let mut initial = analysed(&mask)?;
    initial.reflector_on_last_axis = left_free.reflector_on_last_axis;
    initial.left_free = left_free.parameters;
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
