//! `calib fk` end to end: the printed pose matches the independent f64 reference.

use crate::common;
use common::{ROBOT, calib};

use host_tools::analysis::reference;
use host_tools::io::robot_file::RobotFile;
use std::path::Path;

#[test]
fn fk_json_matches_the_reference() {
    let file = RobotFile::read(Path::new(ROBOT)).unwrap();
    let model = reference::model(&file, &[], &[0.0; 6], &[0.0; 6]);
    for joints in [
        "0,0,0,0,0,0",
        "10,-35.5,120,-170,45,90",
        "-180,90,-90,33,-1e-3,179.9",
    ] {
        let out = calib(&["fk", "--robot", ROBOT, "--joints-deg", joints, "--json"]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let q: Vec<f64> = joints
            .split(',')
            .map(|s| s.parse::<f64>().unwrap().to_radians())
            .collect();
        let t = model.forward(&q);
        let get = |key: &str| -> Vec<f64> {
            json[key]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect()
        };
        let p = get("position_mm");
        for i in 0..3 {
            assert!((p[i] - t[i][3]).abs() < 1e-9, "{joints}: {p:?}");
        }
        let quaternion = get("quaternion_wxyz");
        let expected = reference::quaternion(&t);
        let dot: f64 = quaternion.iter().zip(&expected).map(|(a, b)| a * b).sum();
        assert!(
            (dot.abs() - 1.0).abs() < 1e-14,
            "{joints}: {quaternion:?} vs {expected:?}"
        );
        let r = get("rotation_vector_rad");
        let expected = reference::rotation_vector(&t);
        for i in 0..3 {
            assert!(
                (r[i] - expected[i]).abs() < 1e-12,
                "{joints}: {r:?} vs {expected:?}"
            );
        }
    }
}

#[test]
fn fk_at_zero_is_the_golden_pose() {
    let out = calib(&[
        "fk",
        "--robot",
        ROBOT,
        "--joints-deg",
        "0,0,0,0,0,0",
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    // tests/data/vectors/fk-er10l-c10.csv (the golden vectors), first row: (1355, 0, 920) mm.
    let p: Vec<f64> = json["position_mm"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!((p[0] - 1355.0).abs() < 1e-9 && p[1].abs() < 1e-9 && (p[2] - 920.0).abs() < 1e-9);
}

#[test]
fn wrong_joint_count_fails_with_a_message() {
    let out = calib(&["fk", "--robot", ROBOT, "--joints-deg", "0,0,0"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--joints-deg has 3 values, the robot Efort ER10L-C10 has 6 joints"),
        "{err}"
    );
}

#[test]
fn missing_robot_file_fails_with_its_name() {
    let out = calib(&[
        "fk",
        "--robot",
        "nowhere.toml",
        "--joints-deg",
        "0,0,0,0,0,0",
    ]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("nowhere.toml: cannot read the robot file")
    );
}

#[test]
fn text_output_names_units() {
    let out = calib(&["fk", "--robot", ROBOT, "--joints-deg", "0,0,0,0,0,0"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("position (mm)") && text.contains("1355.000000"),
        "{text}"
    );
    assert!(text.contains("rotation vector (rad)"), "{text}");
}

/// `calib fk` for 7-joint robots: the KUKA LBR iiwa 14 and the Barrett WAM stand straight at
/// zero (their link lengths summed: 360 + 420 + 400 + 126 and 550 + 300 + 60 mm, identity
/// orientation); the Franka Panda, read from its Craig-convention file, at its published zero
/// pose would break joint 4's limits and is refused, naming them; a wrong joint count is refused.
#[test]
fn seven_joint_robots() {
    for (file, z) in [("kuka-iiwa14.toml", 1306.0), ("barrett-wam.toml", 910.0)] {
        let robot = format!("{}/robots/{file}", env!("CARGO_MANIFEST_DIR"));
        let out = calib(&[
            "fk",
            "--robot",
            &robot,
            "--joints-deg",
            "0,0,0,0,0,0,0",
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let pose: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let p: Vec<f64> = pose["position_mm"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert!(
            (p[0].abs() + p[1].abs() + (p[2] - z).abs()) < 1e-9,
            "{file}: {p:?}"
        );
        assert_eq!(pose["quaternion_wxyz"][0].as_f64(), Some(1.0), "{file}");
    }
    let panda = format!("{}/robots/franka-panda.toml", env!("CARGO_MANIFEST_DIR"));
    let out = calib(&["fk", "--robot", &panda, "--joints-deg", "0,0,0,0,0,0,0"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("q4 = 0 deg is outside the joint limits"),
        "{stderr}"
    );
    let out = calib(&["fk", "--robot", &panda, "--joints-deg", "0,0,0,-90,0,90"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("has 6 values, the robot Franka Emika Panda has 7 joints"),
        "{stderr}"
    );
}
