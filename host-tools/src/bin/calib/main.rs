//! `calib`: robot geometric calibration from laser-tracker data.

mod cli;

use crate::cli::calibrate::{self, CalibrateOptions};
use crate::cli::check::{self, CheckOptions};
use crate::cli::compensate::CompensateOptions;
use crate::cli::export::ExportOptions;
use crate::cli::print;
use crate::cli::simulate::{self, Simulation};
use anyhow::Context;
use clap::{Parser, Subcommand};
use host_tools::kinematics::fk;
use std::path::{Path, PathBuf};

/// Robot geometric calibration and pose compensation. Lengths in mm, angles in degrees in files
/// and at the command line unless an option's name says `rad`.
#[derive(Debug, Parser)]
#[command(name = "calib", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Largest input file, MiB, for every input (default: 1024 for data, candidates and reports,
    /// 16 for robot files, profiles and UR calibrations). Raise it for a larger file.
    #[arg(long, global = true, value_name = "MiB", value_parser = clap::value_parser!(u64).range(1..=1 << 30))]
    max_input_mb: Option<u64>,
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
    /// Calibrate many robots from a manifest (TOML: calibrate's options for each robot), each
    /// as calibrate would alone: its identified file, report and certificate in --out-dir
    /// SERIAL/, optionally registered, and a summary of all. Exits with status 1 when a robot was
    /// refused, 3 when an acceptance criterion failed.
    Batch(crate::cli::batch::BatchOptions),
    /// Choose the poses to measure (a D-optimal core, random fill and verification poses) from
    /// candidate joint configurations, predict the accuracy they give, and write the plan as a
    /// tracker CSV to be filled by the tracker software.
    Plan(crate::cli::plan::PlanOptions),
    /// Identify the geometry without an instrument: a ball on the flange touched in sockets
    /// from many configurations (joint readings only), with a known distance between sockets.
    Sockets(crate::cli::sockets::SocketsOptions),
    /// Choose the configurations to record in each socket of a placement (greedy D-optimal
    /// over the reachable ones) and predict what their calibration gives.
    PlanSockets(crate::cli::plan_sockets::PlanSocketsOptions),
    /// Print which identified parameters the data determine (identifiability), without calibrating.
    Check(CheckOptions),
    /// Print the Table 3 statistics of any robot model on any data.
    Evaluate(crate::cli::evaluate::EvaluateOptions),
    /// Joints that put the identified robot on target poses (on-line compensation, off line).
    Compensate(CompensateOptions),
    /// Write identified parameters as the controller's parameter block, TOML, JSON, a URDF or a
    /// UR kinematics YAML.
    Export(ExportOptions),
    /// Render a calibration's JSON report (calibrate --report) as a self-contained HTML page.
    Report(crate::cli::report::ReportOptions),
    /// Convert a Universal Robots controller's factory calibration (calibration.conf) into a
    /// robot file: the same geometry in Hayati parameters.
    ImportUrCalibration(crate::cli::import_ur::ImportUrOptions),
    /// Convert a robot's URDF (the chain from a base link to a tip link) into a robot file whose
    /// kinematics equal the URDF's.
    ImportUrdf(crate::cli::import_urdf::ImportUrdfOptions),
    /// The identified model's predicted uncertainty (1 sigma) at joint configurations, from the
    /// parameters' covariance its robot file records.
    Uncertainty(crate::cli::uncertainty::UncertaintyOptions),
    /// Merge a tracker's export of the measured points into the plan it measured (by id or by
    /// order, joints checked when the export has them): data that calibrate takes directly.
    Merge(crate::cli::merge::MergeOptions),
    /// Calibrate with the f32 core, the f64 core and the independent reference optimiser and
    /// compare; exits with status 1 when a difference is past its documented tolerance.
    Verify(crate::cli::verify::VerifyOptions),
    /// Check the robot against its registered calibration with a short set of measured poses
    /// (at the start of a shift): each pose against its predicted uncertainty, the likely cause
    /// of a drift named, the check recorded and the drift over time stated. Exits with status
    /// 3 on drift.
    CheckShift(crate::cli::check_shift::CheckShiftOptions),
    /// Keep every calibration of every robot in one SQLite file (--db, calib.db by default):
    /// register a report with the files beside it, list, show, export.
    Registry(crate::cli::registry::RegistryOptions),
    /// The ISO 9283 pose test: plan the test cube, its five points and the program of n
    /// cycles; evaluate the measured run (pose accuracy and repeatability AP, RP, distance AD,
    /// RD, drift).
    Iso9283(crate::cli::iso9283::Iso9283Options),
    /// Run the paper's experiment and a realistic cell on simulated data, no input files needed;
    /// prints the tables and writes data, reports and plots into a directory.
    Demo(crate::cli::demo::DemoOptions),
}

