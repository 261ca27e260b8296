//! `calib export`: an identified robot file as the controller's parameter block, TOML, JSON, a
//! URDF or a UR kinematics YAML.

use crate::formats::export::{BlockScalar, ExportFormat};
use crate::io::outputs::Outputs;
use crate::io::robot_file::{RobotFile, RobotModel};
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
    /// URDF: the links after joints 1..N, comma-separated (default link_1,...,link_N).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub link_names: Option<Vec<String>>,
    /// URDF: the revolute joints, comma-separated (default joint_1,...,joint_N).
    #[arg(long, value_delimiter = ',', value_name = "NAMES")]
    pub joint_names: Option<Vec<String>>,
    /// URDF: the root link, where the robot file's `[base]` is given.
    #[arg(long, default_value = "base_link")]
    pub base_link: String,
    /// URDF: the flange link (after the last joint's fixed part).
    #[arg(long, default_value = "flange")]
    pub flange_link: String,
    /// URDF: the controller's tool link (`[tool]` from the flange).
    #[arg(long, default_value = "tool0")]
    pub tool_link: String,
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

/// Runs `calib export`; returns the number of bytes written. Robots of 2 to 9 joints; joint
/// maps, gravity compliance and the UR kinematics file for 6-joint robots.
pub fn export(options: &ExportOptions) -> anyhow::Result<usize> {
    let file = RobotFile::read(&options.params)?;
    let bytes = export_bytes(options, &file)?;
    let mut outputs = Outputs::new(&[("--params", &options.params)]);
    outputs.stage("--out", &options.out, &bytes)?;
    outputs.commit()?;
    Ok(bytes.len())
}

/// The bytes `calib export` writes for `file` (read from `options.params`, which names it in
/// messages); `options.out` is not used.
pub fn export_bytes(options: &ExportOptions, file: &RobotFile) -> anyhow::Result<Vec<u8>> {
    let urdf = urdf_settings(options, file);
    crate::model::counts::joint_count(file.joint.len())?;
    exported(options, file, &urdf)
}

/// The bytes `calib export` writes for `file`.
fn exported(
    options: &ExportOptions,
    file: &RobotFile,
    urdf: &crate::formats::urdf::UrdfSettings,
) -> anyhow::Result<Vec<u8>> {
    let model: RobotModel = file.to_model(&options.params)?;
    Ok(crate::formats::export::export(
        file,
        &model,
        options.format,
        options.scalar,
        options.sequence,
        urdf,
    )?)
}

/// The URDF names of the options (defaults for the file's joint count).
fn urdf_settings(options: &ExportOptions, file: &RobotFile) -> crate::formats::urdf::UrdfSettings {
    let mut urdf = crate::formats::urdf::UrdfSettings::named_for(&file.name, file.joint.len());
    if let Some(names) = &options.link_names {
        urdf.links.clone_from(names);
    }
    if let Some(names) = &options.joint_names {
        urdf.joints.clone_from(names);
    }
    urdf.base_link.clone_from(&options.base_link);
    urdf.flange.clone_from(&options.flange_link);
    urdf.tool.clone_from(&options.tool_link);
    urdf.joints_only = options.joints_only;
    urdf.geometry_only = options.geometry_only;
    urdf
}
