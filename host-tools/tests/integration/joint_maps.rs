//! Issue 14: per-joint angle-error maps identified with the geometry (`calibrate --model
//! joint-maps`) on the real UR10 data: calibrate on M random poses of Series B, validate on all
//! the others.

use crate::common;
use host_tools::calibration::{CalibrationConfig, ErrorModel, Identify, Method};
use host_tools::io::robot_file::{RobotFile, RobotModel};
use host_tools::measurement::frames::Frames;

const ROBOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml");
const DATA_B: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv"
);
const POSITION: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/profiles/ipa-ur10-lasertracker-position.toml"
);

const FULL_POSE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/profiles/ipa-ur10-lasertracker.toml"
);

/// Series B has 1495 poses.
const SERIES_B_POSES: usize = 1495;

const DATA_A: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/ipa-ur10-lasertracker/series-a-grid.csv"
);

/// Series A has 11,911 poses.
const SERIES_A_POSES: usize = 11_911;

const DATA_D: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/ipa-ur10-lasertracker/series-d-iso-cubes.csv"
);

/// Series D has 632 poses.
const SERIES_D_POSES: usize = 632;

/// Calibrates Series B (position only, least squares) with joint maps on `poses` random poses
/// (`seed`) and returns (geometric held-out mean, with maps held-out mean), mm.
fn series_b(poses: usize, seed: u64) -> (f64, f64) {
    series_b_with(POSITION, poses, seed)
}

/// As [`series_b`], through `profile`.
fn series_b_with(profile: &str, poses: usize, seed: u64) -> (f64, f64) {
    held_out(DATA_B, SERIES_B_POSES, profile, poses, seed).unwrap()
}

/// Calibrates `data` (`total` poses) through `profile` with joint maps on `poses` random poses
/// (`seed`) and returns (geometric held-out mean, with maps held-out mean), mm; or the refusal.
fn held_out(
    data: &str,
    total: usize,
    profile: &str,
    poses: usize,
    seed: u64,
) -> host_tools::Result<(f64, f64)> {
    held_out_of(ErrorModel::JointMaps, data, total, profile, poses, seed)
}

/// [`held_out`] with `model` (`joint-maps` or `joint-maps+compliance`).
fn held_out_of(
    model: ErrorModel,
    data: &str,
    total: usize,
    profile: &str,
    poses: usize,
    seed: u64,
) -> host_tools::Result<(f64, f64)> {
    let c = calibrated(model, data, total, profile, poses, seed)?;
    let maps = c.result.joint_maps.as_ref().unwrap();
    assert_eq!(c.result.calibration.poses, poses);
    let geometric = maps.geometric_validation.unwrap().after.position_mm.mean;
    let with_maps = c.result.validation.unwrap().after.position_mm.mean;
    println!(
        "M = {poses}, seed {seed}: held-out mean {geometric:.4} mm (geometric) -> {with_maps:.4} mm (joint maps, H = {}, noise {:.4} mm; supported {:?})",
        maps.harmonics,
        maps.noise_mm,
        maps.joints.iter().map(|j| j.supported).collect::<Vec<_>>()
    );
    // The identified file carries the maps (and the compliance).
    assert!(c.robot_toml().contains("[joint_maps]"));
    assert_eq!(
        c.robot_toml().contains("[compliance]"),
        model == ErrorModel::JointMapsCompliance
    );
    Ok((geometric, with_maps))
}

/// The UR10 calibrated with `model` on `poses` random poses (`seed`) of `data` (`total`
/// poses), through `profile`, least squares, dropping what the data cannot determine
/// (`calibrate --model MODEL --auto-mask --method lm`), the other poses held out.
fn calibrated(
    model: ErrorModel,
    data: &str,
    total: usize,
    profile: &str,
    poses: usize,
    seed: u64,
) -> host_tools::Result<host_tools::calibration::Calibrated> {
    let fraction = (total - poses) as f64 / total as f64;
    let config = CalibrationConfig {
        model,
        method: Method::Lm,
        auto_mask: true,
        ..CalibrationConfig::default()
    };
    common::calibrate_files((ROBOT, data, Some(profile)), config, Some((fraction, seed)))
}

/// The mean of the runs' (geometric, with maps) held-out means, each run better with the maps.
fn means(name: &str, runs: &[(f64, f64)]) -> (f64, f64) {
    for (i, (geometric, with_maps)) in runs.iter().enumerate() {
        assert!(
            with_maps < geometric,
            "{name} run {i}: {geometric} -> {with_maps}"
        );
    }
    let n = runs.len() as f64;
    let geometric = runs.iter().map(|r| r.0).sum::<f64>() / n;
    let with_maps = runs.iter().map(|r| r.1).sum::<f64>() / n;
    println!(
        "{name}, mean of {} subsets: {geometric:.4} -> {with_maps:.4} mm",
        runs.len()
    );
    (geometric, with_maps)
}

