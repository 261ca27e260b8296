//! `calib iso9283`: the ISO 9283 pose test ([`host_tools::pose_test`]): `plan` the cube, its five
//! points and the program of n cycles; `evaluate` a measured run (AP, RP, AD, RD, drift).

use host_tools::io::outputs::Outputs;
use host_tools::io::robot_file::RobotFile;
use host_tools::kinematics::targets::ConfigurationChoice;
use host_tools::pose_test::PoseTest;
use host_tools::pose_test::cube::{DEFAULT_CYCLES, TestCube, TestPlan};
use std::path::PathBuf;

/// `calib iso9283`'s options.
#[derive(Debug, clap::Args)]
pub struct Iso9283Options {
    /// What to do.
    #[command(subcommand)]
    pub command: Iso9283Command,
}

/// The pose test's commands.
#[derive(Debug, clap::Subcommand)]
pub enum Iso9283Command {
    /// Plan the test: the cube's five points as commanded poses (a targets file), the joints that
    /// reach them in the controller's model, the run to measure and the program of n cycles.
    Plan(PlanOptions),
    /// Evaluate a measured run against the commanded poses: AP and RP per point, AD and RD
    /// between P2 and P4, the drift of AP and RP at P1.
    Evaluate(EvaluateOptions),
}

/// `calib iso9283 plan`.
#[derive(Debug, clap::Args)]
pub struct PlanOptions {
    /// The robot file the controller plans with (its tool is the point commanded).
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// The cube's centre (P1) in the robot's base frame, mm.
    #[arg(
        long,
        value_name = "X,Y,Z",
        value_delimiter = ',',
        allow_hyphen_values = true,
        num_args = 1,
        required = true
    )]
    pub centre_mm: Vec<f64>,
    /// The cube's edge, mm (the largest cube in the part of the workspace the application uses).
    #[arg(long, value_name = "MM")]
    pub edge_mm: f64,
    /// The tool's orientation at every point, base frame, deg (R = Rz Ry Rx); default: its
    /// orientation at the posture of --near-deg.
    #[arg(
        long,
        value_name = "R,P,Y",
        value_delimiter = ',',
        allow_hyphen_values = true,
        num_args = 1
    )]
    pub rpy_deg: Option<Vec<f64>>,
    /// The arm configuration: that of this posture (joint readings, deg).
    #[arg(
        long,
        value_name = "DEG,...",
        value_delimiter = ',',
        allow_hyphen_values = true,
        num_args = 1,
        conflicts_with = "branch"
    )]
    pub near_deg: Option<Vec<f64>>,
    /// The arm configuration as a closed-form inverse kinematics branch, 0-7.
    #[arg(long, value_name = "B")]
    pub branch: Option<usize>,
    /// Cycles through the five points.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_CYCLES)]
    pub cycles: usize,
    /// Write the commanded poses (targets file, base frame): what evaluate judges against, and
    /// what calib compensate --targets corrects for a compensated controller.
    #[arg(long, value_name = "FILE")]
    pub targets: PathBuf,
    /// Write the run to measure: a tracker CSV, one row per move, its measurement columns empty.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Write the program as joint targets (id, q1_deg..qN_deg) for any controller.
    #[arg(long, value_name = "FILE")]
    pub joint_targets: Option<PathBuf>,
    /// Write the program in URScript (Universal Robots, 6 joints).
    #[arg(long, value_name = "FILE")]
    pub urscript: Option<PathBuf>,
    /// How the URScript program moves.
    #[command(flatten)]
    pub motion: crate::cli::MotionOptions,
}

/// `calib iso9283 evaluate`.
#[derive(Debug, clap::Args)]
pub struct EvaluateOptions {
    /// The commanded poses (the targets file of calib iso9283 plan, base frame).
    #[arg(long, value_name = "FILE")]
    pub targets: PathBuf,
    /// The measured run (tracker data; ids such as P3-c07: the point, then the cycle; rows of a point in cycle order).
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    /// The data profile the run is read through.
    #[arg(long, value_name = "FILE")]
    pub profile: Option<PathBuf>,
    /// The robot's identified file (calib calibrate --out): its measurement section places the
    /// tracker and the probe; its tool is the controller's.
    #[arg(long, value_name = "FILE")]
    pub robot: PathBuf,
    /// Write the test as JSON.
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Record the test in this registry (calib registry pose-tests lists them).
    #[arg(long, value_name = "FILE")]
    pub registry: Option<PathBuf>,
    /// The robot's serial number the test is recorded under (default: the robot file's).
    #[arg(long, value_name = "SERIAL", requires = "registry")]
    pub serial: Option<String>,
    /// When the run was measured, RFC 3339 (default: now).
    #[arg(long, value_name = "TIME", requires = "registry")]
    pub tested_at: Option<String>,
}

/// Runs `calib iso9283`.
pub fn run(options: &Iso9283Options) -> anyhow::Result<()> {
    match &options.command {
        Iso9283Command::Plan(o) => plan(o),
        Iso9283Command::Evaluate(o) => evaluate(o),
    }
}

