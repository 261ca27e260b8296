//! Issue 53, item 4: each kind of refusal arrives as its own variant of `host_tools::Error`, with
//! its data, so that a program (and Python's exception classes) tells an option out of range
//! from a bad file, an unsupported robot, too few poses or a refused output without reading the
//! message; the message stays the one the command line prints.

use crate::common;

use common::{FULL_POSE, SERIES_B, UR10};
use host_tools::Error;
use host_tools::calibration::CalibrationConfig;
use std::path::Path;

/// The first `rows` poses of Series B (with its header) in a file of `dir`.
fn first_poses(dir: &Path, rows: usize) -> String {
    let text = std::fs::read_to_string(SERIES_B).unwrap();
    let head: Vec<&str> = text.lines().take(rows + 1).collect();
    let path = dir.join("first.csv");
    std::fs::write(&path, head.join("\n") + "\n").unwrap();
    path.to_str().unwrap().to_string()
}

#[test]
fn an_option_out_of_range_names_its_flag() {
    let mut config = CalibrationConfig::default();
    config.swarm.particles = 5000;
    let e = config.check().unwrap_err();
    assert!(
        matches!(&e, Error::InvalidOption { option, .. } if option == "--swarm"),
        "{e:?}"
    );
    assert!(
        e.to_string().starts_with("--swarm 5000 is out of range"),
        "{e}"
    );
}

#[test]
fn a_data_file_of_another_robot_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("five.csv");
    std::fs::write(
        &path,
        "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,x_mm,y_mm,z_mm\np1,0,0,0,0,0,1000,0,500\n",
    )
    .unwrap();
    let data = path.to_str().unwrap();
    let e = common::read(UR10, data, None).unwrap_err();
    assert!(
        matches!(&e, Error::InvalidInput { input, .. } if input == data),
        "{e:?}"
    );
    assert!(e.to_string().contains("has 5 joint columns"), "{e}");
}

#[test]
fn too_few_poses_say_how_many_and_how_many_are_needed() {
    let dir = tempfile::tempdir().unwrap();
    let data = first_poses(dir.path(), 4);
    let dataset = common::read(UR10, &data, Some(FULL_POSE)).unwrap();
    let k = calib_core::identify::objective::DEFAULT_K;
    let e = host_tools::analysis::identifiability::check(&dataset, None, k).unwrap_err();
    // Four 6-DoF poses give 24 equations; the UR10's default set (its DH parameters without
    // those of the base and the flange the frames take) has more.
    let Error::TooFew { have, need, .. } = &e else {
        panic!("{e:?}");
    };
    assert_eq!(*have, 24, "{e}");
    assert!(*need > 24, "{e}");
    assert!(
        e.to_string().contains(&format!("fewer than the {need}")),
        "{e}"
    );
}

#[test]
fn an_unsupported_joint_count_names_the_feature() {
    let e = host_tools::model::counts::joint_count(12).unwrap_err();
    assert!(
        matches!(&e, Error::Unsupported { feature, .. } if feature == "joint count"),
        "{e:?}"
    );
    assert!(e.to_string().contains("handles 2 to 9 joints"), "{e}");
}

#[test]
fn an_output_that_would_replace_an_input_names_the_path_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("data.csv");
    std::fs::write(&input, "kept").unwrap();
    let mut outputs = host_tools::io::outputs::Outputs::new(&[("--data", &input)]);
    let e = outputs.stage("--out", &input, b"new").unwrap_err();
    assert!(
        matches!(&e, Error::Output { path, .. } if path == &input),
        "{e:?}"
    );
    assert_eq!(std::fs::read_to_string(&input).unwrap(), "kept");
}
