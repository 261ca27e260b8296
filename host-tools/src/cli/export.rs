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
    options.check_format()?;
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
        options.scalar.unwrap_or(BlockScalar::F32),
        options.sequence.unwrap_or(1),
        urdf,
    )?)
}

impl ExportOptions {
    /// Refuses an option of another format than `--format`'s: it would change nothing.
    fn check_format(&self) -> anyhow::Result<()> {
        use ExportFormat::{Block, UrKinematicsYaml, Urdf};
        let given: [(&str, bool, &[ExportFormat]); 9] = [
            ("--scalar", self.scalar.is_some(), &[Block]),
            ("--sequence", self.sequence.is_some(), &[Block]),
            ("--link-names", self.link_names.is_some(), &[Urdf]),
            ("--joint-names", self.joint_names.is_some(), &[Urdf]),
            ("--base-link", self.base_link.is_some(), &[Urdf]),
            ("--flange-link", self.flange_link.is_some(), &[Urdf]),
            ("--tool-link", self.tool_link.is_some(), &[Urdf]),
            ("--joints-only", self.joints_only, &[Urdf]),
            // The formats that cannot carry joint maps or compliance.
            (
                "--geometry-only",
                self.geometry_only,
                &[Urdf, UrKinematicsYaml],
            ),
        ];
        for (flag, is_given, formats) in given {
            if is_given && !formats.contains(&self.format) {
                let names: Vec<String> = formats.iter().map(|f| format_name(*f)).collect();
                anyhow::bail!(
                    "{flag} is an option of --format {}, and --format is {}: drop {flag}",
                    names.join(" and "),
                    format_name(self.format)
                );
            }
        }
        Ok(())
    }
}

/// The name `--format` takes for `format`.
fn format_name(format: ExportFormat) -> String {
    clap::ValueEnum::to_possible_value(&format)
        .map_or_else(String::new, |v| v.get_name().to_owned())
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
    for (name, option) in [
        (&mut urdf.base_link, &options.base_link),
        (&mut urdf.flange, &options.flange_link),
        (&mut urdf.tool, &options.tool_link),
    ] {
        if let Some(given) = option {
            name.clone_from(given);
        }
    }
    urdf.joints_only = options.joints_only;
    urdf.geometry_only = options.geometry_only;
    urdf
}
