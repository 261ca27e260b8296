//! The `calib` command line at the edge of the library: each command's clap options and a thin
//! run function (read the files, call the library, return what the binary prints and writes).

pub mod batch;
pub mod calibrate;
pub mod check;
pub mod check_shift;
pub mod compensate;
pub mod demo;
pub mod evaluate;
pub mod export;
pub mod import_ur;
pub mod import_urdf;
pub mod iso9283;
pub mod merge;
pub mod plan;
pub mod plan_sockets;
pub mod registry;
pub mod report;
pub mod simulate;
pub mod sockets;
pub mod uncertainty;
pub mod verify;

use host_tools::io::profile::DataProfile;
use host_tools::measurement::dataset::Dataset;
use std::io::Write;
use std::path::PathBuf;

/// How a URScript program moves between its targets and waits at each (`calib plan` and `calib
/// iso9283 plan` with `--urscript`).
#[derive(Clone, Copy, Debug, clap::Args)]
pub struct MotionOptions {
    /// URScript: time the robot stands still at each pose for the tracker, s (above 0, at most 600).
    #[arg(long, default_value_t = 2.0, requires = "urscript", allow_hyphen_values = true, value_parser = settle_time)]
    pub settle_s: f64,
    /// URScript: joint speed of the moves, rad/s (above 0, at most 3.2: a UR wrist joint reaches pi).
    #[arg(long, default_value_t = 0.5, requires = "urscript", allow_hyphen_values = true, value_parser = joint_speed)]
    pub speed_rad_s: f64,
    /// URScript: joint acceleration of the moves, rad/s^2 (above 0, at most 40).
    #[arg(long, default_value_t = 0.5, requires = "urscript", allow_hyphen_values = true, value_parser = joint_acceleration)]
    pub acceleration_rad_s2: f64,
}

impl MotionOptions {
    /// The motion of the program.
    pub fn motion(&self) -> host_tools::formats::urscript::Motion {
        host_tools::formats::urscript::Motion {
            speed_rad_s: self.speed_rad_s,
            acceleration_rad_s2: self.acceleration_rad_s2,
            settle_s: self.settle_s,
        }
    }
}

/// The files a data command reads (`--robot`, `--data`, `--profile`), shared by `calibrate`,
/// `check`, `evaluate` and `verify`.
#[derive(Clone, Debug, clap::Args)]
pub struct InputFiles {
    /// Robot model file (TOML): the nominal model; its identify lists (or the default rule)
    /// select the parameters.
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// Tracker data file: our CSV, or another export read through --profile.
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    /// Data profile (TOML) for exports not in our CSV format: delimiter, decimal comma, column
    /// mapping with units, Euler convention (see host-tools/profiles/).
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
}

impl InputFiles {
    /// The data profile, then both files read and checked through it, and the orientations
    /// checked against the robot ([`host_tools::measurement::orientation_check`]).
    pub fn load(&self) -> anyhow::Result<(DataProfile, Dataset)> {
        let profile = DataProfile::load(self.profile.as_deref())?;
        let inputs = Dataset::load_with(&self.robot, &self.data, &profile)?;
        host_tools::measurement::orientation_check::check(&inputs, &profile.euler)?;
        Ok((profile, inputs))
    }

    /// The robot file's joint count (the file is read and checked again by [`Self::load`]).
    pub fn joints(&self) -> anyhow::Result<usize> {
        Ok(host_tools::io::robot_file::RobotFile::read(&self.robot)?
            .joint
            .len())
    }
}

/// Smallest and largest orientation weight `--k` accepted, mm^2/rad^2: beyond them one kind of
/// row drowns the other in rounding (the paper's 1e6 makes 1 mrad weigh like 1 mm).
pub(crate) const K_RANGE: [f64; 2] = [1e-6, 1e12];

/// Parses `--k`, the orientation weight of eq. (7): a number in [`K_RANGE`].
pub(crate) fn orientation_weight(text: &str) -> Result<f64, String> {
    let k: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("\"{text}\" is not a number"))?;
    if (K_RANGE[0]..=K_RANGE[1]).contains(&k) {
        Ok(k)
    } else {
        Err(format!(
            "{k:e} mm^2/rad^2 is outside [{:e}, {:e}]: 1e6 makes 1 mrad weigh like 1 mm; for data \
             without orientations read them position-only (a profile without orientation columns)",
            K_RANGE[0], K_RANGE[1]
        ))
    }
}

/// The flags of `options` (flag, given) that were given, in order: what a refusal names.
pub(crate) fn given_flags<const N: usize>(options: [(&'static str, bool); N]) -> Vec<&'static str> {
    options
        .into_iter()
        .filter_map(|(flag, given)| given.then_some(flag))
        .collect()
}

/// The orientation weight `--k` of eq. (7) for `data`: the value given, else the default;
/// refused when given for position-only data, which have no orientation rows to weigh.
pub(crate) fn weight_for(
    k: Option<f64>,
    data: &host_tools::io::tracker_data::TrackerData,
    file: &std::path::Path,
) -> anyhow::Result<f64> {
    match k {
        Some(_) if data.rows_without_orientation() => anyhow::bail!(
            "--k weighs orientation rows against position rows, and {} has positions only: drop --k",
            file.display()
        ),
        Some(k) => Ok(k),
        None => Ok(calib_core::identify::objective::DEFAULT_K),
    }
}

/// Prints `text` to standard output. A closed pipe (the reader has gone, as with `| head`) ends
/// the printing quietly; any other write error (such as a full disk) is an error. Never panics.
pub fn print(text: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(anyhow::Error::new(e).context("writing to standard output")),
    }
}

/// A line (`text` and a newline) to standard output, as [`print`](crate::cli::print()): never a
/// panic on a closed or full output, an error for a full one. `print_line(format_args!(...))?`
/// where `println!` would be.
pub fn print_line(text: std::fmt::Arguments<'_>) -> anyhow::Result<()> {
    print(&format!("{text}\n"))
}

/// `text` to standard output, as [`print`](crate::cli::print()). `print_text(format_args!(...))?`
/// where `print!` would be.
pub fn print_text(text: std::fmt::Arguments<'_>) -> anyhow::Result<()> {
    print(&text.to_string())
}

/// A number of `text` within `(low, high]` in `unit`, for the URScript settings of `plan` and
/// `compensate`: what a controller accepts, no 301-digit literal in a program.
fn within(text: &str, (low, high): (f64, f64), unit: &str) -> Result<f64, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|_| format!("\"{text}\" is not a number"))?;
    if v > low && v <= high {
        Ok(v)
    } else {
        Err(format!("{v} {unit} is outside ({low}, {high}] {unit}"))
    }
}

/// `--settle-s`: above 0, at most 600 s.
pub(crate) fn settle_time(text: &str) -> Result<f64, String> {
    within(text, (0.0, 600.0), "s")
}

/// `--speed-rad-s`: above 0, at most 3.2 rad/s (a UR wrist joint reaches 180 deg/s, pi rad/s).
pub(crate) fn joint_speed(text: &str) -> Result<f64, String> {
    within(text, (0.0, 3.2), "rad/s")
}

/// `--acceleration-rad-s2`: above 0, at most 40 rad/s^2.
pub(crate) fn joint_acceleration(text: &str) -> Result<f64, String> {
    within(text, (0.0, 40.0), "rad/s^2")
}
