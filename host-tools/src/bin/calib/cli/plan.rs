//! `calib plan`: choose the poses to measure from candidate joint configurations, predict the
//! accuracy they give, and write the plan as a tracker CSV without measurements
//! ([`host_tools::planning`]).

use host_tools::io::outputs::Outputs;
use host_tools::io::robot_file::RobotFile;
use host_tools::planning::{self, Candidates, Measure, Noise, Plan, PlanModel, PlanRequest};
use std::path::PathBuf;

/// Options of `calib plan`.
#[derive(Clone, Debug, clap::Args)]
pub struct PlanOptions {
    /// Robot model file (TOML): the nominal model and the parameters to identify.
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// Candidate joint configurations (poses the cell can reach without collision): a tracker
    /// CSV whose joint columns are read (anything else is ignored), or another export through
    /// --profile.
    #[arg(long, value_name = "FILE", required_unless_present = "generate")]
    pub candidates: Option<PathBuf>,
    /// Data profile for a --candidates file not in our CSV format.
    #[arg(long, value_name = "FILE", requires = "candidates")]
    pub profile: Option<PathBuf>,
    /// Generate this many candidates within the joint limits (+-180 deg where unlimited), a
    /// Halton sequence, instead of reading them.
    #[arg(long, value_name = "N", conflicts_with = "candidates")]
    pub generate: Option<usize>,
    /// With --generate: keep only candidates whose nominal tool point lies in this box of the
    /// base frame, mm.
    #[arg(
        long,
        value_name = "XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX",
        value_delimiter = ',',
        allow_hyphen_values = true,
        requires = "generate"
    )]
    pub box_mm: Option<Vec<f64>>,
    /// Poses to fit (core and fill poses); the verification poses come on top.
    #[arg(long, value_name = "N")]
    pub poses: usize,
    /// D-optimal core poses among --poses (the rest are random fill poses). Default: 12, or
    /// the fewest poses that give as many equations as parameters if that is more.
    #[arg(long, value_name = "N")]
    pub core: Option<usize>,
    /// Verification poses, measured and kept out of the fit.
    #[arg(long, value_name = "N", default_value_t = planning::DEFAULT_VERIFY)]
    pub verify: usize,
    /// No two plan poses closer than this in joint space (Euclidean over the joints), deg.
    #[arg(long, value_name = "DEG", default_value_t = planning::DEFAULT_MIN_DISTANCE_DEG)]
    pub min_distance_deg: f64,
    /// What the tracker measures: a reflector's position, or a 6-DoF probe's pose.
    #[arg(long, value_enum)]
    pub measure: Measure,
    /// The model the calibration will identify: the geometry (random fill poses), or the
    /// geometry with joint maps (fill poses that cover each joint's range evenly).
    #[arg(long, value_enum, default_value_t = PlanModel::Geometric)]
    pub model: PlanModel,
    /// Noise of each measured position coordinate, 1 sigma, mm: the tracker's and the robot's
    /// repeatability together (unmodelled errors act as more noise).
    #[arg(long, value_name = "MM", required_unless_present = "noise_from")]
    pub noise_mm: Option<f64>,
    /// Noise of each measured orientation axis, 1 sigma, deg (--measure pose; refused with
    /// position). Default: the
    /// position noise over sqrt(k), the ratio the fit's weight k assumes.
    #[arg(long, value_name = "DEG", requires = "noise_mm")]
    pub noise_deg: Option<f64>,
    /// Take the noise levels from a previous calibration's JSON report (calibrate --report):
    /// the RMS residuals of its calibration poses, per coordinate and per orientation axis,
    /// corrected for the parameters fitted (sqrt(rows / (rows - parameters))). They include the
    /// errors the geometric model does not describe.
    #[arg(long, value_name = "FILE", conflicts_with = "noise_mm")]
    pub noise_from: Option<PathBuf>,
    /// Orientation weight k, mm^2/rad^2 (as for calibrate; default 1e6; --measure pose only).
    #[arg(long, value_parser = crate::cli::orientation_weight)]
    pub k: Option<f64>,
    /// Seed of the random fill and verification poses.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The plan: a tracker CSV with a role column and empty measurement columns.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Also write the plan and its prediction as JSON.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Also write the plan as a URScript program (Universal Robots): a movej to each pose in the
    /// planned order and a pause for the tracker (--settle-s).
    #[arg(long, value_name = "FILE")]
    pub urscript: Option<PathBuf>,
    /// Also write the plan as joint targets for any controller (CSV: id, role, q1_deg..qN_deg in
    /// the planned order).
    #[arg(long, value_name = "FILE")]
    pub joint_targets: Option<PathBuf>,
    /// Generate candidates with the tool below the base's mounting plane too (z < 0 mm in the
    /// base frame; a robot mounted on a wall or ceiling, or reaching below its pedestal). By
    /// default --generate keeps the tool above it (z >= 0), unless --box-mm states the workspace.
    #[arg(long, conflicts_with = "box_mm")]
    pub below_base: bool,
    /// How the URScript program moves.
    #[command(flatten)]
    pub motion: crate::cli::MotionOptions,
}

