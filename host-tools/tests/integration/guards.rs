//! Real-cell guards of issue 13 that are statistical in nature, checked on simulated cells with
//! known truth: the cross-validation estimate flags small pose sets whose calibration makes the
//! robot less accurate.

use crate::common;
use common::{ROBOT, calib_in, ok};
use serde_json::Value;

/// Simulates `poses + 200` poses (random errors of 0.05 mm and 0.1 mrad, tracker noise 0.05 mm
/// and 0.2 mrad, base frame), calibrates by least squares on `poses` of them and returns the
/// report: the other 200 are held out.
fn small_set_report(dir: &std::path::Path, poses: usize, seed: u64) -> Value {
    let (total, seed) = ((poses + 200).to_string(), seed.to_string());
    ok(&calib_in(
        dir,
        &[
            "simulate",
            "--robot",
            ROBOT,
            "--poses",
            &total,
            "--seed",
            &seed,
            "--errors",
            "random",
            "--random-angle-rad",
            "0.0001",
            "--random-length-mm",
            "0.05",
            "--position-sigma-mm",
            "0.05",
            "--orientation-sigma-rad",
            "0.0002",
            "--out",
            "s.csv",
            "--truth-out",
            "t.toml",
        ],
    ));
    let fraction = (200.0 / (poses as f64 + 200.0)).to_string();
    ok(&calib_in(
        dir,
        &[
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            "s.csv",
            "--validate",
            &fraction,
            "--method",
            "lm",
            "--report",
            "r.json",
        ],
    ));
    serde_json::from_slice(&std::fs::read(dir.join("r.json")).unwrap()).unwrap()
}

#[test]
fn cross_validation_flags_small_sets_that_make_the_robot_worse() {
    let dir = tempfile::tempdir().unwrap();
    let (mut worse, mut worse_flagged, mut clearly_worse, mut flagged) = (0, 0, 0, 0);
    for seed in 1..=25 {
        let r = small_set_report(dir.path(), 8, seed);
        let v = &r["validation"];
        let before = v["before"]["position_mm"]["mean"].as_f64().unwrap();
        let after = v["after"]["position_mm"]["mean"].as_f64().unwrap();
        let cv = &r["cross_validation"];
        assert_eq!(cv["folds"], 8, "leave-one-out");
        let flag =
            cv["calibrated_mean_mm"].as_f64().unwrap() > cv["nominal_mean_mm"].as_f64().unwrap();
        flagged += usize::from(flag);
        if after > before {
            worse += 1;
            worse_flagged += usize::from(flag);
        }
        if after > 1.05 * before {
            clearly_worse += 1;
            assert!(
                flag,
                "seed {seed}: held-out {before} -> {after} mm, not flagged"
            );
        }
    }
    println!(
        "8 poses, 25 seeds: {worse} calibrations worse than nominal on 200 held-out poses \
         ({clearly_worse} by more than 5 %), {worse_flagged} of them flagged; {flagged} flagged in all"
    );
    // Measured: 7 worse (5 by more than 5 %), 6 of them flagged; 16 flagged in all (leave-one-out
    // on 8 poses is pessimistic: each fit has 7).
    assert!(clearly_worse >= 3 && worse_flagged * 4 >= worse * 3);
    // With 32 poses the same cells calibrate well, and nothing is flagged.
    for seed in 1..=5 {
        let r = small_set_report(dir.path(), 32, seed);
        let v = &r["validation"];
        let before = v["before"]["position_mm"]["mean"].as_f64().unwrap();
        let after = v["after"]["position_mm"]["mean"].as_f64().unwrap();
        let cv = &r["cross_validation"];
        assert_eq!(cv["folds"], 5);
        assert!(after < before, "seed {seed}: {before} -> {after}");
        assert!(
            cv["calibrated_mean_mm"].as_f64().unwrap() < cv["nominal_mean_mm"].as_f64().unwrap(),
            "seed {seed}: {cv}"
        );
    }
}

