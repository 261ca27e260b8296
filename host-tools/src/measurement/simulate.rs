//! The paper's simulation (section 3.1), in memory. The true robot is the nominal model plus
//! Table 2 (or random errors of given size); joints are drawn uniformly in [-180, 180] deg or
//! within the joint limits; the tracker measures the true pose, with optional Gaussian noise.
//!
//! The paper also adds uniform noise in [-0.1, 0.1] rad to the commanded joints before computing
//! the actual pose. Taken literally that moves the tool by about 100 mm, which no geometric
//! calibration can remove, so it is an option here (`--joint-noise-rad`), 0 by default.

use crate::JOINTS;
use crate::error::Context;
use crate::io::robot_file::FrameEntry;
use crate::io::robot_file::{RobotFile, RobotModel};
use crate::io::tracker_data::{PoseRow, Record, tracker_csv};
use calib_core::model::paper;
use calib_core::model::parameters::all_parameters;
use calib_core::{Kinematics, ParameterErrors};
use nalgebra::Dyn;
use rand::RngExt;
use rand_core::SeedableRng;
use rand_distr::{Distribution, Normal, Uniform};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::path::Path;

/// Which errors the simulated robot has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TrueErrors {
    /// Table 2 of the paper (the ER10L-C10's 24 identified parameters).
    Table2,
    /// Uniform random errors of the identified parameters (see --random-length-mm,
    /// --random-angle-rad).
    Random,
}

/// The realistic cell of the demo, the frames tests and the calibration benchmark: the robot
/// base seen from a tracker about 3 m away, turned arbitrarily (mm, deg).
pub const REALISTIC_TRACKER: FrameEntry = FrameEntry {
    xyz_mm: [2500.0, -1500.0, 600.0],
    rpy_deg: [5.0, -3.0, 140.0],
};

/// The realistic cell's reflector: 150 mm off the flange (mm, flange frame).
pub const REALISTIC_REFLECTOR_MM: [f64; 3] = [0.0, 60.0, 137.4773];

/// Most poses one simulation writes: 10 million (1.6 GB of CSV).
pub(crate) const MAX_POSES: usize = 10_000_000;

/// What to simulate. `Default` is the paper's section 3.1: Table 2 errors, 32 exact 6-DoF poses
/// uniform in [-180, 180] deg, in the base frame, seed 1.
#[derive(Clone, Debug, PartialEq)]
pub struct SimulationConfig {
    /// True errors: Table 2 or random.
    pub errors: TrueErrors,
    /// Half range of random length errors, mm.
    pub random_length_mm: f64,
    /// Half range of random angle errors, rad.
    pub random_angle_rad: f64,
    /// Number of poses.
    pub poses: usize,
    /// Joints within the robot's limits instead of uniform in [-180, 180] deg.
    pub within_limits: bool,
    /// Half range of uniform noise on the commanded joints, rad (the paper's 0.1 moves the tool
    /// by about 100 mm; default 0).
    pub joint_noise_rad: f64,
    /// Tracker position noise, standard deviation per axis, mm.
    pub position_sigma_mm: f64,
    /// Tracker orientation noise, standard deviation per axis, rad.
    pub orientation_sigma_rad: f64,
    /// Position-only data (a spherical reflector).
    pub position_only: bool,
    /// The robot base in the tracker's frame; `None`: data in the base frame.
    pub tracker: Option<FrameEntry>,
    /// The measured point on the flange, mm; `None`: the robot file's tool.
    pub tool_xyz_mm: Option<[f64; 3]>,
    /// Seed of all random draws.
    pub seed: u64,
    /// The commanded joint configurations (id, joints in rad), measured in this order instead of
    /// `poses` random ones: a plan rehearsed before the cell measures it.
    pub commanded: Option<Vec<(String, Vec<f64>)>>,
}

