//! `calib export`: an identified robot file as the controller's parameter block, TOML or JSON.

use crate::JOINTS;
use crate::export::{BlockScalar, ExportFormat};
use crate::files::Outputs;
use crate::robot_file::{RobotFile, RobotModel};
use std::path::PathBuf;

/// Options of `calib export`.
#[derive(Clone, Debug, clap::Args)]
pub struct ExportOptions {
    /// Identified robot file; with joint maps (calibrate --model joint-maps) the block is
    /// version 2 and holds them.
    #[arg(long, value_name = "FILE")]
    pub params: PathBuf,
    /// Output format.
    #[arg(long, value_enum)]
    pub format: ExportFormat,
    /// Output file.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Scalar type of the block.
    #[arg(long, value_enum, default_value_t = BlockScalar::F32)]
    pub scalar: BlockScalar,
    /// Sequence number written into the block.
    #[arg(long, default_value_t = 1)]
    pub sequence: u32,
}

/// Runs `calib export`; returns the number of bytes written.
pub fn export(options: &ExportOptions) -> anyhow::Result<usize> {
    let file = RobotFile::read(&options.params)?;
    let model: RobotModel<JOINTS> = file.to_model(&options.params)?;
    let bytes = crate::export::export(
        &file,
        &model,
        options.format,
        options.scalar,
        options.sequence,
    )?;
    let mut outputs = Outputs::new(&[("--params", &options.params)]);
    outputs.stage("--out", &options.out, &bytes)?;
    outputs.commit()?;
    Ok(bytes.len())
}
