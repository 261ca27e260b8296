//! `calib merge`: a tracker's export merged into the plan it measured
//! ([`crate::measurement::merge`]), written as data that `calibrate` takes directly.

use crate::io::outputs::Outputs;
use crate::io::profile::DataProfile;
use crate::io::tracker_data::TrackerData;
use crate::measurement::merge::{MatchBy, Merged};
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
    /// How points are paired with the plan's poses: by the export's id column, or by order (the
    /// plan's order, in which calib plan's robot program moves).
    #[arg(long, value_enum)]
    pub by: MatchBy,
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
    let merged = crate::measurement::merge::merge(
        &plan,
        &measured,
        options.by,
        options.tolerance_deg.to_radians(),
    )?;
    let mut inputs = vec![
        ("--plan", options.plan.as_path()),
        ("--measured", options.measured.as_path()),
    ];
    if let Some(path) = &options.profile {
        inputs.push(("--profile", path.as_path()));
    }
    let mut outputs = Outputs::new(&inputs);
    outputs.stage("--out", &options.out, merged.csv()?.as_bytes())?;
    outputs.commit()?;
    Ok(merged)
}
