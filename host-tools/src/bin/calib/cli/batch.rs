//! `calib batch`: many robots calibrated by one command from a manifest (issue 55 item 7): each
//! robot exactly as `calib calibrate` calibrates it alone, its files (the identified robot file,
//! the JSON report, the certificate page) in a directory named by its serial, optionally
//! registered, and one summary of all (a CSV file and the text printed).
//!
//! The manifest's keys are `calibrate`'s options without the leading `--` (`-` or `_` alike), so
//! a robot of a batch gets the command's defaults, checks and messages, and nothing new to learn:
//!
//! ```toml
//! [calibrate]              # options every robot shares (optional)
//! profile = "tracker.toml"
//! validate = 0.25
//! accept = ["95% <= 0.5 mm"]
//!
//! [[robot]]                # one table per robot; its keys replace [calibrate]'s
//! robot = "ur10-0042.toml" # its own robot file, stating its serial
//! data = "ur10-0042.csv"
//! ```
//!
//! Files are named relative to the manifest. The outputs are the batch's own (`--out-dir`), so
//! `out`, `report`, `html`, `plot`, `registry` and `quiet` are refused in a manifest.
//!
//! Every robot is checked before the first is calibrated (its options, its robot file's serial,
//! its input files, the registry), so a typing error in the manifest costs nothing. A robot
//! refused while it is calibrated (too few poses, an implausible result) writes nothing, is named
//! in the summary with the reason, and the others go on; the command then exits with status 1
//! (status 3 when all were calibrated and an acceptance criterion failed).

use crate::cli::calibrate::{CalibrateOptions, calibrate_and_write, registry_of};
use anyhow::{Context, bail};
use host_tools::calibration::Report;
use std::path::{Path, PathBuf};

/// `calib batch`'s options.
#[derive(Clone, Debug, clap::Args)]
pub struct BatchOptions {
    /// The manifest (TOML): a table "calibrate" of the options every robot shares and one
    /// table "robot" per robot (an array of tables: robot, data and any other option of calib
    /// calibrate, named without the leading dashes); files relative to the manifest.
    #[arg(value_name = "MANIFEST")]
    pub manifest: PathBuf,
    /// Directory of the results: SERIAL/identified.toml, SERIAL/report.json and
    /// SERIAL/certificate.html for each robot calibrated, and summary.csv (one row per robot).
    #[arg(long, value_name = "DIR")]
    pub out_dir: PathBuf,
    /// Register each calibration in this registry once its files are written, as calibrate
    /// --registry does (created when new).
    #[arg(long, value_name = "FILE")]
    pub registry: Option<PathBuf>,
    /// Never show the progress bars (they are shown only on a terminal anyway).
    #[arg(long)]
    pub quiet: bool,
}

/// The keys a manifest may not set: what the batch names itself.
const SET_BY_BATCH: [&str; 6] = ["out", "report", "html", "plot", "registry", "quiet"];

/// The keys whose values are files, named relative to the manifest.
const FILE_KEYS: [&str; 5] = ["robot", "data", "profile", "holdout", "truth"];

/// The name of the summary in `--out-dir`.
pub const SUMMARY: &str = "summary.csv";

/// The manifest as written.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Manifest {
    /// Options every robot shares.
    #[serde(default)]
    calibrate: toml::Table,
    /// One table of options per robot.
    #[serde(default)]
    robot: Vec<toml::Table>,
}

/// One robot of the batch, checked and ready to calibrate.
struct Job {
    /// Its serial (the robot file's), which names its directory.
    serial: String,
    /// The options `calib calibrate` would be given for it, outputs included.
    options: CalibrateOptions,
}

/// `calib calibrate`'s options as a whole command line, for the manifest's words.
#[derive(clap::Parser)]
#[command(name = "calibrate")]
struct Words {
    #[command(flatten)]
    options: CalibrateOptions,
}

