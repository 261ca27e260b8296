//! The evaluation stage: a model's Table 3 on the calibration and held-out poses and per pose,
//! the held-out accuracy as a certificate states it (percentiles, ISO 9283, the workspace map),
//! and the held-out poses against the band the parameters' covariance predicts. Each model a
//! calibration returns is evaluated here once.

use super::{PerPose, PoseReport, Stage};
use crate::analysis::accuracy::{HeldOutAccuracy, Iso9283};
use crate::measurement::dataset::Seen;
use calib_core::{Kinematics, ParameterErrors, ParameterSet};
use nalgebra::Dyn;

/// A model's statistics on the calibration and held-out poses.
pub(crate) struct Evaluation {
    /// Table 3 on the calibration poses, nominal and identified.
    pub calibration: Stage,
    /// And on the held-out poses.
    pub validation: Option<Stage>,
    /// Per-pose errors.
    pub per_pose: PerPose,
    /// Every calibration pose with its errors and robust weight.
    pub poses: Vec<PoseReport>,
}

/// Table 3 before (the nominal geometry on the poses as `nominal` sees them: the registered
/// frames, the compliance taken off at the geometric fit) and after (the geometry with `errors`
/// on the poses as `model` sees them: with joint maps, their readings mapped) on the calibration
/// and held-out poses, per-pose errors, and the calibration poses' report rows with their robust
/// weights (`weights`, empty: all 1).
pub(crate) fn evaluate(
    nominal: (&Seen<'_>, Option<&Seen<'_>>),
    (model, model_validation, errors): (&Seen<'_>, Option<&Seen<'_>>, &ParameterErrors<f64, Dyn>),
    weights: &[f64],
) -> crate::Result<Evaluation> {
    use crate::measurement::statistics::{orientation_per_pose, signed_errors, table3};
    let (dataset, validation) = nominal;
    let nominal = Kinematics::nominal(&dataset.robot.model.robot)?;
    let actual = Kinematics::new(&model.robot.model.robot, errors)?;
    let (before, before_poses) = table3(&nominal, dataset.measurements());
    let (after, after_poses) = table3(&actual, model.measurements());
    let mut per_pose = PerPose {
        orientation_before: orientation_per_pose(&nominal, dataset),
        orientation_after: orientation_per_pose(&actual, model),
        ..PerPose::default()
    };
    let validation_stage = match (validation, model_validation) {
        (Some(v), Some(m)) => {
            let (before, per_pose_before) = table3(&nominal, v.measurements());
            let (after, per_pose_after) = table3(&actual, m.measurements());
            per_pose.validation_before = per_pose_before;
            per_pose.validation_after = per_pose_after;
            per_pose.validation_before_xyz =
                signed_errors(&nominal, &v.robot.model.robot, v.measurements());
            per_pose.validation_after_xyz =
                signed_errors(&actual, &m.robot.model.robot, m.measurements());
            per_pose.validation_lines = v.data.records.iter().map(|r| r.line).collect();
            Some(Stage {
                poses: v.measurements().len(),
                before,
                after,
            })
        }
        _ => None,
    };
    let poses = (dataset.data.records.iter())
        .zip(before_poses.iter().zip(&after_poses))
        .enumerate()
        .map(|(i, (r, (b, a)))| PoseReport {
            id: r.id.clone(),
            line: r.line,
            before_mm: *b,
            after_mm: *a,
            robust_weight: weights.get(i).copied().unwrap_or(1.0),
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
    Ok(Evaluation {
        calibration,
        validation: validation_stage,
        per_pose,
        poses,
    })
}

/// The accuracy on the held-out poses of `validation` (as the registered geometry sees them)
/// after calibration to `errors`: percentiles and per axis, ISO 9283's figures, and the map of
/// their error over the workspace (with the predicted error of each pose, `predicted_rms_mm`,
/// when the covariance is known: empty otherwise). Places the poses in `per_pose`
/// (`validation_position_mm`, `validation_predicted_rms_mm`).
pub(crate) fn held_out_accuracy(
    per_pose: &mut PerPose,
    validation: &Seen<'_>,
    errors: &ParameterErrors<f64, Dyn>,
    predicted_rms_mm: Vec<f64>,
) -> crate::Result<Option<HeldOutAccuracy>> {
    let poses: Vec<(String, u64)> = (validation.data.records.iter())
        .map(|r| (r.id.clone(), r.line))
        .collect();
    let mut held_out = HeldOutAccuracy::of(
        &poses,
        &per_pose.validation_before_xyz,
        &per_pose.validation_after_xyz,
    );
    if let Some(held) = held_out.as_mut() {
        let q: Vec<Vec<f64>> = (validation.data.records.iter())
            .map(|r| r.q.clone())
            .collect();
        held.iso9283 = Iso9283::of(
            &q,
            &per_pose.validation_lines,
            &per_pose.validation_after_xyz,
        );
    }
    let actual = Kinematics::new(&validation.robot.model.robot, errors)?;
    per_pose.validation_position_mm = crate::measurement::statistics::base_positions(
        &actual,
        &validation.robot.model.robot,
        validation.measurements(),
    );
    per_pose.validation_predicted_rms_mm = predicted_rms_mm;
    if let Some(held) = held_out.as_mut() {
        held.workspace = crate::analysis::workspace::WorkspaceMap::of(
            &per_pose.validation_position_mm,
            &per_pose.validation_after,
            &per_pose.validation_lines,
            Some(&per_pose.validation_predicted_rms_mm)
                .filter(|p| !p.is_empty())
                .map(|p| p.as_slice()),
        );
    }
    Ok(held_out)
}

/// The held-out poses of `validation` against the 95 % band of the model `errors` predicted from
/// the parameters' `covariance` (in the order of `set`) and the instrument's noise: the one the data
/// profile states (`[instrument]`, at each point's distance from the tracker; the covariance then
/// scaled from the fit's residual sigma to the instrument's noise on the calibration poses of
/// `dataset`), else the fit's residual sigma.
pub(crate) fn held_out_coverage(
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
    // Each pose's error, and its distance from the base: the predicted point less the base
    // frame's origin (one forward kinematics for both).
    let base = nalgebra::Vector3::from(validation.robot.model.robot.base.xyz);
    let (poses, reach): (Vec<_>, Vec<f64>) = (validation.measurements().iter())
        .zip(&validation.data.records)
        .map(|(m, r)| {
            let predicted = actual.forward_angles(&m.angles);
            let error = m.error_of(&predicted).position;
            let reach = (predicted.translation.vector - base).norm();
            ((m.angles, error, r.line, noise(validation, m)), reach)
        })
        .unzip();
    let instrument_rms =
        (poses.iter().map(|p| p.3 * p.3).sum::<f64>() / poses.len().max(1) as f64).sqrt();
    let described = instrument.map(|i| {
        format!(
            "{}: MPE {} um + {} um/m",
            i.name.as_deref().unwrap_or("the data profile's instrument"),
            i.mpe_um,
            i.mpe_um_per_m
        )
    });
    Ok(
        crate::analysis::uncertainty::coverage((&actual, set, &covariance), &poses, source).map(
            |mut c| {
                c.reach_mm = reach;
                c.instrument = described.map(|d| (instrument_rms, d));
                c
            },
        ),
    )
}
