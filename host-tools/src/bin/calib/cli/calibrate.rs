//! `calib calibrate`: the command over [`host_tools::calibration::Session`]: the options as a
//! configuration and a hold-out rule, the robot, data, hold-out and truth files read, the input
//! files' hashes as the provenance; the session calibrates, and the identified robot file, the
//! JSON report, the HTML page and the plots it renders are written here.

use crate::cli::InputFiles;
use anyhow::bail;
pub use host_tools::calibration::SwarmOptions;
use host_tools::calibration::{
    Calibrated, CalibrationConfig, ErrorModel, HoldOut, Identify, LossChoice, Method, Provenance,
    Session, Truth,
};
use host_tools::io::outputs::Outputs;
use host_tools::io::robot_file::RobotFile;
use host_tools::measurement::dataset::Dataset;
use host_tools::measurement::frames::Frames;
use std::path::PathBuf;

/// Everything `calib calibrate` needs: its command-line options.
#[derive(Clone, Debug, clap::Args)]
pub struct CalibrateOptions {
    /// Robot, data and data profile files.
    #[command(flatten)]
    pub input: InputFiles,
    /// Frames identified with the geometry: none (data in the base frame, tool known), base
    /// (tracker-to-base), or base+tool (and the tool on the flange: 3 translations for a
    /// reflector, 6 for a 6-DoF probe). Default: base+tool, or none when the data say
    /// `# frame: base`.
    #[arg(long, value_enum)]
    pub frames: Option<Frames>,
    /// What to identify: geometry (the robot file's identify lists, and the frames), or frames
    /// alone, keeping the robot file's geometry: re-registration of an identified robot measured
    /// again (a moved tracker, a new reflector).
    #[arg(long, value_enum, default_value_t = CalibrationConfig::default().identify)]
    pub identify: Identify,
    /// Error model: geometric, or joint-maps (the geometry with each joint's angle-error map, a
    /// periodic function of the joint's own reading, identified jointly with an evidence-tuned
    /// prior; the maps go into the identified file's `[joint_maps]`).
    #[arg(long, value_enum, default_value_t = CalibrationConfig::default().model)]
    pub model: ErrorModel,
    /// Harmonics per joint of the joint maps (--model joint-maps or joint-maps+compliance), 1 to
    /// 60, instead of the evidence's choice among 10, 20, ..., 60: each count tried is a whole
    /// identification, so a fixed count is faster when it is known (a gear train's ratio).
    #[arg(long, value_name = "H")]
    pub harmonics: Option<usize>,
    /// Identification method: the paper's swarm, least squares, or the swarm then least squares.
    #[arg(long, value_enum, default_value_t = CalibrationConfig::default().method)]
    pub method: Method,
    /// Iteration cap of the least-squares stage.
    #[arg(long, default_value_t = CalibrationConfig::default().lm_iterations)]
    pub lm_iterations: u32,
    /// Loss of the least-squares stage: l2, or huber / cauchy to down-weight outlier poses.
    #[arg(long, value_enum, default_value_t = CalibrationConfig::default().loss)]
    pub loss: LossChoice,
    /// Scale of the robust loss (--loss huber or cauchy; refused with l2), mm of pose residual
    /// sqrt(|dp|^2 + k |dr|^2); poses beyond it are reported as outliers. Default: estimated from the data, as the median pose residual of a
    /// plain least-squares fit plus 3 robust standard deviations (1.4826 times the median absolute
    /// deviation), so that orientation residuals counted in millimetres do not make every pose an
    /// outlier.
    #[arg(long)]
    pub loss_scale_mm: Option<f64>,
    /// Drop the parameters the data cannot determine instead of refusing; say which.
    #[arg(long)]
    pub auto_mask: bool,
    /// Keep every parameter of an ill-conditioned pose set (scaled condition number above 1000).
    /// By default the parameter with the largest share of the least determined direction is
    /// dropped, one at a time, until the set is well conditioned: its value would follow the
    /// noise.
    #[arg(long)]
    pub keep_ill_conditioned: bool,
    /// Write a result that fails the plausibility check (identified errors beyond 20 mm or 3 deg,
    /// or a fit worse than 2 mm RMS) instead of refusing it; the problems are printed and kept in
    /// the report.
    #[arg(long)]
    pub accept_implausible: bool,
    /// An acceptance criterion judged on the held-out poses after calibration, such as
    /// "95% <= 0.5 mm" (at least 95 % of them within 0.5 mm); repeat for several. The result
    /// states PASS or FAIL; on FAIL the files are written and calib exits with status 3.
    /// Needs held-out poses (--validate, --holdout or a plan's verification poses).
    #[arg(long, value_name = "CRITERION")]
    pub accept: Vec<host_tools::analysis::accuracy::Criterion>,
    /// The mass the flange carried while measured (probe or reflector, its mount, any load), kg:
    /// stated on the certificate, not modelled (compliance takes the robot file's `[dynamics]`).
    #[arg(long, value_name = "KG")]
    pub payload_kg: Option<f64>,
    /// The command line, for the report (set by the `calib` binary; empty otherwise).
    #[arg(skip)]
    pub command_line: Vec<String>,
    /// Hold out this fraction of the poses (chosen at random with --validate-seed) and report the
    /// statistics on them separately.
    #[arg(long, value_name = "FRACTION", conflicts_with = "holdout")]
    pub validate: Option<f64>,
    /// Seed of the random hold-out of --validate (refused without it).
    #[arg(long, default_value_t = 0, requires = "validate")]
    pub validate_seed: u64,
    /// A separate data file of validation poses.
    #[arg(long, value_name = "FILE")]
    pub holdout: Option<PathBuf>,
    /// Orientation weight k of eq. (7), mm^2/rad^2: 1e6 makes 1 mrad weigh like 1 mm. Refused
    /// for position-only data, which have no orientation rows to weigh.
    #[arg(long, value_parser = crate::cli::orientation_weight)]
    pub k: Option<f64>,
    /// The swarm's settings (--method ipso and ipso+lm; refused with --method lm).
    #[command(flatten)]
    pub swarm: SwarmOptions,
    /// Robot file with the true errors (from calib simulate): prints each parameter's error.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Identified robot file to write.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// JSON report to write.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// The report as one self-contained HTML page (tables and plots inline, no network; prints
    /// well) to write.
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
    /// Directory for plots (convergence and position errors, SVG and PNG).
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    /// Never show the progress bar (it is shown only on a terminal anyway).
    #[arg(long)]
    pub quiet: bool,
    /// Register the calibration in this registry once its files are written, as calib registry
    /// add does with the report, the identified file (--out) and the certificate (--html). Needs
    /// --report and the robot file's serial.
    #[arg(long, value_name = "FILE")]
    pub registry: Option<PathBuf>,
}

