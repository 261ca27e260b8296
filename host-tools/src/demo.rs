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

use crate::calibrate::{self, CalibrateOptions};
use crate::simulate::{self, Simulation};
use anyhow::Context;
use clap::Parser;
use std::path::{Path, PathBuf};

/// The nominal ER10L-C10 robot file, embedded.
pub const ER10L_C10_TOML: &str = include_str!("../robots/er10l-c10.toml");

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

#[derive(Parser)]
#[command(no_binary_name = true)]
struct Wrap<T: clap::Args> {
    #[command(flatten)]
    inner: T,
}

fn parse<T: clap::Args>(args: &[String]) -> anyhow::Result<T> {
    Ok(Wrap::<T>::try_parse_from(args)?.inner)
}

fn path(p: &Path) -> anyhow::Result<String> {
    p.to_str()
        .map(str::to_string)
        .with_context(|| format!("{} is not valid UTF-8", p.display()))
}

fn strings(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| (*s).to_string()).collect()
}

/// Runs the demo and prints its tables.
pub fn demo(options: &DemoOptions) -> anyhow::Result<()> {
    let dir = &options.out;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let robot = dir.join("er10l-c10.toml");
    crate::files::write_atomic(&robot, ER10L_C10_TOML.as_bytes())?;
    let robot = path(&robot)?;

    // 1. The paper's experiment.
    let paper = dir.join("paper");
    std::fs::create_dir_all(&paper)?;
    let data = path(&paper.join("data.csv"))?;
    let truth = path(&paper.join("truth.toml"))?;
    let mut args = strings(&["--robot", &robot, "--poses", "32", "--seed", "1"]);
    args.extend(strings(&["--out", &data, "--truth-out", &truth]));
    simulate::simulate(&parse::<Simulation>(&args)?)?;
    let mut args = strings(&["--robot", &robot, "--data", &data, "--truth", &truth]);
    args.extend(strings(&["--method", "ipso"]));
    args.extend(strings(&[
        "--out",
        &path(&paper.join("identified.toml"))?,
        "--report",
        &path(&paper.join("report.json"))?,
        "--plot",
        &path(&paper.join("plots"))?,
    ]));
    if options.quiet {
        args.push("--quiet".into());
    }
    let options_paper = parse::<CalibrateOptions>(&args)?;
    let result = calibrate::calibrate(&options_paper)?;
    println!(
        "== 1. The paper's experiment: ER10L-C10 with Table 2 errors, 32 exact 6-DoF poses, IPSO ==\n"
    );
    print!("{}", result.text);
    let mut written = calibrate::write_outputs(&result, &options_paper)?;

    // 2. A realistic cell.
    let cell = dir.join("cell");
    std::fs::create_dir_all(&cell)?;
    let cell_args = |poses: &str, seed: &str, out: &str, truth: &str| {
        let head = [
            "--robot",
            &robot,
            "--poses",
            poses,
            "--seed",
            seed,
            "--position-sigma-mm",
            "0.02",
            "--position-only",
        ];
        let tail = ["--out", out, "--truth-out", truth];
        strings(&[&head[..], &simulate::REALISTIC_CELL, &tail].concat())
    };
    let data = path(&cell.join("data.csv"))?;
    let holdout = path(&cell.join("holdout.csv"))?;
    let truth = path(&cell.join("truth.toml"))?;
    simulate::simulate(&parse::<Simulation>(&cell_args("42", "2", &data, &truth))?)?;
    simulate::simulate(&parse::<Simulation>(&cell_args(
        "18",
        "3",
        &holdout,
        &path(&cell.join("holdout-truth.toml"))?,
    ))?)?;
    let mut args = strings(&["--robot", &robot, "--data", &data, "--holdout", &holdout]);
    args.extend(strings(&[
        "--out",
        &path(&cell.join("identified.toml"))?,
        "--report",
        &path(&cell.join("report.json"))?,
        "--plot",
        &path(&cell.join("plots"))?,
    ]));
    if options.quiet {
        args.push("--quiet".into());
    }
    let options_cell = parse::<CalibrateOptions>(&args)?;
    let result = calibrate::calibrate(&options_cell)?;
    println!(
        "\n== 2. A realistic cell: tracker 3 m away, reflector 150 mm off the flange, 0.02 mm noise, \
         42 poses + 18 held out, frames identified, IPSO then least squares ==\n"
    );
    print!("{}", result.text);
    written.extend(calibrate::write_outputs(&result, &options_cell)?);
    println!(
        "\nwrote {} files into {} (data, truth, identified robots, reports, plots)",
        written.len() + 7,
        dir.display()
    );
    Ok(())
}