/// 2,000 random reachable targets away from singularities (see [`SMALLEST_SINGULAR_VALUE`]),
/// without joints: the closed-form nominal inverse kinematics on the target's own branch is the
/// start, as the controller plans it. The actual robot is the ER10L-C10 with the paper's Table 2
/// errors; the bounds are raised to 50 mm and 5 deg (Table 2 needs up to about 25 mm). Measured:
/// 2000 of 2000, with or without the retries. With a laxer filter (scaled manipulability above
/// 1e-2) 1982 of 2000, the 18 refused within a few degrees of the wrist singularity or at a
/// stretched elbow, where the retries did not help either.
/// Targets whose scaled Jacobian (mm over 1000 mm, rad) has a smallest singular value below this
/// are near a singularity and left out.
const SMALLEST_SINGULAR_VALUE: f64 = 0.05;

#[test]
fn compensation_reaches_random_targets_and_names_the_needed_correction() {
    use calib_core::Kinematics;
    use calib_core::controller::compensate::CompensationSettings;
    use calib_core::kinematics::ik::inverse_kinematics;
    use host_tools::io::robot_file::{ER10L_C10_TOML, RobotFile};
    use host_tools::io::tracker_data::{OrientationColumns, Record, TrackerData};
    use host_tools::kinematics::compensate::{Request, compensate_targets};
    use rand::{RngExt, SeedableRng};
    use std::path::Path;

    let file = RobotFile::parse(ER10L_C10_TOML, Path::new("er10l.toml")).unwrap();
    let nominal = file.to_model(Path::new("er10l.toml")).unwrap().robot;
    let truth = file
        .with_errors(
            &calib_core::model::paper::table2::<f64>().recount().unwrap(),
            [],
            &[],
            "",
            "",
        )
        .to_model(Path::new("truth.toml"))
        .unwrap()
        .robot;
    let planned = Kinematics::nominal(&nominal).unwrap();
    let actual = Kinematics::nominal(&truth).unwrap();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(2026);
    let mut by_branch: Vec<Vec<Record>> = vec![Vec::new(); 8];
    let mut count = 0;
    while count < 2000 {
        let q = calib_core::model::JointVec::<f64>::from_fn(6, |_| rng.random_range(-3.1..3.1));
        let (pose, jacobian) = planned.geometric_jacobian(&q).unwrap();
        let mut scaled = nalgebra::Matrix6xX::from_columns(&jacobian);
        for mut row in scaled.rows_mut(0, 3).row_iter_mut() {
            row /= 1000.0;
        }
        let smallest = scaled.singular_values().min();
        if smallest < SMALLEST_SINGULAR_VALUE {
            continue;
        }
        let six = nominal.recount::<nalgebra::U6>().unwrap();
        let solutions = inverse_kinematics(&six, &pose).unwrap();
        let Some(branch) = solutions
            .iter()
            .position(|s| s.is_some_and(|s| s.iter().zip(&q).all(|(a, b)| (a - b).abs() < 1e-6)))
        else {
            continue;
        };
        count += 1;
        by_branch[branch].push(Record {
            line: count,
            id: format!("T{count}"),
            q: Vec::new(),
            position: pose.translation.vector.into(),
            rotation: Some(*pose.rotation.matrix()),
            weight: 1.0,
            role: None,
            configuration: None,
            time_s: None,
            temperature_c: None,
        });
    }
    let settings = CompensationSettings {
        max_correction_mm: 50.0,
        max_correction_rad: 5f64.to_radians(),
        ..CompensationSettings::default()
    };
    let (mut ok, mut worst) = (0usize, 0.0f64);
    let mut failures = Vec::new();
    for (branch, records) in by_branch.into_iter().enumerate() {
        let targets = TrackerData {
            path: "targets".into(),
            base_frame: true,
            header_line: 1,
            joints: 0,
            orientation: OrientationColumns::Quaternion,
            records: records.clone(),
            planned: None,
            has_ids: false,
            has_times: false,
            instrument: None,
        };
        let outcomes = compensate_targets(
            &nominal,
            &truth,
            &targets,
            &settings,
            &Request::branch(branch),
        )
        .unwrap();
        for (outcome, record) in outcomes.iter().zip(&records) {
            match &outcome.result {
                Ok(c) => {
                    let reached = actual.forward(&c.q).unwrap().translation.vector;
                    let target = nalgebra::Vector3::from(record.position);
                    worst = worst.max((reached - target).norm());
                    ok += 1;
                }
                Err(e) => failures.push(format!("{} (branch {branch}): {e}", outcome.id)),
            }
        }
    }
    println!(
        "{ok} of 2000 compensated, worst position residual {worst:.2e} mm; refused: {failures:?}"
    );
    assert!(ok >= 1999, "{failures:?}");
    assert!(worst <= 1e-3);
    // The default bounds refuse most of these targets, and say by how much and which flag.
    let record = Record {
        line: 1,
        id: "T".into(),
        q: Vec::new(),
        position: [1200.0, 300.0, 900.0],
        rotation: Some(*nalgebra::Rotation3::from_euler_angles(3.1, 0.1, 0.2).matrix()),
        weight: 1.0,
        role: None,
        configuration: None,
        time_s: None,
        temperature_c: None,
    };
    let one = TrackerData {
        path: "targets".into(),
        base_frame: true,
        header_line: 1,
        joints: 0,
        orientation: OrientationColumns::Quaternion,
        records: vec![record],
        planned: None,
        has_ids: false,
        has_times: false,
        instrument: None,
    };
    let outcome = compensate_targets(
        &nominal,
        &truth,
        &one,
        &CompensationSettings::default(),
        &Request::branch(0),
    )
    .unwrap();
    let message = outcome[0].result.clone().unwrap_err();
    assert!(
        message.contains("needs") && message.contains("--max-correction-mm"),
        "{message}"
    );
}

