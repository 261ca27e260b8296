//! A calibration session: what an application needs around the stages of [`super::stages`], in
//! the library rather than in the command line, so that `calib calibrate`, the Python package and
//! any other caller get the same policy.
//!
//! - Which poses are held out ([`HoldOut`]): none, a fraction chosen by a seed, separately
//!   measured poses, or a measured plan's verification rows. A new hold-out rule is a variant
//!   there and an arm of [`Session::split`], and nowhere else.
//! - Where the calibration came from ([`Provenance`]): the command line and the input files with
//!   their SHA-256, stamped with the date into the identified file's `[calibration]` (or, for a
//!   re-registration, `[measurement]`).
//! - A measured plan's verification poses held out, to be checked against the plan's prediction,
//!   and the comparison with known errors ([`Truth`], from `calib simulate`).
//!
//! It returns [`Calibrated`]: the identified robot as a model (geometry, frames, joint maps,
//! compliance, covariance: an [`ActualRobot`]), the typed result and the provenance. The
//! identified robot file is emitted from the model once, at the edge
//! ([`Calibrated::robot_toml`]); the JSON report and the text are renderings of the result
//! ([`Calibrated::report`], [`Calibrated::text`]). No file is read or written here.

use super::{CalibrationConfig, CalibrationResult, HoldOutSettings, Identify, Report};
use crate::analysis::truth::TruthRow;
use crate::io::provenance::InputFile;
use crate::io::robot_file::RobotFile;
use crate::io::tracker_data::Role;
use crate::kinematics::actual::ActualRobot;
use crate::measurement::dataset::Dataset;
use std::path::PathBuf;

/// Which poses a calibration holds out of the fit, to state its accuracy on poses it did not see.
#[derive(Clone, Debug, Default)]
pub enum HoldOut {
    /// None: the accuracy is stated by cross-validation only.
    #[default]
    None,
    /// This fraction of the poses (between 0 and 1), chosen at random by `seed`
    /// (`calib calibrate --validate FRACTION --validate-seed SEED`).
    Fraction {
        /// The share of the poses held out, between 0 and 1.
        fraction: f64,
        /// The seed of the random choice.
        seed: u64,
    },
    /// Separately measured poses in the same tracker frame (`--holdout FILE`).
    Poses {
        /// The held-out poses.
        poses: Box<Dataset>,
        /// What the report names them by (the file's path).
        source: String,
    },
    /// The verification rows (role `verify`) of a measured plan (`calib plan`): the data must
    /// carry them. Data with such rows are refused with any other rule.
    PlanVerify,
}

impl HoldOut {
    /// The rule `calib calibrate` applies when no hold-out option is given: a measured plan's
    /// verification rows when `dataset` carries them, else none.
    pub fn of_data(dataset: &Dataset) -> Self {
        if verify_rows(dataset).is_empty() {
            Self::None
        } else {
            Self::PlanVerify
        }
    }

    /// Separately measured poses, named in the report by their data file's path.
    pub fn poses(poses: Dataset) -> Self {
        Self::Poses {
            source: poses.data.path.display().to_string(),
            poses: Box::new(poses),
        }
    }
}

/// Where a calibration came from.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Provenance {
    /// The command line that ran it (empty for a library call).
    pub command_line: Vec<String>,
    /// Its input files (robot, data, profile, hold-out; not the truth) with their SHA-256
    /// ([`InputFile::all`]), in that order; empty for data from memory, whose identified file
    /// then records no inputs and no date.
    pub inputs: Vec<InputFile>,
}

/// The known errors of a simulated robot, to compare the identified ones with.
#[derive(Clone, Debug)]
pub struct Truth {
    /// The robot file of the true errors (`calib simulate --truth-out`), as read.
    pub file: RobotFile,
    /// Where it was read from (named in errors).
    pub path: PathBuf,
}

/// One calibration as an application runs it: the data, the hold-out rule, the settings, where
/// it came from and, for simulated data, the truth.
#[derive(Clone, Debug)]
pub struct Session {
    /// The robot and its measured poses (all of them: the hold-out rule takes its poses out).
    pub dataset: Dataset,
    /// Which poses are held out.
    pub hold_out: HoldOut,
    /// The settings.
    pub config: CalibrationConfig,
    /// Where the calibration comes from.
    pub provenance: Provenance,
    /// The true errors, for simulated data.
    pub truth: Option<Truth>,
}

