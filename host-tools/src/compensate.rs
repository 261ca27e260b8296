//! Compensation of target poses with an identified robot, off line: for each target, the joints
//! that put the actual (identified) robot on it, started from the controller's nominal joints
//! (given, or the closed-form nominal inverse kinematics on a branch).

use crate::JOINTS;
use crate::tracker_data::TrackerData;
use anyhow::Context;
use calib_core::controller::compensate::{Compensated, CompensationSettings, compensate_joints};
use calib_core::kinematics::ik::inverse_kinematics;
use calib_core::{Kinematics, Pose, Robot};
use nalgebra::{Rotation3, Translation3};

/// The outcome for one target.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetOutcome {
    /// The target's id.
    pub id: String,
    /// The compensated joints (rad) and predicted residuals, or why the target was refused.
    pub result: Result<Compensated<f64, JOINTS>, String>,
}

/// Counts of a compensation run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Summary {
    /// Targets compensated.
    pub ok: usize,
    /// Targets refused with an error.
    pub failed: usize,
}

impl Summary {
    /// The counts of `outcomes`.
    pub fn of(outcomes: &[TargetOutcome]) -> Self {
        let ok = outcomes.iter().filter(|o| o.result.is_ok()).count();
        Self {
            ok,
            failed: outcomes.len() - ok,
        }
    }
}

/// Compensates every target of `targets` (base frame, with orientation; joints, when the file
/// has `q1_deg..q6_deg`, are the start): `nominal` is the model the controller plans with,
/// `actual` the identified robot. `branch` (0-7) picks the inverse kinematics solution for
/// targets without joints. One outcome per target, in file order.
pub fn compensate_targets(
    nominal: &Robot<f64, JOINTS>,
    actual: &Robot<f64, JOINTS>,
    targets: &TrackerData,
    settings: &CompensationSettings<f64>,
    branch: usize,
) -> anyhow::Result<Vec<TargetOutcome>> {
    let planned = Kinematics::nominal(nominal).context("nominal robot")?;
    let real = Kinematics::nominal(actual).context("identified robot")?;
    let outcomes = targets
        .records
        .iter()
        .map(|record| {
            let rotation = record.rotation.unwrap_or_else(nalgebra::Matrix3::identity);
            let target = Pose::from_parts(
                Translation3::from(nalgebra::Vector3::from(record.position)),
                Rotation3::from_matrix_unchecked(rotation),
            );
            let start = if targets.joints == JOINTS {
                Ok(std::array::from_fn(|i| {
                    record.q.get(i).copied().unwrap_or(0.0)
                }))
            } else {
                // The controller's plan: closed-form nominal inverse kinematics on the branch.
                inverse_kinematics(nominal, &target)
                    .map_err(|e| e.to_string())
                    .and_then(|solutions| {
                        solutions
                            .get(branch)
                            .copied()
                            .flatten()
                            .ok_or_else(|| format!("target out of reach on branch {branch}"))
                    })
            };
            let result = start.and_then(|start| {
                compensate_joints(&planned, &real, &nominal.limits, &target, &start, settings)
                    .map_err(|e| e.to_string())
            });
            TargetOutcome {
                id: record.id.clone(),
                result,
            }
        })
        .collect();
    Ok(outcomes)
}

/// The outcomes as CSV: `id, q1_deg..q6_deg, residual_mm, residual_deg, status` (`ok` or the
/// error; a refused target leaves the other columns empty).
pub fn to_csv(outcomes: &[TargetOutcome]) -> anyhow::Result<Vec<u8>> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["id".to_string()];
    header.extend((1..=JOINTS).map(|i| format!("q{i}_deg")));
    header.extend(["residual_mm", "residual_deg", "status"].map(String::from));
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
                row.extend(std::iter::repeat_n(String::new(), 8));
                row.push(e.clone());
            }
        }
        writer.write_record(&row)?;
    }
    Ok(writer.into_inner()?)
}
