//! A model on data from another session: Table 3 of a robot file (nominal or identified) on
//! measured poses, after fitting only the frames of the measurement setup (the tracker's position
//! and the reflector or probe) when the data are in a tracker's frame. The geometry is never
//! changed. Poses used to fit the frames can be kept out of the statistics.

use crate::kinematics::actual::ActualRobot;
use crate::measurement::dataset::Dataset;
use crate::measurement::frames::{Frames, FramesReport};
use crate::measurement::statistics::{Table3, table3};
use calib_core::Kinematics;
use serde::Serialize;

/// Table 3 of a model on data, and how its frames were fitted.
#[derive(Clone, Debug, Serialize)]
pub struct Evaluation {
    /// The statistics, on the evaluated poses (at the top level of the JSON).
    #[serde(flatten)]
    pub table: Table3,
    /// The frames fitted (`none`: the data are in the base frame).
    pub frames: FramesReport,
    /// Poses used to fit the frames (0 with `none`).
    pub fitted_poses: usize,
    /// Poses the statistics are computed on.
    pub evaluated_poses: usize,
    /// `true` when the fitted poses are also among the evaluated poses.
    pub fitted_poses_evaluated: bool,
}

/// Where the frames of the measurement setup come from before a model is evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Registration {
    /// Registered and fitted on the poses, the geometry kept: these frames (`None`: base+tool,
    /// or none when the data say `# frame: base`; `calib evaluate --fit-frames`).
    Fit(Option<Frames>),
    /// The registration stored with an identified model (its `[measurement]` section: the
    /// tracker's view of the base and the probe; `calib evaluate --stored-registration`).
    Stored,
}

/// The poses that fit the frames: `count` of them chosen at random by `seed`, as `calib
/// calibrate --validate` chooses its calibration poses (`calib evaluate --fit-poses --seed`);
/// the statistics are then computed on the others.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FitPoses {
    /// Poses fitted (at least 3, fewer than the data's).
    pub count: usize,
    /// Seed of the choice.
    pub seed: u64,
}

/// Evaluates the model of `dataset`'s robot on its poses, the frames had as `registration` says,
/// fitted on `fit_poses` when given (on all poses otherwise: the statistics then flatter the
/// model). A stored registration is refused for a model without one, and with poses to fit.
pub fn evaluate_model(
    dataset: &Dataset,
    registration: Registration,
    fit_poses: Option<FitPoses>,
) -> crate::Result<Evaluation> {
    crate::model::counts::joint_count(dataset.robot.file.joint.len())?;
    let (robot, frames) = match registration {
        Registration::Stored => {
            if fit_poses.is_some() {
                return Err(crate::Error::conflict(
                    &["--stored-registration", "--fit-poses"],
                    "--stored-registration uses the model's own registration, and --fit-poses fits the frames: drop one of the two",
                ));
            }
            if dataset.robot.file.measurement.is_none() {
                return Err(crate::refused!(option "--stored-registration";
                    "--stored-registration: {} has no [measurement] section, no registration to use: give a model \
                     identified on tracker data (calibrate writes it), or fit the frames (--fit-frames)",
                    dataset.robot.model.path.display()
                ));
            }
            (dataset.robot.in_measurement_setup()?, Frames::None)
        }
        Registration::Fit(frames) => (dataset.robot.clone(), Frames::chosen(frames, &dataset.data)),
    };
    let (count, seed) = fit_poses.map_or((None, 0), |f| (Some(f.count), f.seed));
    evaluate(&robot, dataset, frames, count, seed)
}

/// Evaluates the model `robot` (the dataset's own, or that robot in its measurement setup) on
/// the poses of `dataset`. With `frames` `base` or `base+tool`, the frames
/// are registered and fitted first with the geometry fixed: on `fit_poses` poses chosen at random
/// with `seed` as `calib calibrate --validate` chooses its calibration poses (then kept out of the
/// statistics), or on all poses (then the statistics include
/// them, which flatters the model). With only the base fitted, an identified file's probe stays
/// the tool (`probe_kept`).
pub fn evaluate(
    robot: &ActualRobot,
    dataset: &Dataset,
    frames: Frames,
    fit_poses: Option<usize>,
    seed: u64,
) -> crate::Result<Evaluation> {
    let k = calib_core::identify::objective::DEFAULT_K;
    let n = dataset.readings.len();
    if frames == Frames::None {
        if fit_poses.is_some() {
            return Err(crate::refused!(option "--fit-poses";
                "--fit-poses needs frames to fit: the data are evaluated in the base frame (--fit-frames none)"
            ));
        }
        return in_the_base_frame(robot, dataset);
    }
    let parts;
    let (fitting, evaluated, separate) = match fit_poses {
        Some(count) => {
            if count < 3 || count >= n {
                return Err(crate::refused!(option "--fit-poses";
                    "--fit-poses {count}: give at least 3 poses to fit the frames and leave at least one of the {n} poses to evaluate"
                ));
            }
            // The same choice as `calib calibrate --validate (n - count) / n --validate-seed seed`.
            parts =
                crate::measurement::dataset::split(dataset, (n - count) as f64 / n as f64, seed)?;
            (&parts.0, &parts.1, true)
        }
        None => (dataset, dataset, false),
    };
    // The calibration's registration stage, on the poses that fit the frames.
    let crate::measurement::frames::RegisteredSetup {
        setup,
        robot,
        report,
        ..
    } = crate::measurement::frames::register_setup(robot, frames, fitting, k)?;
    let (robot, report, seen) = if robot.compliance.is_some() {
        // The frames again, from the given ones, on the poses with the compliance taken off
        // (evaluated in the frames just fitted: its direction of gravity and lever arms), so that
        // they do not absorb it.
        let zero = calib_core::ParameterErrors::zeros_for(robot.model.robot.joint_count());
        let without = fitting.seen_by_geometry(&robot, &zero)?;
        let (refitted, report, _) =
            crate::measurement::frames::prepare(frames, &without.for_robot(&setup), k)?;
        let seen = evaluated
            .seen_by_geometry(&robot, &zero)?
            .measurements
            .into_owned();
        (refitted, report, seen)
    } else {
        let seen = evaluated.seen_by(&robot)?.measurements.into_owned();
        (robot, report, seen)
    };
    let kinematics = Kinematics::nominal(&robot.model.robot)?;
    Ok(Evaluation {
        table: table3(&kinematics, &seen).0,
        frames: report,
        fitted_poses: fitting.readings.len(),
        evaluated_poses: evaluated.readings.len(),
        fitted_poses_evaluated: !separate,
    })
}

/// The evaluation of data in the robot's base frame: nothing fitted, every pose evaluated (the
/// gravity compliance of `robot`, if any, taken off the measured poses).
fn in_the_base_frame(robot: &ActualRobot, dataset: &Dataset) -> crate::Result<Evaluation> {
    let k = calib_core::identify::objective::DEFAULT_K;
    let zero = calib_core::ParameterErrors::zeros_for(robot.model.robot.joint_count());
    let (_, report, _) =
        crate::measurement::frames::prepare(Frames::None, &dataset.seen_by(robot)?, k)?;
    let kinematics = Kinematics::nominal(&robot.model.robot)?;
    let seen = dataset.seen_by_geometry(robot, &zero)?;
    Ok(Evaluation {
        table: table3(&kinematics, seen.measurements.as_ref()).0,
        frames: report,
        fitted_poses: 0,
        evaluated_poses: dataset.readings.len(),
        fitted_poses_evaluated: false,
    })
}
