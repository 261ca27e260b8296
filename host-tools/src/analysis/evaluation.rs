//! A model on data from another session: Table 3 of a robot file (nominal or identified) on
//! measured poses, after fitting only the frames of the measurement setup (the tracker's position
//! and the reflector or probe) when the data are in a tracker's frame. The geometry is never
//! changed. Poses used to fit the frames can be kept out of the statistics.

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

/// Evaluates the dataset's robot on its poses. With `frames` `base` or `base+tool`, the frames
/// are registered and fitted first with the geometry fixed: on `fit_poses` poses chosen at random
/// with `seed` as `calib calibrate --validate` chooses its calibration poses (then kept out of the
/// statistics), or on all poses (then the statistics include
/// them, which flatters the model). With only the base fitted, an identified file's probe stays
/// the tool (`probe_kept`).
pub fn evaluate(
    dataset: &Dataset,
    frames: Frames,
    fit_poses: Option<usize>,
    seed: u64,
) -> crate::Result<Evaluation> {
    let k = calib_core::identify::objective::DEFAULT_K;
    let zero = calib_core::ParameterErrors::zeros_for(dataset.model.robot.joint_count());
    let n = dataset.measurements.len();
    let with_probe;
    let dataset = match crate::measurement::frames::with_identified_probe(dataset, frames)? {
        Some(kept) => {
            with_probe = kept;
            &with_probe
        }
        None => dataset,
    };
    if frames == Frames::None {
        if fit_poses.is_some() {
            return Err(crate::refused!(
                "--fit-poses needs frames to fit: the data are evaluated in the base frame (--fit-frames none)"
            ));
        }
        return in_the_base_frame(dataset);
    }
    let (mut fitting, mut evaluated, separate) = match fit_poses {
        Some(count) => {
            if count < 3 || count >= n {
                return Err(crate::refused!(
                    "--fit-poses {count}: give at least 3 poses to fit the frames and leave at least one of the {n} poses to evaluate"
                ));
            }
            // The same choice as `calib calibrate --validate (n - count) / n --validate-seed seed`.
            let (fitting, evaluated) =
                crate::measurement::dataset::split(dataset, (n - count) as f64 / n as f64, seed)?;
            (fitting, evaluated, true)
        }
        None => (dataset.clone(), dataset.clone(), false),
    };
    let (mut report, _) =
        crate::measurement::frames::prepare(frames, &mut fitting, &mut [&mut evaluated], k)?;
    if dataset.file.compliance.is_some() {
        // The frames again, on the poses with the compliance taken off (evaluated in the frames
        // just fitted: its direction of gravity and lever arms), so that they do not absorb it.
        let robot = fitting.model.robot;
        let (mut fitting_seen, mut evaluated_seen) = match fit_poses {
            Some(count) => crate::measurement::dataset::split(
                &dataset.without_file_compliance(&robot, &zero)?,
                (n - count) as f64 / n as f64,
                seed,
            )?,
            None => {
                let seen = dataset.without_file_compliance(&robot, &zero)?;
                (seen.clone(), seen)
            }
        };
        report = crate::measurement::frames::prepare(
            frames,
            &mut fitting_seen,
            &mut [&mut evaluated_seen],
            k,
        )?
        .0;
        (fitting, evaluated) = (fitting_seen, evaluated_seen);
    }
    let kinematics = Kinematics::nominal(&evaluated.model.robot)?;
    Ok(Evaluation {
        table: table3(&kinematics, &evaluated.measurements).0,
        frames: report,
        fitted_poses: fitting.measurements.len(),
        evaluated_poses: evaluated.measurements.len(),
        fitted_poses_evaluated: !separate,
    })
}

/// The evaluation of data in the robot's base frame: nothing fitted, every pose evaluated (the
/// robot file's gravity compliance, if any, taken off the measured poses).
fn in_the_base_frame(dataset: &Dataset) -> crate::Result<Evaluation> {
    let k = calib_core::identify::objective::DEFAULT_K;
    let zero = calib_core::ParameterErrors::zeros_for(dataset.model.robot.joint_count());
    let (report, _) =
        crate::measurement::frames::prepare(Frames::None, &mut dataset.clone(), &mut [], k)?;
    let kinematics = Kinematics::nominal(&dataset.model.robot)?;
    let seen = dataset.without_file_compliance(&dataset.model.robot, &zero)?;
    Ok(Evaluation {
        table: table3(&kinematics, &seen.measurements).0,
        frames: report,
        fitted_poses: 0,
        evaluated_poses: dataset.measurements.len(),
        fitted_poses_evaluated: false,
    })
}