impl CalibrateOptions {
    /// The library configuration these options ask for.
    pub fn config(&self) -> CalibrationConfig {
        CalibrationConfig {
            method: self.method,
            frames: self.frames,
            identify: self.identify,
            model: self.model,
            harmonics: self.harmonics,
            k: self.k.unwrap_or(calib_core::identify::objective::DEFAULT_K),
            swarm: self.swarm.config(),
            lm_iterations: self.lm_iterations,
            loss: self.loss,
            loss_scale_mm: self.loss_scale_mm,
            auto_mask: self.auto_mask,
            keep_ill_conditioned: self.keep_ill_conditioned,
            accept_implausible: self.accept_implausible,
            acceptance: self.accept.clone(),
            payload_kg: self.payload_kg,
            cancel: host_tools::calibration::Cancel::default(),
            progress: !self.quiet,
        }
    }

    /// The hold-out rule of these options for the data `all` read from `--data`, with the poses
    /// of `--holdout` already read (`holdout`): `--holdout`, `--validate`, else a measured
    /// plan's verification rows when the data carry them.
    fn hold_out_rule(&self, all: &Dataset, holdout: Option<Dataset>) -> anyhow::Result<HoldOut> {
        Ok(match (holdout, self.validate) {
            (Some(_), Some(_)) => bail!("use either --validate or --holdout, not both"),
            (Some(held), None) => HoldOut::poses(held),
            (None, Some(fraction)) => HoldOut::Fraction {
                fraction,
                seed: self.validate_seed,
            },
            (None, None) => HoldOut::of_data(all),
        })
    }
}

/// Runs `calib calibrate` as the command does: calibrates (the robot file's joint count one of
/// [`JOINT_COUNTS`](host_tools::model::counts::JOINT_COUNTS)), writes the
/// files asked for (all or none), and returns the text to print, with the files written, and
/// whether the acceptance criteria (if any) are met.
pub fn calibrate_and_write(options: &CalibrateOptions) -> anyhow::Result<Written> {
    host_tools::model::counts::joint_count(options.input.joints()?)?;
    let mut registry = registry_of(options)?;
    let calibrated = calibrate(options)?;
    // The files first: a closed or full standard output must not lose them.
    let written = write_outputs(&calibrated, &options.outputs())?;
    let mut text = calibrated.text();
    for path in written {
        text.push_str(&format!("wrote {}\n", path.display()));
    }
    let mut record = None;
    if let Some(registry) = &mut registry {
        use host_tools::registry::record::{NewRecord, RecordFiles};
        let new = NewRecord::from_files(&RecordFiles {
            report: options.report.as_deref(),
            identified: options.out.as_deref(),
            certificate: options.html.as_deref(),
            ..RecordFiles::default()
        })?;
        let id = registry.add(&new)?;
        text.push_str(&format!(
            "registered record {id}: robot {} in {}\n",
            new.serial,
            registry.path().display()
        ));
        record = Some(id);
    }
    Ok(Written {
        text,
        accepted: calibrated.accepted(),
        record,
    })
}