/// A finished calibration: the identified robot, what was found, where it came from.
#[derive(Clone, Debug)]
pub struct Calibrated {
    /// The identified actual robot: nominal geometry plus the identified errors, the
    /// controller's base and tool, the joint maps and compliance found, the covariance and the
    /// measurement setup recorded (`model.file`, as the identified robot file states them).
    pub model: ActualRobot,
    /// What the calibration found: parameters, statistics, checks and caveats.
    pub result: CalibrationResult,
    /// Where it came from.
    pub provenance: Provenance,
    /// How the held-out poses were chosen, as the report states it.
    pub hold_out: HoldOutSettings,
    /// The identified errors against the true ones, when the truth was given.
    pub truth: Option<Vec<TruthRow>>,
}

impl Session {
    /// A session of `dataset` with `config`: no poses held out, no provenance, no truth.
    pub fn new(dataset: Dataset, config: CalibrationConfig) -> Self {
        Self {
            dataset,
            hold_out: HoldOut::None,
            config,
            provenance: Provenance::default(),
            truth: None,
        }
    }

    /// Calibrates: holds out the poses of the rule, runs the stages, checks a measured plan,
    /// stamps the provenance, compares with the truth.
    pub fn run(self) -> crate::Result<Calibrated> {
        let Self {
            dataset,
            hold_out,
            config,
            provenance,
            truth,
        } = self;
        config.check()?;
        let default_k = calib_core::identify::objective::DEFAULT_K;
        if dataset.data.rows_without_orientation() && config.k.to_bits() != default_k.to_bits() {
            return Err(crate::Error::conflict(
                &["--k"],
                format!(
                    "--k weighs orientation rows against position rows, and {} has positions only: drop --k",
                    dataset.data.path.display()
                ),
            ));
        }
        let (fitted, validation, settings, plan) = Self::split(dataset, hold_out)?;
        let (result, mut file) = super::stages(fitted, validation, &config, plan)?;
        if !provenance.inputs.is_empty() {
            stamp(&mut file, &provenance, &result);
        }
        let truth = truth.map(|t| truth_rows(&result, &t)).transpose()?;
        let model = ActualRobot::from_file(file, &result.robot_path)?;
        Ok(Calibrated {
            model,
            result,
            provenance,
            hold_out: settings,
            truth,
        })
    }

    /// The poses fitted and those held out by `rule`, how the report states the rule, and whether
    /// the held-out poses are a measured plan's (whose prediction is then checked).
    fn split(
        dataset: Dataset,
        rule: HoldOut,
    ) -> crate::Result<(Dataset, Option<Dataset>, HoldOutSettings, bool)> {
        let verify = verify_rows(&dataset);
        let data = dataset.data.path.display().to_string();
        if !verify.is_empty() && !matches!(rule, HoldOut::PlanVerify) {
            return Err(crate::Error::conflict(
                &["--validate", "--holdout"],
                format!(
                    "{data}: the plan's {} verify poses are the hold-out; drop --validate and --holdout (or the file's role column)",
                    verify.len()
                ),
            ));
        }
        Ok(match rule {
            HoldOut::None => (dataset, None, HoldOutSettings::default(), false),
            HoldOut::Fraction { fraction, seed } => {
                let (fitted, held) = crate::measurement::dataset::split(&dataset, fraction, seed)?;
                let settings = HoldOutSettings {
                    validate: Some(fraction),
                    validate_seed: seed,
                    holdout: None,
                };
                (fitted, Some(held), settings, false)
            }
            HoldOut::Poses { poses, source } => {
                let settings = HoldOutSettings {
                    holdout: Some(source),
                    ..HoldOutSettings::default()
                };
                (dataset, Some(*poses), settings, false)
            }
            HoldOut::PlanVerify => {
                if verify.is_empty() {
                    return Err(crate::refused!(input data;
                        "{data}: the hold-out is a plan's verification poses, and the data have none (no row with role verify)"
                    ));
                }
                let (fitted, held) = dataset.partition(&verify);
                let settings = HoldOutSettings {
                    holdout: Some(format!("{data} (the plan's verify poses)")),
                    ..HoldOutSettings::default()
                };
                (fitted, Some(held), settings, true)
            }
        })
    }
}

