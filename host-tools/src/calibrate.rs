//! `calib calibrate`: identify the parameter errors of a robot from tracker data with the
//! paper's swarm, and report Table 3 before and after.

use crate::check::{IdentifiabilityReport, Inputs, analyse};
use crate::files::write_atomic;
use crate::frames::{Frames, FramesReport};
use crate::report::{Table3, TruthRow, table3_text, truth_text, unit_of};
use crate::robot_file::RobotFile;
use anyhow::bail;
use calib_core::Problem;
use calib_core::identify::halton::Scrambling;
use calib_core::identify::ipso::{
    self, Control, CostFunction, IpsoSettings, SearchSpace, StopReason,
};
use calib_core::identify::lm::{LeastSquares, LmError, LmResult, LmSettings, LmStop, Loss};
use calib_core::identify::objective::Objective;
use calib_core::{Kinematics, ParameterErrors, ParameterMask, ParameterSet};
use nalgebra::SVector;
use rayon::prelude::*;
use serde::Serialize;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

/// Swarm sizes `calib` is built for (the core takes the swarm size as a const generic).
pub const SWARM_SIZES: [usize; 6] = [10, 20, 30, 40, 50, 100];

/// Identification method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Method {
    /// The paper's improved particle swarm (Halton start, constriction factor).
    Ipso,
    /// Levenberg-Marquardt least squares from the nominal model.
    Lm,
    /// The swarm for a global start, then least squares to the noise floor.
    #[value(name = "ipso+lm")]
    IpsoLm,
}

impl Method {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ipso => "ipso",
            Self::Lm => "lm",
            Self::IpsoLm => "ipso+lm",
        }
    }
}

/// Loss of the least-squares stage, as chosen on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LossChoice {
    /// Plain least squares.
    L2,
    /// Huber: quadratic up to the scale, linear beyond.
    Huber,
    /// Cauchy: weight 1 / (1 + (r / scale)^2).
    Cauchy,
}

impl LossChoice {
    /// The core's loss with the given scale (mm).
    pub fn with_scale(self, scale: f64) -> Loss<f64> {
        match self {
            Self::L2 => Loss::L2,
            Self::Huber => Loss::Huber(scale),
            Self::Cauchy => Loss::Cauchy(scale),
        }
    }
}

/// Halton digit scrambling, as chosen on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ScramblingChoice {
    /// Plain Halton, as in the paper.
    None,
    /// Reverse Halton (Vandewoestyne and Cools 2006).
    Reverse,
}

impl From<ScramblingChoice> for Scrambling {
    fn from(choice: ScramblingChoice) -> Self {
        match choice {
            ScramblingChoice::None => Scrambling::None,
            ScramblingChoice::Reverse => Scrambling::Reverse,
        }
    }
}

