//! Helpers shared by the integration tests: the `calib` binary runner, the success check, and
//! the parser of command options from argument lists. Each test file uses some of them.
#![allow(dead_code)]

use std::path::Path;
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
