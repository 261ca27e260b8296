//! The solve stage: the geometry's errors identified from the calibration poses (the paper's
//! swarm, least squares, or both), with a robot's gravity compliance held fixed, and what the fit
//! says of itself: the parameters' covariance and significance, the robust loss's outliers, the
//! cross-validation of the identification. Nothing is evaluated here (see
//! [`super::evaluation`]).

use super::{
    CalibrationConfig, IdentifiedParameter, LeastSquaresReport, LossChoice, ObjectiveValues,
    Outlier, Selection, SwarmSummary,
};
use crate::kinematics::actual::ActualRobot;
use crate::measurement::dataset::{Dataset, Seen};
use crate::runtime::lanes::LaneObjective;
use crate::runtime::swarm_team::{SwarmTeam, team_size};

use calib_core::identify::ipso::{self, Control, IpsoSettings, SearchSpace};
use calib_core::identify::lm::{LeastSquares, LmError, LmResult, LmSettings};
use calib_core::identify::objective::Objective;
use calib_core::{ParameterErrors, ParameterSet, Problem};
use nalgebra::{DVector, Dyn};
use std::io::IsTerminal;
use std::time::Instant;

/// Fits of the geometry with a robot file's gravity compliance taken off the measurements, each
/// at the previous fit's geometry (see [`solve_geometry`]).
const COMPLIANCE_ROUNDS: usize = 2;

/// What the identification found for the geometry: the errors and their uncertainty, how the
/// swarm and least squares ran, and the cross-validation of the fit; nothing evaluated.
pub(crate) struct Identification {
    /// The identified parameters' set.
    pub set: ParameterSet<Dyn, Dyn>,
    /// The identified values with their standard errors (least squares), in the set's order.
    pub parameters: Vec<IdentifiedParameter>,
    /// All errors (identified ones set, others zero), mm and rad.
    pub errors: ParameterErrors<f64, Dyn>,
    /// The objective (eq. 7) before and after.
    pub objective: ObjectiveValues,
    /// The swarm, when it ran.
    pub swarm: Option<SwarmSummary>,
    /// Least squares, when it ran.
    pub least_squares: Option<LeastSquaresReport>,
    /// Poses beyond the robust loss's scale.
    pub outliers: Vec<Outlier>,
    /// The robust weight of every calibration pose (empty without least squares: all 1).
    pub weights: Vec<f64>,
    /// Wall-clock time of the identification, s.
    pub seconds: f64,
    /// The identified parameters' covariance (least squares), in the set's order.
    pub covariance: Option<nalgebra::DMatrix<f64>>,
    /// The parameters not shown to differ from zero and the correlated pairs (from it).
    pub significance: Option<crate::analysis::uncertainty::Significance>,
    /// The cross-validation of the identification on the calibration poses.
    pub cross_validation: Option<super::cross_validation::CrossValidation>,
}

