//! `calib check-shift`: a short set of poses measured at the start of a shift against the
//! robot's registered calibration ([`host_tools::registry::shift`]); the check is recorded in
//! the registry, and the drift of the checks over time stated.

use host_tools::registry::shift::{ShiftSettings, check_and_record};
use std::path::PathBuf;

/// `calib check-shift`'s options.
#[derive(Debug, clap::Args)]
pub struct CheckShiftOptions {
    /// The robot's serial number.
    #[arg(long, value_name = "SERIAL")]
    pub serial: String,
    /// The poses measured (tracker data, as calib calibrate reads them).
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    /// The data profile the data are read through.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// Check against this calibration record (default: the robot's latest).
    #[arg(long, value_name = "ID")]
    pub record: Option<i64>,
    /// A pose lies beyond its prediction past this many standard deviations (a drift: more
    /// such poses than chance gives, or the errors together past their point).
    #[arg(long, value_name = "K", default_value_t = host_tools::registry::shift::DEFAULT_K)]
    pub k: f64,
    /// A pose past this position error, mm, is a drift (besides K).
    #[arg(long, value_name = "MM")]
    pub limit_mm: Option<f64>,
    /// The instrument's noise per coordinate, mm (default: the calibration's own estimate).
    #[arg(long, value_name = "MM")]
    pub noise_mm: Option<f64>,
    /// The tracker was placed anew since the calibration: fit its placement on these poses
    /// first (a base that moved can then not be told from it).
    #[arg(long)]
    pub register_tracker: bool,
    /// When the poses were measured, RFC 3339 (default: now).
    #[arg(long, value_name = "TIME")]
    pub checked_at: Option<String>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// The registry.
    #[command(flatten)]
    pub db: crate::cli::registry::Db,
}

/// The exit status when a pose drifted.
pub const DRIFTED: i32 = 3;

/// Runs the check, records it, prints it; exits with [`DRIFTED`] when a pose drifted.
pub fn run(o: &CheckShiftOptions) -> anyhow::Result<()> {
    let profile = host_tools::io::profile::DataProfile::load(o.profile.as_deref())?;
    let settings = ShiftSettings {
        k: o.k,
        limit_mm: o.limit_mm,
        noise_mm: o.noise_mm,
        register_tracker: o.register_tracker,
    };
    let recorded = check_and_record(
        &o.db.db,
        &o.serial,
        &o.data,
        &profile,
        (o.record, o.checked_at.as_deref()),
        settings,
    )?;
    let text = match o.json {
        true => format!("{}\n", serde_json::to_string_pretty(&recorded)?),
        false => format!(
            "{}recorded as shift check {} in {}\n{}",
            recorded.result.text(),
            recorded.check,
            o.db.db.display(),
            recorded
                .drift_rate
                .as_ref()
                .map_or(String::new(), |r| r.text())
        ),
    };
    crate::cli::print_text(format_args!("{text}"))?;
    if recorded.result.drifted {
        let _ = std::io::Write::flush(&mut std::io::stdout());
        std::process::exit(DRIFTED);
    }
    Ok(())
}
