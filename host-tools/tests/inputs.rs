//! Input files are read as meant or refused with what to do (issue 13, defects 7, 11, 13, 17 and
//! 18): each test is named after the defect it reproduces and fails on the code before the fix.

mod common;
use common::{ROBOT, calib};
use host_tools::robot_file::{ER10L_C10_TOML, RobotFile};
use host_tools::tracker_data::TrackerData;
use std::path::Path;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/er10l-c10-sim32.csv");

fn data_text() -> String {
    std::fs::read_to_string(DATA).unwrap()
}

#[test]
fn defect_7_a_byte_order_mark_does_not_hide_the_frame_line() {
    let text = data_text();
    assert!(
        text.starts_with('#'),
        "the bundled file starts with its comments"
    );
    let plain = TrackerData::parse(&text, Path::new("data.csv")).unwrap();
    let marked = TrackerData::parse(&format!("\u{feff}{text}"), Path::new("data.csv")).unwrap();
    assert!(plain.base_frame && marked.base_frame);
    assert_eq!(marked.records, plain.records);
}

#[test]
fn defect_11_limits_with_three_values_are_refused() {
    let text = ER10L_C10_TOML.replacen(
        "[[joint]]\n",
        "[[joint]]\nlimits_deg = [-1.0, 0.0, 170.0]\n",
        1,
    );
    let path = Path::new("robot.toml");
    let error = RobotFile::parse(&text, path)
        .and_then(|file| file.to_model::<6>(path))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("limits_deg has 3 values, expected two"),
        "{error}"
    );
}

#[test]
fn defect_13_cr_only_line_endings_are_named() {
    let text = data_text().replace('\n', "\r");
    let error = TrackerData::parse(&text, Path::new("data.csv"))
        .unwrap_err()
        .to_string();
    assert!(error.contains("CR only"), "{error}");
}

#[test]
fn defect_17_a_user_error_prints_no_backtrace() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(["check", "--robot", "no-such-robot.toml", "--data", DATA])
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr.starts_with("Error: ") && stderr.contains("no-such-robot.toml"),
        "{stderr}"
    );
    assert!(!stderr.to_lowercase().contains("backtrace"), "{stderr}");
}

#[test]
fn defect_18_a_semicolon_separated_file_points_to_a_profile() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("export.csv");
    let text: String = data_text()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| format!("{}\n", l.replace(',', ";")))
        .collect();
    std::fs::write(&data, text).unwrap();
    let out = calib(&["check", "--robot", ROBOT, "--data", data.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("semicolon-separated") && stderr.contains("--profile"),
        "{stderr}"
    );
}
