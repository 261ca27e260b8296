//! Real laser-tracker data of a 7-joint robot: the Barrett WAM of Jacobi (2025), bundled with its
//! licence in data/barrett-wam-lasertracker/, read through the shipped profile (the reached
//! position is a derived column, target + difference) and calibrated with `calib calibrate`'s
//! defaults. The expectations are those of an independent float64 calibration (Hayati per joint,
//! base 6 + reflector 3, redundant parameters removed: 29 parameters, condition number 72), stated
//! in the issue: random 20 after calibrating on the grid 3.09 / 3.28 / 5.90 mm (mean / RMS /
//! max), nominal with fitted base and tool 4.05 / 4.66 / 10.53 mm; grid 70/30 over 5 seeds
//! 2.19 mm (4.22 mm with the frames only). The goals: at most 3.15 mm and 2.25 mm.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{calib, ok};

use host_tools::calibration::Calibrated as Calibration;
use host_tools::calibration::{CalibrationConfig, ErrorModel, HoldOut, Identify, Method};
use host_tools::measurement::frames::Frames;

const ROBOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/barrett-wam.toml");
const GRID: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/barrett-wam-lasertracker/grid.csv"
);
const RANDOM: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/barrett-wam-lasertracker/random.csv"
);
const PROFILE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/profiles/barrett-wam-lasertracker.toml"
);

/// The WAM calibrated on the grid (`calib calibrate --robot ROBOT --data GRID --profile
/// PROFILE`) with `config` and the hold-out `hold_out`.
fn calibrate(config: CalibrationConfig, hold_out: HoldOut) -> Calibration {
    let grid = common::read(ROBOT, GRID, Some(PROFILE)).unwrap();
    let mut session = common::session(grid, config);
    session.hold_out = hold_out;
    session.run().unwrap()
}

/// The random 20 poses, held out (`--holdout RANDOM`).
fn random_twenty() -> HoldOut {
    HoldOut::poses(common::read(ROBOT, RANDOM, Some(PROFILE)).unwrap())
}

/// Mean, RMS and largest |difference| of a data file: the error of the robot as delivered (the
/// targets are the controller's model's predictions), mm.
fn as_delivered(path: &str) -> (f64, f64, f64) {
    let text = std::fs::read_to_string(path).unwrap();
    let norms: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|line| {
            let v: Vec<f64> = line.split(',').map(|f| f.parse().unwrap()).collect();
            (v[4] * v[4] + v[5] * v[5] + v[6] * v[6]).sqrt()
        })
        .collect();
    let n = norms.len() as f64;
    let mean = norms.iter().sum::<f64>() / n;
    let rms = (norms.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    (mean, rms, norms.iter().copied().fold(0.0, f64::max))
}

