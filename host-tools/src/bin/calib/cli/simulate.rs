//! `calib simulate`: the options of a simulation ([`host_tools::measurement::simulate`]) and the files it writes.

use anyhow::bail;
use host_tools::io::robot_file::{FrameEntry, RobotFile};
use host_tools::measurement::simulate::{Simulated, SimulationConfig, TrueErrors};
use std::path::PathBuf;

/// Settings of a simulation: the options of `calib simulate`.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Simulation {
    /// Nominal robot model file (default: the paper's Efort ER10L-C10, built into calib: the
    /// file host-tools/robots/er10l-c10.toml, usable from any directory).
    #[arg(long, value_name = "FILE")]
    pub robot: Option<PathBuf>,
    /// True errors: the paper's Table 2, or random ones.
    #[arg(long, value_enum, default_value_t = TrueErrors::Table2)]
    pub errors: TrueErrors,
    /// Half range of random length errors, mm (default 0.5; with --errors random, refused
    /// without it).
    #[arg(long)]
    pub random_length_mm: Option<f64>,
    /// Half range of random angle errors, rad (default 0.01; with --errors random, refused
    /// without it).
    #[arg(long)]
    pub random_angle_rad: Option<f64>,
    /// Number of poses.
    #[arg(long, default_value_t = 32)]
    pub poses: usize,
    /// Measure these joint configurations, in this order, instead of random ones: a plan (calib
    /// plan --out) or any CSV of joints in our format (id, q1_deg..qN_deg); each pose keeps its
    /// id, as a tracker names its points. A rehearsal of a plan before the cell measures it.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["poses", "within_limits"])]
    pub joints_from: Option<PathBuf>,
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

impl Simulation {
    /// The library configuration these options ask for.
    pub fn config(&self) -> anyhow::Result<SimulationConfig> {
        let triple = |v: &Option<Vec<f64>>, name: &str| -> anyhow::Result<Option<[f64; 3]>> {
            match v {
                None => Ok(None),
                Some(v) => match v.as_slice() {
                    [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Some([*x, *y, *z])),
                    _ => bail!("{name} needs three finite numbers, got {v:?}"),
                },
            }
        };
        let tracker_xyz = triple(&self.tracker_xyz_mm, "--tracker-xyz-mm")?;
        let tracker_rpy = triple(&self.tracker_rpy_deg, "--tracker-rpy-deg")?;
        let tracker = (tracker_xyz.is_some() || tracker_rpy.is_some()).then(|| FrameEntry {
            xyz_mm: tracker_xyz.unwrap_or([0.0; 3]),
            rpy_deg: tracker_rpy.unwrap_or([0.0; 3]),
        });
        let random = crate::cli::given_flags([
            ("--random-length-mm", self.random_length_mm.is_some()),
            ("--random-angle-rad", self.random_angle_rad.is_some()),
        ]);
        if self.errors != TrueErrors::Random && !random.is_empty() {
            bail!(
                "{} set the range of random errors, and --errors table2 (the default) takes the paper's Table 2: add --errors random, or drop {}",
                random.join(" and "),
                if random.len() == 1 { "it" } else { "them" }
            );
        }
        Ok(SimulationConfig {
            errors: self.errors,
            random_length_mm: (self.random_length_mm)
                .unwrap_or(SimulationConfig::default().random_length_mm),
            random_angle_rad: (self.random_angle_rad)
                .unwrap_or(SimulationConfig::default().random_angle_rad),
            poses: self.poses,
            within_limits: self.within_limits,
            joint_noise_rad: self.joint_noise_rad,
            position_sigma_mm: self.position_sigma_mm,
            orientation_sigma_rad: self.orientation_sigma_rad,
            position_only: self.position_only,
            tracker,
            tool_xyz_mm: triple(&self.tool_xyz_mm, "--tool-xyz-mm")?,
            seed: self.seed,
            commanded: match &self.joints_from {
                Some(path) => Some(
                    host_tools::io::tracker_data::TrackerData::read_joints(
                        path,
                        &host_tools::io::profile::DataProfile::default(),
                    )?
                    .records
                    .into_iter()
                    .map(|r| (r.id, r.q))
                    .collect(),
                ),
                None => None,
            },
        })
    }
}

/// How the built-in robot of `calib simulate` is named in files and messages.
const BUILT_IN_ROBOT: &str = "er10l-c10.toml (built into calib)";

/// Runs `calib simulate`: simulates, then writes the tracker CSV to `--out` and the true robot to
/// `--truth-out` (nothing unless both are ready; each atomically).
/// Robots of any joint count in [`JOINT_COUNTS`](host_tools::model::counts::JOINT_COUNTS); returns the
/// number of poses written.
pub fn simulate(options: &Simulation) -> anyhow::Result<usize> {
    let config = options.config()?;
    let (file, robot) = match &options.robot {
        Some(path) => (RobotFile::read(path)?, path.clone()),
        None => {
            let path = PathBuf::from(BUILT_IN_ROBOT);
            (
                RobotFile::parse(host_tools::io::robot_file::ER10L_C10_TOML, &path)?,
                path,
            )
        }
    };
    file.refuse_compliance(&robot, "calib simulate")?;
    file.refuse_joint_maps(&robot, "calib simulate")?;
    host_tools::model::counts::joint_count(file.joint.len())?;
    // Commanded joints within the robot's limits, as fk, evaluate and compensate require.
    if let (Some(commanded), Some(path)) = (&config.commanded, &options.joints_from) {
        let model = file.to_model(&robot)?;
        let joints = model.robot.joints.len();
        for (id, q) in commanded.iter().filter(|(_, q)| q.len() == joints) {
            if let Some(outside) = model.outside_limits(q) {
                anyhow::bail!("{}: configuration {id}: {outside}", path.display());
            }
        }
    }
    let simulated: Simulated = host_tools::measurement::simulate::simulate(&file, &robot, &config)?;
    let mut inputs = vec![("--robot", robot.as_path())];
    if let Some(path) = &options.joints_from {
        inputs.push(("--joints-from", path.as_path()));
    }
    simulated.write_beside(&options.out, &options.truth_out, &inputs)?;
    Ok(simulated.rows.len())
}