impl Default for SimulationConfig {
    fn default() -> Self {
        Self {
            errors: TrueErrors::Table2,
            random_length_mm: 0.5,
            random_angle_rad: 0.01,
            poses: 32,
            within_limits: false,
            joint_noise_rad: 0.0,
            position_sigma_mm: 0.0,
            orientation_sigma_rad: 0.0,
            position_only: false,
            tracker: None,
            tool_xyz_mm: None,
            seed: 1,
            commanded: None,
        }
    }
}

impl SimulationConfig {
    /// The same in the realistic cell: [`REALISTIC_TRACKER`] and [`REALISTIC_REFLECTOR_MM`].
    pub fn in_realistic_cell(self) -> Self {
        Self {
            tracker: Some(REALISTIC_TRACKER),
            tool_xyz_mm: Some(REALISTIC_REFLECTOR_MM),
            ..self
        }
    }

    /// An error naming the first setting out of range (by its command-line flag).
    pub fn check(&self) -> crate::Result<()> {
        if self.poses == 0 {
            return Err(crate::refused!(option "--poses"; "--poses must be at least 1"));
        }
        if self.poses > MAX_POSES {
            return Err(crate::refused!(option "--poses";
                "--poses {} is more than the {MAX_POSES} poses a simulation may have (about 160 \
                 bytes of CSV and 500 bytes of memory each); simulate in parts with other seeds",
                self.poses
            ));
        }
        for (name, v) in [
            ("--joint-noise-rad", self.joint_noise_rad),
            ("--position-sigma-mm", self.position_sigma_mm),
            ("--orientation-sigma-rad", self.orientation_sigma_rad),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(crate::refused!(option name;
                    "{name} must be a finite number >= 0, got {v}"
                ));
            }
        }
        // The frames are checked here, by their flags: once in the true robot they would be
        // blamed on the robot file's [base] or [tool].
        use crate::io::robot_file::{MAX_ANGLE_DEG, MAX_LENGTH_MM};
        let tracker = self.tracker.as_ref();
        for (name, values, max, unit) in [
            (
                "--tracker-xyz-mm",
                tracker.map(|t| t.xyz_mm),
                MAX_LENGTH_MM,
                "mm",
            ),
            (
                "--tracker-rpy-deg",
                tracker.map(|t| t.rpy_deg),
                MAX_ANGLE_DEG,
                "deg",
            ),
            ("--tool-xyz-mm", self.tool_xyz_mm, MAX_LENGTH_MM, "mm"),
        ] {
            if let Some(v) = values
                .into_iter()
                .flatten()
                .find(|v| v.abs() > max || v.is_nan())
            {
                return Err(crate::refused!(option name;
                    "{name}: {v:e} {unit} is beyond +-{max} {unit}; give the frame in mm and deg"
                ));
            }
        }
        Ok(())
    }
}

/// The outcome of a simulation: the measured poses, the true errors and the true robot.
///
/// `N` is the robot's joint count.
pub struct Simulated {
    /// The poses, as they are written.
    pub rows: Vec<PoseRow>,
    /// The true parameter errors.
    pub errors: ParameterErrors<f64, Dyn>,
    /// The true robot (with its tracker frame and tool) and a `[calibration]` section of the errors.
    pub truth: RobotFile,
    /// `true` when the poses are in the tracker's frame.
    pub in_tracker_frame: bool,
    /// The `#` comments of the data file.
    pub comments: Vec<String>,
    /// The header comment of the truth file.
    pub truth_comment: String,
}

impl Simulated {
    /// The poses as in-memory records (for [`crate::measurement::dataset::Dataset::from_records`]).
    pub fn records(&self) -> Vec<Record> {
        self.rows
            .iter()
            .enumerate()
            .map(|(i, r)| Record {
                line: i as u64 + 1,
                id: r.id.clone(),
                q: r.q.clone(),
                position: r.position,
                rotation: r.rotation,
                weight: 1.0,
                role: None,
                configuration: None,
                time_s: None,
                temperature_c: None,
            })
            .collect()
    }

