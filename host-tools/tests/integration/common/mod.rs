//! Helpers shared by the integration tests: the `calib` binary runner, the success check, data
//! read and calibrated through the library as `calib` reads and calibrates them, and simulated
//! data. Each test file uses some of them.
#![allow(dead_code)]

use host_tools::calibration::{Calibrated, CalibrationConfig, HoldOut, Session, Truth};
use host_tools::io::profile::DataProfile;
use host_tools::measurement::dataset::Dataset;
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

/// The nominal Franka Panda robot file.
pub const PANDA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/franka-panda.toml");
/// MUKCa's touches of the Panda's `panda_3` set (six placements of the sockets).
pub const PANDA_3: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/mukca-sockets/panda_3");

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
    let compliance = file
        .gravity_compliance(actual, model.robot.joints.len())
        .unwrap();
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

/// Simulated data of the nominal ER10L-C10 ([`ROBOT`]), written by `calib simulate` with the
/// options `args`: the data to `dir/NAME.csv`, the true robot to `dir/NAME-truth.toml`.
/// Returns (data, truth).
pub fn simulate(dir: &Path, name: &str, args: &[&str]) -> (PathBuf, PathBuf) {
    let data = dir.join(format!("{name}.csv"));
    let truth = dir.join(format!("{name}-truth.toml"));
    let mut all = vec![
        "simulate",
        "--robot",
        ROBOT,
        "--out",
        data.to_str().unwrap(),
        "--truth-out",
        truth.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    ok(&calib(&all));
    (data, truth)
}

/// The poses of the data file `data`, read through the data profile `profile` (the default
/// profile with `None`) for the robot file `robot` and checked as `calib` checks them (joint
/// count and limits, the orientations against the profile's Euler convention).
pub fn read(robot: &str, data: &str, profile: Option<&str>) -> host_tools::Result<Dataset> {
    let profile = DataProfile::load(profile.map(Path::new))?;
    let dataset = Dataset::load_with(Path::new(robot), Path::new(data), &profile)?;
    host_tools::measurement::orientation_check::check(&dataset, &profile.euler)?;
    Ok(dataset)
}

/// The calibration session of `dataset` with `config` that `calib calibrate` starts without a
/// hold-out option: a measured plan's verification rows held out, else none.
pub fn session(dataset: Dataset, config: CalibrationConfig) -> Session {
    Session {
        hold_out: HoldOut::of_data(&dataset),
        ..Session::new(dataset, config)
    }
}

/// [`session`] of the files `robot`, `data` and `profile` ([`read`]) with `config`, holding out
/// the random `fraction` of the poses chosen by `seed` (`calib calibrate --validate FRACTION
/// --validate-seed SEED`) when given, calibrated; the files and their hashes are its provenance,
/// as `calib calibrate` records them.
pub fn calibrate_files(
    (robot, data, profile): (&str, &str, Option<&str>),
    config: CalibrationConfig,
    validate: Option<(f64, u64)>,
) -> host_tools::Result<Calibrated> {
    let dataset = read(robot, data, profile)?;
    let mut session = session(dataset, config);
    let mut inputs = vec![("--robot", Path::new(robot)), ("--data", Path::new(data))];
    inputs.extend(profile.map(|p| ("--profile", Path::new(p))));
    session.provenance.inputs = host_tools::io::provenance::InputFile::all(&inputs)?;
    if let Some((fraction, seed)) = validate {
        session.hold_out = HoldOut::Fraction { fraction, seed };
    }
    session.run()
}

/// The robot file of known errors at `path` (`calib simulate --truth-out`), to compare with.
pub fn truth(path: &Path) -> Truth {
    Truth {
        file: host_tools::io::robot_file::RobotFile::read(path).unwrap(),
        path: path.to_path_buf(),
    }
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

/// A simulated arm for [`every_command`]: its robot file, 60 simulated poses (tracker frame,
/// 6-DoF, random errors of every identified parameter, the last 25 % held out) and their truth.
pub struct Arm<'a> {
    /// The scratch directory the outputs go to.
    pub dir: &'a Path,
    /// The robot file, the data and the truth written by `calib simulate --truth-out`.
    pub robot: &'a str,
    pub data: &'a str,
    pub truth: &'a str,
    /// Its joint count.
    pub joints: usize,
    /// The parameters identified (`check` must find them all determined).
    pub parameters: usize,
    /// Joint readings (deg) of the compensation target: the nominal pose there.
    pub target_deg: Vec<f64>,
    /// The largest error of an identified joint parameter against the truth, and of a held-out
    /// pose, that exact data allow.
    pub exact: f64,
}

/// What [`every_command`] wrote: the calibration's text and files.
pub struct Every {
    pub calibrate_text: String,
    pub identified: String,
    pub report: String,
    pub html: String,
}

/// An arm through every command of `calib`, as a user runs them: check -> calibrate (least
/// squares with plots and reports, then the default swarm and least squares) -> evaluate ->
/// verify -> fk -> compensate (6 joints or more; fewer are refused with the reason and nothing
/// is written) -> export. The expectations are independent of the tool: every parameter
/// determined, the simulation's truth given back by exact data, the identified model reproducing
/// every pose. Prints what it measured.
pub fn every_command(arm: &Arm<'_>) -> Every {
    let (dir, robot, data, truth, joints) = (arm.dir, arm.robot, arm.data, arm.truth, arm.joints);
    let minimal = arm.parameters;
    let out = ok(&calib(&["check", "--robot", robot, "--data", data]));
    assert!(
        out.contains(&format!(
            "identifiability of {minimal} parameters: rank {minimal}"
        )),
        "{joints} joints: {out}"
    );

    let report = at(dir, "report.json");
    let identified = at(dir, "identified.toml");
    let plots = at(dir, "plots");
    let html = at(dir, "report.html");
    let out = ok(&calib(&[
        "calibrate",
        "--robot",
        robot,
        "--data",
        data,
        "--method",
        "lm",
        "--validate",
        "0.25",
        "--truth",
        truth,
        "--out",
        &identified,
        "--report",
        &report,
        "--html",
        &html,
        "--plot",
        &plots,
    ]));
    assert!(out.contains("with 45 poses"), "{out}");
    let calibrate_text = out;
    for plot in [
        "position-error.svg",
        "position-error.png",
        "validation-histogram.svg",
    ] {
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
    assert!(worst < arm.exact, "{joints} joints: {worst}");
    assert!(
        held_out < arm.exact,
        "{joints} joints: held-out max {held_out} mm"
    );

    // The default method, the swarm then least squares, reaches the same exact fit.
    let again = at(dir, "again.json");
    let out = ok(&calib(&[
        "calibrate",
        "--robot",
        robot,
        "--data",
        data,
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
        held_out < arm.exact,
        "{joints} joints: held-out max {held_out} mm"
    );

    let out = ok(&calib(&[
        "evaluate",
        "--robot",
        &identified,
        "--data",
        data,
        "--json",
    ]));
    let evaluation: serde_json::Value = serde_json::from_str(&out).unwrap();
    let mean = evaluation["position_mm"]["mean"].as_f64().unwrap();
    assert!(mean < 1e-6, "{joints} joints: evaluate mean {mean} mm");

    let out = ok(&calib(&["verify", "--robot", robot, "--data", data]));
    assert!(
        out.contains("all within tolerance"),
        "{joints} joints: {out}"
    );

    compensate_and_export(dir, joints, robot, &identified, &arm.target_deg);
    Every {
        calibrate_text,
        identified,
        report,
        html,
    }
}

/// fk of the nominal robot at a joint vector gives a target; compensate puts the identified
/// robot on it (6 joints or more; fewer are refused with the reason and nothing is written);
/// export writes the controller's block.
fn compensate_and_export(dir: &Path, joints: usize, robot: &str, identified: &str, q: &[f64]) {
    let q: Vec<String> = q.iter().map(|v| v.to_string()).collect();
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

/// An ISO 9283 pose test in the base frame, noise-free: three targets (`targets.csv`: P1, P2,
/// P4) and a 6-cycle run (`run.csv`) drifting 0.05 mm per cycle along x at P1 and along z at P2,
/// P4 off by 0.3 mm in x, written into `dir`: (targets, run).
pub fn drifting_run(dir: &Path) -> (PathBuf, PathBuf) {
    let targets = dir.join("targets.csv");
    std::fs::write(
        &targets,
        "id,x_mm,y_mm,z_mm,qw,qx,qy,qz\nP1,1000,0,500,1,0,0,0\nP2,900,-100,400,1,0,0,0\nP4,1100,100,600,1,0,0,0\n",
    )
    .unwrap();
    let mut run = String::from(
        "# frame: base\nid,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm\n",
    );
    for c in 1..=6 {
        let dx = 0.05 * c as f64;
        run.push_str(&format!("P1-c{c},0,0,0,0,0,0,{},0,500\n", 1000.0 + dx));
        run.push_str(&format!("P4-c{c},0,0,0,0,0,0,1100.3,100,600\n"));
        run.push_str(&format!("P2-c{c},0,0,0,0,0,0,900,-100,{}\n", 400.0 + dx));
    }
    let data = dir.join("run.csv");
    std::fs::write(&data, run).unwrap();
    (targets, data)
}

/// A calibration from touches (`panda_3` on `frontcenter`) with its report, identified file and
/// certificate in `dir`.
pub fn touches_calibration(dir: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let (report, identified, html) = (
        dir.join("touches.json"),
        dir.join("panda-3.toml"),
        dir.join("panda-3.html"),
    );
    ok(&calib(&[
        "sockets",
        "--robot",
        PANDA,
        "--data",
        PANDA_3,
        "--ball-mm",
        "0.025171,-0.084766,133.528298",
        "--train",
        "frontcenter",
        "--distance",
        "50",
        "--report",
        arg(&report),
        "--out",
        arg(&identified),
        "--html",
        arg(&html),
    ]));
    (report, identified, html)
}
