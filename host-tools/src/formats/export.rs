//! Exports of an identified robot: the controller's parameter block (f32 or f64, byte-identical
//! to [`calib_core::controller::storage::encode`], version 1, for a geometric model, and to
//! [`calib_core::controller::storage::encode_model`], version 2, for a model with joint maps or
//! gravity compliance), a
//! robot file (TOML) or JSON; the geometry as a URDF or a UR kinematics YAML; and the f64 -> f32
//! model cast the controller's single-precision core needs.

use crate::JOINTS;
use crate::io::robot_file::{RobotFile, RobotModel};
use crate::model::compliance::FileCompliance;
use crate::model::controller_model;
use crate::model::joint_maps::{JointMaps, MAX_FILE_HARMONICS};
use calib_core::controller::storage::{self, ControllerModel};
use nalgebra::Dyn;

/// Formats of `calib export`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// The controller's binary parameter block (calib_core::controller::storage), byte-identical to what the
    /// core writes.
    Block,
    /// A robot file (TOML).
    Toml,
    /// The robot file as JSON.
    Json,
    /// The geometry as a URDF whose joint origins reproduce calib's forward kinematics exactly
    /// ([`crate::formats::urdf`]).
    Urdf,
    /// The geometry as the `kinematics:` YAML of Universal Robots' ROS description packages
    /// ([`crate::formats::ur_kinematics`]).
    UrKinematicsYaml,
}

/// Scalar of the exported block.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BlockScalar {
    /// Single precision, for a Cortex-M4F.
    F32,
    /// Double precision.
    F64,
}

/// The controller's parameter block of `robot` (the identified model), its joint maps and its
/// gravity compliance, if any, with `sequence`, in the scalar type of the controller's core.
/// With maps or compliance the block is version 2 with the maps' harmonics (and the compliance
/// section); a controller reads it when built with room for at least as many harmonics (the
/// reference firmware: 64).
pub fn parameter_block(
    robot: &calib_core::Robot<f64, Dyn>,
    maps: Option<&JointMaps>,
    compliance: Option<&FileCompliance>,
    scalar: BlockScalar,
    sequence: u32,
) -> crate::Result<Vec<u8>> {
    if maps.is_some() || compliance.is_some() {
        return Ok(match scalar {
            BlockScalar::F64 => model_block(controller_model(*robot, maps, compliance)?, sequence)?,
            BlockScalar::F32 => {
                model_block(controller_model(to_f32(robot), maps, compliance)?, sequence)?
            }
        });
    }
    geometry_block(robot, scalar, sequence)
}

/// The version 1 parameter block of `robot` (geometry, limits, frames) of any joint count.
pub(crate) fn geometry_block(
    robot: &calib_core::Robot<f64, Dyn>,
    scalar: BlockScalar,
    sequence: u32,
) -> crate::Result<Vec<u8>> {
    Ok(match scalar {
        BlockScalar::F64 => {
            let mut buffer = vec![0u8; storage::block_len::<f64>(robot.joints.len())];
            storage::encode(robot, sequence, &mut buffer)?;
            buffer
        }
        BlockScalar::F32 => {
            let mut buffer = vec![0u8; storage::block_len::<f32>(robot.joints.len())];
            storage::encode(&to_f32(robot), sequence, &mut buffer)?;
            buffer
        }
    })
}

/// A version 2 block of `model`.
fn model_block<T: calib_core::Real>(
    model: ControllerModel<T, Dyn, MAX_FILE_HARMONICS>,
    sequence: u32,
) -> crate::Result<Vec<u8>> {
    let mut buffer = vec![
        0u8;
        storage::model_block_len::<T>(
            model.robot.joints.len(),
            model.maps.harmonics(),
            model.compliance.is_active()
        )
    ];
    storage::encode_model(&model, sequence, &mut buffer)?;
    Ok(buffer)
}