/// Everything `calib calibrate` needs: its command-line options.
#[derive(Clone, Debug, clap::Args)]
pub struct CalibrateOptions {
    /// Robot, data and data profile files.
    #[command(flatten)]
    pub input: crate::check::InputFiles,
    /// Frames identified with the geometry: none (data in the base frame, tool known), base
    /// (tracker-to-base), or base+tool (and the tool on the flange: 3 translations for a
    /// reflector, 6 for a 6-DoF probe). Default: base+tool, or none when the data say
    /// `# frame: base`.
    #[arg(long, value_enum)]
    pub frames: Option<Frames>,
    /// Identification method: the paper's swarm, least squares, or the swarm then least squares.
    #[arg(long, value_enum, default_value_t = Method::IpsoLm)]
    pub method: Method,
    /// Iteration cap of the least-squares stage.
    #[arg(long, default_value_t = 100)]
    pub lm_iterations: u32,
    /// Loss of the least-squares stage: l2, or huber / cauchy to down-weight outlier poses.
    #[arg(long, value_enum, default_value_t = LossChoice::L2)]
    pub loss: LossChoice,
    /// Scale of the robust loss, mm of pose residual sqrt(|dp|^2 + k |dr|^2); poses beyond it are
    /// reported as outliers. About 3 times the typical pose residual works well: with tracker
    /// noise of 0.02 mm and 1e-4 rad (k = 1e6) a pose residual is about 0.17 mm, and 0.5 mm keeps
    /// every clean pose in.
    #[arg(long, default_value_t = 1.0)]
    pub loss_scale_mm: f64,
    /// Drop the parameters the data cannot determine (instead of refusing), then, while the pose
    /// set is ill-conditioned (scaled condition number above 1000), the parameter with the
    /// largest share of the least determined direction; say which.
    #[arg(long)]
    pub auto_mask: bool,
    /// Hold out this fraction of the poses (chosen at random with --validate-seed) and report the
    /// statistics on them separately.
    #[arg(long, value_name = "FRACTION", conflicts_with = "holdout")]
    pub validate: Option<f64>,
    /// Seed of the random hold-out of --validate.
    #[arg(long, default_value_t = 0)]
    pub validate_seed: u64,
    /// A separate data file of validation poses.
    #[arg(long, value_name = "FILE")]
    pub holdout: Option<PathBuf>,
    /// Swarm size (10, 20, 30, 40, 50 or 100).
    #[arg(long, default_value_t = 20)]
    pub swarm: usize,
    /// Maximum number of generations.
    #[arg(long, default_value_t = 2000)]
    pub generations: u32,
    /// Cognitive acceleration coefficient c1 (c1 + c2 > 4).
    #[arg(long, default_value_t = 2.05)]
    pub c1: f64,
    /// Social acceleration coefficient c2.
    #[arg(long, default_value_t = 2.05)]
    pub c2: f64,
    /// Orientation weight k of eq. (7), mm^2/rad^2: 1e6 makes 1 mrad weigh like 1 mm.
    #[arg(long, default_value_t = calib_core::identify::objective::DEFAULT_K)]
    pub k: f64,
    /// Seed of the swarm's random numbers r1, r2.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Initial half range of angle errors, rad (paper: 0.01).
    #[arg(long, default_value_t = ipso::PAPER_ANGLE_RANGE)]
    pub init_angle_rad: f64,
    /// Initial half range of length errors, mm (paper: 0.5).
    #[arg(long, default_value_t = ipso::PAPER_LENGTH_RANGE)]
    pub init_length_mm: f64,
    /// Search bounds as a multiple of the initial half range (absorbing walls).
    #[arg(long, default_value_t = ipso::DEFAULT_BOUND_FACTOR)]
    pub bound_factor: f64,
    /// Stop after this many generations without improvement (0: never).
    #[arg(long, default_value_t = 0)]
    pub stall_generations: u32,
    /// Stop as soon as the objective reaches this value.
    #[arg(long, default_value_t = f64::NEG_INFINITY, allow_hyphen_values = true)]
    pub target: f64,
    /// Halton index of the first particle (the paper's k; 0 is the all-zero point).
    #[arg(long, default_value_t = 1)]
    pub halton_start: u64,
    /// Halton digit scrambling.
    #[arg(long, value_enum, default_value_t = ScramblingChoice::None)]
    pub scrambling: ScramblingChoice,
    /// Robot file with the true errors (from calib simulate): prints each parameter's error.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Identified robot file to write.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// JSON report to write.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Directory for plots (convergence and position errors, SVG and PNG).
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    /// Never show the progress bar (it is shown only on a terminal anyway).
    #[arg(long)]
    pub quiet: bool,
}

/// The JSON report of a calibration.
#[derive(Debug, Serialize)]
pub struct Report {
    /// `ipso`, `lm` or `ipso+lm`.
    pub method: String,
    /// Robot file.
    pub robot: String,
    /// Data file.
    pub data: String,
    /// Identified errors: name -> { value, unit, std_error (after least squares) }.
    pub parameters: serde_json::Map<String, serde_json::Value>,
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
    /// Parameters dropped by --auto-mask.
    pub dropped: Vec<String>,
    /// The frames identified with the geometry and their start values.
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
    pub settings: serde_json::Value,
    /// Comparison with the truth, when `--truth` was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<Vec<TruthRow>>,
    /// Wall-clock time of the optimisation, s.
    pub seconds: f64,
}

