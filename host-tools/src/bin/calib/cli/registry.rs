//! `calib registry`: every calibration of every robot in one SQLite file (`--db`, `calib.db` by
//! default): register a report with the files beside it, list, show, export
//! ([`host_tools::registry`]).

use host_tools::io::outputs::Outputs;
use host_tools::registry::record::{NewRecord, Record, RecordFiles, Summary};
use host_tools::registry::{Access, DEFAULT_PATH, Registry};
use std::path::PathBuf;

/// `calib registry`'s options.
#[derive(Debug, clap::Args)]
pub struct RegistryOptions {
    /// What to do.
    #[command(subcommand)]
    pub command: RegistryCommand,
}

/// The registry file, as every `calib registry` command takes it.
#[derive(Debug, Clone, clap::Args)]
pub struct Db {
    /// The registry: an SQLite file, created readable and writable by you only on the first
    /// registration.
    #[arg(long, value_name = "FILE", default_value = DEFAULT_PATH)]
    pub db: PathBuf,
}

/// The registry's commands.
#[derive(Debug, clap::Subcommand)]
pub enum RegistryCommand {
    /// Register a calibration: its JSON report (calib calibrate --report or calib sockets
    /// --report) and the files beside it, hashed.
    Add(AddOptions),
    /// List the registered calibrations, of one robot with --serial.
    List(ListOptions),
    /// Show one registered calibration whole.
    Show(ShowOptions),
    /// Write every record as JSON (reports included) or CSV (one line per calibration).
    Export(ExportOptions),
    /// Compare two calibrations (of one robot, or of two robots of one model): each
    /// parameter's change against both uncertainties, jointly (Mahalanobis), and what it moves
    /// the tool by over the workspace. Both records need their identified files (add
    /// --identified).
    Compare(CompareOptions),
    /// Is the right calibration on the controller? Check a controller's parameter block (or a
    /// robot file) against the robot's registered calibrations: which record it holds, whether
    /// that is the latest, and if none, what differs from the nearest. Exits with status 3
    /// unless it holds the latest.
    Verify(VerifyOptions),
    /// List a robot's shift checks (calib check-shift) with the drift of their mean error over
    /// time.
    Checks(ChecksOptions),
    /// List a robot's ISO 9283 pose tests (calib iso9283 evaluate --registry): cycles, the
    /// largest AP and RP; one whole with --id.
    PoseTests(PoseTestsOptions),
    /// Write the fleet page: one static HTML page of every robot, its last calibration and
    /// accuracy, when it falls due, its last shift check and drift state, its last pose test.
    Fleet(FleetOptions),
    /// Plot one robot over time: its calibrations' held-out figures and its shift checks' mean
    /// errors against the date, with the drift rate (SVG).
    Trend(TrendOptions),
}

