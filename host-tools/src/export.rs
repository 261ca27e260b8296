//! `calib export`: identified parameters as the controller's parameter block (f32 or f64,
//! byte-identical to [`calib_core::controller::storage::encode`]), a robot file (TOML) or JSON; and
//! the f64 -> f32 model cast the controller's single-precision core needs.

use crate::files::write_atomic;
use crate::robot_file::{RobotFile, RobotModel};
use calib_core::controller::storage;
use std::path::PathBuf;

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
}

/// Scalar of the exported block.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BlockScalar {
    /// Single precision, for a Cortex-M4F.
    F32,
    /// Double precision.
    F64,
}

/// Options of `calib export`.
#[derive(Clone, Debug, clap::Args)]
pub struct ExportOptions {
    /// Identified robot file.
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
    let model: RobotModel<6> = file.to_model(&options.params)?;
    let bytes = match options.format {
        ExportFormat::Block => match options.scalar {
            BlockScalar::F64 => {
                let mut buffer = vec![0u8; storage::block_len::<f64, 6>()];
                storage::encode(&model.robot, options.sequence, &mut buffer)
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
                buffer
            }
            BlockScalar::F32 => {
                let robot = to_f32(&model.robot);
                let mut buffer = vec![0u8; storage::block_len::<f32, 6>()];
                storage::encode(&robot, options.sequence, &mut buffer)
                    .map_err(|e| anyhow::anyhow!("{e}"))?;
                buffer
            }
        },
        ExportFormat::Toml => file.to_toml("exported by calib export").into_bytes(),
        ExportFormat::Json => serde_json::to_vec_pretty(&file)?,
    };
    write_atomic(&options.out, &bytes)?;
    Ok(bytes.len())
}

/// The model rounded to single precision (limits stay infinite where they are).
pub fn to_f32(robot: &calib_core::Robot<f64, 6>) -> calib_core::Robot<f32, 6> {
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