/// Initial and final objective.
#[derive(Debug, Serialize)]
pub struct ObjectiveValues {
    /// At zero errors (the nominal model).
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

/// Table 3 statistics of a set of poses before and after calibration.
#[derive(Debug, Serialize)]
pub struct Stage {
    /// Number of poses.
    pub poses: usize,
    /// With the nominal model.
    pub before: Table3,
    /// With the identified model.
    pub after: Table3,
}

/// One calibration pose in the report.
#[derive(Debug, Serialize)]
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
#[derive(Debug, Serialize)]
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

/// The least-squares stage of a calibration.
#[derive(Debug, Serialize)]
pub struct LeastSquaresReport {
    /// Iterations.
    pub iterations: u32,
    /// Residual evaluations.
    pub evaluations: u32,
    /// Why it stopped.
    pub stop: String,
    /// `0.5 |r|^2` at its start and end (residual `[dp; sqrt(k) dr]`, mm).
    pub cost_initial: f64,
    /// `0.5 |r|^2` at the end.
    pub cost_final: f64,
    /// Residual rows.
    pub rows: u32,
    /// Residual standard deviation, mm.
    pub sigma_mm: f64,
}

/// Result of `calibrate`: the report, the identified robot file, the text for people, the
/// convergence history and the per-pose position errors before and after.
pub struct Calibration {
    /// JSON report.
    pub report: Report,
    /// Identified robot file (TOML text).
    pub robot_toml: String,
    /// Text output (Table 3 and the truth comparison).
    pub text: String,
    /// `(generation, best objective)`.
    pub history: Vec<(u32, f64)>,
    /// `|dp|` per pose with the nominal model, mm.
    pub before: Vec<f64>,
    /// `|dp|` per pose with the identified model, mm.
    pub after: Vec<f64>,
    /// Orientation error per axis per pose with the nominal model, deg (empty without
    /// orientation data).
    pub orientation_before: Vec<[f64; 3]>,
    /// With the identified model.
    pub orientation_after: Vec<[f64; 3]>,
    /// `|dp|` per validation pose with the nominal model, mm (empty without validation).
    pub validation_before: Vec<f64>,
    /// With the identified model.
    pub validation_after: Vec<f64>,
}

/// Evaluates the swarm's particles in parallel on the host's cores (rayon); the core's default
/// evaluates them one by one. Results are identical: each particle's cost is computed alone.
pub struct Parallel<'o, 'a, const D: usize>(pub &'o Objective<'a, f64, 6, D>);

impl<const D: usize> CostFunction<f64, D> for Parallel<'_, '_, D> {
    fn cost(&mut self, x: &SVector<f64, D>) -> f64 {
        self.0.value(x)
    }
    fn cost_batch(&mut self, xs: &[SVector<f64, D>], out: &mut [f64]) {
        let objective = self.0;
        out.par_iter_mut()
            .zip(xs.par_iter())
            .for_each(|(c, x)| *c = objective.value(x));
    }
}

/// Runs the calibration.
pub fn calibrate(options: &CalibrateOptions) -> anyhow::Result<Calibration> {
    if !SWARM_SIZES.contains(&options.swarm) {
        bail!(
            "--swarm {} is not available; choose one of {:?}",
            options.swarm,
            SWARM_SIZES
        );
    }
    for (name, v) in [
        ("--k", options.k),
        ("--init-angle-rad", options.init_angle_rad),
        ("--init-length-mm", options.init_length_mm),
        ("--bound-factor", options.bound_factor),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            bail!("{name} must be a finite number >= 0, got {v}");
        }
    }
    if !(options.loss_scale_mm.is_finite() && options.loss_scale_mm > 0.0) {
        bail!(
            "--loss-scale-mm must be a finite number > 0, got {}",
            options.loss_scale_mm
        );
    }
    if options.loss != LossChoice::L2 && options.method == Method::Ipso {
        bail!(
            "--loss {:?} applies to the least-squares stage: use --method lm or ipso+lm",
            options.loss
        );
    }
    let (profile, all) = options.input.load()?;
    let (mut inputs, mut validation) = match (&options.holdout, options.validate) {
        (Some(_), Some(_)) => bail!("use either --validate or --holdout, not both"),
        (Some(path), None) => (
            all,
            Some(Inputs::load_with(&options.input.robot, path, &profile)?),
        ),
        (None, Some(fraction)) => {
            let (calibration, held) =
                crate::evaluate::split(&all, fraction, options.validate_seed)?;
            (calibration, Some(held))
        }
        (None, None) => (all, None),
    };
    let frames = Frames::chosen(options.frames, &inputs.data);
    let (frames_report, mut mask) = {
        let mut others: Vec<&mut Inputs> = validation.iter_mut().collect();
        crate::frames::prepare(frames, &mut inputs, &mut others, options.k)?
    };
    let mut identifiability =
        crate::with_parameter_count!(mask.count(), analyse(&inputs, &mask, options.k))?;
    let initial = identifiability.clone();
    let mut dropped = Vec::new();
    if identifiability.rank < identifiability.parameters {
        if !options.auto_mask {
            bail!(
                "the data cannot determine every identified parameter (rank {} of {}): {}. \
                 Drop them with --auto-mask, or set identify = [...] in the robot file; `calib check` shows the analysis",
                identifiability.rank,
                identifiability.parameters,
                identifiability.problem()
            );
        }
        for parameter in identifiability.to_drop() {
            mask.set(parameter, false);
            dropped.push(parameter.to_string());
        }
        identifiability =
            crate::with_parameter_count!(mask.count(), analyse(&inputs, &mask, options.k))?;
    }
    if options.auto_mask {
        while identifiability.ill_conditioned && mask.count() > 1 {
            let Some(parameter) = identifiability
                .weakest_direction
                .first()
                .and_then(|(name, _)| calib_core::Parameter::from_name(name, 6))
            else {
                break;
            };
            mask.set(parameter, false);
            dropped.push(parameter.to_string());
            identifiability =
                crate::with_parameter_count!(mask.count(), analyse(&inputs, &mask, options.k))?;
        }
    }
    // Report the analysis of the full set (it says why parameters were dropped), with the
    // condition number reached.
    if !dropped.is_empty() {
        let reached = identifiability.condition_number;
        identifiability = initial;
        identifiability.condition_number_after_drop = reached;
    }
    crate::with_parameter_count!(
        mask.count(),
        run(
            options,
            &inputs,
            validation.as_ref(),
            &mask,
            identifiability,
            dropped,
            frames_report
        )
    )
}