/// `calib merge`: merges, writes, says what it wrote.
fn merge(options: &crate::cli::merge::MergeOptions) -> anyhow::Result<()> {
    let merged = crate::cli::merge::merge(options)?;
    crate::cli::print_line(format_args!(
        "merged {} measured poses into the plan; wrote {}",
        merged.rows.len(),
        options.out.display()
    ))
}

/// Runs the command; a user error is reported as a message with its causes, never with a stack
/// backtrace (even under `RUST_BACKTRACE=1`), and exit status 1.
fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    if let Some(mib) = cli.max_input_mb {
        host_tools::io::input::set_limit_mib(mib);
    }
    let command = cli.command;
    match host_tools::io::outputs::clean_up_on_interrupt()
        .map_err(anyhow::Error::from)
        .and_then(|()| run(command))
    {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(error) => {
            let mut message = format!("Error: {error}\n");
            let causes: Vec<String> = error.chain().skip(1).map(ToString::to_string).collect();
            if !causes.is_empty() {
                message.push_str("\nCaused by:\n");
                for cause in causes {
                    message.push_str(&format!("    {cause}\n"));
                }
            }
            let _ = std::io::Write::write_all(&mut std::io::stderr(), message.as_bytes());
            std::process::ExitCode::FAILURE
        }
    }
}

/// `calib calibrate`: calibrates, writes, prints; exits with [`ACCEPTANCE_FAILED`] when an
/// acceptance criterion is not met (after the files are written).
fn calibrate_command(mut options: CalibrateOptions) -> anyhow::Result<()> {
    options.command_line = std::env::args().collect();
    let written = calibrate::calibrate_and_write(&options)?;
    print(&written.text)?;
    if written.accepted == Some(false) {
        acceptance_failed();
    }
    Ok(())
}

/// `calib batch`: calibrates every robot of the manifest, prints the summary; an error when a
/// robot was refused, exit status [`ACCEPTANCE_FAILED`] when an acceptance criterion failed
/// (after every file is written).
fn batch_command(options: &crate::cli::batch::BatchOptions) -> anyhow::Result<()> {
    let batch = crate::cli::batch::batch(options)?;
    print(&batch.text)?;
    let refused = batch.rows.iter().filter(|r| r.status == "refused").count();
    if refused > 0 {
        anyhow::bail!(
            "{refused} of {} robots were refused (the reasons above and in {}); the others' files were written",
            batch.rows.len(),
            options.out_dir.join(crate::cli::batch::SUMMARY).display()
        );
    }
    if batch.rows.iter().any(|r| r.status == "FAIL") {
        acceptance_failed();
    }
    Ok(())
}

/// Ends the process with [`ACCEPTANCE_FAILED`] after what was printed, saying so on standard
/// error (the files were written: a failed criterion is a result, not a refusal).
fn acceptance_failed() -> ! {
    let _ = std::io::Write::flush(&mut std::io::stdout());
    let _ = std::io::Write::write_all(
        &mut std::io::stderr(),
        b"Error: an acceptance criterion is not met (FAIL above and in the reports); the files were written\n",
    );
    std::process::exit(ACCEPTANCE_FAILED);
}

/// `calib simulate`: simulates, writes, says what it wrote.
fn simulate_command(settings: &Simulation) -> anyhow::Result<()> {
    let poses = simulate::simulate(settings)?;
    crate::cli::print_line(format_args!(
        "wrote {} poses to {} and the true robot to {}",
        poses,
        settings.out.display(),
        settings.truth_out.display()
    ))
}

/// `calib compensate`: compensates, writes, says how many targets were compensated.
fn compensate(options: &crate::cli::compensate::CompensateOptions) -> anyhow::Result<()> {
    let summary = crate::cli::compensate::compensate(options)?;
    let extrapolated = if summary.extrapolated > 0 {
        format!(
            ", {} with a joint map extrapolated beyond its identified readings",
            summary.extrapolated
        )
    } else {
        String::new()
    };
    let moves = match &summary.largest_move {
        Some((id, joint, deg)) => format!(
            ", {} with a joint moved by more than {} deg from the given joints (near a singularity; largest: target {id}, joint {joint} by {deg:.3} deg)",
            summary.large_moves,
            host_tools::kinematics::compensate::LARGE_MOVE_DEG
        ),
        None => String::new(),
    };
    crate::cli::print_line(format_args!(
        "compensated {} of {} targets ({} refused, see the status column{extrapolated}{moves}); wrote {}",
        summary.ok,
        summary.ok + summary.failed,
        summary.failed,
        options.out.display()
    ))?;
    Ok(())
}

/// Exit status of `calib calibrate` when an acceptance criterion (`--accept`) is not met.
const ACCEPTANCE_FAILED: i32 = 3;

