//! The typed result of a calibration, and its JSON report (a serde rendering of the result).

use super::config::CalibrationConfig;
use crate::analysis::identifiability::IdentifiabilityReport;
use crate::analysis::truth::{TruthRow, unit_of};
use crate::measurement::frames::FramesReport;
use crate::measurement::statistics::Table3;
use calib_core::identify::ipso::StopReason;
use calib_core::identify::lm::LmStop;
use calib_core::{Parameter, ParameterErrors};
use nalgebra::Dyn;
use serde::Serialize;
use std::path::PathBuf;

/// One identified parameter error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifiedParameter {
    /// The parameter.
    pub parameter: Parameter,
    /// Its identified error, mm or rad ([`unit_of`]).
    pub value: f64,
    /// Its standard error (after least squares), same unit.
    pub std_error: Option<f64>,
}

/// Initial and final objective (eq. 7).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct ObjectiveValues {
    /// At zero errors (the nominal model, frames fitted).
    pub initial: f64,
    /// At the identified errors.
    pub r#final: f64,
    /// Best of the initial swarm (without the swarm: the initial value).
    pub initial_swarm_best: f64,
    /// After the swarm (without the swarm: the initial value).
    pub after_swarm: f64,
    /// `k`, mm^2/rad^2.
    pub k: f64,
}

/// What the swarm did.
#[derive(Clone, Debug, PartialEq)]
pub struct SwarmSummary {
    /// Generations run.
    pub generations: u32,
    /// Objective evaluations.
    pub evaluations: u64,
    /// Why it stopped.
    pub stop: StopReason,
    /// `(generation, best objective)`, the convergence history.
    pub history: Vec<(u32, f64)>,
}

/// The least-squares stage of a calibration.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct LeastSquaresReport {
    /// Iterations.
    pub iterations: u32,
    /// Residual evaluations.
    pub evaluations: u32,
    /// Why it stopped.
    pub stop: String,
    /// `0.5 |r|^2` at its start (residual `[dp; sqrt(k) dr]`, mm).
    pub cost_initial: f64,
    /// `0.5 |r|^2` at the end.
    pub cost_final: f64,
    /// Residual rows.
    pub rows: u32,
    /// Residual standard deviation, mm.
    pub sigma_mm: f64,
    /// Scale of the robust loss used, mm (`null` for l2).
    pub loss_scale_mm: Option<f64>,
    /// `true` when that scale was estimated from the data.
    pub loss_scale_estimated: bool,
    /// With an estimated scale: the position residual beyond which a pose is an outlier, mm.
    pub outlier_position_mm: Option<f64>,
    /// With an estimated scale: the orientation residual beyond which a pose is an outlier, deg
    /// (`null` without orientations).
    pub outlier_rotation_deg: Option<f64>,
}

impl LeastSquaresReport {
    /// The report of the plain (not robust) least-squares run `fit`: no loss scale, no outlier
    /// thresholds.
    pub fn of(fit: &calib_core::identify::lm::LmResult<f64, Dyn>) -> Self {
        Self {
            iterations: fit.iterations,
            evaluations: fit.evaluations,
            stop: lm_stop(fit.stop).to_string(),
            cost_initial: fit.initial_cost,
            cost_final: fit.cost,
            rows: fit.rows,
            sigma_mm: fit.sigma(),
            loss_scale_mm: None,
            loss_scale_estimated: false,
            outlier_position_mm: None,
            outlier_rotation_deg: None,
        }
    }
}

/// Table 3 statistics of a set of poses before and after calibration.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Stage {
    /// Number of poses.
    pub poses: usize,
    /// With the nominal model (frames fitted, when identified).
    pub before: Table3,
    /// With the identified model.
    pub after: Table3,
}

/// One calibration pose in the report.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct PoseReport {
    /// The pose's id.
    pub id: String,
    /// Its line in the data file.
    pub line: u64,
    /// `|dp|` with the nominal model (frames fitted, when identified), mm.
    pub before_mm: f64,
    /// `|dp|` with the identified model, mm.
    pub after_mm: f64,
    /// Final weight of the robust loss (1 for l2).
    pub robust_weight: f64,
}

/// A pose flagged by the robust loss.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Outlier {
    /// The pose's id.
    pub id: String,
    /// Its line in the data file.
    pub line: u64,
    /// Its residual norm `sqrt(|dp|^2 + k |dr|^2)` at the result, mm.
    pub residual_mm: f64,
    /// Its final robust weight.
    pub weight: f64,
}