/// The bundled simulated data (6-DoF, quaternions `qw, qx, qy, qz`) with every quaternion
/// rewritten by `reorder` (from `[w, x, y, z]` to what stands under the four columns), calibrated:
/// returns standard error, the run must fail.
fn quaternion_error(reorder: impl Fn([&str; 4]) -> [String; 4]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let data = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/er10l-c10-sim32.csv"
    ))
    .unwrap();
    let rewritten: Vec<String> = data
        .lines()
        .map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            if line.starts_with('#') || line.starts_with("id,") {
                return line.to_string();
            }
            let n = fields.len();
            let q = reorder([fields[n - 4], fields[n - 3], fields[n - 2], fields[n - 1]]);
            let mut out: Vec<String> = fields[..n - 4].iter().map(|f| f.to_string()).collect();
            out.extend(q);
            out.join(",")
        })
        .collect();
    std::fs::write(dir.path().join("d.csv"), rewritten.join("\n")).unwrap();
    let out = calib_in(
        dir.path(),
        &[
            "calibrate",
            "--robot",
            ROBOT,
            "--data",
            "d.csv",
            "--out",
            "x.toml",
        ],
    );
    assert!(!out.status.success());
    assert!(!dir.path().join("x.toml").exists());
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn quaternions_in_scalar_last_order_are_refused_and_the_order_named() {
    let message = quaternion_error(|[w, x, y, z]| [x, y, z, w].map(String::from));
    assert!(
        message.contains("do not move as the robot does")
            && message.contains("hold x, y, z, w (scalar last)"),
        "{message}"
    );
}

#[test]
fn inverse_quaternions_are_refused_and_named() {
    let negated = |v: &str| {
        let v: f64 = v.parse().unwrap();
        (-v).to_string()
    };
    let message =
        quaternion_error(|[w, x, y, z]| [w.to_string(), negated(x), negated(y), negated(z)]);
    assert!(
        message.contains("do not move as the robot does")
            && message.contains("the quaternions are the inverse rotations"),
        "{message}"
    );
}