/// Series A (a grid), position-only, M = 50 (5 seeds) and 200 (3 seeds). The study: 0.435 ->
/// 0.243 and 0.410 -> 0.125 mm; goal: within 10 % (0.267 and 0.1375 mm). Measured: 0.4347 ->
/// 0.2227 and 0.4062 -> 0.1353 mm.
#[test]
fn series_a_fifty_and_two_hundred_poses_with_joint_maps() {
    let run =
        |poses: usize, seed: u64| held_out(DATA_A, SERIES_A_POSES, POSITION, poses, seed).unwrap();
    let fifty: Vec<_> = (0..5).map(|seed| run(50, seed)).collect();
    let (geometric, with_maps) = means("Series A, M = 50", &fifty);
    assert!(
        (0.41..0.46).contains(&geometric) && with_maps <= 0.243 * 1.1,
        "{with_maps}"
    );
    let two_hundred: Vec<_> = (0..3).map(|seed| run(200, seed)).collect();
    let (geometric, with_maps) = means("Series A, M = 200", &two_hundred);
    assert!(
        (0.38..0.43).contains(&geometric) && with_maps <= 0.125 * 1.1,
        "{with_maps}"
    );
}

/// Series A, M = 1000 (seed 0). The study: 0.404 -> 0.087 mm; goal: within 10 % (0.0957 mm).
/// Measured: 0.3994 -> 0.0900 mm. About 15 s:
/// `cargo test --release -p host-tools --test integration joint_maps::series_a_thousand -- --ignored`.
#[test]
#[ignore = "slow: 1000 calibration poses, 10,911 held out"]
fn series_a_thousand_poses_with_joint_maps() {
    let run = held_out(DATA_A, SERIES_A_POSES, POSITION, 1000, 0).unwrap();
    let (_, with_maps) = means("Series A, M = 1000", &[run]);
    assert!(with_maps <= 0.087 * 1.1, "{with_maps}");
}

/// Series D (ISO cubes, narrow joint ranges), position-only, M = 50 (seeds 0-4) and 200 (seeds
/// 0-2). The study: about 0.40 -> 0.20-0.23 and 0.372 -> 0.128 mm. **Not reached**: measured
/// 0.404 -> 0.297 and 0.356 -> 0.168 mm; this test holds those figures.
#[test]
fn series_d_with_joint_maps_short_of_the_study() {
    let run = |poses: usize, seed: u64| held_out(DATA_D, SERIES_D_POSES, POSITION, poses, seed);
    let fifty: Vec<_> = (0..5).map(|seed| run(50, seed).unwrap()).collect();
    let (_, with_maps) = means("Series D, M = 50", &fifty);
    assert!(with_maps <= 0.30, "{with_maps}");
    let two_hundred: Vec<_> = (0..3).map(|seed| run(200, seed).unwrap()).collect();
    let (_, with_maps) = means("Series D, M = 200", &two_hundred);
    assert!(with_maps <= 0.17, "{with_maps}");
}

/// M = 50, 5 seeds. The study quoted in issue 14: 0.430 -> 0.224 mm (with gravity compliance,
/// not modelled here). Goal: at most 0.25 mm, never worse than geometric.
#[test]
fn series_b_fifty_poses_with_joint_maps() {
    let runs: Vec<(f64, f64)> = (0..5).map(|seed| series_b(50, seed)).collect();
    for (seed, (geometric, with_maps)) in runs.iter().enumerate() {
        assert!(
            with_maps < geometric,
            "seed {seed}: {geometric} -> {with_maps}"
        );
    }
    let mean = |f: fn(&(f64, f64)) -> f64| runs.iter().map(f).sum::<f64>() / runs.len() as f64;
    let (geometric, with_maps) = (mean(|r| r.0), mean(|r| r.1));
    println!("M = 50, mean of 5 seeds: {geometric:.4} -> {with_maps:.4} mm");
    assert!((0.40..0.46).contains(&geometric), "{geometric}");
    assert!(with_maps <= 0.25, "{with_maps}");
}

