//! Input files are read as meant or refused with what to do (issue 13, defects 7, 11, 13, 17 and
//! 18): each test is named after the defect it reproduces and fails on the code before the fix.

use crate::common;
use common::{ROBOT, calib};
use host_tools::io::robot_file::{ER10L_C10_TOML, RobotFile};
use host_tools::io::tracker_data::TrackerData;
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
        .and_then(|file| file.to_model(path))
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

/// `calib` with `args`, expected to fail with exit 1 and a message holding every one of `expect`.
fn refused(args: &[&str], expect: &[&str]) {
    let out = calib(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    for e in expect {
        assert!(stderr.contains(e), "{e:?} not in: {stderr}");
    }
}

/// The bundled robot file with the first `from` replaced by `to`, written into `dir`.
fn robot_with(dir: &Path, from: &str, to: &str) -> String {
    assert!(ER10L_C10_TOML.contains(from));
    let path = dir.join("robot.toml");
    std::fs::write(&path, ER10L_C10_TOML.replacen(from, to, 1)).unwrap();
    path.to_str().unwrap().to_owned()
}

#[test]
fn defect_1_a_huge_robot_parameter_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    for huge in ["1e160", "1e154", "1.7e308"] {
        let robot = robot_with(dir.path(), "a_mm = 780.0", &format!("a_mm = {huge}"));
        for command in ["check", "calibrate", "verify"] {
            let mut args = vec![command, "--robot", robot.as_str()];
            args.extend(["--data", DATA]);
            refused(
                &args,
                &["robot.toml", "joint 2: a_mm", "beyond the plausible range"],
            );
        }
    }
}

#[test]
fn defect_16_robot_files_have_plausibility_limits() {
    let dir = tempfile::tempdir().unwrap();
    for (from, to, field) in [
        ("a_mm = 780.0", "a_mm = 1e300", "joint 2: a_mm"),
        (
            "alpha_deg = -90.0",
            "alpha_deg = 1e300",
            "joint 1: alpha_deg",
        ),
        (
            "theta_offset_deg = 0.0",
            "theta_offset_deg = 1e20",
            "joint 1: theta_offset_deg",
        ),
    ] {
        let robot = robot_with(dir.path(), from, to);
        refused(
            &["fk", "--robot", &robot, "--joints-deg", "0,0,0,0,0,0"],
            &[field, "beyond the plausible range"],
        );
    }
}

#[test]
fn defect_10_a_block_beyond_f32_range_is_not_written() {
    let dir = tempfile::tempdir().unwrap();
    let robot = robot_with(dir.path(), "a_mm = 780.0", "a_mm = 1e300");
    let block = dir.path().join("params.bin");
    refused(
        &[
            "export",
            "--params",
            &robot,
            "--format",
            "block",
            "--scalar",
            "f32",
            "--out",
            block.to_str().unwrap(),
        ],
        &["a_mm"],
    );
    assert!(!block.exists());
}

/// The bundled data with the value `from` on data line `line` (1-based among data rows)
/// replaced by `to`, written into `dir`.
fn data_with(dir: &Path, row: usize, from: &str, to: &str) -> String {
    let text = data_text();
    let header = text.lines().position(|l| l.starts_with("id,")).unwrap();
    let lines: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == header + row {
                assert!(l.contains(from), "{l}");
                l.replacen(from, to, 1)
            } else {
                l.to_owned()
            }
        })
        .collect();
    let path = dir.join("data.csv");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    path.to_str().unwrap().to_owned()
}

#[test]
fn defect_8_absurd_joint_and_position_values_are_refused_with_their_line() {
    let dir = tempfile::tempdir().unwrap();
    // Data row 1 is physical line 5 of the bundled file.
    for (from, to, expect) in [
        ("112.18037719747859", "1e308", "beyond ten turns"),
        ("-432.88307855299564", "1e100", "beyond the 100 m range"),
    ] {
        let data = data_with(dir.path(), 1, from, to);
        refused(
            &[
                "calibrate",
                "--robot",
                ROBOT,
                "--data",
                &data,
                "--method",
                "lm",
            ],
            &["data.csv:5", expect],
        );
    }
}