/// The indices of `dataset`'s rows with role `verify` (a measured plan's verification poses).
fn verify_rows(dataset: &Dataset) -> Vec<usize> {
    (dataset.data.records.iter().enumerate())
        .filter(|(_, r)| r.role == Some(Role::Verify))
        .map(|(i, _)| i)
        .collect()
}

/// The identified robot `file` of `result` with its provenance: the input files with their
/// SHA-256 and the date, in `[calibration]` for the files the geometry was identified from; for a
/// re-registration (`Identify::Frames`) in `[measurement]`, with the robot file whose geometry was
/// kept as `geometry_from` (its `[calibration]` is kept as it was).
fn stamp(file: &mut RobotFile, provenance: &Provenance, result: &CalibrationResult) {
    let records = provenance.inputs.clone();
    let at = result.calibrated_at.clone();
    if result.config.identify == Identify::Frames {
        if let Some(m) = file.measurement.as_mut() {
            let (robot, rest): (Vec<_>, Vec<_>) =
                records.into_iter().partition(|r| r.flag == "--robot");
            m.registered_at = Some(at);
            m.geometry_from = robot.into_iter().next();
            m.inputs = rest;
        }
    } else {
        if let Some(m) = file.measurement.as_mut() {
            m.registered_at = Some(at.clone());
        }
        if let Some(c) = file.calibration.as_mut() {
            c.calibrated_at = Some(at);
            c.inputs = records;
        }
    }
}

/// The identified errors of `result` against the true errors of `truth`.
fn truth_rows(result: &CalibrationResult, truth: &Truth) -> crate::Result<Vec<TruthRow>> {
    let (file, path) = (&truth.file, truth.path.as_path());
    file.expect_joints(path, result.errors.joints.len(), "the robot calibrated")?;
    // The whole file checked as a robot file (finite joint values, ordered limits), not only the
    // errors read from it (issue 39, N19: inf and NaN in its joints were accepted).
    file.to_model(path)?;
    let truth = file.calibration_errors(path)?;
    Ok(result
        .parameters
        .iter()
        .map(|p| {
            TruthRow::new(
                p.parameter,
                result.errors.get(p.parameter).unwrap_or(0.0),
                truth.get(p.parameter).unwrap_or(0.0),
            )
        })
        .collect())
}

impl Calibrated {
    /// The identified robot file, emitted from the model: what `calib calibrate --out` writes.
    pub fn robot_toml(&self) -> String {
        let result = &self.result;
        let header = if result.config.identify == Identify::Frames {
            format!(
                "{}: the geometry of {} (its [calibration] says where it came from), the measurement frames re-registered by calib calibrate --identify frames ({}) from {} ([measurement]).",
                result.robot,
                result.robot_path.display(),
                result.config.method.name(),
                result.data_path.display()
            )
        } else {
            format!(
                "{} identified by calib calibrate ({}) from {}.",
                result.robot,
                result.config.method.name(),
                result.data_path.display()
            )
        };
        self.model.file.to_toml(&format!(
            "{header}\nValues are nominal + identified errors; [calibration.errors] lists the errors and [calibration.std_errors] their standard errors, in mm and rad; [calibration.inputs] the files they were identified from, with their SHA-256."
        ))
    }

    /// The text `calib calibrate` prints: Table 3 and, with the truth, the comparison with it.
    pub fn text(&self) -> String {
        self.result.text(self.truth.as_deref())
    }

    /// The JSON report (`calib calibrate --report`).
    pub fn report(&self) -> Report {
        self.result
            .report(self.hold_out.clone(), self.truth.clone(), &self.provenance)
    }

    /// Whether the acceptance criteria of the configuration are met (`None` without criteria).
    pub fn accepted(&self) -> Option<bool> {
        self.result.acceptance.as_ref().map(|a| a.pass)
    }
}