/// An export as asked for: the format and the options given, each an option of some formats
/// only. [`ExportRequest::export`] refuses an option of another format (naming it by its
/// command-line flag) and exports: the one place `calib export` and the Python package's
/// `Robot.export` share.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExportRequest {
    /// The format.
    pub format: ExportFormat,
    /// The block's scalar (block only; default f32).
    pub scalar: Option<BlockScalar>,
    /// The block's sequence number (block only; default 1).
    pub sequence: Option<u32>,
    /// The links after each joint (URDF only; default `link_1..link_N`).
    pub link_names: Option<Vec<String>>,
    /// The joints (URDF only; default `joint_1..joint_N`).
    pub joint_names: Option<Vec<String>>,
    /// The root link (URDF only; default `base_link`).
    pub base_link: Option<String>,
    /// The flange link (URDF only; default `flange`).
    pub flange_link: Option<String>,
    /// The tool link (URDF only; default `tool0`).
    pub tool_link: Option<String>,
    /// Only the `<joint>` elements (URDF only).
    pub joints_only: bool,
    /// The geometry of a model with joint maps or compliance (URDF and UR kinematics YAML,
    /// which cannot carry them).
    pub geometry_only: bool,
}

impl ExportRequest {
    /// `format` with no option given.
    pub fn new(format: ExportFormat) -> Self {
        Self {
            format,
            scalar: None,
            sequence: None,
            link_names: None,
            joint_names: None,
            base_link: None,
            flange_link: None,
            tool_link: None,
            joints_only: false,
            geometry_only: false,
        }
    }

    /// The export of the robot file `file` (read from `path`, which names it in errors), or the
    /// refusal of an option of another format.
    pub fn export(&self, file: &RobotFile, path: &std::path::Path) -> crate::Result<Vec<u8>> {
        self.check_format()?;
        crate::model::counts::joint_count(file.joint.len())?;
        let model = file.to_model(path)?;
        export(
            file,
            &model,
            self.format,
            self.scalar.unwrap_or(BlockScalar::F32),
            self.sequence.unwrap_or(1),
            &self.urdf_settings(file),
        )
    }

