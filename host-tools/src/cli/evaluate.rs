//! `calib evaluate`: the paper's Table 3 statistics of any robot model on any data.

use crate::statistics::Table3;

/// Options of `calib evaluate`.
#[derive(Clone, Debug, clap::Args)]
#[command(mut_arg("robot", |a| a.help("Robot model file (TOML): a nominal or an identified model")))]
pub struct EvaluateOptions {
    /// Robot, data and data profile files.
    #[command(flatten)]
    pub input: crate::cli::InputFiles,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `calib evaluate`.
pub fn evaluate(options: &EvaluateOptions) -> anyhow::Result<Table3> {
    let (_, dataset) = options.input.load()?;
    crate::statistics::evaluate(&dataset)
}
