//! Helpers shared by the integration tests: the `calib` binary runner, the success check, the
//! parser of command options from argument lists, and simulated data. Each test file uses some
//! of them.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The nominal ER10L-C10 robot file.
pub const ROBOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/er10l-c10.toml");
/// The nominal UR10 robot file.
pub const UR10: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml");
/// The real UR10 measurements of Series B (1495 poses).
pub const SERIES_B: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv"
);
/// Their data profile with orientation (6-DoF).
pub const FULL_POSE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/profiles/ipa-ur10-lasertracker.toml"
);
/// Their data profile with positions only.
pub const POSITION: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/profiles/ipa-ur10-lasertracker-position.toml"
);

/// Runs the `calib` binary with `args` in the current directory.
pub fn calib(args: &[&str]) -> Output {
    calib_in(Path::new("."), args)
}

/// Runs the `calib` binary with `args` in `dir`.
pub fn calib_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_calib"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run calib")
}

/// Standard output of a run that must have succeeded (its standard error in the failure message).
pub fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "calib failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[derive(clap::Parser)]
#[command(no_binary_name = true)]
struct Wrap<T: clap::Args> {
    #[command(flatten)]
    inner: T,
}

/// A command's options parsed from `args` (without the command name), as `calib` parses them.
pub fn parse<T: clap::Args>(args: &[&str]) -> T {
    <Wrap<T> as clap::Parser>::parse_from(args.iter().copied()).inner
}

/// Per row of a `calib compensate` output `out` of a robot of `joints` joints (every row `ok`),
/// the position miss (mm) of the real robot at the joints commanded: `reached(q)` is its pose at
/// the joints `q` (rad), `target(i)` the target of row `i` (reference kinematics, 4x4).
pub fn compensation_misses(
    out: &Path,
    joints: usize,
    reached: impl Fn(&calib_core::model::JointVec<f64>) -> host_tools::analysis::reference::Mat4,
    target: impl Fn(usize) -> host_tools::analysis::reference::Mat4,
) -> Vec<f64> {
    let mut reader = csv::Reader::from_path(out).unwrap();
    reader
        .records()
        .enumerate()
        .map(|(i, record)| {
            let record = record.unwrap();
            // id, q1..qN, residual, iterations, status.
            assert_eq!(&record[joints + 3], "ok", "{} row {i}", out.display());
            let q = calib_core::model::JointVec::<f64>::from_fn(joints, |j| {
                record[j + 1].parse::<f64>().unwrap().to_radians()
            });
            let e = host_tools::analysis::reference::pose_error(&target(i), &reached(&q));
            (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt()
        })
        .collect()
}

/// `calib compensate --robot ROBOT --params PARAMS` of targets in `dir`: the poses the nominal
/// robot of `robot` reaches at `readings` (rad). Returns per target the position miss (mm) of the
/// robot of the file `actual` at the joints compensate commands: the reference kinematics at the
/// readings plus its joint maps, plus its gravity compliance (the identification's columns) if it
/// has one.
pub fn compensated_misses(
    dir: &Path,
    robot: &str,
    params: &Path,
    actual: &Path,
    readings: &[Vec<f64>],
) -> Vec<f64> {
    use host_tools::analysis::reference;
    use host_tools::io::robot_file::{RobotFile, RobotModel};
    use host_tools::io::tracker_data::{PoseRow, write_tracker_csv};
    let no_errors = |file: &RobotFile| reference::model(file, &[], &[0.0; 6], &[0.0; 6]);
    let nominal = no_errors(&RobotFile::read(Path::new(robot)).unwrap());
    let file = RobotFile::read(actual).unwrap();
    let maps = file.joint_maps(actual).unwrap();
    let real = no_errors(&file);
    let model: RobotModel = file.to_model(actual).unwrap();
    let compliance = file.gravity_compliance(actual).unwrap();
    let rows: Vec<PoseRow> = readings
        .iter()
        .enumerate()
        .map(|(i, q)| {
            let pose = nominal.forward(q);
            PoseRow {
                id: format!("T{i:02}"),
                q: q.clone(),
                position: [pose[0][3], pose[1][3], pose[2][3]],
                rotation: Some(nalgebra::Matrix3::from_fn(|r, c| pose[r][c])),
            }
        })
        .collect();
    let targets = dir.join("targets.csv");
    write_tracker_csv(&targets, &["frame: base".into()], &rows).unwrap();
    let stem = params.file_stem().unwrap().to_str().unwrap();
    let out = dir.join(format!("{stem}-compensated.csv"));
    ok(&calib(&[
        "compensate",
        "--robot",
        robot,
        "--params",
        arg(params),
        "--targets",
        arg(&targets),
        "--out",
        arg(&out),
        // The maps are evaluated where the targets are, within their identified readings or
        // not: what is checked here is that compensation uses them.
        "--allow-extrapolation",
    ]));
    compensation_misses(
        &out,
        readings[0].len(),
        |q| {
            let angles = maps.as_ref().map_or(*q, |m| m.apply(q));
            let mut reached = real.forward(&angles);
            if let Some(c) = &compliance {
                let columns = host_tools::model::compliance::columns(
                    &c.gravity,
                    &model.robot,
                    &calib_core::ParameterErrors::zeros_for(model.robot.joint_count()),
                    &angles,
                )
                .unwrap();
                let v = host_tools::model::compliance::displacement(&columns, &c.gains);
                for (r, row) in reached.iter_mut().take(3).enumerate() {
                    row[3] += v[r];
                }
            }
            reached
        },
        |i| nominal.forward(&rows[i].q),
    )
}

/// Simulated data of the nominal ER10L-C10 ([`ROBOT`]), as `calib simulate` with the options
/// `args` writes them: the data to `dir/NAME.csv`, the true robot to `dir/NAME-truth.toml`.
/// Returns (data, truth).
pub fn simulate(dir: &Path, name: &str, args: &[&str]) -> (PathBuf, PathBuf) {
    let data = dir.join(format!("{name}.csv"));
    let truth = dir.join(format!("{name}-truth.toml"));
    let mut all = vec![
        "--robot",
        ROBOT,
        "--out",
        data.to_str().unwrap(),
        "--truth-out",
        truth.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    host_tools::cli::simulate::simulate(&parse::<host_tools::cli::simulate::Simulation>(&all))
        .unwrap();
    (data, truth)
}

/// Simulated data of the nominal ER10L-C10 ([`ROBOT`]) under a simulation configuration of the
/// library: the data to `dir/NAME.csv`, the true robot to `dir/NAME-truth.toml`. Returns (data,
/// truth).
pub fn simulate_with(
    dir: &Path,
    name: &str,
    config: &host_tools::measurement::simulate::SimulationConfig,
) -> (PathBuf, PathBuf) {
    let data = dir.join(format!("{name}.csv"));
    let truth = dir.join(format!("{name}-truth.toml"));
    let robot = host_tools::io::robot_file::RobotFile::read(Path::new(ROBOT)).unwrap();
    host_tools::measurement::simulate::simulate(&robot, Path::new(ROBOT), config)
        .unwrap()
        .write(&data, &truth, Path::new(ROBOT))
        .unwrap();
    (data, truth)
}

/// `dir/name` as a string.
pub fn at(dir: &Path, name: &str) -> String {
    dir.join(name).to_str().unwrap().to_string()
}

/// A path as the `&str` a command line takes.
pub fn arg(path: &Path) -> &str {
    path.to_str().unwrap()
}
