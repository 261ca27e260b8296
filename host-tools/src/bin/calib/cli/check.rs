//! `calib check`: the identifiability of the identified parameters from a data set, without
//! calibrating.

use host_tools::analysis::identifiability::IdentifiabilityReport;

/// Options of `calib check`.
#[derive(Clone, Debug, clap::Args)]
pub struct CheckOptions {
    /// Robot, data and data profile files.
    #[command(flatten)]
    pub input: crate::cli::InputFiles,
    /// Frames identified with the geometry (as for calibrate; default base+tool unless the data
    /// say `# frame: base`).
    #[arg(long, value_enum)]
    pub frames: Option<host_tools::measurement::frames::Frames>,
    /// Orientation weight k, mm^2/rad^2 (as for calibrate; default 1e6; refused for
    /// position-only data).
    #[arg(long, value_parser = crate::cli::orientation_weight)]
    pub k: Option<f64>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// `calib check`: the identifiability analysis of a robot file's parameters on a data file.
pub fn check(options: &CheckOptions) -> anyhow::Result<IdentifiabilityReport> {
    host_tools::model::counts::joint_count(options.input.joints()?)?;
    // Joint maps and gravity compliance of the file are held fixed: the analysis is that of the
    // geometric parameters at the kinematic angles (the readings with the maps).
    let (_, dataset) = options.input.load()?;
    let k = crate::cli::weight_for(options.k, &dataset.data, &options.input.data)?;
    Ok(host_tools::analysis::identifiability::check(
        &dataset,
        options.frames,
        k,
    )?)
}