fn run<const D: usize>(
    options: &CalibrateOptions,
    inputs: &Inputs,
    validation: Option<&Inputs>,
    mask: &ParameterMask<6>,
    identifiability: IdentifiabilityReport,
    dropped: Vec<String>,
    mut frames: FramesReport,
) -> anyhow::Result<Calibration> {
    let (file, model, measurements) = (&inputs.file, &inputs.model, inputs.measurements.as_slice());
    let set = ParameterSet::<6, D>::from_mask(mask)?;
    let problem = Problem::new(
        &model.robot,
        &ParameterErrors::zero(),
        set,
        measurements,
        options.k,
    )?;
    let objective = Objective::new(&problem);
    let zero = SVector::<f64, D>::zeros();
    let mut outliers: Vec<Outlier> = Vec::new();
    let mut robust_weights = vec![1.0; measurements.len()];
    let started = Instant::now();
    let swarm = match options.method {
        Method::Ipso | Method::IpsoLm => Some(run_swarm(options, &objective, &set)?),
        Method::Lm => None,
    };
    let swarm_end = swarm.as_ref().map_or(zero, |s| s.result.best);
    let least_squares = match options.method {
        Method::Lm | Method::IpsoLm => {
            let least_squares = LeastSquares::new(&problem);
            let settings = LmSettings {
                max_iterations: options.lm_iterations,
                ..LmSettings::default()
            };
            let mut weights = vec![1.0; measurements.len()];
            let loss = options.loss.with_scale(options.loss_scale_mm);
            let robust = least_squares
                .solve_robust(&swarm_end, &settings, loss, &mut weights)
                .map_err(|e| lm_error(e, &set))?;
            robust_weights.clone_from(&weights);
            if options.loss != LossChoice::L2 {
                let mut norms = vec![0.0; measurements.len()];
                least_squares.pose_residual_norms(&robust.result.x, &mut norms);
                let poses = inputs.data.records.iter().zip(&norms).zip(&weights);
                for ((record, norm), weight) in poses {
                    if *norm > options.loss_scale_mm {
                        outliers.push(Outlier {
                            id: record.id.clone(),
                            line: record.line,
                            residual_mm: *norm,
                            weight: *weight,
                        });
                    }
                }
            }
            Some(robust.result)
        }
        Method::Ipso => None,
    };
    let seconds = started.elapsed().as_secs_f64();
    let best = least_squares.as_ref().map_or(swarm_end, |l| l.x);
    let standard_errors = least_squares.as_ref().and_then(LmResult::standard_errors);

    let identified = set.unpack(&best);
    let nominal = Kinematics::nominal(&model.robot).map_err(|e| anyhow::anyhow!("{e}"))?;
    let actual = Kinematics::new(&model.robot, &identified).map_err(|e| anyhow::anyhow!("{e}"))?;
    let (before, before_poses) = crate::evaluate::table3(&nominal, inputs);
    let (after, after_poses) = crate::evaluate::table3(&actual, inputs);
    let orientation_before = crate::evaluate::orientation_per_pose(&nominal, inputs);
    let orientation_after = crate::evaluate::orientation_per_pose(&actual, inputs);
    let (mut validation_before, mut validation_after) = (Vec::new(), Vec::new());
    let validation_stage = match validation {
        None => None,
        Some(v) => {
            let (before, per_pose_before) = crate::evaluate::table3(&nominal, v);
            let (after, per_pose_after) = crate::evaluate::table3(&actual, v);
            validation_before = per_pose_before;
            validation_after = per_pose_after;
            Some(Stage {
                poses: v.measurements.len(),
                before,
                after,
            })
        }
    };
    let mut parameters = serde_json::Map::new();
    let mut std_error_list = Vec::new();
    for (i, (p, v)) in set.parameters().iter().zip(best.iter()).enumerate() {
        let mut entry = serde_json::json!({ "value": v, "unit": unit_of(*p) });
        if let Some(se) = standard_errors.as_ref().and_then(|s| s.get(i)) {
            entry["std_error"] = serde_json::json!(se);
            std_error_list.push((*p, *se));
        }
        parameters.insert(p.to_string(), entry);
    }
    let truth = match &options.truth {
        None => None,
        Some(path) => {
            let truth_file = RobotFile::read(path)?;
            let truth_errors = truth_file.calibration_errors::<6>(path)?;
            Some(
                set.parameters()
                    .iter()
                    .map(|p| {
                        TruthRow::new(
                            *p,
                            identified.get(*p).unwrap_or(0.0),
                            truth_errors.get(*p).unwrap_or(0.0),
                        )
                    })
                    .collect::<Vec<_>>(),
            )
        }
    };
    let initial = objective.value(&zero);
    let final_objective = objective.value(&best);
    let mut text = format!(
        "calibrated {} with {} poses of {} by {} in {seconds:.3} s\n",
        model.name,
        measurements.len(),
        options.input.data.display(),
        options.method.name(),
    );
    if let Some(s) = &swarm {
        text.push_str(&format!(
            "  IPSO: {} particles, {} generations ({}), {} evaluations, objective {:.6e} -> {:.6e}\n",
            options.swarm,
            s.result.generations,
            swarm_stop(s.result.stop),
            s.result.evaluations,
            initial,
            s.result.best_cost
        ));
    }
    if let Some(l) = &least_squares {
        text.push_str(&format!(
            "  least squares: {} iterations ({}), 0.5 |r|^2 {:.6e} -> {:.6e}, residual sigma {:.4e} mm\n",
            l.iterations,
            lm_stop(l.stop),
            l.initial_cost,
            l.cost,
            l.sigma()
        ));
    }
    text.push_str(&format!(
        "  identifiability: {} parameters, rank {}, scaled condition number {}\n",
        identifiability.parameters,
        identifiability.rank,
        identifiability
            .condition_number
            .map_or_else(|| "infinite".to_string(), |c| format!("{c:.3e}"))
    ));
    if identifiability.ill_conditioned && dropped.is_empty() {
        text.push_str("  ");
        text.push_str(&identifiability.ill_conditioned_text());
    }
    if !dropped.is_empty() {
        text.push_str(&format!(
            "  --auto-mask dropped {} ({}scaled condition number {} -> {})\n",
            dropped.join(", "),
            if identifiability.undetermined.is_empty() {
                String::new()
            } else {
                format!("the data cannot determine {}; ", identifiability.problem())
            },
            identifiability
                .condition_number
                .map_or_else(|| "infinite".to_string(), |c| format!("{c:.3e}")),
            identifiability
                .condition_number_after_drop
                .map_or_else(|| "infinite".to_string(), |c| format!("{c:.3e}")),
        ));
    }
    if frames.identified != "none" {
        text.push_str(&format!(
            "  frames: {} identified; registration of the nominal robot {:.3} mm RMS ({:.3} mm max), \
             nominal geometry with fitted frames {:.3} mm RMS; not identified (the frames absorb them): {}\n",
            frames.identified,
            frames.registration_rms_mm,
            frames.registration_max_mm,
            frames.frames_fit_rms_mm,
            if frames.redundant_with_frames.is_empty() {
                "none".to_string()
            } else {
                frames.redundant_with_frames.join(", ")
            }
        ));
    }
    if options.loss != LossChoice::L2 {
        let ids: Vec<String> = outliers
            .iter()
            .map(|o| format!("{} (line {}, {:.3} mm)", o.id, o.line, o.residual_mm))
            .collect();
        text.push_str(&format!(
            "  {:?} loss, scale {} mm: {} outlier pose(s){}{}\n",
            options.loss,
            options.loss_scale_mm,
            outliers.len(),
            if ids.is_empty() { "" } else { ": " },
            ids.join(", ")
        ));
    }
    text.push_str(&format!(
        "objective (eq. 7, k = {:e} mm^2/rad^2): {initial:.6e} at the nominal model -> {final_objective:.6e}\n\n",
        options.k
    ));
    let before_note = if frames.identified == "none" {
        ""
    } else {
        "; before = nominal geometry with the frames fitted"
    };
    text.push_str(&table3_text(
        &format!("Table 3 statistics on the calibration poses{before_note}"),
        &before,
        &after,
    ));
    if let Some(stage) = &validation_stage {
        text.push('\n');
        text.push_str(&table3_text(
            &format!("Table 3 statistics on the validation poses (held out, not used to calibrate{before_note})"),
            &stage.before,
            &stage.after,
        ));
    }
    if let Some(rows) = &truth {
        text.push_str("\nidentified errors against the truth\n");
        text.push_str(&truth_text(rows));
    }
    let identified_file = file.with_errors(
        &identified,
        set.parameters().iter().copied(),
        &std_error_list,
        options.method.name(),
        &options.input.robot.display().to_string(),
    );
    if frames.identified != "none" {
        frames.base = identified_file.base.clone();
        if frames.identified == "base+tool" {
            frames.tool = identified_file.tool.clone();
        }
    }
    let robot_toml = identified_file.to_toml(&format!(
            "{} identified by calib calibrate ({}) from {}.\nValues are nominal + identified errors; [calibration.errors] lists the errors and [calibration.std_errors] their standard errors, in mm and rad.",
            model.name,
            options.method.name(),
            options.input.data.display()
        ));
    let swarm_evaluations = swarm.as_ref().map_or(0, |s| s.result.evaluations);
    let lm_evaluations = least_squares
        .as_ref()
        .map_or(0, |l| u64::from(l.evaluations));
    let stop = match (&least_squares, &swarm) {
        (Some(l), _) => lm_stop(l.stop),
        (None, Some(s)) => swarm_stop(s.result.stop),
        (None, None) => "",
    };
    let report = Report {
        method: options.method.name().into(),
        robot: options.input.robot.display().to_string(),
        data: options.input.data.display().to_string(),
        parameters,
        objective: ObjectiveValues {
            initial,
            r#final: final_objective,
            initial_swarm_best: swarm.as_ref().map_or(initial, |s| s.result.initial_cost),
            after_swarm: swarm.as_ref().map_or(initial, |s| s.result.best_cost),
            k: options.k,
        },
        generations: swarm.as_ref().map_or(0, |s| s.result.generations),
        evaluations: swarm_evaluations + lm_evaluations,
        stop: stop.into(),
        least_squares: least_squares.as_ref().map(|l| LeastSquaresReport {
            iterations: l.iterations,
            evaluations: l.evaluations,
            stop: lm_stop(l.stop).into(),
            cost_initial: l.initial_cost,
            cost_final: l.cost,
            rows: l.rows,
            sigma_mm: l.sigma(),
        }),
        identifiability,
        dropped,
        frames,
        outliers,
        poses: inputs
            .data
            .records
            .iter()
            .zip(before_poses.iter().zip(&after_poses))
            .zip(&robust_weights)
            .map(|((r, (b, a)), w)| PoseReport {
                id: r.id.clone(),
                line: r.line,
                before_mm: *b,
                after_mm: *a,
                robust_weight: *w,
            })
            .collect(),
        calibration: Stage {
            poses: measurements.len(),
            before,
            after,
        },
        validation: validation_stage,
        before,
        after,
        settings: serde_json::json!({
            "swarm": options.swarm, "generations": options.generations, "c1": options.c1, "c2": options.c2,
            "seed": options.seed, "init_angle_rad": options.init_angle_rad, "init_length_mm": options.init_length_mm,
            "bound_factor": options.bound_factor, "stall_generations": options.stall_generations,
            "target": options.target, "halton_start": options.halton_start,
            "scrambling": format!("{:?}", options.scrambling).to_lowercase(),
            "lm_iterations": options.lm_iterations,
            "loss": format!("{:?}", options.loss).to_lowercase(), "loss_scale_mm": options.loss_scale_mm,
            "auto_mask": options.auto_mask,
            "validate": options.validate, "validate_seed": options.validate_seed,
            "holdout": options.holdout.as_ref().map(|p| p.display().to_string()),
        }),
        truth,
        seconds,
    };
    Ok(Calibration {
        report,
        robot_toml,
        text,
        history: swarm.map(|s| s.history).unwrap_or_default(),
        before: before_poses,
        after: after_poses,
        orientation_before,
        orientation_after,
        validation_before,
        validation_after,
    })
}