#[test]
fn random_twenty_after_calibrating_on_the_grid() {
    let (mean, rms, max) = as_delivered(RANDOM);
    println!("random 20, as delivered: mean {mean:.2} / RMS {rms:.2} / max {max:.2} mm");
    assert!((mean - 17.62).abs() < 0.005 && (rms - 17.75).abs() < 0.005);
    assert!((max - 20.62).abs() < 0.005);

    let c = calibrate(CalibrationConfig::default(), random_twenty());
    let r = &c.result;
    assert_eq!(r.frames.identified, Frames::BaseTool);
    assert_eq!(
        (r.calibration.poses, r.validation.as_ref().unwrap().poses),
        (216, 20)
    );
    // What is identified: 7 joints x 4 Hayati parameters, the base (6) and the reflector (3),
    // less what the frames absorb (dd1, dtheta1 with the base; joint 7 with the reflector) and
    // what a reflector on axis 7 cannot tell apart (dtheta6 from da6, dalpha6 from dd6).
    let names = r.names();
    assert_eq!(names.len(), 29, "{names:?}");
    for absent in [
        "dd1", "dtheta1", "da7", "dd7", "dalpha7", "dtheta7", "dalpha6", "dtheta6",
    ] {
        assert!(!names.iter().any(|n| n == absent), "{absent} in {names:?}");
    }
    let reflector = r.identifiability.reflector_on_last_axis.as_ref().unwrap();
    let left_out: Vec<String> = reflector
        .not_identified
        .iter()
        .map(|u| u.parameter.to_string())
        .collect();
    assert_eq!(left_out, ["dtheta6", "dalpha6"]);
    assert!(reflector.distance_mm < 10.0);
    let condition = r.identifiability.condition_number.unwrap();
    println!(
        "29 parameters, scaled condition number {condition:.2}; reflector {:.2} mm from axis 7",
        reflector.distance_mm
    );
    assert!((condition - 72.0).abs() < 1.0, "condition {condition}");

    let v = r.validation.as_ref().unwrap();
    let (before, after) = (&v.before.position_mm, &v.after.position_mm);
    println!(
        "random 20, nominal with fitted base and tool: mean {:.2} / RMS {:.2} / max {:.2} mm",
        before.mean, before.rms, before.max
    );
    println!(
        "random 20, geometric calibration: mean {:.2} / RMS {:.2} / max {:.2} mm",
        after.mean, after.rms, after.max
    );
    // The independent calibration: 4.05 / 4.66 / 10.53 and 3.09 / 3.28 / 5.90 mm.
    assert!((before.mean - 4.05).abs() < 0.02 && (before.max - 10.53).abs() < 0.05);
    assert!((before.rms - 4.66).abs() < 0.02);
    assert!(after.mean <= 3.15, "random 20 mean {}", after.mean);
    assert!((after.rms - 3.28).abs() < 0.05 && (after.max - 5.90).abs() < 0.1);
    assert!(r.implausible.is_empty());
}

/// Joint maps on a 7-joint arm: identified jointly with the geometry on the 216 grid poses. The
/// evidence (noise about 1.2 mm per coordinate, the robot's repeatability 2 mm) supports no map,
/// and the maps' cross-validation keeps every map at zero: the result is the geometric
/// calibration (held out: the independent float64 calibration's 3.09 / 3.28 / 5.90 mm).
#[test]
fn joint_maps_are_identified_on_the_seven_joint_arm_and_kept_at_zero_when_they_do_not_predict() {
    let maps = CalibrationConfig {
        model: ErrorModel::JointMaps,
        ..CalibrationConfig::default()
    };
    let c = calibrate(maps, random_twenty());
    let r = &c.result;
    let maps = r.joint_maps.as_ref().expect("the joint-maps stage ran");
    assert_eq!(maps.joints.len(), 7);
    let cv = maps
        .cross_validation
        .expect("the maps' cross-validation ran");
    println!(
        "joint maps, {} harmonics, noise {:.3} mm; cross-validation {:.3} mm with maps, {:.3} mm geometry",
        maps.harmonics, maps.noise_mm, cv.maps_mean_mm, cv.geometric_mean_mm
    );
    assert!(cv.kept_at_zero);
    assert!(
        maps.joints
            .iter()
            .all(|j| !j.supported && j.max_mrad == 0.0)
    );
    assert!(
        (maps.noise_mm - 1.17).abs() < 0.05,
        "noise {}",
        maps.noise_mm
    );
    let after = &r.validation.as_ref().unwrap().after.position_mm;
    assert!(after.mean <= 3.15, "random 20 mean {}", after.mean);
    assert!((after.rms - 3.28).abs() < 0.05 && (after.max - 5.90).abs() < 0.1);
    // The geometric calibration's file: no [joint_maps] written for maps kept at zero.
    assert!(c.model.file.joint_maps.is_none() && c.model.maps.is_none());
}

