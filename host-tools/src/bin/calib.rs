//! `calib`: robot geometric calibration from laser-tracker data.

use anyhow::Context;
use clap::{Parser, Subcommand};
use host_tools::fk;
use host_tools::robot_file::RobotModel;
use std::path::PathBuf;

/// Robot geometric calibration and pose compensation (lengths in mm, angles in degrees at the
/// command line and in files, radians inside).
#[derive(Debug, Parser)]
#[command(name = "calib", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print the end pose of a robot model for joint readings (forward kinematics).
    Fk {
        /// Robot model file (TOML; see host-tools/robots/er10l-c10.toml).
        #[arg(long, value_name = "FILE")]
        robot: PathBuf,
        /// Joint readings q1,...,qN in degrees, comma-separated.
        #[arg(
            long,
            value_name = "DEG,...",
            value_delimiter = ',',
            allow_hyphen_values = true,
            required = true
        )]
        joints_deg: Vec<f64>,
        /// Print one JSON object (position_mm, quaternion_wxyz, rotation_vector_rad).
        #[arg(long)]
        json: bool,
    },
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::Fk {
            robot,
            joints_deg,
            json,
        } => {
            let model = RobotModel::<6>::load(&robot)?;
            let pose = fk::forward_deg(&model, &joints_deg)?;
            if json {
                println!(
                    "{}",
                    serde_json::to_string(&pose).context("serialising the pose")?
                );
            } else {
                println!("robot: {} ({})", model.name, robot.display());
                print!("{}", pose.to_text());
            }
        }
    }
    Ok(())
}
