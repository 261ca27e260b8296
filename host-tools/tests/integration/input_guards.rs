//! Inputs as the commands take them (issue 52): the provenance hashes the bytes a run read (piped
//! input, a named pipe), joints outside the robot's limits are refused by every command that
//! takes joints, and a recorded covariance beyond any calibration's is refused.

use crate::common;
use common::{UR10 as ROBOT, calib, ok};
use host_tools::io::robot_file::RobotFile;
use sha2::Digest as _;
use std::path::Path;
use std::process::{Command, Stdio};

/// Simulates `poses` poses of the bundled UR10 (random errors) into `dir`: data and truth.
fn simulated(dir: &Path, poses: &str) -> (String, String) {
    let (data, truth) = (dir.join("sim.csv"), dir.join("truth.toml"));
    ok(&calib(&[
        "simulate",
        "--robot",
        ROBOT,
        "--poses",
        poses,
        "--errors",
        "random",
        "--out",
        data.to_str().unwrap(),
        "--truth-out",
        truth.to_str().unwrap(),
    ]));
    (
        data.to_str().unwrap().to_string(),
        truth.to_str().unwrap().to_string(),
    )
}

fn sha256_hex(bytes: &[u8]) -> String {
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// V3: `--data /dev/stdin` records the SHA-256 of the bytes piped in (it recorded that of empty
/// input, the file opened again after the run), and a named pipe is read once (the second
/// opening blocked forever).
#[test]
fn the_recorded_hash_is_of_the_bytes_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (data, _) = simulated(d, "60");
    let bytes = std::fs::read(&data).unwrap();
    let out = d.join("identified.toml");
    let run = Command::new(env!("CARGO_BIN_EXE_calib"))
        .args([
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            "/dev/stdin",
            "--method",
            "lm",
            "--out",
            out.to_str().unwrap(),
        ])
        .stdin(std::fs::File::open(&data).unwrap())
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let file = RobotFile::read(&out).unwrap();
    let inputs = &file.calibration.as_ref().unwrap().inputs;
    let piped = inputs.iter().find(|i| i.flag == "--data").unwrap();
    assert_eq!(piped.path, "/dev/stdin");
    assert_eq!(piped.sha256, sha256_hex(&bytes));
    assert_ne!(piped.sha256, sha256_hex(b""));
    // A named pipe: written once by a child, read once by calib, which must end.
    let fifo = d.join("data.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let mut writer = Command::new("sh")
        .args(["-c", &format!("cat '{data}' > '{}'", fifo.display())])
        .stdin(Stdio::null())
        .spawn()
        .unwrap();
    let out2 = d.join("identified-fifo.toml");
    let mut run = Command::new(env!("CARGO_BIN_EXE_calib"))
        .args([
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            fifo.to_str().unwrap(),
            "--method",
            "lm",
            "--out",
            out2.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(status) = run.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > std::time::Duration::from_secs(60) {
            let _ = run.kill();
            let _ = writer.kill();
            panic!("calib blocked on the named pipe");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    writer.wait().unwrap();
    assert!(status.success());
    let file = RobotFile::read(&out2).unwrap();
    let inputs = &file.calibration.as_ref().unwrap().inputs;
    let piped = inputs.iter().find(|i| i.flag == "--data").unwrap();
    assert_eq!(piped.sha256, sha256_hex(&bytes));
}

/// V9: `simulate --joints-from` and `uncertainty --joints` refuse joints outside the robot's
/// limits (here the first limited joint at 10 deg beyond the upper limit the file states), naming the
/// value and the limits, as `fk`, `evaluate` and `compensate` do; nothing is written. V12 on the
/// same identified file: a variance of 1e300 in its covariance is refused.
#[test]
fn joints_outside_the_limits_are_refused_everywhere() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = RobotFile::read(Path::new(ROBOT))
        .unwrap()
        .to_model(Path::new(ROBOT))
        .unwrap();
    // The first joint with a finite upper limit, 10 deg beyond it; the others at 0 or 30 deg.
    let j = (model.robot.limits.iter())
        .position(|l| l.upper.is_finite())
        .unwrap();
    let mut q = [0.0, 0.0, 0.0, 0.0, 30.0, 0.0];
    q[j] = model.robot.limits[j].upper.to_degrees() + 10.0;
    let row: Vec<String> = q.iter().map(ToString::to_string).collect();
    let joints = d.join("joints.csv");
    std::fs::write(
        &joints,
        format!(
            "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\nA,{}\n",
            row.join(",")
        ),
    )
    .unwrap();
    let named = format!("q{} =", j + 1);
    let out = d.join("out.csv");
    let simulate = calib(&[
        "simulate",
        "--robot",
        ROBOT,
        "--joints-from",
        joints.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--truth-out",
        d.join("t.toml").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&simulate.stderr);
    assert!(!simulate.status.success());
    assert!(
        stderr.contains(&format!("configuration A: {named}"))
            && stderr.contains("outside the joint limits"),
        "{stderr}"
    );
    assert!(!out.exists());
    // uncertainty needs an identified file with a covariance: calibrate by least squares.
    let (data, _) = simulated(d, "60");
    let identified = d.join("identified.toml");
    ok(&calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        &data,
        "--method",
        "lm",
        "--out",
        identified.to_str().unwrap(),
    ]));
    // `calib uncertainty` of `params` at `joints`: refused, nothing written; its message.
    let refused = |params: &Path| {
        let result = calib(&[
            "uncertainty",
            "--params",
            params.to_str().unwrap(),
            "--joints",
            joints.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(!result.status.success());
        assert!(!out.exists());
        String::from_utf8_lossy(&result.stderr).into_owned()
    };
    let stderr = refused(&identified);
    assert!(
        stderr.contains(&format!("joints.csv:2: {named}"))
            && stderr.contains("outside the joint limits"),
        "{stderr}"
    );
    // V12: a variance of 1e300 in the recorded covariance is refused, naming the parameter.
    let text = std::fs::read_to_string(&identified).unwrap();
    let mut file: toml::Table = text.parse().unwrap();
    let matrix = file["calibration"]["covariance"]["matrix"]
        .as_array()
        .unwrap()
        .clone();
    let mut first_row = matrix[0].as_array().unwrap().clone();
    first_row[0] = toml::Value::Float(1e300);
    let mut matrix = matrix;
    matrix[0] = toml::Value::Array(first_row);
    file["calibration"]["covariance"]
        .as_table_mut()
        .unwrap()
        .insert("matrix".into(), toml::Value::Array(matrix));
    let damaged = d.join("damaged.toml");
    std::fs::write(&damaged, toml::to_string(&file).unwrap()).unwrap();
    std::fs::write(
        &joints,
        "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\nA,10,-90,90,-90,-90,0\n",
    )
    .unwrap();
    let stderr = refused(&damaged);
    assert!(
        stderr.contains("the standard deviation of") && stderr.contains("1e150"),
        "{stderr}"
    );
}

/// Issue 52 (V10): options that would be ignored without a word are refused, naming what to do,
/// and nothing is written: `--swarm` with `--method lm`, `--loss-scale-mm` with the plain least squares, `--validate-seed`
/// without `--validate`, `--time-tolerance-s` without a robot log (merging by id or order), and
/// `--noise-deg` for a plan that measures positions only (the URScript settings without
/// `--urscript`: `plan::urscript_settings_are_bounded_and_need_urscript`).
#[test]
fn options_that_would_be_ignored_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (data, _) = simulated(d, "30");
    let out = d.join("out.toml");
    let o = out.to_str().unwrap();
    let cases: [(Vec<&str>, &str); 5] = [
        (
            vec![
                "calibrate",
                "--robot",
                ROBOT,
                "--data",
                &data,
                "--method",
                "lm",
                "--swarm",
                "30",
                "--out",
                o,
            ],
            "--method lm runs none",
        ),
        (
            vec![
                "calibrate",
                "--robot",
                ROBOT,
                "--data",
                &data,
                "--loss-scale-mm",
                "1",
                "--out",
                o,
            ],
            "--loss-scale-mm scales a robust loss",
        ),
        (
            vec![
                "calibrate",
                "--robot",
                ROBOT,
                "--data",
                &data,
                "--validate-seed",
                "3",
                "--out",
                o,
            ],
            "--validate",
        ),
        (
            vec![
                "merge",
                "--plan",
                &data,
                "--measured",
                &data,
                "--by",
                "id",
                "--time-tolerance-s",
                "2",
                "--out",
                o,
            ],
            "--robot-log",
        ),
        (
            vec![
                "plan",
                "--robot",
                ROBOT,
                "--generate",
                "200",
                "--poses",
                "20",
                "--measure",
                "position",
                "--noise-mm",
                "0.05",
                "--noise-deg",
                "0.01",
                "--out",
                o,
            ],
            "--noise-deg is the noise of a measured orientation",
        ),
    ];
    for (args, says) in cases {
        let result = calib(&args);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(!result.status.success(), "{args:?}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
        assert!(!out.exists(), "{args:?}");
    }
}
