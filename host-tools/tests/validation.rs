//! Held-out validation (`--validate`, `--holdout`) and `calib evaluate`.

mod common;
use common::{ROBOT, calib, ok};

use serde_json::Value;
use std::path::Path;

/// `poses` simulated poses (0.02 mm, 1e-4 rad of noise) in `dir/NAME.csv`, as a string.
fn simulate(dir: &Path, name: &str, poses: &str, seed: &str) -> String {
    let noise = [
        "--position-sigma-mm",
        "0.02",
        "--orientation-sigma-rad",
        "1e-4",
    ];
    let (data, _) = common::simulate(
        dir,
        name.trim_end_matches(".csv"),
        &[&["--poses", poses, "--seed", seed][..], &noise].concat(),
    );
    common::arg(&data).to_string()
}

#[test]
fn random_hold_out_is_reported_separately() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), "d.csv", "60", "4");
    let report = dir.path().join("r.json");
    let text = ok(&calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        &data,
        "--validate",
        "0.3",
        "--report",
        report.to_str().unwrap(),
    ]));
    assert!(
        text.contains("Table 3 statistics on the calibration poses (42 poses)"),
        "{text}"
    );
    assert!(text.contains("Table 3 statistics on the validation poses (held out, not used to calibrate) (18 poses)"), "{text}");
    let json: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    assert_eq!(json["calibration"]["poses"], 42);
    assert_eq!(json["validation"]["poses"], 18);
    assert_eq!(json["calibration"]["after"], json["after"]);
    let before = json["validation"]["before"]["position_mm"]["mean"]
        .as_f64()
        .unwrap();
    let after = json["validation"]["after"]["position_mm"]["mean"]
        .as_f64()
        .unwrap();
    println!("validation mean |dp|: {before:.4} mm -> {after:.4} mm");
    assert!(before > 5.0 && after < 0.1, "{before} -> {after}");
}

#[test]
fn holdout_file_statistics_equal_calib_evaluate_of_the_identified_model() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), "cal.csv", "40", "5");
    let holdout = simulate(dir.path(), "hold.csv", "30", "6");
    let report = dir.path().join("r.json");
    let identified = dir.path().join("identified.toml");
    ok(&calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        &data,
        "--holdout",
        &holdout,
        "--report",
        report.to_str().unwrap(),
        "--out",
        identified.to_str().unwrap(),
    ]));
    let json: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let evaluated: Value = serde_json::from_str(&ok(&calib(&[
        "evaluate",
        "--robot",
        identified.to_str().unwrap(),
        "--data",
        &holdout,
        "--json",
    ])))
    .unwrap();
    let a = json["validation"]["after"]["position_mm"]["mean"]
        .as_f64()
        .unwrap();
    let b = evaluated["position_mm"]["mean"].as_f64().unwrap();
    // The identified file stores degrees in decimal text: agreement to rounding.
    assert!((a - b).abs() < 1e-9, "{a} vs {b}");
    let nominal: Value = serde_json::from_str(&ok(&calib(&[
        "evaluate", "--robot", ROBOT, "--data", &holdout, "--json",
    ])))
    .unwrap();
    assert_eq!(
        nominal["position_mm"],
        json["validation"]["before"]["position_mm"]
    );
    let text = ok(&calib(&["evaluate", "--robot", ROBOT, "--data", &holdout]));
    assert!(
        text.contains("absolute position error (mm)") && text.contains("(30 poses)"),
        "{text}"
    );

    let both = calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        &data,
        "--holdout",
        &holdout,
        "--validate",
        "0.2",
    ]);
    assert!(!both.status.success());
    let bad = calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        &data,
        "--validate",
        "1.5",
    ]);
    assert!(
        String::from_utf8_lossy(&bad.stderr)
            .contains("--validate must be a fraction between 0 and 1")
    );
}
