//! `calib export`: an identified robot file as the controller's parameter block, TOML, JSON, a
//! URDF or a UR kinematics YAML.

use host_tools::formats::export::{BlockScalar, ExportFormat, ExportRequest};
use host_tools::io::outputs::Outputs;
use host_tools::io::robot_file::RobotFile;
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
    /// Block: scalar type (default f32).
    #[arg(long, value_enum)]
    pub scalar: Option<BlockScalar>,
    /// Block: sequence number written into it (default 1).
    #[arg(long)]
    pub sequence: Option<u32>,
    /// URDF: the links after joints 1..N, comma-separated (default link_1,...,link_N).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub link_names: Option<Vec<String>>,
    /// URDF: the revolute joints, comma-separated (default joint_1,...,joint_N).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub joint_names: Option<Vec<String>>,
    /// URDF: the root link, where the robot file's `[base]` is given (default base_link).
    #[arg(long)]
    pub base_link: Option<String>,
    /// URDF: the flange link, after the last joint's fixed part (default flange).
    #[arg(long)]
    pub flange_link: Option<String>,
    /// URDF: the controller's tool link, `[tool]` from the flange (default tool0).
    #[arg(long)]
    pub tool_link: Option<String>,
    /// URDF: only the `<joint>` elements, with these link names. Their link frames are ours (each
    /// joint's frame at the fixed part of the one before), not a vendor description's: meshes
    /// placed in a vendor's link frames would be misplaced. For UR robots use --format
    /// ur-kinematics-yaml, which ur_description composes with its own link frames.
    #[arg(long)]
    pub joints_only: bool,
    /// URDF and UR YAML: export the geometry of a model with joint maps or gravity compliance
    /// (which they cannot carry) instead of refusing it.
    #[arg(long)]
    pub geometry_only: bool,
}

/// Runs `calib export`; returns the number of bytes written. Robots of 2 to 9 joints, with their
/// joint maps and gravity compliance; the UR kinematics file for 6-joint robots.
pub fn export(options: &ExportOptions) -> anyhow::Result<usize> {
    let file = RobotFile::read(&options.params)?;
    let bytes = export_bytes(options, &file)?;
    let mut outputs = Outputs::new(&[("--params", &options.params)]);
    outputs.stage("--out", &options.out, &bytes)?;
    outputs.commit()?;
    Ok(bytes.len())
}

/// The bytes `calib export` writes for the robot file `file` (read from `options.params`), as the
/// library's [`ExportRequest`] of these options.
pub fn export_bytes(options: &ExportOptions, file: &RobotFile) -> anyhow::Result<Vec<u8>> {
    Ok(options.request().export(file, &options.params)?)
}

impl ExportOptions {
    /// The library's request of these options.
    pub fn request(&self) -> ExportRequest {
        ExportRequest {
            format: self.format,
            scalar: self.scalar,
            sequence: self.sequence,
            link_names: self.link_names.clone(),
            joint_names: self.joint_names.clone(),
            base_link: self.base_link.clone(),
            flange_link: self.flange_link.clone(),
            tool_link: self.tool_link.clone(),
            joints_only: self.joints_only,
            geometry_only: self.geometry_only,
        }
    }
}