impl PlanOptions {
    /// The library's request for these options. Errors: options that name what the request
    /// cannot hold together (`--box-mm` or `--below-base` with `--candidates`, `--profile` with
    /// `--generate`, a box of other than six values, no candidates or no noise).
    pub fn request(&self) -> host_tools::Result<PlanRequest> {
        let candidates = match (&self.candidates, self.generate) {
            (Some(path), _) => {
                if self.box_mm.is_some() {
                    return Err(host_tools::Error::conflict(
                        &["--box-mm", "--candidates"],
                        "--box-mm selects among generated candidates (--generate); with --candidates, give only the configurations to choose from",
                    ));
                }
                if self.below_base {
                    return Err(host_tools::Error::conflict(
                        &["--below-base", "--candidates"],
                        "--below-base lets generated candidates (--generate) put the tool below the base; --candidates are taken as the file gives them: drop --below-base",
                    ));
                }
                Candidates::File {
                    path: path.clone(),
                    profile: self.profile.clone(),
                }
            }
            (None, Some(count)) => {
                if self.profile.is_some() {
                    return Err(host_tools::Error::conflict(
                        &["--profile", "--generate"],
                        "--profile reads a --candidates file, and --generate reads none: drop --profile",
                    ));
                }
                let box_mm = match self.box_mm.as_deref() {
                    None => None,
                    Some(&[a, b, c, d, e, f]) => Some([a, b, c, d, e, f]),
                    Some(_) => {
                        return Err(host_tools::refused!(option "--box-mm";
                            "--box-mm takes six values: XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX"
                        ));
                    }
                };
                Candidates::Generate {
                    count,
                    box_mm,
                    below_base: self.below_base,
                }
            }
            (None, None) => {
                return Err(host_tools::refused!(option "--candidates";
                    "give the candidates: --candidates FILE or --generate N"
                ));
            }
        };
        let noise = match (self.noise_mm, &self.noise_from) {
            (Some(mm), _) => Noise::Given {
                mm,
                deg: self.noise_deg,
            },
            (None, Some(path)) => {
                Noise::Residuals(host_tools::calibration::Report::read(path)?.residuals(path)?)
            }
            (None, None) => {
                return Err(host_tools::refused!(option "--noise-mm";
                    "give the noise level: --noise-mm or --noise-from"
                ));
            }
        };
        Ok(PlanRequest {
            core: self.core,
            verify: self.verify,
            min_distance_deg: self.min_distance_deg,
            model: self.model,
            k: self.k,
            seed: self.seed,
            ..PlanRequest::new(candidates, self.poses, self.measure, noise)
        })
    }
}

/// `calib plan`: plans, writes the plan (and the report) together, returns the plan. Warns on
/// standard error when a planned pose puts the tool below the base's mounting plane.
pub fn plan(options: &PlanOptions) -> anyhow::Result<Plan> {
    let file = RobotFile::read(&options.robot)?;
    let plan = planned(options, &file)?;
    write(options, &file, &plan)?;
    if let Some(warning) = below_base(options, &file, &plan)? {
        eprintln!("{warning}");
    }
    Ok(plan)
}

/// The warning for planned poses whose tool point lies below the base's mounting plane (z < 0
/// mm in the base frame): how many, the lowest, and what to do; `None` when there are none.
fn below_base(
    options: &PlanOptions,
    file: &RobotFile,
    plan: &Plan,
) -> anyhow::Result<Option<String>> {
    let kinematics = calib_core::Kinematics::nominal(&file.to_model(&options.robot)?.robot)?;
    let mut below = Vec::new();
    for pose in &plan.poses {
        let q = calib_core::model::JointVec::from_slice(&pose.q)
            .ok_or_else(|| anyhow::anyhow!("more than 9 joints"))?;
        let z = kinematics.forward(&q)?.translation.vector.z;
        if z < 0.0 {
            below.push((pose.id.as_str(), z));
        }
    }
    let Some((id, z)) = below.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1)) else {
        return Ok(None);
    };
    Ok(Some(format!(
        "warning: {} of the {} planned poses put the tool below the base's mounting plane (z < 0 mm in the base frame; lowest: {id} at {z:.0} mm), and the robot program goes there: make sure the cell has room, or plan above it (--generate keeps z >= 0 unless --below-base; --box-mm states the workspace)",
        below.len(),
        plan.poses.len()
    )))
}

/// The plan `calib plan` makes for the robot `file` (read from `options.robot`), written nowhere
/// (`options.out` is not used).
pub fn planned(options: &PlanOptions, file: &RobotFile) -> anyhow::Result<Plan> {
    Ok(options.request()?.plan(file, &options.robot)?)
}

/// Writes `plan` of the robot `file` where `options` ask, all files together.
fn write(options: &PlanOptions, file: &RobotFile, plan: &Plan) -> anyhow::Result<()> {
    let source = match (&options.candidates, options.generate) {
        (Some(path), _) => format!("candidates {}", path.display()),
        (_, n) => format!("{} generated candidates", n.unwrap_or(0)),
    };
    let comments = [
        format!(
            "measurement plan by calib plan for {} ({}), {source}",
            file.name,
            options.robot.display()
        ),
        "fill in the measurement columns (tracker frame) and calibrate this file: the verify poses are held out".to_string(),
    ];
    let mut inputs = vec![("--robot", options.robot.as_path())];
    if let Some(path) = &options.candidates {
        inputs.push(("--candidates", path.as_path()));
    }
    let mut outputs = Outputs::new(&inputs);
    outputs.stage("--out", &options.out, plan.csv(&comments)?.as_bytes())?;
    if let Some(path) = &options.report {
        outputs.stage(
            "--report",
            path,
            serde_json::to_string_pretty(&plan)?.as_bytes(),
        )?;
    }
    if let Some(path) = &options.urscript {
        let program = planning::program::urscript(plan, &file.name, &options.motion.motion())?;
        outputs.stage("--urscript", path, program.as_bytes())?;
    }
    if let Some(path) = &options.joint_targets {
        let targets = planning::program::joint_targets(plan)?;
        outputs.stage("--joint-targets", path, targets.as_bytes())?;
    }
    outputs.commit()?;
    Ok(())
}
