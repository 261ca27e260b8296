//! Robots of every joint count `calib` is compiled for (2 to 9), as a user runs them: simulate ->
//! check -> calibrate (least squares with plots, then the default swarm and least squares) -> evaluate ->
//! verify -> fk -> compensate (6 joints or more) -> export. The expectations are independent of the tool: the number of
//! parameters a complete and minimal model has (`4 N + 6` for `N` revolute joints with both
//! frames identified; Zhuang, Roth and Hamano 1992) and the simulation's truth, which exact data
//! must give back.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{at, calib, ok};

use std::path::Path;

/// A serial arm of `joints` revolute joints in our robot-file format: twists alternating
/// +-90 deg, except that joints 2 and 3 have parallel axes from four joints on (as the shoulder
/// and elbow of most industrial arms), links growing along the chain. `every_parameter`: each
/// joint's `identify` lists all five Hayati parameters instead of the default rule's four.
fn robot_file(joints: usize, every_parameter: bool) -> String {
    let mut text = format!("name = \"test arm of {joints} joints\"\n");
    for j in 1..=joints {
        let alpha = if joints >= 4 && j == 2 {
            0.0
        } else if j % 2 == 0 {
            -90.0
        } else {
            90.0
        };
        text.push_str(&format!(
            "\n[[joint]]\na_mm = {}\nalpha_deg = {alpha}\ntheta_offset_deg = {}\nd_mm = {}\nbeta_deg = 0.0\nlimits_deg = [-170.0, 170.0]\n{}",
            40.0 + 35.0 * j as f64,
            if j == 3 { 90.0 } else { 0.0 },
            if j == 2 { 0.0 } else { 180.0 - 10.0 * j as f64 },
            if every_parameter {
                "identify = [\"a\", \"d\", \"alpha\", \"beta\", \"theta\"]\n"
            } else {
                ""
            },
        ));
    }
    text
}

/// The arm of `joints` joints written to `dir` and 60 poses simulated for it (tracker frame,
/// 6-DoF, random errors of every identified parameter): the robot file, the data and the truth.
fn simulated(dir: &Path, joints: usize, every_parameter: bool) -> (String, String, String) {
    let robot = at(dir, "arm.toml");
    std::fs::write(&robot, robot_file(joints, every_parameter)).unwrap();
    let (data, truth) = (at(dir, "arm.csv"), at(dir, "truth.toml"));
    let out = ok(&calib(&[
        "simulate",
        "--robot",
        &robot,
        "--errors",
        "random",
        "--poses",
        "60",
        "--within-limits",
        "--tracker-xyz-mm",
        "1500,-400,200",
        "--tracker-rpy-deg",
        "0,0,-40",
        "--out",
        &data,
        "--truth-out",
        &truth,
    ]));
    assert!(out.contains("wrote 60 poses"), "{out}");
    (robot, data, truth)
}

/// The runs of one joint count ([`common::every_command`]).
fn identify(joints: usize) {
    let dir = tempfile::tempdir().unwrap();
    let (robot, data, truth) = simulated(dir.path(), joints, false);
    common::every_command(&common::Arm {
        dir: dir.path(),
        robot: &robot,
        data: &data,
        truth: &truth,
        joints,
        parameters: 4 * joints + 6,
        target_deg: (1..=joints).map(|j| 25.0 - 7.0 * j as f64).collect(),
        exact: 1e-8,
    });
}

#[test]
fn every_joint_count_from_two_to_nine_is_identified_exactly() {
    for joints in host_tools::model::counts::JOINT_COUNTS {
        identify(joints);
    }
}

/// Every Hayati parameter of a 9-joint arm asked for: the analysis takes them all and finds the
/// rank of a complete and minimal model, 4 x 9 + 6 = 42; `--auto-mask` drops the rest and the
/// calibration is exact.
#[test]
fn every_parameter_of_a_nine_joint_arm_is_analysed_and_the_redundant_dropped() {
    let dir = tempfile::tempdir().unwrap();
    let (robot, data, _) = simulated(dir.path(), 9, true);
    let out = ok(&calib(&["check", "--robot", &robot, "--data", &data]));
    let first = out.lines().next().unwrap();
    println!("9 joints, every parameter: {first}");
    assert!(
        first.ends_with("parameters: rank 42, rank-deficient"),
        "{out}"
    );
    let asked: usize = first.split_whitespace().nth(2).unwrap().parse().unwrap();
    assert!(asked > 42, "{out}");

    let report = at(dir.path(), "report.json");
    ok(&calib(&[
        "calibrate",
        "--robot",
        &robot,
        "--data",
        &data,
        "--auto-mask",
        "--validate",
        "0.25",
        "--report",
        &report,
        "--quiet",
    ]));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(json["parameters"].as_object().unwrap().len(), 42);
    assert_eq!(json["dropped"].as_array().unwrap().len(), asked - 42);
    let held_out = json["validation"]["after"]["position_mm"]["max"]
        .as_f64()
        .unwrap();
    assert!(held_out < 1e-8, "held-out max {held_out} mm");
}

#[test]
fn a_robot_of_ten_joints_is_refused_with_the_supported_counts() {
    let dir = tempfile::tempdir().unwrap();
    let robot = at(dir.path(), "arm.toml");
    std::fs::write(&robot, robot_file(10, false)).unwrap();
    let (data, truth) = (at(dir.path(), "arm.csv"), at(dir.path(), "truth.toml"));
    let out = calib(&[
        "simulate",
        "--robot",
        &robot,
        "--errors",
        "random",
        "--out",
        &data,
        "--truth-out",
        &truth,
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("the robot file has 10 joints; this command handles 2 to 9 joints"),
        "{err}"
    );
    assert!(!Path::new(&data).exists() && !Path::new(&truth).exists());
}