    /// Refuses an option given for a format it is not an option of.
    fn check_format(&self) -> crate::Result<()> {
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
                return Err(crate::Error::conflict(
                    &[flag, "--format"],
                    format!(
                        "{flag} is an option of --format {}, and --format is {}: drop {flag}",
                        names.join(" and "),
                        format_name(self.format)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The URDF names of the request (defaults for the file's joint count).
    fn urdf_settings(&self, file: &RobotFile) -> crate::formats::urdf::UrdfSettings {
        let mut urdf = crate::formats::urdf::UrdfSettings::named_for(&file.name, file.joint.len());
        if let Some(names) = &self.link_names {
            urdf.links.clone_from(names);
        }
        if let Some(names) = &self.joint_names {
            urdf.joints.clone_from(names);
        }
        for (name, option) in [
            (&mut urdf.base_link, &self.base_link),
            (&mut urdf.flange, &self.flange_link),
            (&mut urdf.tool, &self.tool_link),
        ] {
            if let Some(given) = option {
                name.clone_from(given);
            }
        }
        urdf.joints_only = self.joints_only;
        urdf.geometry_only = self.geometry_only;
        urdf
    }
}

/// The name `--format` takes for `format`.
pub fn format_name(format: ExportFormat) -> String {
    clap::ValueEnum::to_possible_value(&format)
        .map_or_else(String::new, |v| v.get_name().to_owned())
}

/// `file` (an identified robot file of any joint count) in `format`; `scalar` and `sequence` for the
/// block, `urdf` for the URDF (names; whether a file with joint maps or compliance may be
/// exported as its geometry alone, also for the UR YAML). The block carries the joint maps and
/// the gravity compliance of any joint count; the UR kinematics file is for 6-joint robots.
pub fn export(
    file: &RobotFile,
    model: &RobotModel,
    format: ExportFormat,
    scalar: BlockScalar,
    sequence: u32,
    urdf: &crate::formats::urdf::UrdfSettings,
) -> crate::Result<Vec<u8>> {
    let source = model.path.display().to_string();
    let geometry = |what: &str| -> crate::Result<()> {
        let beyond = match (file.joint_maps.is_some(), file.compliance.is_some()) {
            (true, true) => "joint maps and gravity compliance",
            (true, false) => "joint maps",
            (false, true) => "gravity compliance",
            (false, false) => return Ok(()),
        };
        if urdf.geometry_only {
            return Ok(());
        }
        Err(crate::refused!(unsupported what;
            "{source}: the model has {beyond}, which {what} cannot carry: exported, it would be less accurate \
             than the model (Series B: 0.43 against 0.21 mm held out). Pass --geometry-only to export the geometry \
             anyway, or use --format block for the controller"
        ))
    };
    Ok(match format {
        ExportFormat::Block => {
            let actual =
                crate::kinematics::actual::ActualRobot::from_file(file.clone(), &model.path)?;
            parameter_block(
                &actual.model.robot,
                actual.maps.as_ref(),
                actual.compliance.as_ref(),
                scalar,
                sequence,
            )?
        }
        ExportFormat::UrKinematicsYaml => {
            let joints = model.robot.joints.len();
            if joints != JOINTS {
                return Err(crate::refused!(unsupported "UR kinematics file";
                    "{source}: a UR kinematics file describes a {JOINTS}-joint UR robot; this one has {joints} joints"
                ));
            }
            geometry("a UR kinematics file")?;
            crate::formats::ur_kinematics::yaml(&model.robot, &source)?.into_bytes()
        }
        ExportFormat::Urdf => {
            geometry("a URDF")?;
            geometry_formats(file, model, format, scalar, sequence, urdf)?
        }
        ExportFormat::Toml | ExportFormat::Json => {
            geometry_formats(file, model, format, scalar, sequence, urdf)?
        }
    })
}

/// The formats of the geometry alone, for any joint count: the version 1 block, TOML, JSON and
/// a URDF (the UR kinematics file describes a 6-joint UR robot: other counts are refused).
fn geometry_formats(
    file: &RobotFile,
    model: &RobotModel,
    format: ExportFormat,
    scalar: BlockScalar,
    sequence: u32,
    urdf: &crate::formats::urdf::UrdfSettings,
) -> crate::Result<Vec<u8>> {
    let source = model.path.display().to_string();
    Ok(match format {
        ExportFormat::Block => geometry_block(&model.robot, scalar, sequence)?,
        ExportFormat::Toml => file.to_toml("exported by calib export").into_bytes(),
        ExportFormat::Json => serde_json::to_vec_pretty(file)?,
        ExportFormat::Urdf => crate::formats::urdf::urdf(&model.robot, urdf, &source)?.into_bytes(),
        ExportFormat::UrKinematicsYaml => {
            return Err(crate::refused!(unsupported "UR kinematics file";
                "{source}: a UR kinematics file describes a {JOINTS}-joint UR robot; this one has {} joints",
                model.robot.joints.len()
            ));
        }
    })
}

/// The model rounded to single precision (limits stay infinite where they are).
pub fn to_f32(robot: &calib_core::Robot<f64, Dyn>) -> calib_core::Robot<f32, Dyn> {
    let f = |v: f64| v as f32;
    calib_core::Robot {
        joints: robot.joints.map(|j| calib_core::MdhJoint {
            a: f(j.a),
            alpha: f(j.alpha),
            theta_offset: f(j.theta_offset),
            d: f(j.d),
            beta: f(j.beta),
        }),
        limits: robot.limits.map(|l| calib_core::JointLimits {
            lower: f(l.lower),
            upper: f(l.upper),
        }),
        base: calib_core::FramePose {
            xyz: robot.base.xyz.map(f),
            rpy: robot.base.rpy.map(f),
        },
        tool: calib_core::FramePose {
            xyz: robot.tool.xyz.map(f),
            rpy: robot.tool.rpy.map(f),
        },
    }
}