/// Per-pose errors for plots: `|dp|` (mm) and orientation per axis (deg), before and after.
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct PerPose {
    /// The data file's line of each calibration pose.
    pub lines: Vec<u64>,
    /// The data file's line of each calibration pose with an orientation (the poses of
    /// `orientation_before` and `orientation_after`).
    pub orientation_lines: Vec<u64>,
    /// `|dp|` per calibration pose with the nominal model, mm.
    pub before: Vec<f64>,
    /// With the identified model.
    pub after: Vec<f64>,
    /// `|dr_x|, |dr_y|, |dr_z|` per calibration pose with orientation, nominal model, deg.
    pub orientation_before: Vec<[f64; 3]>,
    /// With the identified model.
    pub orientation_after: Vec<[f64; 3]>,
    /// `|dp|` per validation pose with the nominal model, mm (empty without validation).
    pub validation_before: Vec<f64>,
    /// With the identified model.
    pub validation_after: Vec<f64>,
    /// `measured - predicted` per validation pose with the nominal model, along the robot's base
    /// axes, mm.
    pub validation_before_xyz: Vec<[f64; 3]>,
    /// With the identified model.
    pub validation_after_xyz: Vec<[f64; 3]>,
    /// The data file's line of each validation pose.
    pub validation_lines: Vec<u64>,
    /// The position of each validation pose in the robot's base frame as the identified model
    /// predicts it, mm.
    pub validation_position_mm: Vec<[f64; 3]>,
    /// The RMS position error the parameters' covariance predicts at each validation pose, mm
    /// (empty without a covariance).
    pub validation_predicted_rms_mm: Vec<f64>,
}

/// Everything a calibration found.
#[derive(Clone, Debug)]
///
/// `N` is the robot's joint count.
pub struct CalibrationResult {
    /// The robot's name.
    pub robot: String,
    /// Where the robot came from (a file, or `<memory>`).
    pub robot_path: PathBuf,
    /// Where the data came from.
    pub data_path: PathBuf,
    /// The settings used.
    pub config: CalibrationConfig,
    /// The identified parameters, in canonical order.
    pub parameters: Vec<IdentifiedParameter>,
    /// All errors (identified ones set, others zero), mm and rad.
    pub errors: ParameterErrors<f64, Dyn>,
    /// The objective before and after.
    pub objective: ObjectiveValues,
    /// The swarm stage, when it ran.
    pub swarm: Option<SwarmSummary>,
    /// The least-squares stage, when it ran.
    pub least_squares: Option<LeastSquaresReport>,
    /// Identifiability of the parameters asked for (before any were dropped).
    pub identifiability: IdentifiabilityReport,
    /// Parameters dropped by `auto_mask`.
    pub dropped: Vec<Parameter>,
    /// The frames identified with the geometry.
    pub frames: FramesReport,
    /// Poses beyond the robust loss scale (empty for l2).
    pub outliers: Vec<Outlier>,
    /// Every calibration pose: its error before and after and its robust weight.
    pub poses: Vec<PoseReport>,
    /// Table 3 on the calibration poses.
    pub calibration: Stage,
    /// Table 3 on the held-out poses, when given.
    pub validation: Option<Stage>,
    /// Per-pose errors for plots.
    pub per_pose: PerPose,
    /// Wall-clock time of the optimisation, s.
    pub seconds: f64,
    /// When the calibration finished, RFC 3339 (UTC, to the second).
    pub calibrated_at: String,
    /// Why the result is not plausible ([`super::plausibility`]); empty when it is. Non-empty only
    /// when the configuration accepts implausible results.
    pub implausible: Vec<String>,
    /// The cross-validation estimate of the held-out error on the calibration poses.
    pub cross_validation: Option<super::cross_validation::CrossValidation>,
    /// The joint maps identified with the geometry (`--model joint-maps`); the statistics above
    /// are then those of the model with the maps, the geometric calibration's are in it.
    pub joint_maps: Option<super::maps::JointMapsReport>,
    /// The measured verification poses of a plan against its prediction (`calib plan`), set by
    /// `calibrate` when the data file is a measured plan.
    pub plan_check: Option<crate::planning::PlanCheck>,
    /// The accuracy on the held-out poses (percentiles, per axis, the poses to look at), when
    /// poses were held out.
    pub held_out: Option<crate::analysis::accuracy::HeldOutAccuracy>,
    /// The acceptance criteria of the configuration judged on the held-out poses.
    pub acceptance: Option<crate::analysis::accuracy::Acceptance>,
    /// The held-out poses against the 95 % band predicted from the parameters' covariance (least
    /// squares and held-out poses needed; not for a model with joint maps).
    pub uncertainty: Option<crate::analysis::uncertainty::Coverage>,
    /// The uncertainty budget of the accuracy statement (GUM, k = 2), with the held-out band's
    /// inputs.
    pub budget: Option<crate::analysis::budget::UncertaintyBudget>,
    /// The identified parameters' covariance (mm and rad, in the order of `parameters`), from
    /// least squares.
    pub covariance: Option<nalgebra::DMatrix<f64>>,
    /// The parameters smaller than twice their standard error and the strongly correlated pairs
    /// (from the covariance).
    pub significance: Option<crate::analysis::uncertainty::Significance>,
    /// The conditions of the measurement: robot serial, payload, instrument, temperature.
    pub conditions: Option<crate::measurement::conditions::MeasurementConditions>,
    /// What limits the accuracy statement (empty: nothing found).
    pub caveats: Vec<crate::analysis::caveats::Caveat>,
}