/// One row of the summary.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SummaryRow {
    /// The robot's serial.
    pub serial: String,
    /// `calibrated`, `PASS` or `FAIL` (acceptance criteria judged), or `refused`.
    pub status: String,
    /// Calibration poses.
    pub poses: Option<usize>,
    /// Held-out poses.
    pub held_out_poses: Option<usize>,
    /// 95th percentile of the held-out position error after calibration, mm.
    pub held_out_p95_mm: Option<f64>,
    /// Largest held-out position error after calibration, mm.
    pub held_out_max_mm: Option<f64>,
    /// Expanded uncertainty (k = 2) of the accuracy statement, mm.
    pub expanded_uncertainty_mm: Option<f64>,
    /// The registry record, with `--registry`.
    pub record: Option<i64>,
    /// The robot's directory in `--out-dir` (empty when refused: nothing written).
    pub directory: String,
    /// Why it was refused.
    pub message: String,
}

/// The manifest's robots, each checked as far as it can be without calibrating: the options
/// parse, the robot file states a serial no other robot has, every input file opens, and with a
/// registry, `calibrate --registry`'s checks.
fn jobs(batch: &BatchOptions) -> anyhow::Result<Vec<Job>> {
    let path = &batch.manifest;
    let bytes = host_tools::io::input::read(path, host_tools::io::input::Input::Document)
        .with_context(|| format!("reading the manifest {}", path.display()))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| anyhow::anyhow!("{}: not UTF-8 text; save it as UTF-8", path.display()))?;
    let manifest: Manifest = toml::from_str(&text).map_err(|e| {
        anyhow::anyhow!(
            "{}: {}; a manifest has a [calibrate] table and [[robot]] tables",
            path.display(),
            e.message()
        )
    })?;
    if manifest.robot.is_empty() {
        bail!(
            "{} names no robot: add a [[robot]] table (robot = \"FILE\", data = \"FILE\") per robot",
            path.display()
        );
    }
    let base = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let mut jobs: Vec<Job> = Vec::new();
    for (i, own) in manifest.robot.iter().enumerate() {
        let job = job(batch, &base, &manifest.calibrate, own)
            .with_context(|| format!("{}: robot {} of the manifest", path.display(), i + 1))?;
        if let Some(same) = jobs.iter().position(|j| j.serial == job.serial) {
            bail!(
                "{}: robots {} and {} are both serial {}: one calibration per robot in a batch",
                path.display(),
                same + 1,
                i + 1,
                job.serial
            );
        }
        jobs.push(job);
    }
    no_output_is_an_input(batch, &jobs)?;
    for (i, job) in jobs.iter().enumerate() {
        registry_of(&job.options)
            .with_context(|| format!("{}: robot {} of the manifest", path.display(), i + 1))?;
    }
    Ok(jobs)
}

/// Refuses a batch in which a file written (a robot's, the summary, the registry) is a file read
/// (the manifest, any robot's input): one robot's results must not replace another's data.
fn no_output_is_an_input(batch: &BatchOptions, jobs: &[Job]) -> anyhow::Result<()> {
    let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let mut inputs = vec![("the manifest", absolute(&batch.manifest))];
    for job in jobs {
        for (flag, path) in job.options.outputs().inputs {
            inputs.push((flag, absolute(&path)));
        }
    }
    let summary = batch.out_dir.join(SUMMARY);
    let mut outputs: Vec<&Path> = vec![&summary];
    outputs.extend(batch.registry.as_deref());
    for job in jobs {
        let o = &job.options;
        outputs.extend(
            [&o.out, &o.report, &o.html]
                .into_iter()
                .flatten()
                .map(PathBuf::as_path),
        );
    }
    for output in outputs {
        if let Some((what, _)) = inputs.iter().find(|(_, p)| *p == absolute(output)) {
            bail!(
                "{} would be written by the batch and is also read ({what}): choose another --out-dir or --registry; nothing was calibrated",
                output.display()
            );
        }
    }
    Ok(())
}