#[test]
fn grid_seventy_thirty_over_five_seeds() {
    let mut calibrated = Vec::new();
    let mut frames_only = Vec::new();
    for seed in 0..5 {
        let c = calibrate(
            CalibrationConfig::default(),
            HoldOut::Fraction {
                fraction: 0.3,
                seed,
            },
        );
        let v = c.result.validation.as_ref().unwrap();
        assert_eq!((c.result.calibration.poses, v.poses), (151, 65));
        println!(
            "grid seed {seed}: held-out mean {:.3} mm (frames only) -> {:.3} mm",
            v.before.position_mm.mean, v.after.position_mm.mean
        );
        frames_only.push(v.before.position_mm.mean);
        calibrated.push(v.after.position_mm.mean);
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    println!(
        "grid 70/30, 5 seeds: nominal with fitted frames {:.3} mm, geometric calibration {:.3} mm",
        mean(&frames_only),
        mean(&calibrated)
    );
    // The independent calibration: 4.22 and 2.19 mm, on other random 70/30 splits (the
    // frames-only mean of a split varies by +-0.4 mm here: 4.04 to 4.77).
    assert!(mean(&calibrated) <= 2.25, "{calibrated:?}");
    assert!((mean(&frames_only) - 4.22).abs() < 0.25, "{frames_only:?}");
}

/// `calib check` says what the reflector on axis 7 leaves out, and re-registering the frames of
/// the identified robot on the random poses (a new session) needs no geometry.
#[test]
fn check_and_re_registration_through_the_command_line() {
    let out = ok(&calib(&[
        "check",
        "--robot",
        ROBOT,
        "--data",
        GRID,
        "--profile",
        PROFILE,
    ]));
    assert!(
        out.contains("identifiability of 29 parameters: rank 29"),
        "{out}"
    );
    assert!(
        out.contains(
            "not identified (kept nominal): dtheta6 (acts like da6), dalpha6 (acts like dd6)"
        ),
        "{out}"
    );
    let lm = CalibrationConfig {
        method: Method::Lm,
        ..CalibrationConfig::default()
    };
    let c = calibrate(lm.clone(), random_twenty());
    let dir = tempfile::tempdir().unwrap();
    let identified = dir.path().join("wam-identified.toml");
    std::fs::write(&identified, c.robot_toml()).unwrap();
    let identified = identified.to_str().unwrap();
    // `calib calibrate --robot IDENTIFIED --data RANDOM --identify frames --method lm`.
    let frames_only = CalibrationConfig {
        identify: Identify::Frames,
        ..lm
    };
    let files = (identified, RANDOM, Some(PROFILE));
    let again = common::calibrate_files(files, frames_only, None).unwrap();
    assert_eq!(again.result.config.identify, Identify::Frames);
    // 20 poses, the frames alone fitted on them: at most the held-out error of the grid
    // calibration on the same poses.
    let held_out = c.result.validation.as_ref().unwrap().after.position_mm.mean;
    let refit = again.result.calibration.after.position_mm.mean;
    println!(
        "random 20: identified model, frames re-fitted on them {refit:.3} mm (held out {held_out:.3} mm)"
    );
    assert!(refit <= held_out + 1e-9);
}

/// `calib verify` on the real grid (its default 70/30 split): the f32 and f64 cores and the
/// independent reference fit the same 29 parameters (the reflector rule applies as in
/// `calibrate`) and agree within the verify tolerances. Measured: f64 - reference 4.7e-8 mm
/// (`da4`) and 3.8e-10 rad (`dalpha5`); f32 - f64 3.3e-5 mm and 4.9e-7 rad; validation RMS
/// 2.4446 mm for all three.
#[test]
fn verify_passes_on_the_real_grid() {
    let out = ok(&calib(&[
        "verify",
        "--robot",
        ROBOT,
        "--data",
        GRID,
        "--profile",
        PROFILE,
        "--json",
    ]));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    println!("{v}");
    assert_eq!(v["parameters"], 29);
    assert_eq!(v["passed"], true);
    let f64_angle = v["f64_angle"][0].as_f64().unwrap();
    let f64_length = v["f64_length"][0].as_f64().unwrap();
    assert!(f64_angle <= 1e-9 && f64_length <= 1e-6, "{v}");
    let rms: Vec<f64> = v["validation_rms_mm"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!(rms.iter().all(|r| (r - 2.4446).abs() < 1e-3), "{rms:?}");
}