    /// Writes the tracker CSV to `data` and the true robot to `truth`, both or neither (see
    /// [`crate::io::outputs::Outputs`]); neither may be `robot`, the robot file simulated.
    pub fn write(&self, data: &Path, truth: &Path, robot: &Path) -> crate::Result<()> {
        self.write_beside(data, truth, &[("--robot", robot)])
    }

    /// As [`Self::write`], refusing to replace any of `inputs` (each named by its flag).
    pub fn write_beside(
        &self,
        data: &Path,
        truth: &Path,
        inputs: &[(&str, &Path)],
    ) -> crate::Result<()> {
        let mut outputs = crate::io::outputs::Outputs::new(inputs);
        outputs.stage(
            "--out",
            data,
            tracker_csv(&self.comments, &self.rows)?.as_bytes(),
        )?;
        outputs.stage(
            "--truth-out",
            truth,
            self.truth.to_toml(&self.truth_comment).as_bytes(),
        )?;
        outputs.commit().map(|_| ())
    }
}

/// Simulates measurements of the robot of `file` (read from `path`, which names it in comments).
pub fn simulate(
    file: &RobotFile,
    path: &Path,
    config: &SimulationConfig,
) -> crate::Result<Simulated> {
    config.check()?;
    let mut file = file.clone();
    if let Some(tracker) = &config.tracker {
        file.base = Some(tracker.clone());
    }
    if let Some(xyz_mm) = config.tool_xyz_mm {
        let rpy_deg = file.tool.as_ref().map_or([0.0; 3], |t| t.rpy_deg);
        file.tool = Some(FrameEntry { xyz_mm, rpy_deg });
    }
    let model: RobotModel = file.to_model(path)?;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(config.seed);
    let errors = true_errors(config, &model, &mut rng)?;
    let truth = Kinematics::new(&model.robot, &errors).context("true model")?;
    let rows = measure(config, &model, &truth, &mut rng)?;
    let errors_text = match config.errors {
        TrueErrors::Table2 => "Table 2 of the paper".to_string(),
        TrueErrors::Random => format!(
            "random, uniform within +-{} mm and +-{} rad",
            config.random_length_mm, config.random_angle_rad
        ),
    };
    let listed: Vec<_> = all_parameters(model.robot.joint_count())
        .filter(|p| model.mask.contains(*p) || errors.get(*p) != Some(0.0))
        .collect();
    let robot = path.display().to_string();
    Ok(Simulated {
        rows,
        errors,
        truth: file.with_errors(&errors, listed, &[], "simulated truth", &robot),
        in_tracker_frame: config.tracker.is_some(),
        comments: comments(config, &robot, &errors_text),
        truth_comment: format!(
            "True robot of a simulation: {robot} plus {errors_text}.\nErrors in mm (da, dd, translations) and rad (dalpha, dbeta, dtheta, rotations)."
        ),
    })
}

/// Table 2, or uniform random errors of the identified parameters.
fn true_errors(
    config: &SimulationConfig,
    model: &RobotModel,
    rng: &mut Xoshiro256PlusPlus,
) -> crate::Result<ParameterErrors<f64, Dyn>> {
    Ok(match config.errors {
        TrueErrors::Table2 => {
            let joints = model.robot.joints.len();
            if joints != JOINTS {
                return Err(crate::refused!(unsupported "--errors table2";
                    "Table 2 of the paper holds the errors of a {JOINTS}-joint robot; this robot has {joints} joints: use --errors random"
                ));
            }
            // Every parameter of the paper's robot, by name (the same joints: 6).
            let table2 = paper::table2::<f64>();
            let mut e = ParameterErrors::zeros_for(model.robot.joint_count());
            for p in calib_core::model::parameters::all_parameters(table2.joint_count()) {
                e.set(p, table2.get(p).unwrap_or(0.0));
            }
            e
        }
        TrueErrors::Random => {
            let mut e = ParameterErrors::zeros_for(model.robot.joint_count());
            for p in model.mask.iter() {
                let half = if p.is_angle() {
                    config.random_angle_rad
                } else {
                    config.random_length_mm
                };
                e.set(p, half * (2.0 * rng.random::<f64>() - 1.0));
            }
            e
        }
    })
}