impl CalibrationResult {
    /// The identified parameter called `name` (such as `da2` or `base_tx`).
    pub fn parameter(&self, name: &str) -> Option<&IdentifiedParameter> {
        self.parameters
            .iter()
            .find(|p| p.parameter.to_string() == name)
    }

    /// The identified parameters' names (such as `da2`, `base_tx`), in canonical order.
    pub fn names(&self) -> Vec<String> {
        self.parameters
            .iter()
            .map(|p| p.parameter.to_string())
            .collect()
    }

    /// Objective evaluations of the swarm plus residual evaluations of least squares.
    pub fn evaluations(&self) -> u64 {
        self.swarm.as_ref().map_or(0, |s| s.evaluations)
            + self
                .least_squares
                .as_ref()
                .map_or(0, |l| u64::from(l.evaluations))
    }

    /// Why the last stage stopped.
    pub(crate) fn stop(&self) -> &str {
        match (&self.least_squares, &self.swarm) {
            (Some(l), _) => &l.stop,
            (None, Some(s)) => swarm_stop(s.stop),
            (None, None) => "",
        }
    }

    /// The JSON report of the calibration `self`, with how its poses were held out (`hold_out`),
    /// the comparison with known errors (`truth`) and where it came from (`provenance`); see
    /// [`super::Calibrated::report`].
    pub(crate) fn report(
        &self,
        hold_out: HoldOutSettings,
        truth: Option<Vec<TruthRow>>,
        provenance: &super::Provenance,
    ) -> Report {
        Report {
            method: self.config.method.name().to_string(),
            robot: self.robot_path.display().to_string(),
            data: self.data_path.display().to_string(),
            parameters: self.parameters.iter().map(reported).collect(),
            objective: self.objective,
            generations: self.swarm.as_ref().map_or(0, |s| s.generations),
            evaluations: self.evaluations(),
            stop: self.stop().to_string(),
            least_squares: self.least_squares.clone(),
            identifiability: self.identifiability.clone(),
            dropped: self.dropped.iter().map(ToString::to_string).collect(),
            implausible: self.implausible.clone(),
            cross_validation: self.cross_validation,
            joint_maps: self.joint_maps.clone(),
            plan_check: self.plan_check.clone(),
            held_out: self.held_out.clone(),
            acceptance: self.acceptance.clone(),
            uncertainty: self.uncertainty.clone(),
            budget: self.budget.clone(),
            significance: self.significance.clone(),
            conditions: self.conditions.clone(),
            caveats: self.caveats.clone(),
            covariance: self.covariance.as_ref().map(|c| Covariance {
                parameters: self.names(),
                matrix: c.row_iter().map(|r| r.iter().copied().collect()).collect(),
            }),
            frames: self.frames.clone(),
            outliers: self.outliers.clone(),
            poses: self.poses.clone(),
            calibration: self.calibration,
            validation: self.validation,
            before: self.calibration.before,
            after: self.calibration.after,
            settings: Settings {
                config: self.config.clone(),
                hold_out,
            },
            truth,
            seconds: self.seconds,
            calibrated_at: self.calibrated_at.clone(),
            per_pose: self.per_pose.clone(),
            convergence: self
                .swarm
                .as_ref()
                .map_or_else(Vec::new, |s| s.history.clone()),
            software: format!(
                "calib {} (commit {})",
                env!("CARGO_PKG_VERSION"),
                env!("CALIB_COMMIT")
            ),
            command_line: provenance.command_line.clone(),
            inputs: provenance.inputs.clone(),
        }
    }
}

