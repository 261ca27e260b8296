//! `calib`: robot geometric calibration from laser-tracker data.

use anyhow::Context;
use clap::{Parser, Subcommand, ValueEnum};
use host_tools::calibrate::{self, CalibrateOptions};
use host_tools::fk;
use host_tools::robot_file::RobotModel;
use host_tools::simulate::{self, Simulation, TrueErrors};
use std::io::IsTerminal;
use std::path::PathBuf;

/// Robot geometric calibration and pose compensation. Lengths in mm, angles in degrees in files
/// and at the command line unless an option's name says `rad`.
#[derive(Debug, Parser)]
#[command(name = "calib", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ErrorsChoice {
    /// Table 2 of the paper (for the ER10L-C10).
    Table2,
    /// Uniform random errors of the identified parameters (see --random-length-mm, --random-angle-rad).
    Random,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Method {
    /// The paper's improved particle swarm (Halton start, constriction factor).
    Ipso,
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum ScramblingChoice {
    /// Plain Halton, as in the paper.
    None,
    /// Reverse Halton (Vandewoestyne and Cools 2006).
    Reverse,
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
    Simulate {
        /// Nominal robot model file.
        #[arg(
            long,
            value_name = "FILE",
            default_value = "host-tools/robots/er10l-c10.toml"
        )]
        robot: PathBuf,
        /// True errors: the paper's Table 2, or random ones.
        #[arg(long, value_enum, default_value_t = ErrorsChoice::Table2)]
        errors: ErrorsChoice,
        /// Half range of random length errors, mm (with --errors random).
        #[arg(long, default_value_t = 0.5)]
        random_length_mm: f64,
        /// Half range of random angle errors, rad (with --errors random).
        #[arg(long, default_value_t = 0.01)]
        random_angle_rad: f64,
        /// Number of poses.
        #[arg(long, default_value_t = 32)]
        poses: usize,
        /// Draw joints within the robot file's limits instead of uniformly in [-180, 180] deg.
        #[arg(long)]
        within_limits: bool,
        /// Half range (rad) of uniform noise added to the commanded joints before the true pose is
        /// computed. The paper uses 0.1 rad, which taken literally moves the tool by about 100 mm:
        /// errors no geometric calibration can remove. Default 0.
        #[arg(long, default_value_t = 0.0)]
        joint_noise_rad: f64,
        /// Tracker position noise, standard deviation per axis, mm.
        #[arg(long, default_value_t = 0.0)]
        position_sigma_mm: f64,
        /// Tracker orientation noise, standard deviation per axis, rad.
        #[arg(long, default_value_t = 0.0)]
        orientation_sigma_rad: f64,
        /// Write position-only data (a spherical reflector) instead of full 6-DoF poses.
        #[arg(long)]
        position_only: bool,
        /// Seed of all random draws.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Tracker data output (CSV).
        #[arg(long, value_name = "FILE")]
        out: PathBuf,
        /// True robot output (robot file with a [calibration] section of the true errors).
        #[arg(long, value_name = "FILE")]
        truth_out: PathBuf,
    },
    /// Identify the robot's parameter errors from tracker data.
    Calibrate {
        /// Nominal robot model file.
        #[arg(long, value_name = "FILE")]
        robot: PathBuf,
        /// Tracker data file (CSV).
        #[arg(long, value_name = "FILE")]
        data: PathBuf,
        /// Identification method.
        #[arg(long, value_enum, default_value_t = Method::Ipso)]
        method: Method,
        /// Swarm size (10, 20, 30, 40, 50 or 100).
        #[arg(long, default_value_t = 20)]
        swarm: usize,
        /// Maximum number of generations.
        #[arg(long, default_value_t = 2000)]
        generations: u32,
        /// Cognitive acceleration coefficient c1 (c1 + c2 > 4).
        #[arg(long, default_value_t = 2.05)]
        c1: f64,
        /// Social acceleration coefficient c2.
        #[arg(long, default_value_t = 2.05)]
        c2: f64,
        /// Orientation weight k of eq. (7), mm^2/rad^2: 1e6 makes 1 mrad weigh like 1 mm.
        #[arg(long, default_value_t = calib_core::objective::DEFAULT_K)]
        k: f64,
        /// Seed of the swarm's random numbers r1, r2.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Initial half range of angle errors, rad (paper: 0.01).
        #[arg(long, default_value_t = 0.01)]
        init_angle_rad: f64,
        /// Initial half range of length errors, mm (paper: 0.5).
        #[arg(long, default_value_t = 0.5)]
        init_length_mm: f64,
        /// Search bounds as a multiple of the initial half range (absorbing walls).
        #[arg(long, default_value_t = 10.0)]
        bound_factor: f64,
        /// Stop after this many generations without improvement (0: never).
        #[arg(long, default_value_t = 0)]
        stall_generations: u32,
        /// Stop as soon as the objective reaches this value.
        #[arg(long, default_value_t = f64::NEG_INFINITY, allow_hyphen_values = true)]
        target: f64,
        /// Halton index of the first particle (the paper's k; 0 is the all-zero point).
        #[arg(long, default_value_t = 1)]
        halton_start: u64,
        /// Halton digit scrambling.
        #[arg(long, value_enum, default_value_t = ScramblingChoice::None)]
        scrambling: ScramblingChoice,
        /// Robot file with the true errors (from calib simulate): prints each parameter's error.
        #[arg(long, value_name = "FILE")]
        truth: Option<PathBuf>,
        /// Identified robot file to write.
        #[arg(long, value_name = "FILE")]
        out: Option<PathBuf>,
        /// JSON report to write.
        #[arg(long, value_name = "FILE")]
        report: Option<PathBuf>,
        /// Directory for plots (convergence and position errors, SVG and PNG).
        #[arg(long, value_name = "DIR")]
        plot: Option<PathBuf>,
        /// Never show the progress bar.
        #[arg(long)]
        quiet: bool,
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
        Command::Simulate {
            robot,
            errors,
            random_length_mm,
            random_angle_rad,
            poses,
            within_limits,
            joint_noise_rad,
            position_sigma_mm,
            orientation_sigma_rad,
            position_only,
            seed,
            out,
            truth_out,
        } => {
            let settings = Simulation {
                robot,
                errors: match errors {
                    ErrorsChoice::Table2 => TrueErrors::Table2,
                    ErrorsChoice::Random => TrueErrors::Random {
                        length_mm: random_length_mm,
                        angle_rad: random_angle_rad,
                    },
                },
                poses,
                within_limits,
                joint_noise_rad,
                position_sigma_mm,
                orientation_sigma_rad,
                position_only,
                seed,
            };
            let simulated = simulate::simulate(&settings, &out, &truth_out)?;
            println!(
                "wrote {} poses to {} and the true robot to {}",
                simulated.rows.len(),
                out.display(),
                truth_out.display()
            );
        }
        Command::Calibrate {
            robot,
            data,
            method: Method::Ipso,
            swarm,
            generations,
            c1,
            c2,
            k,
            seed,
            init_angle_rad,
            init_length_mm,
            bound_factor,
            stall_generations,
            target,
            halton_start,
            scrambling,
            truth,
            out,
            report,
            plot,
            quiet,
        } => {
            let options = CalibrateOptions {
                robot,
                data,
                swarm,
                generations,
                c1,
                c2,
                k,
                seed,
                init_angle_rad,
                init_length_mm,
                bound_factor,
                stall_generations,
                target,
                halton_start,
                scrambling: match scrambling {
                    ScramblingChoice::None => calib_core::halton::Scrambling::None,
                    ScramblingChoice::Reverse => calib_core::halton::Scrambling::Reverse,
                },
                progress: !quiet && std::io::stderr().is_terminal(),
                truth,
            };
            let calibration = calibrate::calibrate(&options)?;
            print!("{}", calibration.text);
            let written = calibrate::write_outputs(
                &calibration,
                out.as_deref(),
                report.as_deref(),
                plot.as_deref(),
            )?;
            for path in written {
                println!("wrote {}", path.display());
            }
        }
    }
    Ok(())
}