fn three(values: &[f64], option: &str) -> anyhow::Result<[f64; 3]> {
    <[f64; 3]>::try_from(values).map_err(|_| {
        anyhow::anyhow!(
            "{option}: give three numbers separated by commas, got {}",
            values.len()
        )
    })
}

fn plan(o: &PlanOptions) -> anyhow::Result<()> {
    let file = RobotFile::read(&o.robot)?;
    let cube = TestCube::new(three(&o.centre_mm, "--centre-mm")?, o.edge_mm)?;
    let rpy = o
        .rpy_deg
        .as_deref()
        .map(|v| three(v, "--rpy-deg"))
        .transpose()?;
    let configuration = match (&o.near_deg, o.branch, &file.compensation) {
        (Some(posture), _, _) => ConfigurationChoice::NearDeg(posture.clone()),
        (None, Some(branch), _) => ConfigurationChoice::Branch(branch),
        (None, None, Some(c)) => match (&c.near_deg, c.branch) {
            (Some(posture), _) => ConfigurationChoice::NearDeg(posture.clone()),
            (None, Some(branch)) => ConfigurationChoice::Branch(branch),
            (None, None) => anyhow::bail!(no_configuration(&o.robot)),
        },
        (None, None, None) => anyhow::bail!(no_configuration(&o.robot)),
    };
    let test = TestPlan::new((&file, &o.robot), cube, rpy, configuration, o.cycles)?;
    let mut outputs = Outputs::new(&[("--robot", o.robot.as_path())]);
    outputs.stage("--targets", &o.targets, test.targets_csv().as_bytes())?;
    outputs.stage("--out", &o.out, test.run_csv().as_bytes())?;
    if let Some(path) = &o.joint_targets {
        outputs.stage("--joint-targets", path, test.joint_targets().as_bytes())?;
    }
    if let Some(path) = &o.urscript {
        outputs.stage(
            "--urscript",
            path,
            test.urscript(&o.motion.motion())?.as_bytes(),
        )?;
    }
    outputs.commit()?;
    let mut text = format!(
        "ISO 9283 test cube for {}: centre {:?} mm, edge {} mm, tool rpy {:.4?} deg; {} cycles ({} moves)\n",
        test.robot,
        test.cube.centre_mm,
        test.cube.edge_mm,
        test.rpy_deg,
        test.cycles,
        test.cycles * test.targets.len()
    );
    for (t, q) in test.targets.iter().zip(&test.joints) {
        let q: Vec<String> = q.iter().map(|v| format!("{:.3}", v.to_degrees())).collect();
        text.push_str(&format!(
            "  {}  at {:.3?} mm  joints {} deg\n",
            t.id,
            t.position_mm,
            q.join(", ")
        ));
    }
    crate::cli::print_text(format_args!("{text}"))
}

fn no_configuration(robot: &std::path::Path) -> String {
    format!(
        "the arm configuration of the cube's points is not stated: give --near-deg (a posture) or --branch, or a [compensation] section in {}",
        robot.display()
    )
}

fn evaluate(o: &EvaluateOptions) -> anyhow::Result<()> {
    use host_tools::registry::{Access, Registry, pose_tests};
    let profile = host_tools::io::profile::DataProfile::load(o.profile.as_deref())?;
    let test = PoseTest::evaluate(&o.targets, &o.data, &o.robot, &profile)?;
    let mut inputs = vec![
        ("--targets", o.targets.as_path()),
        ("--data", o.data.as_path()),
        ("--robot", o.robot.as_path()),
    ];
    if let Some(p) = &o.profile {
        inputs.push(("--profile", p.as_path()));
    }
    let mut outputs = Outputs::new(&inputs);
    if let Some(path) = &o.report {
        outputs.stage(
            "--report",
            path,
            serde_json::to_string_pretty(&test)?.as_bytes(),
        )?;
    }
    // Recorded before the report replaces its file: a refusal (a run recorded before) leaves
    // both as they were.
    let recorded = match &o.registry {
        Some(db) => {
            if inputs.iter().any(|(_, p)| p == db) || o.report.as_ref() == Some(db) {
                anyhow::bail!(
                    "--registry {}: the registry is named as an input or output too; name it once",
                    db.display()
                );
            }
            let serial = pose_tests::serial_of(o.serial.as_deref(), &test)?;
            let tested_at = pose_tests::tested_at(o.tested_at.as_deref())?;
            let id = Registry::open(db, Access::Write)?.add_pose_test(serial, &test, &tested_at)?;
            Some(format!(
                "recorded as pose test {id} of {serial} in {}\n",
                db.display()
            ))
        }
        None => None,
    };
    outputs.commit()?;
    match o.json {
        true => crate::cli::print_text(format_args!("{}\n", serde_json::to_string_pretty(&test)?)),
        false => crate::cli::print_text(format_args!(
            "{}{}",
            test.text(),
            recorded.unwrap_or_default()
        )),
    }
}