/// An identified parameter as the report states it: its name and its entry.
pub(super) fn reported(p: &IdentifiedParameter) -> (String, ParameterEntry) {
    let entry = ParameterEntry {
        value: p.value,
        unit: unit_of(p.parameter).to_string(),
        std_error: p.std_error,
    };
    (p.parameter.to_string(), entry)
}

/// How the validation poses were chosen, as the report's settings state it (the rule itself is
/// [`super::HoldOut`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, serde::Deserialize)]
pub struct HoldOutSettings {
    /// Fraction held out at random.
    pub validate: Option<f64>,
    /// Seed of that random hold-out.
    pub validate_seed: u64,
    /// A separate file of validation poses.
    pub holdout: Option<String>,
}

/// The settings block of the report.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Settings {
    /// The calibration's configuration.
    #[serde(flatten)]
    pub config: CalibrationConfig,
    /// The hold-out.
    #[serde(flatten)]
    pub hold_out: HoldOutSettings,
}

/// One identified parameter in the JSON report (its name is the key of its entry).
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterEntry {
    /// The identified error, in `unit`.
    pub value: f64,
    /// `mm` or `rad`.
    pub unit: String,
    /// Its standard error from least squares (1 sigma, in `unit`), when least squares ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub std_error: Option<f64>,
}

impl ParameterEntry {
    /// Whether the parameter is an angle (its unit is rad).
    pub fn is_angle(&self) -> bool {
        self.unit == "rad"
    }
}

/// The identified parameters as a JSON object, name -> entry, in the order of identification.
pub type Parameters = indexmap::IndexMap<String, ParameterEntry>;

/// The JSON report of a calibration (a rendering of [`CalibrationResult`]).
///
/// The same type is written by `calib calibrate --report` and read back by `calib report --from`
/// and the HTML certificate ([`crate::report::html`]), so a field renamed here is renamed
/// everywhere it is shown, or the build fails.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Report {
    /// `ipso`, `lm` or `ipso+lm`.
    pub method: String,
    /// Robot file.
    pub robot: String,
    /// Data file.
    pub data: String,
    /// Identified errors: name -> { value, unit, std_error (after least squares) }.
    pub parameters: Parameters,
    /// Objective (eq. 7) at the nominal model and at the result.
    pub objective: ObjectiveValues,
    /// Swarm generations run (0 without the swarm).
    pub generations: u32,
    /// Objective evaluations of the swarm plus residual evaluations of least squares.
    pub evaluations: u64,
    /// Why the last stage stopped.
    pub stop: String,
    /// The least-squares stage, when it ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub least_squares: Option<LeastSquaresReport>,
    /// Identifiability of the parameters of the robot file on these data, at the nominal model.
    pub identifiability: IdentifiabilityReport,
    /// Parameters dropped: undetermined ones (--auto-mask), then along the weakest direction of an
    /// ill-conditioned pose set (unless --keep-ill-conditioned).
    pub dropped: Vec<String>,
    /// Why the result is not plausible (written only with --accept-implausible); empty when it is.
    pub implausible: Vec<String>,
    /// The cross-validation estimate of the held-out error (`null` with fewer than 3 poses).
    pub cross_validation: Option<super::cross_validation::CrossValidation>,
    /// The joint maps identified with the geometry (`--model joint-maps`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub joint_maps: Option<super::maps::JointMapsReport>,
    /// The plan's verification poses against its prediction, for a measured plan.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plan_check: Option<crate::planning::PlanCheck>,
    /// The accuracy on the held-out poses: `|dp|` percentiles and signed error per base axis,
    /// before and after; the largest and the flagged poses with their lines.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub held_out: Option<crate::analysis::accuracy::HeldOutAccuracy>,
    /// The acceptance criteria judged on the held-out poses: each with its measured share, and
    /// `pass` when all are met.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub acceptance: Option<crate::analysis::accuracy::Acceptance>,
    /// The held-out poses against their predicted 95 % band (parameters' covariance and noise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<crate::analysis::uncertainty::Coverage>,
    /// The uncertainty budget of the accuracy statement (GUM: components, combined, expanded
    /// with k = 2, the held-out coordinates within it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub budget: Option<crate::analysis::budget::UncertaintyBudget>,
    /// The identified parameters' covariance from least squares.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub covariance: Option<Covariance>,
    /// Parameters not shown to differ from zero, and strongly correlated pairs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub significance: Option<crate::analysis::uncertainty::Significance>,
    /// The conditions of the measurement.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub conditions: Option<crate::measurement::conditions::MeasurementConditions>,
    /// What limits the accuracy statement (empty: nothing found).
    pub caveats: Vec<crate::analysis::caveats::Caveat>,
    /// The frames identified with the geometry and their values.
    pub frames: FramesReport,
    /// Poses whose residual exceeds the robust loss scale (empty for l2).
    pub outliers: Vec<Outlier>,
    /// Every calibration pose: its position error before and after, and its robust weight.
    pub poses: Vec<PoseReport>,
    /// Statistics on the calibration poses (the same as `before` and `after`).
    pub calibration: Stage,
    /// Statistics on the held-out validation poses, when asked for.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation: Option<Stage>,
    /// Table 3 statistics with the nominal model.
    pub before: Table3,
    /// Table 3 statistics with the identified model.
    pub after: Table3,
    /// Settings used.
    pub settings: Settings,
    /// Comparison with the truth, when given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<Vec<TruthRow>>,
    /// Wall-clock time of the optimisation, s.
    pub seconds: f64,
    /// When the calibration finished, RFC 3339 (UTC, to the second): the date of the result, which
    /// a report rendered later states (not the time of rendering).
    #[serde(default)]
    pub calibrated_at: String,
    /// Per-pose errors (calibration and validation poses), for plots.
    pub per_pose: PerPose,
    /// The swarm's convergence: `[generation, best objective]` (empty without the swarm).
    pub convergence: Vec<(u32, f64)>,
    /// The software that wrote the report: its version and the git commit it was built from.
    pub software: String,
    /// The command line that ran the calibration (empty for a library call); with `settings`
    /// (seeds included) and the identified file's input hashes, what reproduces it.
    #[serde(default)]
    pub command_line: Vec<String>,
    /// The run's input files with their SHA-256 (as the identified robot file records them).
    #[serde(default)]
    pub inputs: Vec<crate::io::provenance::InputFile>,
}