fn run(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Fk {
            robot,
            joints_deg,
            json,
        } => forward_kinematics(&robot, &joints_deg, json)?,
        Command::Simulate(settings) => simulate_command(&settings)?,
        Command::Compensate(options) => compensate(&options)?,
        Command::Export(options) => {
            let bytes = crate::cli::export::export(&options)?;
            crate::cli::print_line(format_args!(
                "wrote {} bytes to {}",
                bytes,
                options.out.display()
            ))?;
        }
        Command::Report(options) => {
            crate::cli::report::report(&options)?;
            for path in options.html.iter().chain(&options.pdf) {
                crate::cli::print_line(format_args!("wrote {}", path.display()))?;
            }
        }
        Command::ImportUrCalibration(options) => {
            let (_, text) = crate::cli::import_ur::import(&options)?;
            crate::cli::print_text(format_args!("{text}"))?;
        }
        Command::Merge(options) => merge(&options)?,
        Command::ImportUrdf(options) => {
            let text = crate::cli::import_urdf::import_urdf(&options)?;
            crate::cli::print_text(format_args!("{text}"))?;
        }
        Command::Uncertainty(options) => {
            let summary = crate::cli::uncertainty::uncertainty(&options)?;
            crate::cli::print_text(format_args!("{}", summary.text(&options.out)))?;
        }
        Command::Evaluate(options) => evaluate(&options)?,
        Command::Plan(options) => {
            let plan = crate::cli::plan::plan(&options)?;
            crate::cli::print_text(format_args!("{}", plan.text()))?;
            crate::cli::print_line(format_args!("wrote {}", options.out.display()))?;
            if let Some(path) = &options.report {
                crate::cli::print_line(format_args!("wrote {}", path.display()))?;
            }
        }
        Command::Check(options) => {
            let report = check::check(&options)?;
            print_json_or_text(options.json, &report, || report.text())?;
        }
        Command::Verify(options) => {
            let verification = crate::cli::verify::verify(&options)?;
            print_json_or_text(options.json, &verification, || verification.text())?;
            if !verification.passed {
                std::process::exit(1);
            }
        }
        Command::Demo(options) => crate::cli::demo::demo(&options)?,
        Command::Sockets(mut options) => {
            options.command_line = std::env::args().collect();
            let text = crate::cli::sockets::sockets(&options)?;
            crate::cli::print_text(format_args!("{text}"))?;
            let written = [&options.out, &options.report, &options.html, &options.pdf];
            for path in written.into_iter().flatten() {
                crate::cli::print_line(format_args!("wrote {}", path.display()))?;
            }
        }
        Command::PlanSockets(options) => crate::cli::plan_sockets::run(&options)?,
        Command::Registry(options) => crate::cli::registry::run(&options)?,
        Command::CheckShift(options) => crate::cli::check_shift::run(&options)?,
        Command::Iso9283(options) => crate::cli::iso9283::run(&options)?,
        Command::Calibrate(options) => calibrate_command(options)?,
        Command::Batch(options) => batch_command(&options)?,
    }
    Ok(())
}

/// Prints `value` as pretty JSON, or the text for people.
fn print_json_or_text<T: serde::Serialize>(
    json: bool,
    value: &T,
    text: impl FnOnce() -> String,
) -> anyhow::Result<()> {
    if json {
        crate::cli::print_line(format_args!("{}", serde_json::to_string_pretty(value)?))?;
    } else {
        crate::cli::print_text(format_args!("{}", text()))?;
    }
    Ok(())
}

/// `calib fk`: the end pose of a robot file for joint readings in degrees (2 to 9 joints, with
/// their joint maps and gravity compliance).
fn forward_kinematics(robot: &Path, joints_deg: &[f64], json: bool) -> anyhow::Result<()> {
    let file = host_tools::io::robot_file::RobotFile::read(robot)?;
    host_tools::model::counts::joint_count(file.joint.len())?;
    let kinematics = fk::FileKinematics::new(&file, robot)?;
    let pose = fk::forward_deg(&kinematics, joints_deg)?;
    let name = kinematics.name();
    if json {
        crate::cli::print_line(format_args!(
            "{}",
            serde_json::to_string(&pose).context("serialising the pose")?
        ))?;
    } else {
        crate::cli::print_line(format_args!("robot: {} ({})", name, robot.display()))?;
        crate::cli::print_text(format_args!("{}", pose.to_text()))?;
    }
    Ok(())
}

/// `calib evaluate`: Table 3 of a robot file on a data file.
fn evaluate(options: &crate::cli::evaluate::EvaluateOptions) -> anyhow::Result<()> {
    let evaluation = crate::cli::evaluate::evaluate(options)?;
    print_json_or_text(options.json, &evaluation, || {
        let title = format!(
            "{} on {}",
            options.input.robot.display(),
            options.input.data.display()
        );
        host_tools::report::evaluation(&evaluation, &title)
    })
}