#[test]
fn defect_9_errors_name_the_line_and_the_value() {
    let dir = tempfile::tempdir().unwrap();
    // A position of 1e200 (was "least squares: a parameter or residual is not finite") and of
    // 1e100 (was "the measured points do not span a plane").
    for value in ["1e200", "1e100"] {
        let data = {
            let text = data_text();
            let header = text.lines().position(|l| l.starts_with("id,")).unwrap();
            let lines: Vec<String> = text
                .lines()
                .enumerate()
                .map(|(i, l)| {
                    if i == header + 3 {
                        let mut fields: Vec<&str> = l.split(',').collect();
                        fields[7] = value;
                        fields.join(",")
                    } else {
                        l.to_owned()
                    }
                })
                .collect();
            let path = dir.path().join("data.csv");
            std::fs::write(&path, lines.join("\n") + "\n").unwrap();
            path.to_str().unwrap().to_owned()
        };
        for frames in ["none", "base+tool"] {
            refused(
                &[
                    "calibrate",
                    "--robot",
                    ROBOT,
                    "--data",
                    &data,
                    "--method",
                    "lm",
                    "--frames",
                    frames,
                ],
                &["data.csv:7", "x_mm", value],
            );
        }
    }
    // All weights 0 (was "rank 0 of 24"), and one weight of 1e308.
    let text = data_text().replace(",qw,", ",weight,qw,");
    let zero: String = text
        .lines()
        .map(|l| {
            if l.starts_with('P') {
                let mut f: Vec<&str> = l.split(',').collect();
                f.insert(10, "0");
                f.join(",") + "\n"
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    let path = dir.path().join("weights.csv");
    std::fs::write(&path, &zero).unwrap();
    let path = path.to_str().unwrap();
    refused(
        &[
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            path,
            "--method",
            "lm",
        ],
        &["weights.csv", "every pose has weight 0"],
    );
    let heavy = zero.replacen(",0,", ",1e308,", 1);
    std::fs::write(path, heavy).unwrap();
    refused(
        &[
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            path,
            "--method",
            "lm",
        ],
        &["weights.csv:5", "weight 1e308"],
    );
}

#[test]
fn defect_12_invalid_utf8_is_reported_with_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = data_text().into_bytes();
    let line_7 = bytes
        .iter()
        .enumerate()
        .filter(|(_, b)| **b == b'\n')
        .nth(5)
        .unwrap()
        .0
        + 1;
    bytes[line_7 + 1] = 0xff;
    let path = dir.path().join("data.csv");
    std::fs::write(&path, bytes).unwrap();
    refused(
        &["check", "--robot", ROBOT, "--data", path.to_str().unwrap()],
        &["data.csv:7", "not UTF-8"],
    );
}

#[test]
fn defect_15_a_truth_file_with_nan_inf_or_seven_joints_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let truth = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/er10l-c10-sim32-truth.toml"
    );
    let text = std::fs::read_to_string(truth).unwrap();
    let start = text.find("da1 = ").unwrap();
    let end = start + text[start..].find('\n').unwrap();
    let nan = format!("{}da1 = nan{}", &text[..start], &text[end..]);
    let path = dir.path().join("truth.toml");
    std::fs::write(&path, nan).unwrap();
    let args = |truth: &str| {
        calib(&[
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            DATA,
            "--method",
            "lm",
            "--truth",
            truth,
        ])
    };
    let out = args(path.to_str().unwrap());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("da1 = NaN") || stderr.contains("da1 = nan"),
        "{stderr}"
    );
    let seven = text.replacen(
        "[[joint]]",
        "[[joint]]\na_mm = 0.0\nalpha_deg = 0.0\ntheta_offset_deg = 0.0\nd_mm = 0.0\n\n[[joint]]",
        1,
    );
    std::fs::write(&path, seven).unwrap();
    let out = args(path.to_str().unwrap());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("has 7 [[joint]] tables, expected 6"),
        "{stderr}"
    );
    // Issue 39, N19: inf in the joint table (not an error) is refused too: the file is checked
    // as a robot file, not only read for its errors.
    let start = text.find("a_mm =").unwrap();
    let end = start + text[start..].find('\n').unwrap();
    let inf = format!("{}a_mm = inf{}", &text[..start], &text[end..]);
    std::fs::write(&path, inf).unwrap();
    let out = args(path.to_str().unwrap());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("a_mm = inf is not a finite number"),
        "{stderr}"
    );
}