/// The registry `--registry` names, opened (created when new) before anything is calibrated,
/// so that a file that is not a registry is refused first. Refused: no `--report` (the registry
/// keeps the report and its SHA-256), a robot file stating no serial.
pub(crate) fn registry_of(
    options: &CalibrateOptions,
) -> anyhow::Result<Option<host_tools::registry::Registry>> {
    use host_tools::registry::{Access, Registry};
    let Some(db) = &options.registry else {
        return Ok(None);
    };
    if options.report.is_none() {
        bail!(
            "--registry needs --report FILE: the registry keeps the report and its SHA-256; nothing was calibrated"
        );
    }
    let paths = options.outputs();
    let named = (paths.inputs.iter().map(|(flag, path)| (*flag, path))).chain(
        [
            ("--out", &paths.out),
            ("--report", &paths.report),
            ("--html", &paths.html),
            ("--plot", &paths.plot),
        ]
        .into_iter()
        .filter_map(|(flag, path)| Some((flag, path.as_ref()?))),
    );
    let absolute = |p: &std::path::Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    for (flag, path) in named {
        if absolute(path) == absolute(db) {
            bail!(
                "--registry {} is also {flag}: name the registry apart from every input and output; nothing was calibrated",
                db.display()
            );
        }
    }
    let robot = &options.input.robot;
    if RobotFile::read(robot)?.serial.is_none() {
        bail!(
            "--registry: {} states no serial (serial = \"...\" in the robot file, as on the robot's plate); the registry keys calibrations by serial: add it, or register later with calib registry add --serial; nothing was calibrated",
            robot.display()
        );
    }
    Ok(Some(Registry::open(db, Access::Write)?))
}

/// What `calib calibrate` did, for the command to print and to set its exit status by.
#[derive(Clone, Debug, PartialEq)]
pub struct Written {
    /// The text to print (the result and the files written).
    pub text: String,
    /// With acceptance criteria (`--accept`): whether all are met.
    pub accepted: Option<bool>,
    /// With `--registry`: the id of the record registered.
    pub record: Option<i64>,
}

/// Runs `calib calibrate` without writing anything: reads the files, calibrates.
pub fn calibrate(options: &CalibrateOptions) -> anyhow::Result<Calibrated> {
    calibrate_with(options, options.config())
}

/// [`calibrate`] with the library configuration `config` (that of `options`, with what the
/// command line does not set: a [`host_tools::calibration::Cancel`] flag).
pub fn calibrate_with(
    options: &CalibrateOptions,
    config: CalibrationConfig,
) -> anyhow::Result<Calibrated> {
    config.check()?; // bad settings are reported before any file is read
    let (profile, all) = options.input.load()?;
    if options.holdout.is_some() && options.validate.is_some() {
        bail!("use either --validate or --holdout, not both");
    }
    let holdout = match &options.holdout {
        Some(path) => {
            let held = Dataset::load_with(&options.input.robot, path, &profile)?;
            host_tools::measurement::orientation_check::check(&held, &profile.euler)?;
            Some(held)
        }
        None => None,
    };
    check_options(options, &all)?;
    let truth = match &options.truth {
        Some(path) => Some(Truth {
            file: RobotFile::read(path)?,
            path: path.clone(),
        }),
        None => None,
    };
    let given = options.outputs().inputs;
    let inputs: Vec<(&str, &std::path::Path)> = (given.iter())
        .filter(|(flag, _)| *flag != "--truth")
        .map(|(flag, path)| (*flag, path.as_path()))
        .collect();
    let session = Session {
        hold_out: options.hold_out_rule(&all, holdout)?,
        provenance: Provenance {
            command_line: options.command_line.clone(),
            inputs: host_tools::io::provenance::InputFile::all(&inputs)?,
        },
        truth,
        ..Session::new(all, config)
    };
    Ok(session.run()?)
}