/// A swarm run and its convergence history.
struct SwarmOutcome<const D: usize> {
    result: ipso::IpsoResult<f64, D>,
    history: Vec<(u32, f64)>,
}

fn run_swarm<const D: usize>(
    options: &CalibrateOptions,
    objective: &Objective<'_, f64, 6, D>,
    set: &ParameterSet<6, D>,
) -> anyhow::Result<SwarmOutcome<D>> {
    let space = SearchSpace::for_parameters(
        set,
        options.init_angle_rad,
        options.init_length_mm,
        options.bound_factor,
    );
    let settings = IpsoSettings {
        c1: options.c1,
        c2: options.c2,
        max_generations: options.generations,
        target_cost: options.target,
        stall_generations: options.stall_generations,
        halton_start: options.halton_start,
        scrambling: options.scrambling.into(),
        seed: options.seed,
    };
    let bar = if !options.quiet && std::io::stderr().is_terminal() {
        indicatif::ProgressBar::new(u64::from(options.generations))
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "IPSO {bar:40} {pos}/{len} generations, best f = {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut history = Vec::with_capacity(options.generations as usize + 1);
    let mut observer = |generation: u32, best: f64| {
        history.push((generation, best));
        if generation.is_multiple_of(20) {
            bar.set_position(u64::from(generation));
            bar.set_message(format!("{best:.6e}"));
        }
        Control::Continue
    };
    let mut cost = Parallel(objective);
    macro_rules! swarm {
        ($($p:literal)*) => {
            match options.swarm {
                $($p => ipso::optimize::<f64, $p, D>(&mut cost, &space, &settings, &mut observer)?,)*
                other => bail!("--swarm {other} is not available"),
            }
        };
    }
    let result = swarm!(10 20 30 40 50 100);
    bar.finish_and_clear();
    Ok(SwarmOutcome { result, history })
}

fn swarm_stop(stop: StopReason) -> &'static str {
    match stop {
        StopReason::MaxGenerations => "maximum generations",
        StopReason::TargetReached => "target objective reached",
        StopReason::Stalled => "no improvement",
        StopReason::Cancelled => "cancelled",
    }
}

