//! `calib`: robot geometric calibration from laser-tracker data.

use anyhow::Context;
use clap::{Parser, Subcommand};
use host_tools::calibrate::{self, CalibrateOptions};
use host_tools::check::{self, CheckOptions};
use host_tools::compensate::CompensateOptions;
use host_tools::export::ExportOptions;
use host_tools::fk;
use host_tools::robot_file::RobotModel;
use host_tools::simulate::{self, Simulation};
use std::path::PathBuf;

/// Robot geometric calibration and pose compensation. Lengths in mm, angles in degrees in files
/// and at the command line unless an option's name says `rad`.
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
    /// Simulate tracker measurements of a robot with known errors (the paper's section 3.1).
    Simulate(Simulation),
    /// Identify the robot's parameter errors from tracker data.
    Calibrate(CalibrateOptions),
    /// Print which identified parameters the data determine (identifiability), without calibrating.
    Check(CheckOptions),
    /// Print the Table 3 statistics of any robot model on any data.
    Evaluate(host_tools::evaluate::EvaluateOptions),
    /// Joints that put the identified robot on target poses (on-line compensation, off line).
    Compensate(CompensateOptions),
    /// Write identified parameters as the controller's parameter block, TOML or JSON.
    Export(ExportOptions),
    /// Calibrate with the f32 core, the f64 core and the independent reference optimiser and
    /// compare; exits with status 1 when a difference is past its documented tolerance.
    Verify(host_tools::verify::VerifyOptions),
    /// Run the paper's experiment and a realistic cell on simulated data, no input files needed;
    /// prints the tables and writes data, reports and plots into a directory.
    Demo(host_tools::demo::DemoOptions),
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
        Command::Simulate(settings) => {
            let simulated = simulate::simulate(&settings)?;
            println!(
                "wrote {} poses to {} and the true robot to {}",
                simulated.rows.len(),
                settings.out.display(),
                settings.truth_out.display()
            );
        }
        Command::Compensate(options) => {
            let summary = host_tools::compensate::compensate(&options)?;
            println!(
                "compensated {} of {} targets ({} refused, see the status column); wrote {}",
                summary.ok,
                summary.ok + summary.failed,
                summary.failed,
                options.out.display()
            );
        }
        Command::Export(options) => {
            let bytes = host_tools::export::export(&options)?;
            println!("wrote {} bytes to {}", bytes, options.out.display());
        }
        Command::Evaluate(options) => {
            let table = host_tools::evaluate::evaluate(&options)?;
            if options.json {
                println!("{}", serde_json::to_string_pretty(&table)?);
            } else {
                print!(
                    "{}",
                    host_tools::report::table3_single_text(
                        &format!(
                            "{} on {}",
                            options.input.robot.display(),
                            options.input.data.display()
                        ),
                        &table
                    )
                );
            }
        }
        Command::Check(options) => {
            let report = check::check(&options)?;
            if options.json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", report.text());
            }
        }
        Command::Verify(options) => {
            let verification = host_tools::verify::verify(&options)?;
            if options.json {
                println!("{}", serde_json::to_string_pretty(&verification)?);
            } else {
                print!("{}", verification.text());
            }
            if !verification.passed {
                std::process::exit(1);
            }
        }
        Command::Demo(options) => host_tools::demo::demo(&options)?,
        Command::Calibrate(options) => {
            let calibration = calibrate::calibrate(&options)?;
            print!("{}", calibration.text);
            for path in calibrate::write_outputs(&calibration, &options)? {
                println!("wrote {}", path.display());
            }
        }
    }
    Ok(())
}
