//! `calib compensate`: joints that put the identified (actual) robot on target poses.

use crate::files::write_atomic;
use crate::robot_file::RobotModel;
use crate::tracker_data::TrackerData;
use anyhow::{Context, bail};
use calib_core::controller::compensate::{CompensationSettings, compensate_joints};
use calib_core::kinematics::ik::inverse_kinematics;
use calib_core::{Kinematics, Pose};
use nalgebra::{Rotation3, Translation3};
use std::path::PathBuf;

/// Options of `calib compensate`.
#[derive(Clone, Debug, clap::Args)]
pub struct CompensateOptions {
    /// Nominal robot file: the model the controller plans with.
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// Identified robot file (from calib calibrate --out): the actual robot.
    #[arg(long, value_name = "FILE")]
    pub params: PathBuf,
    /// Target poses in the base frame (CSV: x_mm, y_mm, z_mm and an orientation; optional
    /// q1_deg..q6_deg as the start, i.e. the controller's nominal joints for the target; without
    /// them the closed-form nominal inverse kinematics on --branch is the start).
    #[arg(long, value_name = "FILE")]
    pub targets: PathBuf,
    /// Output CSV: one row per target, in input order.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Largest allowed change of the commanded pose, mm.
    #[arg(long, default_value_t = 5.0)]
    pub max_correction_mm: f64,
    /// Largest allowed change of the commanded orientation, deg.
    #[arg(long, default_value_t = 0.5)]
    pub max_correction_deg: f64,
    /// Largest allowed change of any joint, deg.
    #[arg(long, default_value_t = 0.5f64.to_degrees())]
    pub max_joint_correction_deg: f64,
    /// Inverse kinematics branch for targets without joints (closed form, spherical wrist):
    /// 0-7, bit 4 = shoulder back, bit 2 = elbow down, bit 1 = wrist flipped.
    #[arg(long, default_value_t = 0)]
    pub branch: usize,
}

/// Counts of a compensation run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Summary {
    /// Targets compensated.
    pub ok: usize,
    /// Targets refused with an error.
    pub failed: usize,
}

/// Runs `calib compensate`.
pub fn compensate(options: &CompensateOptions) -> anyhow::Result<Summary> {
    let nominal: RobotModel<6> = RobotModel::load(&options.robot)?;
    let actual: RobotModel<6> = RobotModel::load(&options.params)?;
    let targets = TrackerData::read_targets(&options.targets)?;
    if targets.rows_without_orientation() {
        bail!(
            "{}: targets need an orientation (qw..qz or rx_deg..rz_deg)",
            options.targets.display()
        );
    }
    if targets.joints != 0 && targets.joints != 6 {
        bail!(
            "{}: has {} joint columns; give all of q1_deg..q6_deg as start values, or none",
            options.targets.display(),
            targets.joints
        );
    }
    if options.branch > 7 {
        bail!("--branch must be 0 to 7, got {}", options.branch);
    }
    for (name, v) in [
        ("--max-correction-mm", options.max_correction_mm),
        ("--max-correction-deg", options.max_correction_deg),
        (
            "--max-joint-correction-deg",
            options.max_joint_correction_deg,
        ),
    ] {
        if !(v.is_finite() && v > 0.0) {
            bail!("{name} must be a finite number > 0, got {v}");
        }
    }
    let settings = CompensationSettings {
        max_correction_mm: options.max_correction_mm,
        max_correction_rad: options.max_correction_deg.to_radians(),
        max_joint_correction_rad: options.max_joint_correction_deg.to_radians(),
        ..CompensationSettings::default()
    };
    let planned = Kinematics::nominal(&nominal.robot).context("nominal robot")?;
    let real = Kinematics::nominal(&actual.robot).context("identified robot")?;
    let mut writer = csv::Writer::from_writer(Vec::new());
    let mut header = vec!["id".to_string()];
    header.extend((1..=6).map(|i| format!("q{i}_deg")));
    header.extend(["residual_mm", "residual_deg", "status"].map(String::from));
    writer.write_record(&header)?;
    let mut summary = Summary { ok: 0, failed: 0 };
    for record in &targets.records {
        let rotation = record.rotation.unwrap_or_else(nalgebra::Matrix3::identity);
        let target = Pose::from_parts(
            Translation3::from(nalgebra::Vector3::from(record.position)),
            Rotation3::from_matrix_unchecked(rotation),
        );
        let mut row = vec![record.id.clone()];
        let start = if targets.joints == 6 {
            Ok(std::array::from_fn(|i| {
                record.q.get(i).copied().unwrap_or(0.0)
            }))
        } else {
            // The controller's plan: closed-form nominal inverse kinematics on the chosen branch.
            inverse_kinematics(&nominal.robot, &target)
                .map_err(|e| e.to_string())
                .and_then(|solutions| {
                    solutions
                        .get(options.branch)
                        .copied()
                        .flatten()
                        .ok_or_else(|| format!("target out of reach on branch {}", options.branch))
                })
        };
        let result = start.and_then(|start| {
            compensate_joints(
                &planned,
                &real,
                &nominal.robot.limits,
                &target,
                &start,
                &settings,
            )
            .map_err(|e| e.to_string())
        });
        match result {
            Ok(c) => {
                row.extend(c.q.iter().map(|q| q.to_degrees().to_string()));
                row.push(format!("{:.6e}", c.residual_mm));
                row.push(format!("{:.6e}", c.residual_rad.to_degrees()));
                row.push("ok".into());
                summary.ok += 1;
            }
            Err(e) => {
                row.extend(std::iter::repeat_n(String::new(), 8));
                row.push(e);
                summary.failed += 1;
            }
        }
        writer.write_record(&row)?;
    }
    write_atomic(&options.out, &writer.into_inner()?)?;
    Ok(summary)
}