impl Report {
    /// The JSON report at `path` (written by `calib calibrate --report`). Refused, naming the
    /// field and line, when it is not one this version reads.
    pub fn read(path: &std::path::Path) -> crate::Result<Self> {
        let text = crate::io::input::read_text(path, crate::io::input::Input::Data)?;
        Self::from_json(&text, path)
    }

    /// The report in `text`, read from `path` (named in messages).
    pub fn from_json(text: &str, path: &std::path::Path) -> crate::Result<Self> {
        serde_json::from_str(text).map_err(|e| {
            crate::refused!(input path.display();
                "{}: not a JSON report of calib calibrate that this version reads ({e}); write one with calib calibrate --report \
                 (a report written by another version renders with that version)",
                path.display()
            )
        })
    }

    /// The residuals of its calibration poses (`source` names the report in messages), for the
    /// noise of a plan (`calib plan --noise-from`). Refused when least squares did not run.
    pub fn residuals(&self, source: &std::path::Path) -> crate::Result<crate::planning::Residuals> {
        let Some(least_squares) = &self.least_squares else {
            return Err(crate::refused!(input source.display();
                "{}: no least-squares stage (the calibration ran the swarm alone), so no residuals to take the noise from; give --noise-mm",
                source.display()
            ));
        };
        let after = &self.calibration.after;
        Ok(crate::planning::Residuals {
            source: source.to_path_buf(),
            rows: least_squares.rows,
            parameters: self.parameters.len(),
            position_rms_mm: after.position_mm.rms,
            orientation_rms_deg: after.orientation_deg.map(|o| [o.x.rms, o.y.rms, o.z.rms]),
        })
    }
}

/// The identified parameters' covariance in the JSON report.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct Covariance {
    /// The parameters, in the order of the rows and columns.
    pub parameters: Vec<String>,
    /// The matrix by rows, in the parameters' units (mm, rad) squared and crossed.
    pub matrix: Vec<Vec<f64>>,
}

/// Why the swarm stopped, in words.
pub fn swarm_stop(stop: StopReason) -> &'static str {
    match stop {
        StopReason::MaxGenerations => "maximum generations",
        StopReason::TargetReached => "target objective reached",
        StopReason::Stalled => "no improvement",
        StopReason::Cancelled => "cancelled",
    }
}

/// Why least squares stopped, in words.
pub fn lm_stop(stop: LmStop) -> &'static str {
    match stop {
        LmStop::ZeroResidual => "zero residual",
        LmStop::Gradient => "gradient below tolerance",
        LmStop::Step => "step below tolerance",
        LmStop::CostChange => "cost change below tolerance",
        LmStop::MaxIterations => "iteration cap",
        LmStop::NoProgress => "no further progress (rounding floor)",
    }
}