/// One robot's job from its table `own` over the shared `defaults`.
fn job(
    batch: &BatchOptions,
    base: &Path,
    defaults: &toml::Table,
    own: &toml::Table,
) -> anyhow::Result<Job> {
    let mut table = defaults.clone();
    table.extend(own.clone());
    let mut words = vec!["calibrate".to_string()];
    for (key, value) in &table {
        words.extend(option_words(key, value, base)?);
    }
    let mut options = match <Words as clap::Parser>::try_parse_from(&words) {
        Ok(words) => words.options,
        Err(e) => bail!("{}", clap_message(&e)),
    };
    let file = host_tools::io::robot_file::RobotFile::read(&options.input.robot)?;
    let Some(serial) = file.serial.clone() else {
        bail!(
            "{} states no serial: add serial = \"...\" (as on the robot's plate) to it; the batch names each robot's directory by its serial",
            options.input.robot.display()
        );
    };
    let directory = batch.out_dir.join(directory_name(&serial)?);
    options.out = Some(directory.join("identified.toml"));
    options.report = Some(directory.join("report.json"));
    options.html = Some(directory.join("certificate.html"));
    options.registry.clone_from(&batch.registry);
    options.quiet = batch.quiet;
    // What reproduces this robot's calibration alone, as its report records it.
    let outputs = [
        ("--out", &options.out),
        ("--report", &options.report),
        ("--html", &options.html),
        ("--registry", &options.registry),
    ];
    let mut line = words;
    line[0] = "calib calibrate".to_string();
    for (flag, path) in outputs {
        if let Some(path) = path {
            line.extend([flag.to_string(), path.display().to_string()]);
        }
    }
    options.command_line = line;
    for (flag, input) in options.outputs().inputs {
        std::fs::File::open(&input)
            .with_context(|| format!("{flag} {} cannot be read", input.display()))?;
    }
    Ok(Job { serial, options })
}

/// The command-line words of the manifest's `key = value`: `--key value`, once per element of an
/// array, `--key` alone for `true`, nothing for `false`; a file relative to `base`.
fn option_words(key: &str, value: &toml::Value, base: &Path) -> anyhow::Result<Vec<String>> {
    let name = key.replace('_', "-");
    if SET_BY_BATCH.contains(&name.as_str()) {
        bail!(
            "{key}: set by calib batch itself (each robot's files go to --out-dir DIR/SERIAL/, the registry is --registry): remove it from the manifest"
        );
    }
    let flag = format!("--{name}");
    let one = |value: &toml::Value| -> anyhow::Result<String> {
        Ok(match value {
            toml::Value::String(text) if FILE_KEYS.contains(&name.as_str()) => {
                base.join(text).display().to_string()
            }
            toml::Value::String(text) => text.clone(),
            toml::Value::Integer(n) => n.to_string(),
            toml::Value::Float(x) => x.to_string(),
            _ => bail!(
                "{key}: give a string, a number, true or a list of them (as on calibrate's command line)"
            ),
        })
    };
    Ok(match value {
        toml::Value::Boolean(true) => vec![flag],
        toml::Value::Boolean(false) => Vec::new(),
        toml::Value::Array(values) => {
            let mut words = Vec::new();
            for value in values {
                words.extend([flag.clone(), one(value)?]);
            }
            words
        }
        value => vec![flag, one(value)?],
    })
}

/// A clap error about the manifest's words, as a manifest's message: its first line, the
/// option named as a key, without clap's usage and tips (which name a command line).
fn clap_message(e: &clap::Error) -> String {
    let text = e.render().to_string();
    let first = text.lines().next().unwrap_or_default();
    let first = first.trim_start_matches("error: ");
    format!(
        "{first} (the keys are calibrate's options without the leading --; see calib calibrate --help)"
    )
}

/// The directory name of a serial: itself when it is a plain name (letters, digits, `-`, `_`,
/// `.`, not starting with a dot); refused otherwise rather than changed into a name that two
/// serials might share.
fn directory_name(serial: &str) -> anyhow::Result<&str> {
    let plain = serial
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c));
    if serial.is_empty() || serial.starts_with('.') || !plain || serial.len() > 100 {
        bail!(
            "serial {serial:?} cannot name a directory: calib batch needs serials of letters, digits, '-', '_' and '.' (not first), at most 100"
        );
    }
    Ok(serial)
}