/// `calib registry trend`.
#[derive(Debug, clap::Args)]
pub struct TrendOptions {
    /// The robot's serial number.
    #[arg(long, value_name = "SERIAL")]
    pub serial: String,
    /// Write the SVG here (an existing file is replaced whole, as by every command).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// `calib registry checks`.
#[derive(Debug, clap::Args)]
pub struct ChecksOptions {
    /// The robot's serial number.
    #[arg(long, value_name = "SERIAL")]
    pub serial: String,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// `calib registry fleet`.
#[derive(Debug, clap::Args)]
pub struct FleetOptions {
    /// The page to write (HTML).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Days from a calibration until the robot is due again.
    #[arg(long, value_name = "DAYS", default_value_t = host_tools::registry::fleet::DEFAULT_INTERVAL_DAYS)]
    pub interval_days: u32,
    /// Judge due dates on this day, YYYY-MM-DD (default: today).
    #[arg(long, value_name = "DATE")]
    pub today: Option<String>,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// `calib registry pose-tests`.
#[derive(Debug, clap::Args)]
pub struct PoseTestsOptions {
    /// The robot's serial number.
    #[arg(long, value_name = "SERIAL")]
    pub serial: String,
    /// Show this test whole (its characteristics per point).
    #[arg(long, value_name = "ID")]
    pub id: Option<i64>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// `calib registry verify`.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("given").required(true).args(["block", "robot"])))]
pub struct VerifyOptions {
    /// The robot's serial number.
    #[arg(long, value_name = "SERIAL")]
    pub serial: String,
    /// The parameter block read back from the controller (as calib export --format block
    /// writes it, f32 or f64).
    #[arg(long, value_name = "FILE")]
    pub block: Option<PathBuf>,
    /// A robot file (the one the controller's software was given).
    #[arg(long, value_name = "FILE")]
    pub robot: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// `calib registry compare`.
#[derive(Debug, clap::Args)]
pub struct CompareOptions {
    /// The earlier (reference) calibration's record number.
    #[arg(value_name = "A")]
    pub a: i64,
    /// The calibration compared with it.
    #[arg(value_name = "B")]
    pub b: i64,
    /// Configurations the tool's movement is computed at, spread over the joint limits.
    #[arg(long, value_name = "N", default_value_t = host_tools::registry::compare::DEFAULT_POSES)]
    pub poses: usize,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// `calib registry add`.
#[derive(Debug, clap::Args)]
pub struct AddOptions {
    /// The calibration's JSON report.
    #[arg(value_name = "REPORT.json")]
    pub report: PathBuf,
    /// The identified robot file it wrote (--out): kept whole in the record.
    #[arg(long, value_name = "FILE")]
    pub identified: Option<PathBuf>,
    /// Its certificate (HTML or PDF): its SHA-256 is kept.
    #[arg(long, value_name = "FILE")]
    pub certificate: Option<PathBuf>,
    /// The controller's parameter block (calib export --format block): its SHA-256 is kept.
    #[arg(long, value_name = "FILE")]
    pub block: Option<PathBuf>,
    /// The robot's serial number (needed when the report does not state it; must equal it
    /// when it does).
    #[arg(long, value_name = "SERIAL")]
    pub serial: Option<String>,
    /// The robot's model (default: the identified file's name, else the report's robot).
    #[arg(long, value_name = "MODEL")]
    pub model: Option<String>,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// `calib registry list`.
#[derive(Debug, clap::Args)]
pub struct ListOptions {
    /// Only this robot's calibrations.
    #[arg(long, value_name = "SERIAL")]
    pub serial: Option<String>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// `calib registry show`.
#[derive(Debug, clap::Args)]
pub struct ShowOptions {
    /// The record's number (calib registry list).
    #[arg(value_name = "ID")]
    pub id: i64,
    /// Print the record as JSON (its report included).
    #[arg(long)]
    pub json: bool,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// The formats `calib registry export` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Every record whole, reports included.
    Json,
    /// One line per calibration: robot, dates, held-out figure, the files' SHA-256.
    Csv,
}

/// `calib registry export`.
#[derive(Debug, clap::Args)]
pub struct ExportOptions {
    /// The format.
    #[arg(long, value_enum)]
    pub format: Format,
    /// Write it here (an existing file is replaced whole, as by every command).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// The registry.
    #[command(flatten)]
    pub db: Db,
}

/// The exit status of `calib registry verify` when the controller does not hold the robot's
/// latest calibration (as `calib calibrate` exits when an acceptance criterion is not met).
pub const NOT_VERIFIED: i32 = 3;

/// Runs a registry command and prints what it found or did; `verify` exits with
/// [`NOT_VERIFIED`] when it did not pass.
pub fn run(options: &RegistryOptions) -> anyhow::Result<()> {
    if let RegistryCommand::Verify(o) = &options.command {
        if !verify(o)? {
            let _ = std::io::Write::flush(&mut std::io::stdout());
            std::process::exit(NOT_VERIFIED);
        }
        return Ok(());
    }
    let text = text_of(options)?;
    crate::cli::print_text(format_args!("{text}"))
}

/// `calib registry verify`: prints the verdict; whether it passed.
fn verify(o: &VerifyOptions) -> anyhow::Result<bool> {
    use host_tools::registry::verify::{Given, verify};
    let records = Registry::open(&o.db.db, Access::Read)?.robot(&o.serial)?;
    let given = match (&o.block, &o.robot) {
        (Some(block), _) => Given::Block(block.clone()),
        (None, Some(robot)) => Given::Robot(robot.clone()),
        (None, None) => anyhow::bail!("give --block FILE or --robot FILE"),
    };
    let verification = verify(&o.serial, &records, &given)?;
    let text = match o.json {
        true => format!("{}\n", serde_json::to_string_pretty(&verification)?),
        false => verification.text(&records),
    };
    crate::cli::print_text(format_args!("{text}"))?;
    Ok(verification.passed)
}

/// Runs a registry command; the text to print.
fn text_of(options: &RegistryOptions) -> anyhow::Result<String> {
    Ok(match &options.command {
        RegistryCommand::Add(o) => {
            let record = NewRecord::from_files(&RecordFiles {
                report: Some(&o.report),
                identified: o.identified.as_deref(),
                certificate: o.certificate.as_deref(),
                block: o.block.as_deref(),
                serial: o.serial.as_deref(),
                model: o.model.as_deref(),
            })?;
            let id = Registry::open(&o.db.db, Access::Write)?.add(&record)?;
            format!(
                "registered record {id}: robot {} ({}), {} calibration of {}, report SHA-256 {}, in {}\n",
                record.serial,
                record.model,
                record.kind.name(),
                empty_as_unknown(&record.calibrated_at),
                record.report_sha256,
                o.db.db.display()
            )
        }
        RegistryCommand::List(o) => {
            let list = Registry::open(&o.db.db, Access::Read)?.list(o.serial.as_deref())?;
            match o.json {
                true => format!("{}\n", serde_json::to_string_pretty(&list)?),
                false => list_text(&list),
            }
        }
        RegistryCommand::Show(o) => {
            let record = Registry::open(&o.db.db, Access::Read)?.show(o.id)?;
            match o.json {
                true => host_tools::registry::export::json(std::slice::from_ref(&record))?,
                false => show_text(&record),
            }
        }
        RegistryCommand::Compare(o) => {
            let registry = Registry::open(&o.db.db, Access::Read)?;
            let (a, b) = (registry.show(o.a)?, registry.show(o.b)?);
            let comparison = host_tools::registry::compare::compare(&a, &b, o.poses)?;
            match o.json {
                true => format!("{}\n", serde_json::to_string_pretty(&comparison)?),
                false => comparison.text(),
            }
        }
        RegistryCommand::Verify(_) => String::new(),
        RegistryCommand::Trend(o) => trend(o)?,
        RegistryCommand::Checks(o) => checks(o)?,
        RegistryCommand::PoseTests(o) => pose_tests(o)?,
        RegistryCommand::Fleet(o) => fleet(o)?,
        RegistryCommand::Export(o) => {
            let records = Registry::open(&o.db.db, Access::Read)?.all()?;
            let text = match o.format {
                Format::Json => host_tools::registry::export::json(&records)?,
                Format::Csv => host_tools::registry::export::csv(&records)?,
            };
            let mut outputs = Outputs::new(&[("--db", o.db.db.as_path())]);
            outputs.stage("--out", &o.out, text.as_bytes())?;
            outputs.commit()?;
            format!("wrote {} records to {}\n", records.len(), o.out.display())
        }
    })
}

/// "unknown" for an empty date.
fn empty_as_unknown(text: &str) -> &str {
    if text.is_empty() {
        "unknown date"
    } else {
        text
    }
}

/// The listing as a table.
fn list_text(list: &[Summary]) -> String {
    if list.is_empty() {
        return "no calibrations registered\n".to_string();
    }
    let mut text = format!(
        "{:>6}  {:<16} {:<24} {:<8} {:<22} {:>12}  software\n",
        "id", "serial", "model", "kind", "calibrated at", "held out, mm"
    );
    for s in list {
        text.push_str(&format!(
            "{:>6}  {:<16} {:<24} {:<8} {:<22} {:>12}  {}\n",
            s.id,
            s.serial,
            s.model,
            s.kind.name(),
            empty_as_unknown(&s.calibrated_at),
            s.held_out_mm.map_or("-".to_string(), |v| format!("{v:.4}")),
            s.software
        ));
    }
    text.push_str("held out: a tracker calibration's held-out position error (median, after); touches' held-out consistency (mean, the authors' rule; not accuracy)\n");
    text
}

/// One record for people.
fn show_text(r: &Record) -> String {
    let c = &r.calibration;
    let hash = |v: &Option<String>| v.clone().unwrap_or_else(|| "-".to_string());
    let mut text = format!(
        "record {}: robot {} ({}), {} calibration\ncalibrated at {}, registered at {}, by {}\nheld out: {}\nreport SHA-256 {}\nidentified file SHA-256 {}\ncertificate SHA-256 {}\ncontroller block SHA-256 {}\ncovariance: {}\ninputs:\n",
        r.id,
        c.serial,
        c.model,
        c.kind.name(),
        empty_as_unknown(&c.calibrated_at),
        r.registered_at,
        c.software,
        c.held_out_mm
            .map_or("nothing held out".to_string(), |v| format!("{v:.4} mm")),
        c.report_sha256,
        hash(&c.identified_sha256),
        hash(&c.certificate_sha256),
        hash(&c.block_sha256),
        if c.covariance.is_null() {
            "not recorded"
        } else {
            "recorded"
        }
    );
    for input in c.inputs.as_array().into_iter().flatten() {
        let field = |k: &str| {
            input
                .get(k)
                .and_then(|v| v.as_str())
                .unwrap_or("-")
                .to_string()
        };
        text.push_str(&format!(
            "  {} {}  {}\n",
            field("flag"),
            field("path"),
            field("sha256")
        ));
    }
    if let Some(toml) = &c.identified_toml {
        text.push_str(&format!(
            "identified robot file ({} lines) kept whole (--json prints it)\n",
            toml.lines().count()
        ));
    }
    text
}

/// A robot's shift checks as a table, with the drift rate.
fn checks_text(
    serial: &str,
    checks: &[host_tools::registry::shift::CheckSummary],
    rate: Option<&host_tools::registry::shift::DriftRate>,
) -> String {
    if checks.is_empty() {
        return format!("no shift checks of robot {serial} recorded\n");
    }
    let mut text = format!(
        "{:>6}  {:>11}  {:<22} {:>5} {:>10} {:>10}  verdict\n",
        "check", "calibration", "checked at", "poses", "mean, mm", "max, mm"
    );
    for c in checks {
        text.push_str(&format!(
            "{:>6}  {:>11}  {:<22} {:>5} {:>10.4} {:>10.4}  {}\n",
            c.id,
            c.calibration,
            c.checked_at,
            c.poses,
            c.mean_mm,
            c.max_mm,
            match (c.drifted, &c.cause) {
                (false, _) => "ok".to_string(),
                (true, Some(cause)) => format!("DRIFT: {cause}"),
                (true, None) => "DRIFT".to_string(),
            }
        ));
    }
    if let Some(rate) = rate {
        text.push_str(&rate.text());
    }
    text
}

/// `calib registry trend`: writes the SVG; what it wrote.
fn trend(o: &TrendOptions) -> anyhow::Result<String> {
    let registry = Registry::open(&o.db.db, Access::Read)?;
    let (calibrations, checks) = (registry.list(Some(&o.serial))?, registry.checks(&o.serial)?);
    let rate = host_tools::registry::shift::drift_rate(&checks);
    let svg = host_tools::registry::trend::svg(&o.serial, &calibrations, &checks, rate.as_ref())?;
    let mut outputs = Outputs::new(&[("--db", o.db.db.as_path())]);
    outputs.stage("--out", &o.out, svg.as_bytes())?;
    outputs.commit()?;
    Ok(format!(
        "wrote {} ({} calibrations, {} shift checks of robot {})\n",
        o.out.display(),
        calibrations.len(),
        checks.len(),
        o.serial
    ))
}

/// `calib registry checks`: the robot's shift checks and drift rate, as text or JSON.
fn checks(o: &ChecksOptions) -> anyhow::Result<String> {
    let checks = Registry::open(&o.db.db, Access::Read)?.checks(&o.serial)?;
    let rate = host_tools::registry::shift::drift_rate(&checks);
    Ok(match o.json {
        true => format!(
            "{}\n",
            serde_json::to_string_pretty(
                &serde_json::json!({"checks": checks, "drift_rate": rate})
            )?
        ),
        false => checks_text(&o.serial, &checks, rate.as_ref()),
    })
}

fn pose_tests(o: &PoseTestsOptions) -> anyhow::Result<String> {
    let registry = Registry::open(&o.db.db, Access::Read)?;
    let tests = registry.pose_tests(&o.serial)?;
    if let Some(id) = o.id {
        let test = registry.robot_pose_test(&o.serial, id)?;
        return Ok(match o.json {
            true => format!("{}\n", serde_json::to_string_pretty(&test)?),
            false => test.text(),
        });
    }
    Ok(match (o.json, tests.is_empty()) {
        (true, _) => format!("{}\n", serde_json::to_string_pretty(&tests)?),
        (false, true) => format!("no pose tests of robot {} recorded\n", o.serial),
        (false, false) => tests.iter().map(|t| t.line() + "\n").collect(),
    })
}

fn fleet(o: &FleetOptions) -> anyhow::Result<String> {
    let registry = Registry::open(&o.db.db, Access::Read)?;
    let source = o.db.db.display().to_string();
    let (page, rows) =
        host_tools::registry::fleet::page(&registry, &source, o.interval_days, o.today.as_deref())?;
    let mut outputs = Outputs::new(&[("--db", o.db.db.as_path())]);
    outputs.stage("--out", &o.out, page.as_bytes())?;
    outputs.commit()?;
    let overdue = rows.iter().filter(|r| r.due.1).count();
    Ok(format!(
        "wrote {}: {} robots, {overdue} overdue\n",
        o.out.display(),
        rows.len()
    ))
}
