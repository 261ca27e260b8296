//! Robots of every joint count `calib` is compiled for (2 to 9), as a user runs them: simulate ->
//! check -> calibrate (least squares with plots, then the default swarm and least squares) -> evaluate ->
//! verify -> fk -> compensate (6 joints or more) -> export. The expectations are independent of the tool: the number of
//! parameters a complete and minimal model has (`4 N + 6` for `N` revolute joints with both
//! frames identified; Zhuang, Roth and Hamano 1992) and the simulation's truth, which exact data
//! must give back.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
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

/// The runs of one joint count; prints what it measured.
fn identify(joints: usize) {
    let dir = tempfile::tempdir().unwrap();
    let (robot, data, truth) = simulated(dir.path(), joints, false);

    let minimal = 4 * joints + 6;
    let out = ok(&calib(&["check", "--robot", &robot, "--data", &data]));
    assert!(
        out.contains(&format!(
            "identifiability of {minimal} parameters: rank {minimal}"
        )),
        "{joints} joints: {out}"
    );

    let report = at(dir.path(), "report.json");
    let identified = at(dir.path(), "identified.toml");
    let plots = at(dir.path(), "plots");
    let out = ok(&calib(&[
        "calibrate",
        "--robot",
        &robot,
        "--data",
        &data,
        "--method",
        "lm",
        "--validate",
        "0.25",
        "--truth",
        &truth,
        "--out",
        &identified,
        "--report",
        &report,
        "--plot",
        &plots,
    ]));
    assert!(out.contains("with 45 poses"), "{out}");
    for plot in ["position-error.svg", "position-error.png"] {
        assert!(
            Path::new(&plots).join(plot).is_file(),
            "{joints} joints: {plot}"
        );
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let rows = json["truth"].as_array().unwrap();
    assert_eq!(rows.len(), minimal, "{joints} joints");
    // The frames' rows differ from the truth's zero by what they absorb of the first and last
    // joints' errors; the joints' own parameters are the truth.
    let worst = rows
        .iter()
        .filter(|row| {
            let name = row["name"].as_str().unwrap();
            !(name.starts_with("base") || name.starts_with("tool"))
        })
        .map(|row| (row["identified"].as_f64().unwrap() - row["truth"].as_f64().unwrap()).abs())
        .fold(0.0, f64::max);
    let held_out = json["validation"]["after"]["position_mm"]["max"]
        .as_f64()
        .unwrap();
    println!(
        "{joints} joints: {minimal} parameters, largest error against the truth {worst:.1e}, held-out max {held_out:.1e} mm"
    );
    assert!(worst < 1e-8, "{joints} joints: {worst}");
    assert!(
        held_out < 1e-8,
        "{joints} joints: held-out max {held_out} mm"
    );

    // The default method, the swarm then least squares, reaches the same exact fit.
    let again = at(dir.path(), "again.json");
    let out = ok(&calib(&[
        "calibrate",
        "--robot",
        &robot,
        "--data",
        &data,
        "--validate",
        "0.25",
        "--report",
        &again,
        "--quiet",
    ]));
    assert!(out.contains("by ipso+lm"), "{out}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&again).unwrap()).unwrap();
    let held_out = json["validation"]["after"]["position_mm"]["max"]
        .as_f64()
        .unwrap();
    assert!(
        held_out < 1e-8,
        "{joints} joints: held-out max {held_out} mm"
    );

    let out = ok(&calib(&[
        "evaluate",
        "--robot",
        &identified,
        "--data",
        &data,
        "--json",
    ]));
    let evaluation: serde_json::Value = serde_json::from_str(&out).unwrap();
    let mean = evaluation["position_mm"]["mean"].as_f64().unwrap();
    assert!(mean < 1e-6, "{joints} joints: evaluate mean {mean} mm");

    let out = ok(&calib(&["verify", "--robot", &robot, "--data", &data]));
    assert!(
        out.contains("all within tolerance"),
        "{joints} joints: {out}"
    );

    compensate_and_export(dir.path(), joints, &robot, &identified);
}

/// fk of the nominal robot at a joint vector gives a target; compensate puts the identified
/// robot on it (6 joints or more; fewer are refused with the reason and nothing is written);
/// export writes the controller's block.
fn compensate_and_export(dir: &Path, joints: usize, robot: &str, identified: &str) {
    let q: Vec<String> = (1..=joints)
        .map(|j| format!("{}", 25.0 - 7.0 * j as f64))
        .collect();
    let out = ok(&calib(&[
        "fk",
        "--robot",
        robot,
        "--joints-deg",
        &q.join(","),
        "--json",
    ]));
    let pose: serde_json::Value = serde_json::from_str(&out).unwrap();
    let numbers = |key: &str| -> Vec<String> {
        pose[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap().to_string())
            .collect()
    };
    let targets = at(dir, "targets.csv");
    std::fs::write(
        &targets,
        format!(
            "id,x_mm,y_mm,z_mm,qw,qx,qy,qz,{}\nT1,{},{},{}\n",
            (1..=joints)
                .map(|j| format!("q{j}_deg"))
                .collect::<Vec<_>>()
                .join(","),
            numbers("position_mm").join(","),
            numbers("quaternion_wxyz").join(","),
            q.join(",")
        ),
    )
    .unwrap();
    let compensated = at(dir, "compensated.csv");
    let out = calib(&[
        "compensate",
        "--robot",
        robot,
        "--params",
        identified,
        "--targets",
        &targets,
        "--out",
        &compensated,
        "--max-correction-mm",
        "50",
        "--max-correction-deg",
        "5",
    ]);
    if joints < 6 {
        assert!(!out.status.success(), "{joints} joints");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&format!(
                "which takes at least 6 joints; this robot has {joints}"
            )),
            "{err}"
        );
        assert!(!Path::new(&compensated).exists());
    } else {
        let text = ok(&out);
        let mut reader = csv::Reader::from_path(&compensated).unwrap();
        let row = reader.records().next().unwrap().unwrap();
        assert!(
            text.contains("compensated 1 of 1 targets"),
            "{text}\n{row:?}"
        );
        let residual: f64 = row[joints + 1].parse().unwrap();
        println!("{joints} joints: compensated to {residual:.1e} mm");
        assert!(residual < 1e-3, "{joints} joints: {residual} mm");
    }

    let block = at(dir, "arm.bin");
    let out = ok(&calib(&[
        "export", "--params", identified, "--format", "block", "--out", &block,
    ]));
    assert!(out.contains("wrote"), "{out}");
    assert!(std::fs::metadata(&block).unwrap().len() > 0);
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