/// Calibrates one robot as `calib calibrate` does; its summary row.
fn calibrate_one(job: &Job, out_dir: &Path) -> SummaryRow {
    let mut row = SummaryRow {
        serial: job.serial.clone(),
        status: "refused".to_string(),
        poses: None,
        held_out_poses: None,
        held_out_p95_mm: None,
        held_out_max_mm: None,
        expanded_uncertainty_mm: None,
        record: None,
        directory: String::new(),
        message: String::new(),
    };
    let written = calibrate_and_write(&job.options).and_then(|written| {
        let path = job.options.report.as_deref().unwrap_or(Path::new(""));
        Ok((written, Report::read(path)?))
    });
    match written {
        Ok((written, report)) => {
            row.status = match written.accepted {
                None => "calibrated",
                Some(true) => "PASS",
                Some(false) => "FAIL",
            }
            .to_string();
            row.poses = Some(report.poses.len());
            if let Some(held) = &report.held_out {
                row.held_out_poses = Some(held.after.poses);
                row.held_out_p95_mm = Some(held.after.position.p95_mm);
                row.held_out_max_mm = Some(held.after.position.max_mm);
            }
            row.expanded_uncertainty_mm = report.budget.as_ref().map(|b| b.expanded_mm);
            row.record = written.record;
            row.directory = out_dir.join(&job.serial).display().to_string();
        }
        Err(e) => {
            let causes: Vec<String> = e.chain().map(ToString::to_string).collect();
            row.message = causes.join(": ");
        }
    }
    row
}

/// The summary as text: one line per robot.
fn summary_text(rows: &[SummaryRow]) -> String {
    let mm = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.4}"));
    let mut text = format!(
        "{:<16} {:<10} {:>5} {:>8} {:>10} {:>10} {:>9}\n",
        "serial", "status", "poses", "held out", "p95 mm", "max mm", "U mm k=2"
    );
    for row in rows {
        let count = |n: Option<usize>| n.map_or("-".to_string(), |n| n.to_string());
        text.push_str(&format!(
            "{:<16} {:<10} {:>5} {:>8} {:>10} {:>10} {:>9}\n",
            row.serial,
            row.status,
            count(row.poses),
            count(row.held_out_poses),
            mm(row.held_out_p95_mm),
            mm(row.held_out_max_mm),
            mm(row.expanded_uncertainty_mm),
        ));
        if !row.message.is_empty() {
            text.push_str(&format!("  refused: {}\n", row.message));
        }
    }
    text
}

/// The summary as CSV.
fn summary_csv(rows: &[SummaryRow]) -> anyhow::Result<Vec<u8>> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    for row in rows {
        writer.serialize(row)?;
    }
    Ok(writer.into_inner()?)
}

/// What the batch did, for the command to print and to set its exit status by.
pub struct Batch {
    /// The summary, one row per robot of the manifest, in its order.
    pub rows: Vec<SummaryRow>,
    /// The text to print.
    pub text: String,
}

/// Runs `calib batch`: checks every robot, calibrates each, writes the summary.
pub fn batch(options: &BatchOptions) -> anyhow::Result<Batch> {
    let jobs = jobs(options)?;
    let mut rows = Vec::with_capacity(jobs.len());
    let mut text = String::new();
    for (i, job) in jobs.iter().enumerate() {
        if !options.quiet {
            // Progress only: a closed standard error does not stop the batch.
            let _ = std::io::Write::write_fmt(
                &mut std::io::stderr(),
                format_args!(
                    "calib batch: robot {} of {}: {}\n",
                    i + 1,
                    jobs.len(),
                    job.serial
                ),
            );
        }
        rows.push(calibrate_one(job, &options.out_dir));
    }
    let summary = options.out_dir.join(SUMMARY);
    let inputs: Vec<(&str, &Path)> = vec![("MANIFEST", options.manifest.as_path())];
    let mut outputs = host_tools::io::outputs::Outputs::new(&inputs);
    outputs.stage("--out-dir", &summary, &summary_csv(&rows)?)?;
    outputs.commit()?;
    text.push_str(&summary_text(&rows));
    text.push_str(&format!("wrote {}\n", summary.display()));
    Ok(Batch { rows, text })
}
