//! `calib merge`: a tracker's export merged into the plan it measured
//! ([`host_tools::measurement::merge`]), written as data that `calibrate` takes directly.

use host_tools::io::outputs::Outputs;
use host_tools::io::profile::DataProfile;
use host_tools::io::tracker_data::TrackerData;
use host_tools::measurement::merge::{MatchBy, Merged, RobotLog};
use std::path::PathBuf;

/// Options of `calib merge`.
#[derive(Clone, Debug, clap::Args)]
pub struct MergeOptions {
    /// The plan (calib plan --out): ids, roles and joints of the poses measured.
    #[arg(long, value_name = "FILE")]
    pub plan: PathBuf,
    /// The tracker's export of the measured points (positions, and orientations for 6-DoF):
    /// our CSV, or another format read through --profile.
    #[arg(long, value_name = "FILE")]
    pub measured: PathBuf,
    /// Data profile of the export (delimiter, decimal comma, columns with units, Euler
    /// convention; see host-tools/profiles/).
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// How points are paired with the plan's poses: by the export's id column, by order (the
    /// plan's order, in which calib plan's robot program moves), or by time (the export's
    /// time_s column against the --robot-log's).
    #[arg(long, value_enum)]
    pub by: MatchBy,
    /// For --by time: the robot's log of when it stood at each planned pose (CSV: time_s or
    /// time_ms; id naming the planned pose, or one row per planned pose in the plan's order;
    /// optional joint columns, checked against the plan's).
    #[arg(long, value_name = "FILE")]
    pub robot_log: Option<PathBuf>,
    /// Data profile of the robot log (as --profile for the export).
    #[arg(long, value_name = "FILE", requires = "robot_log")]
    pub log_profile: Option<PathBuf>,
    /// For --by time: largest time between a logged pose and the point measured for it, s.
    #[arg(long, default_value_t = 1.0, requires = "robot_log")]
    pub time_tolerance_s: f64,
    /// Largest difference between an export's joint columns (when it has them) and the plan's,
    /// deg.
    #[arg(long, default_value_t = 0.1)]
    pub tolerance_deg: f64,
    /// The measured plan to write (our CSV with id, role, joints and the measurements).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// Runs `calib merge`; returns the merge (written to `--out`).
pub fn merge(options: &MergeOptions) -> anyhow::Result<Merged> {
    if !(options.tolerance_deg.is_finite() && options.tolerance_deg >= 0.0) {
        anyhow::bail!(
            "--tolerance-deg must be a finite angle >= 0, got {}",
            options.tolerance_deg
        );
    }
    let plan = TrackerData::read_joints(&options.plan, &DataProfile::default())?;
    let profile = DataProfile::load(options.profile.as_deref())?;
    let measured = TrackerData::read_measured(&options.measured, &profile)?;
    if !(options.time_tolerance_s.is_finite() && options.time_tolerance_s > 0.0) {
        anyhow::bail!(
            "--time-tolerance-s must be a finite time > 0, got {}",
            options.time_tolerance_s
        );
    }
    let log = match &options.robot_log {
        Some(path) => Some(TrackerData::read_log(
            path,
            &DataProfile::load(options.log_profile.as_deref())?,
        )?),
        None => None,
    };
    let log = log.as_ref().map(|log| RobotLog {
        log,
        tolerance_s: options.time_tolerance_s,
    });
    let merged = host_tools::measurement::merge::merge(
        &plan,
        &measured,
        options.by,
        options.tolerance_deg.to_radians(),
        log.as_ref(),
    )?;
    let mut inputs = vec![
        ("--plan", options.plan.as_path()),
        ("--measured", options.measured.as_path()),
    ];
    for (flag, path) in [
        ("--profile", &options.profile),
        ("--robot-log", &options.robot_log),
        ("--log-profile", &options.log_profile),
    ] {
        if let Some(path) = path {
            inputs.push((flag, path.as_path()));
        }
    }
    let mut outputs = Outputs::new(&inputs);
    outputs.stage("--out", &options.out, merged.csv()?.as_bytes())?;
    outputs.commit()?;
    Ok(merged)
}