fn lm_stop(stop: LmStop) -> &'static str {
    match stop {
        LmStop::ZeroResidual => "zero residual",
        LmStop::Gradient => "gradient below tolerance",
        LmStop::Step => "step below tolerance",
        LmStop::CostChange => "cost change below tolerance",
        LmStop::MaxIterations => "iteration cap",
        LmStop::NoProgress => "no further progress (rounding floor)",
    }
}

/// A least-squares error in the user's terms (parameter names, not indices).
fn lm_error<const D: usize>(error: LmError, set: &ParameterSet<6, D>) -> anyhow::Error {
    match error {
        LmError::UnobservableParameter(i) => {
            let name = set
                .parameters()
                .get(usize::from(i))
                .map(ToString::to_string)
                .unwrap_or_default();
            anyhow::anyhow!(
                "the data cannot determine {name}: it changes no residual; remove it from the identified parameters"
            )
        }
        other => anyhow::anyhow!("least squares: {other}"),
    }
}

/// Writes the outputs of a calibration that were asked for (each atomically).
pub fn write_outputs(
    calibration: &Calibration,
    options: &CalibrateOptions,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    if let Some(path) = &options.out {
        write_atomic(path, calibration.robot_toml.as_bytes())?;
        written.push(path.clone());
    }
    if let Some(path) = &options.report {
        let json = serde_json::to_string_pretty(&calibration.report)?;
        write_atomic(path, json.as_bytes())?;
        written.push(path.clone());
    }
    if let Some(dir) = &options.plot {
        written.extend(crate::plots::write_plots(
            dir,
            &crate::plots::PlotData {
                history: &calibration.history,
                title: "absolute position error per calibration pose",
                before: &calibration.before,
                after: &calibration.after,
                orientation_before: &calibration.orientation_before,
                orientation_after: &calibration.orientation_after,
                validation_before: &calibration.validation_before,
                validation_after: &calibration.validation_after,
            },
        )?);
    }
    Ok(written)
}