/// The solve stage: the errors of `selection` identified for the geometry of `robot` (its frames
/// registered) from the poses of `dataset`, returned with the poses of `dataset` and `validation`
/// as the identified geometry's evaluation must see them. A robot's gravity compliance is part of
/// the model and held fixed: the geometry is fitted to the measured poses with its deflection
/// taken off, evaluated at the registered frames, then again at the first fit's errors (the
/// deflection depends on the geometry only through its small change).
pub(crate) fn solve_geometry<'a>(
    robot: &'a ActualRobot,
    (dataset, validation): (&'a Dataset, Option<&'a Dataset>),
    config: &CalibrationConfig,
    selection: &Selection,
) -> crate::Result<(Identification, Seen<'a>, Option<Seen<'a>>)> {
    if robot.compliance.is_none() {
        let calibration = dataset.seen_by(robot)?;
        let held_out = validation.map(|v| v.seen_by(robot)).transpose()?;
        let identification = solve(&calibration, config, selection)?;
        return Ok((identification, calibration, held_out));
    }
    // The rounds before the last only move the geometry the deflection is evaluated at: their
    // errors are all that is kept, so they are identified and nothing else (no covariance, no
    // cross-validation); the last round is the calibration.
    let mut errors = ParameterErrors::zeros_for(robot.model.robot.joint_count());
    for _ in 1..COMPLIANCE_ROUNDS {
        let calibration = dataset.seen_by_geometry(robot, &errors)?;
        errors = identified_errors(&calibration, config, selection)?;
    }
    let calibration = dataset.seen_by_geometry(robot, &errors)?;
    let held_out = (validation.map(|v| v.seen_by_geometry(robot, &errors))).transpose()?;
    let identification = solve(&calibration, config, selection)?;
    Ok((identification, calibration, held_out))
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

/// Identifies the parameters of `selection` on `dataset`: the errors, their covariance and
/// significance, the cross-validation of the identification.
fn solve(
    dataset: &Seen<'_>,
    config: &CalibrationConfig,
    selection: &Selection,
) -> crate::Result<Identification> {
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
    let covariance = fit.as_ref().and_then(|f| f.result.covariance());
    let significance = covariance.as_ref().map(|covariance| {
        crate::analysis::uncertainty::Significance::of(
            &(set.parameters().iter())
                .map(ToString::to_string)
                .collect::<Vec<_>>(),
            best.as_slice(),
            covariance,
        )
    });
    // Cross-validation with the loss scale of the fit (estimated or given).
    let cv_config = CalibrationConfig {
        loss_scale_mm: fit
            .as_ref()
            .and_then(|f| f.report.loss_scale_mm)
            .or(config.loss_scale_mm),
        ..config.clone()
    };
    let cross_validation = super::cross_validation::cross_validate(dataset, set, &cv_config);
    let initial = objective.value(&zero);
    let objective = ObjectiveValues {
        initial,
        r#final: objective.value(&best),
        initial_swarm_best: swarm.as_ref().map_or(initial, |s| s.initial_cost),
        after_swarm: swarm.as_ref().map_or(initial, |s| s.best_cost),
        k: config.k,
    };
    let (least_squares, outliers, weights) = match fit {
        Some(f) => (Some(f.report), f.outliers, f.weights),
        None => (None, Vec::new(), Vec::new()),
    };
    Ok(Identification {
        set: set.clone(),
        parameters,
        errors,
        objective,
        swarm: swarm.map(|s| s.summary),
        least_squares,
        outliers,
        weights,
        seconds,
        covariance,
        significance,
        cross_validation,
    })
}

/// The identified values of `set` with their standard errors, when least squares gave them.
pub(super) fn identified_parameters(
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
    let result = SwarmTeam::run(&lanes, team_size(cores(), particles), |team| {
        team.optimize(memory, &space, &settings, &mut observer)
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
    least_squares: &LeastSquares<'_, Problem<'_, f64, Dyn, Dyn>>,
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
        loss_scale_mm: scale,
        loss_scale_estimated: estimated.is_some(),
        outlier_position_mm: estimated.map(|e| e.position_mm),
        outlier_rotation_deg: estimated
            .map(|e| e.rotation_rad.to_degrees())
            .filter(|d| d.is_finite()),
        ..LeastSquaresReport::of(l)
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
/// One of the thresholds set from data (docs/RESULTS.md, "Thresholds set from data").
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
    least_squares: &LeastSquares<'_, Problem<'_, f64, Dyn, Dyn>>,
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
pub(super) fn lm_error(error: LmError, set: &ParameterSet<Dyn, Dyn>) -> crate::Error {
    match error {
        LmError::UnobservableParameter(i) => {
            let name = set
                .parameters()
                .get(usize::from(i))
                .map(ToString::to_string)
                .unwrap_or_default();
            crate::refused!(undetermined vec![name.to_string()];
                "the data cannot determine {name}: it changes no residual; remove it from the identified parameters"
            )
        }
        other => crate::Error::from(other).context("least squares"),
    }
}
