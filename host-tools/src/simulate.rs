//! `calib simulate`: the paper's simulation (section 3.1). The true robot is the nominal model plus
//! Table 2 (or random errors of given size); joints are drawn uniformly in [-180, 180] deg or
//! within the joint limits; the tracker measures the true pose, with optional Gaussian noise.
//!
//! The paper also adds uniform noise in [-0.1, 0.1] rad to the commanded joints before computing
//! the actual pose. Taken literally that moves the tool by about 100 mm, which no geometric
//! calibration can remove, so it is an option here (`--joint-noise-rad`), 0 by default.

use crate::robot_file::{RobotFile, RobotModel};
use crate::tracker_data::{PoseRow, write_tracker_csv};
use anyhow::{Context, bail};
use calib_core::parameters::all_parameters;
use calib_core::{Kinematics, ParameterErrors, paper};
use rand::RngExt;
use rand_core::SeedableRng;
use rand_distr::{Distribution, Normal, Uniform};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::path::{Path, PathBuf};

/// Which errors the simulated robot has.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TrueErrors {
    /// Table 2 of the paper (the ER10L-C10's 24 identified parameters).
    Table2,
    /// Uniform random errors of the identified parameters within +-length mm and +-angle rad.
    Random {
        /// Half range of length errors, mm.
        length_mm: f64,
        /// Half range of angle errors, rad.
        angle_rad: f64,
    },
}

/// Settings of a simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct Simulation {
    /// The nominal robot file.
    pub robot: PathBuf,
    /// The true errors.
    pub errors: TrueErrors,
    /// Number of poses.
    pub poses: usize,
    /// Draw joints within the robot's joint limits instead of [-180, 180] deg.
    pub within_limits: bool,
    /// Half range of the uniform commanded-joint noise, rad (paper: 0.1; default 0).
    pub joint_noise_rad: f64,
    /// Standard deviation of the tracker's position noise per axis, mm.
    pub position_sigma_mm: f64,
    /// Standard deviation of the tracker's orientation noise per axis, rad.
    pub orientation_sigma_rad: f64,
    /// Write position-only data (a spherical reflector) instead of full poses.
    pub position_only: bool,
    /// Seed of every random draw.
    pub seed: u64,
}

/// The outcome of a simulation: the rows written and the true errors.
pub struct Simulated {
    /// The poses as written.
    pub rows: Vec<PoseRow>,
    /// The true parameter errors.
    pub errors: ParameterErrors<f64, 6>,
}

/// Runs a simulation and writes the tracker CSV to `data_out` and the true robot to `truth_out`.
pub fn simulate(
    settings: &Simulation,
    data_out: &Path,
    truth_out: &Path,
) -> anyhow::Result<Simulated> {
    let file = RobotFile::read(&settings.robot)?;
    let model: RobotModel<6> = file.to_model(&settings.robot)?;
    if settings.poses == 0 {
        bail!("--poses must be at least 1");
    }
    for (name, v) in [
        ("--joint-noise-rad", settings.joint_noise_rad),
        ("--position-sigma-mm", settings.position_sigma_mm),
        ("--orientation-sigma-rad", settings.orientation_sigma_rad),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            bail!("{name} must be a finite number >= 0, got {v}");
        }
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(settings.seed);
    let errors = match settings.errors {
        TrueErrors::Table2 => paper::table2::<f64>(),
        TrueErrors::Random {
            length_mm,
            angle_rad,
        } => {
            let mut e = ParameterErrors::zero();
            for p in model.mask.iter() {
                let half = if p.is_angle() { angle_rad } else { length_mm };
                e.set(p, half * (2.0 * rng.random::<f64>() - 1.0));
            }
            e
        }
    };
    let truth = Kinematics::new(&model.robot, &errors).context("true model")?;
    let mut rows = Vec::with_capacity(settings.poses);
    let position_noise = Normal::new(0.0, settings.position_sigma_mm)?;
    let orientation_noise = Normal::new(0.0, settings.orientation_sigma_rad)?;
    for i in 0..settings.poses {
        let mut q = [0.0; 6];
        for (qi, limits) in q.iter_mut().zip(&model.robot.limits) {
            let (lo, hi) =
                if settings.within_limits && limits.lower.is_finite() && limits.upper.is_finite() {
                    (limits.lower, limits.upper)
                } else {
                    (-std::f64::consts::PI, std::f64::consts::PI)
                };
            *qi = Uniform::new_inclusive(lo, hi)?.sample(&mut rng);
        }
        // The robot moves to the commanded joints plus noise; the file records the commanded ones.
        let mut actual_q = q;
        if settings.joint_noise_rad > 0.0 {
            for a in &mut actual_q {
                *a += settings.joint_noise_rad * (2.0 * rng.random::<f64>() - 1.0);
            }
        }
        let pose = truth.forward(&actual_q)?;
        let mut position = [pose.translation.x, pose.translation.y, pose.translation.z];
        for p in &mut position {
            *p += position_noise.sample(&mut rng);
        }
        let rotation = (!settings.position_only).then(|| {
            let noise = nalgebra::Vector3::from_fn(|_, _| orientation_noise.sample(&mut rng));
            *(nalgebra::Rotation3::new(noise) * pose.rotation).matrix()
        });
        rows.push(PoseRow {
            id: format!("P{:03}", i + 1),
            q: q.to_vec(),
            position,
            rotation,
        });
    }
    let errors_text = match settings.errors {
        TrueErrors::Table2 => "Table 2 of the paper".to_string(),
        TrueErrors::Random {
            length_mm,
            angle_rad,
        } => {
            format!("random, uniform within +-{length_mm} mm and +-{angle_rad} rad")
        }
    };
    let comments = vec![
        "frame: base".to_string(),
        format!(
            "simulated by calib simulate: robot {}, errors {errors_text}, {} poses, joints {}",
            settings.robot.display(),
            settings.poses,
            if settings.within_limits {
                "within limits"
            } else {
                "uniform in [-180, 180] deg"
            }
        ),
        format!(
            "joint noise +-{} rad, tracker noise sigma {} mm and {} rad, seed {}",
            settings.joint_noise_rad,
            settings.position_sigma_mm,
            settings.orientation_sigma_rad,
            settings.seed
        ),
    ];
    let listed: Vec<_> = all_parameters::<6>()
        .filter(|p| model.mask.contains(*p) || errors.get(*p) != Some(0.0))
        .collect();
    let truth_file = file.with_errors(
        &errors,
        listed,
        &[],
        "simulated truth",
        &settings.robot.display().to_string(),
    );
    let truth_text = truth_file.to_toml(&format!(
        "True robot of a simulation: {} plus {errors_text}.\nErrors in mm (da, dd, translations) and rad (dalpha, dbeta, dtheta, rotations).",
        settings.robot.display()
    ));
    // Write nothing unless both outputs are ready; each write is atomic.
    write_tracker_csv(data_out, &comments, &rows)?;
    crate::files::write_atomic(truth_out, truth_text.as_bytes())?;
    Ok(Simulated { rows, errors })
}