#[test]
fn defect_8_positions_in_the_wrong_unit_are_refused_with_the_likely_cause() {
    let dir = tempfile::tempdir().unwrap();
    let text = data_text();
    // Millimetre values under metre headers, and metres under millimetre headers.
    let as_metres_header = text.replace("x_mm,y_mm,z_mm", "x_m,y_m,z_m");
    let in_metres: String = text
        .lines()
        .map(|l| {
            if l.starts_with('P') {
                let mut f: Vec<String> = l.split(',').map(str::to_owned).collect();
                for v in &mut f[7..10] {
                    *v = (v.parse::<f64>().unwrap() / 1000.0).to_string();
                }
                f.join(",") + "\n"
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    for (name, text, expect) in [
        // 432 m: beyond a tracker's range, refused on its line.
        ("m.csv", as_metres_header, "beyond the 100 m range"),
        ("mm.csv", in_metres, "metres under millimetre headers"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        refused(
            &[
                "calibrate",
                "--robot",
                ROBOT,
                "--data",
                path.to_str().unwrap(),
                "--method",
                "lm",
            ],
            &[name, expect, "unit"],
        );
    }
}

/// Issue 39, N5: an Euler angle beyond two turns (`1e300`) is refused, naming the line and the
/// column, instead of turning the measured orientation into noise; one turn and a half is read.
#[test]
fn n5_an_euler_angle_out_of_range_is_refused_with_its_line() {
    let head = "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg\n";
    let row = |rx: &str| format!("p1,0,0,0,0,0,0,1000,0,500,{rx},0,0\n");
    let error = TrackerData::parse(&format!("{head}{}", row("1e300")), Path::new("data.csv"))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("data.csv:2") && error.contains("rx_deg") && error.contains("720 deg"),
        "{error}"
    );
    let read = TrackerData::parse(&format!("{head}{}", row("540")), Path::new("data.csv")).unwrap();
    assert!(read.records[0].rotation.is_some());
}

/// Issue 39, N19: `fk` with a joint reading beyond ten turns (`1e308` deg) is refused with the
/// joint, not turned into a pose; an output path ending with a separator (`dir/`) is refused
/// instead of written as a file named `dir`, and nothing is created.
#[test]
fn n19_huge_fk_readings_and_a_directory_as_output_are_refused() {
    let out = calib(&["fk", "--robot", ROBOT, "--joints-deg", "0,1e308,0,0,0,0"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("q2 = 1e308 deg is beyond ten turns"),
        "{stderr}"
    );
    assert!(out.stdout.is_empty());
    let dir = tempfile::tempdir().unwrap();
    let target = format!("{}/new/", dir.path().display());
    let out = calib(&[
        "export", "--params", ROBOT, "--format", "toml", "--out", &target,
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("names a directory"), "{stderr}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// Issue 39, N9: inputs have a size limit, checked before they are read. A data file over 1
/// GiB (sparse, so the test writes nothing) and an endless robot file (`/dev/zero`) are refused
/// with the limit and the option that raises it, in bounded memory; `--max-input-mb` raises it
/// (a robot file of 17 MiB, mostly a comment, is then read); `simulate --poses 100000000000` is refused instead
/// of allocating terabytes.
#[test]
fn n9_inputs_over_their_size_limit_are_refused_with_the_option_to_raise_it() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("big.csv");
    let file = std::fs::File::create(&data).unwrap();
    file.set_len(1100 << 20).unwrap();
    let data = data.to_str().unwrap();
    let out = calib(&["check", "--robot", ROBOT, "--data", data]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("cannot read the data file")
            && stderr.contains("1100.0 MiB, more than the 1024 MiB")
            && stderr.contains("--max-input-mb"),
        "{stderr}"
    );
    let robot = dir.path().join("robot.toml");
    let comment = format!("# {}\n", "x".repeat(17 << 20));
    std::fs::write(&robot, format!("{comment}{ER10L_C10_TOML}")).unwrap();
    let robot = robot.to_str().unwrap();
    let out = calib(&["check", "--robot", robot, "--data", DATA]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("17.0 MiB, more than the 16 MiB"),
        "{stderr}"
    );
    let out = calib(&[
        "check",
        "--max-input-mb",
        "20",
        "--robot",
        robot,
        "--data",
        DATA,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    if Path::new("/dev/zero").exists() {
        let out = calib(&["check", "--robot", "/dev/zero", "--data", DATA]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains("/dev/zero: cannot read the robot file")
                && stderr.contains("goes on past the 16 MiB"),
            "{stderr}"
        );
    }
    let truth = dir.path().join("truth.toml");
    let out = calib(&[
        "simulate",
        "--robot",
        ROBOT,
        "--poses",
        "100000000000",
        "--out",
        data,
        "--truth-out",
        truth.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("more than the 10000000 poses"), "{stderr}");
    assert!(!truth.exists());
}

/// Issue 39, N19 (the rest): a robot file whose `[calibration.errors]` holds `da2 = 1e39` is
/// refused by every command that reads it (`export --format toml` copied it on); a run that
/// fails leaves no directory it created for its outputs; N16: an output name of 250 bytes (legal:
/// the limit is 255) is written, although its temporary's name would be longer.
#[test]
fn n19_implausible_calibration_errors_and_directories_of_a_failed_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let robot = d.join("robot.toml");
    std::fs::write(
        &robot,
        format!("{ER10L_C10_TOML}\n[calibration]\nmethod = \"lm\"\nnominal = \"x\"\n[calibration.errors]\nda2 = 1e39\n"),
    )
    .unwrap();
    let out = d.join("new/deeper/out.toml");
    let result = calib(&[
        "export",
        "--params",
        robot.to_str().unwrap(),
        "--format",
        "toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("[calibration.errors]: da2 = 1e39 is beyond the plausible range"),
        "{stderr}"
    );
    // A failure after the outputs' directories were made: the second output replaces an input.
    let result = calib(&[
        "simulate",
        "--robot",
        ROBOT,
        "--out",
        out.to_str().unwrap(),
        "--truth-out",
        ROBOT,
    ]);
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(1), "{stderr}");
    assert!(!d.join("new").exists(), "{stderr}");
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 1);
    // N16: a name of 250 bytes.
    let long = d.join(format!("{}.toml", "n".repeat(245)));
    let result = calib(&[
        "export",
        "--params",
        ROBOT,
        "--format",
        "toml",
        "--out",
        long.to_str().unwrap(),
    ]);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    assert!(long.exists());
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 2);
}

/// Issue 39, N18: messages name the real cause. A tracker frame of 1e300 mm is refused as the
/// `--tracker-xyz-mm` given, not as the robot file's `[base]`; measured points on one line and
/// joint readings the model turns into one point are told apart (both were "the measured points
/// do not span a plane").
#[test]
fn n18_messages_name_the_real_cause() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = calib(&[
        "simulate",
        "--robot",
        ROBOT,
        "--tracker-xyz-mm",
        "1e300,0,0",
        "--out",
        d.join("s.csv").to_str().unwrap(),
        "--truth-out",
        d.join("t.toml").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("--tracker-xyz-mm: 1e300 mm is beyond") && !stderr.contains("[base]"),
        "{stderr}"
    );
    let head = "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm\n";
    // Varied joints, measured points on the x axis.
    let mut on_a_line = String::from(head);
    // Only joint 6 turns: the flange centre, the tool point of position-only data, stays put.
    let mut one_point = String::from(head);
    for i in 0..12 {
        let f = f64::from(i);
        on_a_line.push_str(&format!(
            "{},{},{},{},{},{},{},0,0\n",
            10.0 * f,
            -5.0 * f,
            3.0 * f,
            7.0 * f,
            20.0 + f,
            f,
            100.0 * f
        ));
        one_point.push_str(&format!(
            "10,20,30,40,50,{},{},{},{}\n",
            25.0 * f,
            1000.0 + 50.0 * f.sin(),
            200.0 * f.cos(),
            300.0 + 10.0 * f
        ));
    }
    for (text, expected) in [
        (on_a_line, "the 12 measured points lie on one line"),
        (
            one_point,
            "the nominal model puts the tool points of the 12 joint readings on one line",
        ),
    ] {
        std::fs::write(d.join("data.csv"), text).unwrap();
        let out = calib(&[
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            d.join("data.csv").to_str().unwrap(),
            "--out",
            d.join("x.toml").to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(expected), "{expected}: {stderr}");
    }
}

/// Issue 40, item 6: `calib simulate`'s default robot was the relative path
/// `host-tools/robots/er10l-c10.toml`, so the command failed outside the repository; the
/// default is now the ER10L-C10 built into calib, and the data match the bundled file's.
#[test]
fn simulate_without_a_robot_works_in_any_directory() {
    let dir = tempfile::tempdir().unwrap();
    let out = common::calib_in(
        dir.path(),
        &["simulate", "--out", "s.csv", "--truth-out", "t.toml"],
    );
    common::ok(&out);
    let built_in = TrackerData::read(&dir.path().join("s.csv")).unwrap();
    let other = tempfile::tempdir().unwrap();
    common::ok(&common::calib_in(
        other.path(),
        &[
            "simulate",
            "--robot",
            ROBOT,
            "--out",
            "s.csv",
            "--truth-out",
            "t.toml",
        ],
    ));
    let from_file = TrackerData::read(&other.path().join("s.csv")).unwrap();
    assert_eq!(built_in.records, from_file.records);
    assert_eq!(built_in.records.len(), 32);
}
