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
use calib_core::model::paper;
use calib_core::model::parameters::all_parameters;
use calib_core::{Kinematics, ParameterErrors};
use rand::RngExt;
use rand_core::SeedableRng;
use rand_distr::{Distribution, Normal, Uniform};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::path::PathBuf;

/// Which errors the simulated robot has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TrueErrors {
    /// Table 2 of the paper (the ER10L-C10's 24 identified parameters).
    Table2,
    /// Uniform random errors of the identified parameters (see --random-length-mm,
    /// --random-angle-rad).
    Random,
}

/// `calib simulate` arguments of the realistic cell used by the demo, the frames tests and the
/// calibration benchmark: the robot base seen from a tracker about 3 m away, turned arbitrarily,
/// and a reflector 150 mm off the flange.
pub const REALISTIC_CELL: [&str; 6] = [
    "--tracker-xyz-mm",
    "2500,-1500,600",
    "--tracker-rpy-deg",
    "5,-3,140",
    "--tool-xyz-mm",
    "0,60,137.4773",
];

/// Settings of a simulation: the options of `calib simulate`.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Simulation {
    /// Nominal robot model file.
    #[arg(
        long,
        value_name = "FILE",
        default_value = "host-tools/robots/er10l-c10.toml"
    )]
    pub robot: PathBuf,
    /// True errors: the paper's Table 2, or random ones.
    #[arg(long, value_enum, default_value_t = TrueErrors::Table2)]
    pub errors: TrueErrors,
    /// Half range of random length errors, mm (with --errors random).
    #[arg(long, default_value_t = 0.5)]
    pub random_length_mm: f64,
    /// Half range of random angle errors, rad (with --errors random).
    #[arg(long, default_value_t = 0.01)]
    pub random_angle_rad: f64,
    /// Number of poses.
    #[arg(long, default_value_t = 32)]
    pub poses: usize,
    /// Draw joints within the robot file's limits instead of uniformly in [-180, 180] deg.
    #[arg(long)]
    pub within_limits: bool,
    /// Half range (rad) of uniform noise added to the commanded joints before the true pose is
    /// computed. The paper uses 0.1 rad, which taken literally moves the tool by about 100 mm:
    /// errors no geometric calibration can remove. Default 0.
    #[arg(long, default_value_t = 0.0)]
    pub joint_noise_rad: f64,
    /// Tracker position noise, standard deviation per axis, mm.
    #[arg(long, default_value_t = 0.0)]
    pub position_sigma_mm: f64,
    /// Tracker orientation noise, standard deviation per axis, rad.
    #[arg(long, default_value_t = 0.0)]
    pub orientation_sigma_rad: f64,
    /// Write position-only data (a spherical reflector) instead of full 6-DoF poses.
    #[arg(long)]
    pub position_only: bool,
    /// Where the tracker sees the robot's base: the base frame's position in the tracker frame,
    /// mm (x,y,z). Without it (and --tracker-rpy-deg) the data are in the base frame.
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub tracker_xyz_mm: Option<Vec<f64>>,
    /// The base frame's orientation in the tracker frame, roll,pitch,yaw in degrees
    /// (R = Rz(yaw) Ry(pitch) Rx(roll)).
    #[arg(
        long,
        value_name = "R,P,Y",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub tracker_rpy_deg: Option<Vec<f64>>,
    /// The measured point (reflector) or probe frame on the flange: offset in mm (x,y,z in the
    /// flange frame). Default: the robot file's tool.
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub tool_xyz_mm: Option<Vec<f64>>,
    /// Seed of all random draws.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Tracker data output (CSV).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// True robot output (robot file with a `[calibration]` section of the true errors).
    #[arg(long, value_name = "FILE")]
    pub truth_out: PathBuf,
}

/// The outcome of a simulation: the rows written and the true errors.
pub struct Simulated {
    /// The poses as written.
    pub rows: Vec<PoseRow>,
    /// The true parameter errors.
    pub errors: ParameterErrors<f64, 6>,
}

/// Runs a simulation and writes the tracker CSV to `settings.out` and the true robot to
/// `settings.truth_out`.
pub fn simulate(settings: &Simulation) -> anyhow::Result<Simulated> {
    let (data_out, truth_out) = (&settings.out, &settings.truth_out);
    let mut file = RobotFile::read(&settings.robot)?;
    let triple = |v: &Option<Vec<f64>>, name: &str| -> anyhow::Result<Option<[f64; 3]>> {
        match v {
            None => Ok(None),
            Some(v) => match v.as_slice() {
                [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Some([*x, *y, *z])),
                _ => bail!("{name} needs three finite numbers, got {v:?}"),
            },
        }
    };
    let tracker_xyz = triple(&settings.tracker_xyz_mm, "--tracker-xyz-mm")?;
    let tracker_rpy = triple(&settings.tracker_rpy_deg, "--tracker-rpy-deg")?;
    let in_tracker_frame = tracker_xyz.is_some() || tracker_rpy.is_some();
    if in_tracker_frame {
        file.base = Some(crate::robot_file::FrameEntry {
            xyz_mm: tracker_xyz.unwrap_or([0.0; 3]),
            rpy_deg: tracker_rpy.unwrap_or([0.0; 3]),
        });
    }
    if let Some(xyz) = triple(&settings.tool_xyz_mm, "--tool-xyz-mm")? {
        let rpy_deg = file.tool.as_ref().map_or([0.0; 3], |t| t.rpy_deg);
        file.tool = Some(crate::robot_file::FrameEntry {
            xyz_mm: xyz,
            rpy_deg,
        });
    }
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
        TrueErrors::Random => {
            let (length_mm, angle_rad) = (settings.random_length_mm, settings.random_angle_rad);
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
        TrueErrors::Random => format!(
            "random, uniform within +-{} mm and +-{} rad",
            settings.random_length_mm, settings.random_angle_rad
        ),
    };
    let comments = vec![
        if in_tracker_frame {
            "measurements in the tracker's frame (the truth file's [base] is the robot base in it)"
                .to_string()
        } else {
            "frame: base".to_string()
        },
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