/// The measured poses: commanded joints, the true pose (joint noise added), tracker noise.
fn measure(
    config: &SimulationConfig,
    model: &RobotModel,
    truth: &Kinematics<f64, Dyn>,
    rng: &mut Xoshiro256PlusPlus,
) -> crate::Result<Vec<PoseRow>> {
    let mut rows = Vec::with_capacity(config.poses);
    let position_noise = Normal::new(0.0, config.position_sigma_mm)
        .map_err(|e| crate::refused!(option "--noise-mm"; "position noise: {e}"))?;
    let orientation_noise = Normal::new(0.0, config.orientation_sigma_rad)
        .map_err(|e| crate::refused!(option "--noise-deg"; "orientation noise: {e}"))?;
    let joints = model.robot.joints.len();
    let count = config.commanded.as_ref().map_or(config.poses, Vec::len);
    for i in 0..count {
        let mut q = calib_core::model::JointVec::<f64>::from_fn(joints, |_| 0.0);
        let commanded = config.commanded.as_ref().and_then(|c| c.get(i));
        if let Some((id, given)) = commanded {
            if given.len() != joints {
                return Err(crate::refused!(input "the commanded configurations";
                    "commanded configuration {id} has {} joints, the robot {joints}",
                    given.len()
                ));
            }
            q.iter_mut().zip(given).for_each(|(a, b)| *a = *b);
        }
        for (qi, limits) in q
            .iter_mut()
            .zip(&model.robot.limits)
            .filter(|_| commanded.is_none())
        {
            let (lo, hi) =
                if config.within_limits && limits.lower.is_finite() && limits.upper.is_finite() {
                    (limits.lower, limits.upper)
                } else {
                    (-std::f64::consts::PI, std::f64::consts::PI)
                };
            *qi = Uniform::new_inclusive(lo, hi)
                .map_err(|e| crate::refused!(input "the robot's joint limits"; "joint range [{lo}, {hi}] rad: {e}"))?
                .sample(rng);
        }
        // The robot moves to the commanded joints plus noise; the file records the commanded ones.
        let mut actual_q = q;
        if config.joint_noise_rad > 0.0 {
            for a in &mut actual_q {
                *a += config.joint_noise_rad * (2.0 * rng.random::<f64>() - 1.0);
            }
        }
        let pose = truth.forward(&actual_q)?;
        let mut position = [pose.translation.x, pose.translation.y, pose.translation.z];
        for p in &mut position {
            *p += position_noise.sample(rng);
        }
        let rotation = (!config.position_only).then(|| {
            let noise = nalgebra::Vector3::from_fn(|_, _| orientation_noise.sample(rng));
            *(nalgebra::Rotation3::new(noise) * pose.rotation).matrix()
        });
        rows.push(PoseRow {
            id: commanded.map_or_else(|| format!("P{:03}", i + 1), |(id, _)| id.clone()),
            q: q.to_vec(),
            position,
            rotation,
        });
    }
    Ok(rows)
}

/// The data file's comments: the frame and how the data were made.
fn comments(config: &SimulationConfig, robot: &str, errors_text: &str) -> Vec<String> {
    vec![
        if config.tracker.is_some() {
            "measurements in the tracker's frame (the truth file's [base] is the robot base in it)"
                .to_string()
        } else {
            "frame: base".to_string()
        },
        format!(
            "simulated by calib simulate: robot {robot}, errors {errors_text}, {} poses, joints {}",
            config.commanded.as_ref().map_or(config.poses, Vec::len),
            match (&config.commanded, config.within_limits) {
                (Some(_), _) => "as commanded (--joints-from)",
                (None, true) => "within limits",
                (None, false) => "uniform in [-180, 180] deg",
            }
        ),
        format!(
            "joint noise +-{} rad, tracker noise sigma {} mm and {} rad, seed {}",
            config.joint_noise_rad,
            config.position_sigma_mm,
            config.orientation_sigma_rad,
            config.seed
        ),
    ]
}