/// The refusals of option combinations that the library's configuration cannot see (it holds
/// values, not which options were given): `--k` on position-only data, the swarm's settings with
/// `--method lm`.
fn check_options(options: &CalibrateOptions, all: &Dataset) -> anyhow::Result<()> {
    crate::cli::weight_for(options.k, &all.data, &options.input.data)?;
    let swarm = options.swarm.given();
    if options.method == Method::Lm && !swarm.is_empty() {
        // Named as given: a setting given at its default value is refused too.
        return Err(host_tools::calibration::swarm_without_swarm(&swarm).into());
    }
    Ok(())
}

/// The files a calibration writes, each optional, and the inputs they must not replace.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OutputPaths {
    /// The identified robot file.
    pub out: Option<PathBuf>,
    /// The JSON report.
    pub report: Option<PathBuf>,
    /// The HTML report.
    pub html: Option<PathBuf>,
    /// The directory of plots.
    pub plot: Option<PathBuf>,
    /// The command's input files, by flag.
    pub inputs: Vec<(&'static str, PathBuf)>,
}

impl CalibrateOptions {
    /// The files asked for.
    pub fn outputs(&self) -> OutputPaths {
        let mut inputs = vec![
            ("--robot", self.input.robot.clone()),
            ("--data", self.input.data.clone()),
        ];
        for (flag, path) in [
            ("--profile", &self.input.profile),
            ("--holdout", &self.holdout),
            ("--truth", &self.truth),
        ] {
            if let Some(path) = path {
                inputs.push((flag, path.clone()));
            }
        }
        OutputPaths {
            out: self.out.clone(),
            report: self.report.clone(),
            html: self.html.clone(),
            plot: self.plot.clone(),
            inputs,
        }
    }
}

/// Writes the outputs of a calibration that were asked for, all together or none (see
/// [`Outputs`]); returns the files written.
pub(crate) fn write_outputs(
    calibration: &Calibrated,
    paths: &OutputPaths,
) -> anyhow::Result<Vec<PathBuf>> {
    let inputs: Vec<(&str, &std::path::Path)> = paths
        .inputs
        .iter()
        .map(|(f, p)| (*f, p.as_path()))
        .collect();
    let mut outputs = Outputs::new(&inputs);
    if let Some(path) = &paths.out {
        outputs.stage("--out", path, calibration.robot_toml().as_bytes())?;
    }
    // The report is built once for both of its renderings.
    let report = (paths.report.is_some() || paths.html.is_some()).then(|| calibration.report());
    if let (Some(path), Some(report)) = (&paths.report, &report) {
        let json = serde_json::to_string_pretty(report)?;
        outputs.stage("--report", path, json.as_bytes())?;
    }
    if let (Some(path), Some(report)) = (&paths.html, &report) {
        let page =
            host_tools::report::html::render(report, &host_tools::report::html::Rendering::now())?;
        outputs.stage("--html", path, page.as_bytes())?;
    }
    if let Some(dir) = &paths.plot {
        host_tools::report::plots::stage_calibration(&mut outputs, dir, calibration)?;
    }
    Ok(outputs.commit()?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{CommandFactory, Parser};
    use host_tools::calibration::SwarmConfig;

    /// The options as a whole command line.
    #[derive(clap::Parser)]
    struct Words {
        #[command(flatten)]
        options: CalibrateOptions,
    }

    /// One source of every default: the command line's options, none given, are the library's
    /// [`CalibrationConfig::default`] (a terminal's progress bar aside), and each swarm setting's
    /// help states the value of [`SwarmConfig::default`] it leaves in place.
    #[test]
    fn the_command_lines_defaults_are_the_librarys() {
        let words = ["calibrate", "--robot", "r.toml", "--data", "d.csv"];
        let options = Words::try_parse_from(words).unwrap().options;
        let expected = CalibrationConfig {
            progress: true,
            ..CalibrationConfig::default()
        };
        assert_eq!(options.config(), expected);
        let d = SwarmConfig::default();
        let stated = [
            ("swarm", d.particles.to_string()),
            ("generations", d.generations.to_string()),
            ("c1", d.c1.to_string()),
            ("c2", d.c2.to_string()),
            ("seed", d.seed.to_string()),
            ("init_angle_rad", d.init_angle_rad.to_string()),
            ("init_length_mm", d.init_length_mm.to_string()),
            ("bound_factor", d.bound_factor.to_string()),
            ("stall_generations", d.stall_generations.to_string()),
            ("halton_start", d.halton_start.to_string()),
        ];
        let command = Words::command();
        for (id, value) in stated {
            let help = (command.get_arguments())
                .find(|a| a.get_id() == id)
                .and_then(|a| a.get_help())
                .map(ToString::to_string)
                .unwrap_or_default();
            assert!(
                help.contains(&format!("default {value}")),
                "--{id}: the help does not state the default {value}: {help}"
            );
        }
    }
}
