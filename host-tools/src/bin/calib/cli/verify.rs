//! `calib verify`: the same calibration by the f32 core, the f64 core and the reference
//! optimiser ([`host_tools::calibration::verify`]); exits non-zero past the documented tolerances.

use host_tools::calibration::verify::Verification;

/// Options of `calib verify`.
#[derive(Clone, Debug, clap::Args)]
pub struct VerifyOptions {
    /// Robot, data and data profile files.
    #[command(flatten)]
    pub input: crate::cli::InputFiles,
    /// Frames identified with the geometry (default base+tool unless the data say
    /// `# frame: base`).
    #[arg(long, value_enum)]
    pub frames: Option<host_tools::measurement::frames::Frames>,
    /// Fraction of the poses held out for the validation error.
    #[arg(long, default_value_t = 0.3)]
    pub validate: f64,
    /// Seed of the hold-out.
    #[arg(long, default_value_t = 0)]
    pub validate_seed: u64,
    /// Orientation weight k, mm^2/rad^2 (default 1e6; refused for position-only data).
    #[arg(long, value_parser = crate::cli::orientation_weight)]
    pub k: Option<f64>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `calib verify`: reads the files, holds out `--validate` of the poses, verifies.
pub fn verify(options: &VerifyOptions) -> anyhow::Result<Verification> {
    host_tools::model::counts::joint_count(options.input.joints()?)?;
    let (_, all) = options.input.load()?;
    let k = crate::cli::weight_for(options.k, &all.data, &options.input.data)?;
    let (calibration, validation) =
        host_tools::measurement::dataset::split(&all, options.validate, options.validate_seed)?;
    Ok(host_tools::calibration::verify::verify(
        &calibration,
        &validation,
        options.frames,
        k,
    )?)
}
