//! `calib demo`: the toolkit on simulated data, without input files. Two runs:
//!
//! 1. The paper's experiment (section 3.1): the ER10L-C10 with the errors of Table 2, 32 poses,
//!    exact 6-DoF measurements in the base frame, identified by the paper's swarm (IPSO).
//! 2. A realistic cell: the tracker 3 m from the robot at an arbitrary orientation, a reflector
//!    150 mm off the flange (position only), tracker noise 0.02 mm, 42 calibration poses and 18
//!    held-out validation poses; the frames are registered and identified with the geometry
//!    (IPSO, then least squares).
//!
//! Everything (robot file, simulated data, truth, identified robots, JSON reports, plots) is
//! written into the output directory so that each step can be rerun with `calib`.

use crate::cli::calibrate::{OutputPaths, write_outputs};
use anyhow::Context;
use host_tools::calibration::{CalibrationConfig, HoldOut, Method, Session, Truth};
use host_tools::io::robot_file::{ER10L_C10_TOML, RobotFile};
use host_tools::measurement::dataset::Dataset;
use host_tools::measurement::simulate::{self, SimulationConfig};
use std::path::{Path, PathBuf};

/// Options of `calib demo`.
#[derive(Clone, Debug, clap::Args)]
pub struct DemoOptions {
    /// Output directory (created if needed).
    #[arg(long, value_name = "DIR", default_value = "calib-demo")]
    pub out: PathBuf,
    /// Never show progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// Simulates with `config` into `dir/data.csv` and `dir/truth.toml` (or the given names).
fn simulate_into(
    robot: &(RobotFile, PathBuf),
    config: &SimulationConfig,
    data: &Path,
    truth: &Path,
) -> anyhow::Result<()> {
    Ok(simulate::simulate(&robot.0, &robot.1, config)?.write(data, truth, &robot.1)?)
}

/// Calibrates `data` (validating on `holdout`), renders against `truth`, writes the identified
/// robot, the report and the plots into `dir`; returns the text and the files written.
fn calibrate_into(
    robot: &Path,
    data: &Path,
    holdout: Option<&Path>,
    truth: Option<&Path>,
    config: &CalibrationConfig,
    dir: &Path,
) -> anyhow::Result<(String, Vec<PathBuf>)> {
    let dataset = Dataset::load(robot, data)?;
    let validation = holdout.map(|h| Dataset::load(robot, h)).transpose()?;
    let truth_file = match truth {
        Some(path) => Some(Truth {
            file: RobotFile::read(path)?,
            path: path.to_path_buf(),
        }),
        None => None,
    };
    let calibration = Session {
        hold_out: validation.map_or(HoldOut::None, HoldOut::poses),
        truth: truth_file,
        ..Session::new(dataset, config.clone())
    }
    .run()?;
    let mut inputs = vec![
        ("--robot", robot.to_path_buf()),
        ("--data", data.to_path_buf()),
    ];
    inputs.extend(holdout.map(|h| ("--holdout", h.to_path_buf())));
    inputs.extend(truth.map(|t| ("--truth", t.to_path_buf())));
    let outputs = OutputPaths {
        out: Some(dir.join("identified.toml")),
        report: Some(dir.join("report.json")),
        html: Some(dir.join("report.html")),
        plot: Some(dir.join("plots")),
        inputs,
    };
    let written = write_outputs(&calibration, &outputs)?;
    Ok((calibration.text(), written))
}

/// Runs the demo and prints its tables.
pub fn demo(options: &DemoOptions) -> anyhow::Result<()> {
    let dir = &options.out;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let robot_path = dir.join("er10l-c10.toml");
    host_tools::io::outputs::write_atomic(&robot_path, ER10L_C10_TOML.as_bytes())?;
    let robot = (
        RobotFile::parse(ER10L_C10_TOML, &robot_path)?,
        robot_path.clone(),
    );
    let progress = !options.quiet;

    // 1. The paper's experiment.
    let paper = dir.join("paper");
    std::fs::create_dir_all(&paper)?;
    let (data, truth) = (paper.join("data.csv"), paper.join("truth.toml"));
    simulate_into(&robot, &SimulationConfig::default(), &data, &truth)?;
    let config = CalibrationConfig {
        method: Method::Ipso,
        progress,
        ..CalibrationConfig::default()
    };
    let (text, mut written) =
        calibrate_into(&robot_path, &data, None, Some(&truth), &config, &paper)?;
    crate::cli::print_line(format_args!(
        "== 1. The paper's experiment: ER10L-C10 with Table 2 errors, 32 exact 6-DoF poses, IPSO ==\n"
    ))?;
    crate::cli::print_text(format_args!("{text}"))?;

    // 2. A realistic cell.
    let cell = dir.join("cell");
    std::fs::create_dir_all(&cell)?;
    let noisy = |poses, seed| {
        SimulationConfig {
            poses,
            seed,
            position_sigma_mm: 0.02,
            position_only: true,
            ..SimulationConfig::default()
        }
        .in_realistic_cell()
    };
    let (data, holdout, truth) = (
        cell.join("data.csv"),
        cell.join("holdout.csv"),
        cell.join("truth.toml"),
    );
    simulate_into(&robot, &noisy(42, 2), &data, &truth)?;
    simulate_into(
        &robot,
        &noisy(18, 3),
        &holdout,
        &cell.join("holdout-truth.toml"),
    )?;
    let config = CalibrationConfig {
        progress,
        ..CalibrationConfig::default()
    };
    let (text, cell_written) =
        calibrate_into(&robot_path, &data, Some(&holdout), None, &config, &cell)?;
    crate::cli::print_line(format_args!(
        "\n== 2. A realistic cell: tracker 3 m away, reflector 150 mm off the flange, 0.02 mm noise, \
         42 poses + 18 held out, frames identified, IPSO then least squares ==\n"
    ))?;
    crate::cli::print_text(format_args!("{text}"))?;
    written.extend(cell_written);
    crate::cli::print_line(format_args!(
        "\nwrote {} files into {} (data, truth, identified robots, reports, plots)",
        written.len() + 7,
        dir.display()
    ))?;
    Ok(())
}