/// `--harmonics` (issue 56): the count the evidence chose, given, is the same identification
/// (every map coefficient and the log evidence to the bit), with that one count tried; another
/// count gives other maps; a count out of 1-60, or with the geometric model, is refused.
#[test]
fn given_harmonics_are_the_evidence_s_choice_or_another_model() {
    let run = |harmonics: Option<usize>| {
        let config = CalibrationConfig {
            model: ErrorModel::JointMaps,
            harmonics,
            method: Method::Lm,
            auto_mask: true,
            ..CalibrationConfig::default()
        };
        let fraction = (SERIES_B_POSES - 50) as f64 / SERIES_B_POSES as f64;
        common::calibrate_files((ROBOT, DATA_B, Some(POSITION)), config, Some((fraction, 0)))
    };
    let chosen = run(None).unwrap();
    let maps = chosen.result.joint_maps.clone().unwrap();
    assert!(
        !maps.harmonics_given && maps.evidence.len() >= 2,
        "{:?}",
        maps.evidence
    );
    let given = run(Some(maps.harmonics)).unwrap();
    let given_maps = given.result.joint_maps.clone().unwrap();
    assert!(given_maps.harmonics_given);
    assert_eq!(given_maps.harmonics, maps.harmonics);
    assert_eq!(
        given_maps.evidence,
        vec![(maps.harmonics, maps.log_evidence)]
    );
    // The identified files are equal but for the time they were written.
    let untimed = |c: &host_tools::calibration::Calibrated| {
        (c.robot_toml().lines())
            .filter(|l| !l.starts_with("calibrated_at") && !l.starts_with("registered_at"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(untimed(&given), untimed(&chosen));
    assert!(
        given
            .text()
            .contains("harmonics per joint as given (--harmonics)")
    );
    let other = run(Some(maps.harmonics + 7)).unwrap();
    let other_maps = other.result.joint_maps.clone().unwrap();
    assert_eq!(other_maps.harmonics, maps.harmonics + 7);
    assert_ne!(other_maps.log_evidence, maps.log_evidence);
    for (harmonics, flag) in [(0, "--harmonics"), (61, "--harmonics")] {
        let error = run(Some(harmonics)).unwrap_err().to_string();
        assert!(error.contains(flag) && error.contains("1 to 60"), "{error}");
    }
    let geometric = CalibrationConfig {
        harmonics: Some(30),
        method: Method::Lm,
        ..CalibrationConfig::default()
    };
    let error = common::calibrate_files((ROBOT, DATA_B, Some(POSITION)), geometric, None)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("--harmonics") && error.contains("--model"),
        "{error}"
    );
}

/// M = 50, 5 seeds, 6-DoF data: the maps also use the orientation rows (weighted by the
/// geometric fit's position-to-orientation residual ratio). Measured: 0.4205 -> 0.2207 mm.
#[test]
fn series_b_fifty_poses_six_dof_with_joint_maps() {
    let runs: Vec<(f64, f64)> = (0..5)
        .map(|seed| series_b_with(FULL_POSE, 50, seed))
        .collect();
    for (seed, (geometric, with_maps)) in runs.iter().enumerate() {
        assert!(
            with_maps < geometric,
            "seed {seed}: {geometric} -> {with_maps}"
        );
    }
    let with_maps = runs.iter().map(|r| r.1).sum::<f64>() / 5.0;
    println!("M = 50, 6-DoF, mean of 5 seeds: {with_maps:.4} mm");
    assert!(with_maps <= 0.23, "{with_maps}");
}

/// M = 200, 3 seeds. The study: 0.411 -> 0.130 mm. Goal: at most 0.14 mm.
#[test]
fn series_b_two_hundred_poses_with_joint_maps() {
    let runs: Vec<(f64, f64)> = (0..3).map(|seed| series_b(200, seed)).collect();
    for (seed, (geometric, with_maps)) in runs.iter().enumerate() {
        assert!(
            with_maps < geometric,
            "seed {seed}: {geometric} -> {with_maps}"
        );
    }
    let with_maps = runs.iter().map(|r| r.1).sum::<f64>() / 3.0;
    println!("M = 200, mean of 3 seeds: {with_maps:.4} mm");
    assert!(with_maps <= 0.14, "{with_maps}");
}

/// A robot file with joint maps: commands that model the robot apply the maps (fk, evaluate);
/// those that cannot yet (export, compensate, simulate) refuse it instead of leaving them out.
#[test]
fn a_file_with_joint_maps_is_applied_or_refused_never_ignored() {
    use common::{calib_in, ok};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let base = [
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        DATA_B,
        "--profile",
        POSITION,
        "--auto-mask",
        "--method",
        "lm",
        "--validate",
        "0.9666",
    ];
    let maps_args = [
        &base[..],
        &[
            "--model",
            "joint-maps",
            "--out",
            "maps.toml",
            "--plot",
            "plots",
        ],
    ]
    .concat();
    ok(&calib_in(d, &maps_args));
    let svg = std::fs::read_to_string(d.join("plots/joint-maps.svg")).unwrap();
    assert!(svg.contains("joint 1: angle error") && svg.contains("joint 6: angle error"));
    assert!(d.join("plots/joint-maps.png").exists());
    let geometric_args = [&base[..], &["--out", "geometric.toml"]].concat();
    ok(&calib_in(d, &geometric_args));
    let text = std::fs::read_to_string(d.join("maps.toml")).unwrap();
    assert!(text.contains("[joint_maps]") && text.contains("harmonics = "));
    // fk: the maps move the end point (by up to a few tenths of a millimetre).
    let fk = |robot: &str| -> Vec<f64> {
        let out = ok(&calib_in(
            d,
            &[
                "fk",
                "--robot",
                robot,
                "--joints-deg",
                "-100,-60,30,-100,-50,10",
                "--json",
            ],
        ));
        let json: serde_json::Value = serde_json::from_str(&out).unwrap();
        (0..3)
            .map(|i| json["position_mm"][i].as_f64().unwrap())
            .collect()
    };
    let (with, without) = (fk("maps.toml"), fk("geometric.toml"));
    let moved = with
        .iter()
        .zip(&without)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!((0.01..2.0).contains(&moved), "{moved} mm");
    // evaluate on the calibration session (frames refitted): the maps are applied, so the
    // model with maps fits better than the geometric one.
    let evaluate = |robot: &str| -> f64 {
        let out = ok(&calib_in(
            d,
            &[
                "evaluate",
                "--robot",
                robot,
                "--data",
                DATA_B,
                "--profile",
                POSITION,
                "--json",
            ],
        ));
        let json: serde_json::Value = serde_json::from_str(&out).unwrap();
        json["position_mm"]["mean"].as_f64().unwrap()
    };
    let (with, without) = (evaluate("maps.toml"), evaluate("geometric.toml"));
    assert!(with < 0.8 * without, "{with} vs {without}");
    // Re-registration keeps the model with its maps; new maps on top of maps are refused.
    let frames_only = [
        "calibrate",
        "--robot",
        "maps.toml",
        "--identify",
        "frames",
        "--data",
        DATA_B,
        "--profile",
        POSITION,
        "--method",
        "lm",
        "--out",
        "again.toml",
    ];
    ok(&calib_in(d, &frames_only));
    let again = std::fs::read_to_string(d.join("again.toml")).unwrap();
    let maps_of = |text: &str| text[text.find("[joint_maps]").unwrap()..].to_string();
    assert_eq!(maps_of(&again), maps_of(&text));
    let out = calib_in(
        d,
        &[&base[..], &["--model", "joint-maps"]]
            .concat()
            .iter()
            .map(|a| if *a == ROBOT { "maps.toml" } else { a })
            .collect::<Vec<_>>(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("already has joint maps"), "{stderr}");
    exported_blocks_hold_the_maps(d);
    compensation_uses_the_maps(d);
    // simulate refuses it and says why (it would simulate the geometry alone).
    let args = [
        "simulate",
        "--robot",
        "maps.toml",
        "--out",
        "s.csv",
        "--truth-out",
        "t.toml",
    ];
    let out = calib_in(d, &args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("has joint maps"), "{stderr}");
    for file in ["s.csv", "t.toml"] {
        assert!(!d.join(file).exists());
    }
}

/// `export --format block` of `maps.toml` in `d`: a version 2 block whose geometry is the
/// file's and whose maps, as the core evaluates them, equal the file's series (summed here with
/// libm's sine and cosine of `h q`) to the scalar's rounding.
fn exported_blocks_hold_the_maps(d: &std::path::Path) {
    use calib_core::controller::storage::{decode_model, model_block_len};
    use common::{calib_in, ok};
    let file = RobotFile::read(&d.join("maps.toml")).unwrap();
    let maps = file.joint_maps(&d.join("maps.toml")).unwrap().unwrap();
    let model: RobotModel = file.to_model(&d.join("maps.toml")).unwrap();
    let readings: Vec<f64> = (0..200).map(|i| -6.2 + 0.062 * f64::from(i)).collect();
    for (scalar, tolerance) in [("f64", 1e-15), ("f32", 2e-9)] {
        let name = format!("maps-{scalar}.bin");
        ok(&calib_in(
            d,
            &[
                "export",
                "--params",
                "maps.toml",
                "--format",
                "block",
                "--scalar",
                scalar,
                "--out",
                &name,
            ],
        ));
        let bytes = std::fs::read(d.join(&name)).unwrap();
        let mut worst = 0.0f64;
        if scalar == "f64" {
            assert_eq!(
                bytes.len(),
                model_block_len::<f64>(6, maps.harmonics, false)
            );
            let (block, _) = decode_model::<f64, nalgebra::Dyn, 64>(&bytes).unwrap();
            assert_eq!(block.robot, model.robot);
            for j in 0..6 {
                for q in &readings {
                    worst = worst.max((block.maps.error(j, *q) - maps.error(j, *q)).abs());
                }
            }
        } else {
            assert_eq!(
                bytes.len(),
                model_block_len::<f32>(6, maps.harmonics, false)
            );
            assert!(bytes.len() <= 8192, "{} bytes", bytes.len());
            let (block, _) = decode_model::<f32, nalgebra::Dyn, 64>(&bytes).unwrap();
            assert_eq!(
                block.robot,
                host_tools::formats::export::to_f32(&model.robot)
            );
            for j in 0..6 {
                for q in &readings {
                    let core = f64::from(block.maps.error(j, *q as f32));
                    // The f32 reading itself is rounded: compare at the rounded reading.
                    let host = maps.error(j, f64::from(*q as f32));
                    worst = worst.max((core - host).abs());
                }
            }
        }
        println!(
            "{scalar} block: {} bytes, maps within {worst:.1e} rad",
            bytes.len()
        );
        assert!(worst < tolerance, "{scalar}: {worst:e} rad");
    }
}

/// `compensate --params maps.toml` in `d`: the joints it commands put the robot with maps
/// (independent reference kinematics at the file's series added to the readings) on the targets;
/// the geometric model's joints would miss them by the maps' tenths of a millimetre.
fn compensation_uses_the_maps(d: &std::path::Path) {
    compensation_uses_the_model(d, "maps.toml", "geometric.toml", 0.05);
}

/// `compensate --params params` in `d`: the joints it commands put the robot of `params` (maps
/// and, if it has it, gravity compliance, evaluated by the reference kinematics and the
/// identification's compliance columns) on 30 targets within 1e-3 mm; the joints for the model
/// of `baseline` miss them by more than `missed_by` mm on average.
fn compensation_uses_the_model(d: &std::path::Path, params: &str, baseline: &str, missed_by: f64) {
    // Readings around Series B's ranges (partly beyond them: extrapolation allowed).
    let readings: Vec<Vec<f64>> = (0..30)
        .map(|i| {
            let t = f64::from(i);
            vec![
                -1.7 + 0.05 * t,
                -1.0 - 0.02 * t,
                0.4 + 0.03 * t,
                -1.8 + 0.04 * t,
                -1.0 + 0.02 * t,
                0.2 + 0.05 * t,
            ]
        })
        .collect();
    let misses = |used: &str| {
        common::compensated_misses(d, ROBOT, &d.join(used), &d.join(params), &readings)
    };
    let with = misses(params);
    let without = misses(baseline);
    let worst = with.iter().fold(0.0f64, |m, v| m.max(*v));
    let mean_without = without.iter().sum::<f64>() / without.len() as f64;
    println!(
        "compensated with {params}: worst {worst:.1e} mm; with {baseline}: mean {mean_without:.3} mm"
    );
    assert!(worst < 1e-3, "{worst} mm");
    assert!(mean_without > missed_by, "{mean_without} mm");
}

/// 200 poses of Series A (a grid: joint 6 mostly at one of a few readings; the others held out). Joint 6's map is
/// not determined by them; before maps with less than half a determined coefficient were
/// switched off, it followed rounding errors to a coefficient of 11 mrad and the run refused its
/// own result ("the identified joint maps are not plausible"). Now it is kept at zero and the
/// others are identified.
#[test]
fn a_map_the_poses_do_not_determine_is_kept_at_zero() {
    let c = calibrated(
        ErrorModel::JointMaps,
        DATA_A,
        SERIES_A_POSES,
        POSITION,
        200,
        0,
    )
    .unwrap();
    let maps = c.result.joint_maps.as_ref().unwrap();
    assert_eq!(c.result.calibration.poses, 200);
    let supported: Vec<bool> = maps.joints.iter().map(|j| j.supported).collect();
    assert_eq!(supported, [true, true, true, true, true, false]);
    assert_eq!(maps.joints[5].rms_mrad, 0.0);
    for j in &maps.joints[..5] {
        assert!((0.1..1.0).contains(&j.rms_mrad), "{j:?}");
    }
    // The file written is one its reader accepts, and the maps fit A's poses far better than the
    // geometry alone.
    let file = host_tools::io::robot_file::RobotFile::parse(
        &c.robot_toml(),
        std::path::Path::new("a.toml"),
    )
    .unwrap();
    assert!(
        file.joint_maps(std::path::Path::new("a.toml"))
            .unwrap()
            .is_some()
    );
    let (geometric, with_maps) = (
        maps.geometric_calibration.after.position_mm.mean,
        c.result.calibration.after.position_mm.mean,
    );
    assert!(with_maps < 0.5 * geometric, "{geometric} -> {with_maps}");
}

/// A new session with the same probe: Series B's model with joint maps (50 poses,
/// `onboard/data/ur10-series-b-maps.toml`) on Series D, only the tracker's position (the base)
/// re-fitted on 30 poses. The probe identified with the model is kept; before, `--fit-frames base`
/// kept the controller's tool instead (0.588 mm here; 16 mm for a model of Series A).
#[test]
fn a_new_session_with_only_the_base_refitted_keeps_the_identified_probe() {
    let model = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../onboard/data/ur10-series-b-maps.toml"
    );
    let mean = |frames: &str| -> f64 {
        let out = common::ok(&common::calib(&[
            "evaluate",
            "--robot",
            model,
            "--data",
            DATA_D,
            "--profile",
            POSITION,
            "--fit-poses",
            "30",
            "--fit-frames",
            frames,
            "--json",
        ]));
        let json: serde_json::Value = serde_json::from_str(&out).unwrap();
        json["position_mm"]["mean"].as_f64().unwrap()
    };
    let (base, both) = (mean("base"), mean("base+tool"));
    println!(
        "Series B model on Series D: base re-fitted {base:.4} mm, base and probe {both:.4} mm"
    );
    assert!(base < 0.5 && both < 0.45, "{base} {both}");
}

/// Never worse than the geometry on poses it did not see: on 50 full poses of Series D (narrow
/// ISO-cube joint ranges, orientations that disagree with the positions) the maps predicted the
/// held-out poses worse in seeds 4 (0.5607 -> 0.5814 mm) and 1 (0.4268 -> 0.4335). The
/// cross-validation check on the calibration poses sees it (seed 4: maps 0.4814 mm, geometry
/// 0.4452; seed 1: 0.472 and 0.486, not the 5 % gain it asks for): the maps are kept at zero,
/// the result and the file are the geometric calibration's, and the text says so.
#[test]
fn maps_that_do_not_predict_better_are_kept_at_zero() {
    for (seed, held_out) in [(4, 0.55..0.57), (1, 0.42..0.43)] {
        let c = calibrated(
            ErrorModel::JointMaps,
            DATA_D,
            SERIES_D_POSES,
            FULL_POSE,
            50,
            seed,
        )
        .unwrap();
        let maps = c.result.joint_maps.as_ref().unwrap();
        let cv = maps.cross_validation.unwrap();
        println!("seed {seed}: {cv:?}");
        assert!(cv.kept_at_zero && cv.maps_mean_mm > 0.95 * cv.geometric_mean_mm);
        let geometric = maps.geometric_validation.unwrap().after.position_mm.mean;
        let result = c.result.validation.unwrap().after.position_mm.mean;
        assert_eq!(result, geometric);
        assert!(held_out.contains(&result), "{result}");
        assert!(!c.robot_toml().contains("[joint_maps]"));
        assert!(maps.joints.iter().all(|j| !j.supported));
        assert!(c.result.text(None).contains("every map is kept at zero"));
    }
}

/// Gravity compliance with the maps (`--model joint-maps+compliance`, the UR10's published masses,
/// an assumed 1.5 kg probe): Series D, position-only, M = 200 (seeds 0-2) and 50 (seeds 0-4).
/// The study: 0.372 -> 0.128 and about 0.40 -> 0.20-0.23 mm; goal within 10 % (0.1408 and 0.253
/// mm). Measured: 0.1250 and 0.2524 mm (maps alone: 0.1675 and 0.2974).
#[test]
fn series_d_with_joint_maps_and_compliance() {
    let run = |poses: usize, seed: u64| {
        held_out_of(
            ErrorModel::JointMapsCompliance,
            DATA_D,
            SERIES_D_POSES,
            POSITION,
            poses,
            seed,
        )
    };
    let two_hundred: Vec<_> = (0..3).map(|seed| run(200, seed).unwrap()).collect();
    let (_, with_model) = means("Series D with compliance, M = 200", &two_hundred);
    assert!(with_model <= 0.128 * 1.1, "{with_model}");
    let fifty: Vec<_> = (0..5).map(|seed| run(50, seed).unwrap()).collect();
    let (_, with_model) = means("Series D with compliance, M = 50", &fifty);
    assert!(with_model <= 0.23 * 1.1, "{with_model}");
}

/// Never worse than the geometry with compliance either: 50 full poses of Series D (seeds 0-4,
/// where the maps alone were worse than the geometry in 2 of 5). Measured (geometric -> maps and
/// compliance): 0.4597 -> 0.3039, 0.4268 -> 0.2977, 0.4035 -> 0.4035 (the cross-validation keeps
/// the model at zero), 0.4796 -> 0.3396, 0.5607 -> 0.4491 mm; mean 0.4661 -> 0.3588 (maps alone
/// 0.4514).
#[test]
fn series_d_six_dof_with_joint_maps_and_compliance() {
    let runs: Vec<(f64, f64)> = (0..5)
        .map(|seed| {
            let c = calibrated(
                ErrorModel::JointMapsCompliance,
                DATA_D,
                SERIES_D_POSES,
                FULL_POSE,
                50,
                seed,
            )
            .unwrap();
            let maps = c.result.joint_maps.as_ref().unwrap();
            let geometric = maps.geometric_validation.unwrap().after.position_mm.mean;
            let with_model = c.result.validation.unwrap().after.position_mm.mean;
            println!(
                "Series D full pose, M = 50, seed {seed}: {geometric:.4} -> {with_model:.4} mm"
            );
            assert!(
                with_model <= geometric,
                "seed {seed}: {geometric} -> {with_model}"
            );
            (geometric, with_model)
        })
        .collect();
    let mean = runs.iter().map(|r| r.1).sum::<f64>() / 5.0;
    let geometric = runs.iter().map(|r| r.0).sum::<f64>() / 5.0;
    println!("Series D full pose, M = 50: mean {geometric:.4} -> {mean:.4} mm");
    assert!(mean < 0.8 * geometric, "{geometric} -> {mean}");
}

/// Series B and A with compliance: B at M = 50 (5 seeds) stays within the goal of 0.25 mm
/// (measured 0.2392; maps alone 0.2334, study 0.224), A at M = 200 (3 seeds) within 10 % of the
/// study's 0.125 (measured 0.1017; maps alone 0.1353).
#[test]
fn series_a_and_b_with_joint_maps_and_compliance() {
    let model = ErrorModel::JointMapsCompliance;
    let b: Vec<_> = (0..5)
        .map(|seed| held_out_of(model, DATA_B, SERIES_B_POSES, POSITION, 50, seed).unwrap())
        .collect();
    let (_, with_model) = means("Series B with compliance, M = 50", &b);
    assert!(with_model <= 0.25, "{with_model}");
    let a: Vec<_> = (0..3)
        .map(|seed| held_out_of(model, DATA_A, SERIES_A_POSES, POSITION, 200, seed).unwrap())
        .collect();
    let (_, with_model) = means("Series A with compliance, M = 200", &a);
    assert!(with_model <= 0.125 * 1.1, "{with_model}");
}

/// A file with `[compliance]` is applied by `evaluate` and `calibrate --identify frames` (see the
/// cross-session test), `fk`, `check`, `verify`, `export --format block` and `compensate`;
/// `simulate` refuses it and says why, writing nothing; a robot file without `[dynamics]` is refused by `--model joint-maps+compliance` with
/// what to add.
#[test]
fn a_file_with_compliance_is_applied_or_refused_never_ignored() {
    use calib_core::controller::storage::{decode_model, model_block_len};
    use common::{calib_in, ok};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fraction = ((SERIES_B_POSES - 50) as f64 / SERIES_B_POSES as f64).to_string();
    let base = [
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        DATA_B,
        "--profile",
        POSITION,
        "--auto-mask",
        "--method",
        "lm",
        "--validate",
        &fraction,
        "--model",
        "joint-maps+compliance",
    ];
    ok(&calib_in(d, &[&base[..], &["--out", "c.toml"]].concat()));
    let text = std::fs::read_to_string(d.join("c.toml")).unwrap();
    assert!(text.contains("[compliance]") && text.contains("[dynamics]"));
    let file = RobotFile::read(&d.join("c.toml")).unwrap();
    let mut without = file.clone();
    without.compliance = None;
    std::fs::write(d.join("no-c.toml"), without.to_toml("test")).unwrap();
    // check analyses the geometry with maps and compliance held fixed: the same analysis as of the
    // file without the compliance (it does not change the geometry's Jacobian).
    let check = |robot: &str| {
        ok(&calib_in(
            d,
            &[
                "check",
                "--robot",
                robot,
                "--data",
                DATA_B,
                "--profile",
                POSITION,
            ],
        ))
    };
    assert_eq!(check("c.toml"), check("no-c.toml"));
    // verify fits the geometry to the (full) poses with the maps and the compliance taken off:
    // the reference optimiser and the f32 core see the same poses and agree with the f64 core
    // (before, both read the raw readings and missed by 0.2 mm and more), and the geometry refitted
    // under the file's model predicts the held-out poses better than the nominal robot's refit,
    // and worse with the compliance left out of the file (measured RMS 0.2924 mm; without the
    // compliance 0.3372; nominal 0.4512).
    let verified = |robot: &str| -> f64 {
        let out = ok(&calib_in(
            d,
            &[
                "verify",
                "--robot",
                robot,
                "--data",
                DATA_B,
                "--profile",
                FULL_POSE,
                "--json",
            ],
        ));
        let json: serde_json::Value = serde_json::from_str(&out).unwrap();
        println!("verify {robot}: {json}");
        assert_eq!(json["passed"], true, "{robot}: {json}");
        json["validation_rms_mm"][1].as_f64().unwrap()
    };
    // The identified file (parallel axes now 0.01-0.09 deg off) keeps the nominal file's
    // identification set: beta, not d, for the parallel joints 2 and 3.
    let mask = |path: &std::path::Path| RobotFile::read(path).unwrap().to_model(path).unwrap().mask;
    assert_eq!(mask(&d.join("c.toml")), mask(std::path::Path::new(ROBOT)));
    let nominal = verified(ROBOT);
    let (with, without) = (verified("c.toml"), verified("no-c.toml"));
    assert!(
        with < without && with < 0.7 * nominal,
        "{with} {without} {nominal}"
    );
    let out = calib_in(
        d,
        &[
            "simulate",
            "--robot",
            "c.toml",
            "--out",
            "s.csv",
            "--truth-out",
            "s.toml",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("has gravity compliance"), "{stderr}");
    for file in ["s.csv", "s.toml"] {
        assert!(!d.join(file).exists(), "{file}");
    }
    // The parameter block holds the compliance: masses and gains as the file has them.
    let c = file
        .gravity_compliance(&d.join("c.toml"), 6)
        .unwrap()
        .unwrap();
    let maps = file.joint_maps(&d.join("c.toml")).unwrap().unwrap();
    ok(&calib_in(
        d,
        &[
            "export", "--params", "c.toml", "--format", "block", "--scalar", "f64", "--out",
            "b.bin",
        ],
    ));
    let bytes = std::fs::read(d.join("b.bin")).unwrap();
    assert_eq!(bytes.len(), model_block_len::<f64>(6, maps.harmonics, true));
    let (block, _) = decode_model::<f64, nalgebra::Dyn, 64>(&bytes).unwrap();
    assert_eq!(block.compliance, c.to_core::<f64>(6).unwrap());
    assert!(block.compliance.is_active());
    // compensate applies it: the robot with maps and compliance reaches the targets.
    compensation_uses_the_model(d, "c.toml", "no-c.toml", 0.1);
    // fk applies it: the pose moves by the compliance's displacement at the mapped readings.
    let fk = |robot: &str| -> nalgebra::Vector3<f64> {
        let out = ok(&calib_in(
            d,
            &[
                "fk",
                "--robot",
                robot,
                "--joints-deg",
                "-100,-60,30,-100,-50,10",
                "--json",
            ],
        ));
        let json: serde_json::Value = serde_json::from_str(&out).unwrap();
        nalgebra::Vector3::from_fn(|i, _| json["position_mm"][i].as_f64().unwrap())
    };
    let moved = fk("c.toml") - fk("no-c.toml");
    let model: RobotModel = file.to_model(&d.join("c.toml")).unwrap();
    let q = calib_core::model::JointVec::from_slice(
        &[-100.0f64, -60.0, 30.0, -100.0, -50.0, 10.0].map(f64::to_radians),
    )
    .unwrap();
    let gravity = file.dynamics.as_ref().unwrap().to_gravity(6).unwrap();
    let gains = file.compliance.as_ref().unwrap().to_gains(6).unwrap();
    let columns = host_tools::model::compliance::columns(
        &gravity,
        &model.robot,
        &calib_core::ParameterErrors::zeros_for(model.robot.joint_count()),
        &maps.apply(&q),
    )
    .unwrap();
    let d6 = host_tools::model::compliance::displacement(&columns, &gains);
    let expected = nalgebra::Vector3::new(d6[0], d6[1], d6[2]);
    println!("fk moved by compliance: {moved} (expected {expected})");
    assert!(expected.norm() > 1e-3, "{expected}");
    assert!((moved - expected).norm() < 1e-9, "{moved} vs {expected}");
    // The ER10L-C10's file has no masses.
    let er10 = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/er10l-c10.toml");
    let out = calib_in(
        d,
        &base
            .iter()
            .map(|a| if *a == ROBOT { er10 } else { a })
            .collect::<Vec<_>>(),
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("add a [dynamics]"), "{stderr}");
}

/// Cross-session (issue 14's goal: at most 0.33 mm; the study 0.308): the model with maps and
/// compliance from 200 poses of Series A, on Series B with only the tracker (base) re-fitted on 30
/// poses (seeds 0-2), evaluated on the other 1465. Measured: 0.2752, 0.2771, 0.2827 mm (maps
/// alone from 1000 poses of A: 0.37). `evaluate` applies the compliance: on A itself, with the
/// calibration's split, it reproduces the calibration's held-out error; `calibrate --identify
/// frames` of B's 30 poses reproduces evaluate's.
#[test]
fn a_series_a_model_with_compliance_carries_over_to_series_b() {
    use common::{calib_in, ok};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let c = calibrated(
        ErrorModel::JointMapsCompliance,
        DATA_A,
        SERIES_A_POSES,
        POSITION,
        200,
        0,
    )
    .unwrap();
    let held_out = c.result.validation.unwrap().after.position_mm.mean;
    std::fs::write(d.join("a.toml"), c.robot_toml()).unwrap();
    let evaluate = |data: &str, fit_poses: &str, seed: &str, frames: &str| -> f64 {
        let out = ok(&calib_in(
            d,
            &[
                "evaluate",
                "--robot",
                "a.toml",
                "--data",
                data,
                "--profile",
                POSITION,
                "--fit-poses",
                fit_poses,
                "--seed",
                seed,
                "--fit-frames",
                frames,
                "--json",
            ],
        ));
        let json: serde_json::Value = serde_json::from_str(&out).unwrap();
        json["position_mm"]["mean"].as_f64().unwrap()
    };
    let again = evaluate(DATA_A, "200", "0", "base+tool");
    println!("Series A held out: calibrate {held_out:.6} mm, evaluate {again:.6} mm");
    assert!((again - held_out).abs() < 1e-3, "{again} vs {held_out}");
    let b: Vec<f64> = ["0", "1", "2"]
        .iter()
        .map(|seed| evaluate(DATA_B, "30", seed, "base"))
        .collect();
    let mean = b.iter().sum::<f64>() / 3.0;
    println!("Series A model on Series B (base re-fitted on 30 poses): {b:?}, mean {mean:.4} mm");
    assert!(mean <= 0.33, "{mean}");
    // The frames-only re-registration (`calibrate --identify frames`) of the same 30 poses keeps
    // the maps and the compliance: its held-out error is evaluate's (which re-registers by its
    // own path), and the file it writes still has both.
    let fraction = (SERIES_B_POSES - 30) as f64 / SERIES_B_POSES as f64;
    let a_model = d.join("a.toml");
    for (frames, identified) in [("base+tool", Frames::BaseTool), ("base", Frames::Base)] {
        let evaluated = evaluate(DATA_B, "30", "0", frames);
        let frames_only = CalibrationConfig {
            identify: Identify::Frames,
            frames: Some(identified),
            method: Method::Lm,
            ..CalibrationConfig::default()
        };
        let files = (a_model.to_str().unwrap(), DATA_B, Some(POSITION));
        let registered = common::calibrate_files(files, frames_only, Some((fraction, 0))).unwrap();
        let held_out = registered.result.validation.unwrap().after.position_mm.mean;
        println!(
            "Series A model, {frames} re-registered on 30 poses of B: calibrate --identify frames {held_out:.4} mm, evaluate {evaluated:.4} mm"
        );
        assert!(
            (held_out - evaluated).abs() < 0.01 * evaluated,
            "{held_out} vs {evaluated}"
        );
        assert!(registered.robot_toml().contains("[compliance]"));
        assert!(registered.robot_toml().contains("[joint_maps]"));
    }
}

/// Issue 39, N11: maps whose cross-validation cannot run are not kept. On the first 5 poses of
/// Series B (every pose its own fold, and no fold of 4 poses determines the maps) the evidence
/// supported a map of joint 2 (0.21 mrad RMS), written with exit 0 while the geometric
/// cross-validation predicted 84 mm misses; now every map is kept at zero and the text says why.
#[test]
fn n11_maps_that_cannot_be_cross_validated_are_kept_at_zero() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(DATA_B).unwrap();
    let five: String = text.lines().take(6).map(|l| format!("{l}\n")).collect();
    let data = dir.path().join("five.csv");
    std::fs::write(&data, five).unwrap();
    let out = dir.path().join("maps.toml");
    let out = common::calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        data.to_str().unwrap(),
        "--profile",
        FULL_POSE,
        "--model",
        "joint-maps",
        "--auto-mask",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = common::ok(&out);
    assert!(
        stdout.contains("the maps could not be cross-validated"),
        "{stdout}"
    );
    let rows: Vec<&str> = stdout
        .lines()
        .filter(|l| l.trim_start().starts_with(|c: char| c.is_ascii_digit()) && l.contains(" to "))
        .collect();
    assert_eq!(rows.len(), 6, "{stdout}");
    assert!(
        rows.iter()
            .all(|r| r.split_whitespace().nth(1) == Some("zero")),
        "{rows:?}"
    );
}
