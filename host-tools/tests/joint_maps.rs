//! Issue 14: per-joint angle-error maps identified with the geometry (`calibrate --model
//! joint-maps`) on the real UR10 data: calibrate on M random poses of Series B, validate on all
//! the others.

mod common;
use common::parse;
use host_tools::cli::calibrate::{self, CalibrateOptions};

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

/// Calibrates Series B (position only, least squares) with joint maps on `poses` random poses
/// (`seed`) and returns (geometric held-out mean, with maps held-out mean), mm.
fn series_b(poses: usize, seed: u64) -> (f64, f64) {
    series_b_with(POSITION, poses, seed)
}

/// As [`series_b`], through `profile`.
fn series_b_with(profile: &str, poses: usize, seed: u64) -> (f64, f64) {
    let fraction = ((SERIES_B_POSES - poses) as f64 / SERIES_B_POSES as f64).to_string();
    let seed_text = seed.to_string();
    let args = [
        "--robot",
        ROBOT,
        "--data",
        DATA_B,
        "--profile",
        profile,
        "--auto-mask",
        "--method",
        "lm",
        "--validate",
        &fraction,
        "--validate-seed",
        &seed_text,
        "--model",
        "joint-maps",
    ];
    let c = calibrate::calibrate(&parse::<CalibrateOptions>(&args)).unwrap();
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
    // The identified file carries the maps.
    assert!(c.robot_toml.contains("[joint_maps]"));
    (geometric, with_maps)
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
    // export, compensate and simulate refuse it and say why.
    for args in [
        &[
            "export",
            "--params",
            "maps.toml",
            "--format",
            "block",
            "--out",
            "b.bin",
        ][..],
        &[
            "compensate",
            "--robot",
            ROBOT,
            "--params",
            "maps.toml",
            "--targets",
            DATA_B,
            "--out",
            "c.csv",
        ][..],
        &[
            "simulate",
            "--robot",
            "maps.toml",
            "--out",
            "s.csv",
            "--truth-out",
            "t.toml",
        ][..],
    ] {
        let out = calib_in(d, args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
        assert!(stderr.contains("has joint maps"), "{args:?}: {stderr}");
    }
    for file in ["b.bin", "c.csv", "s.csv", "t.toml"] {
        assert!(!d.join(file).exists());
    }
}

/// 200 poses of Series A (a grid: joint 6 mostly at one of a few readings). Joint 6's map is
/// not determined by them; before maps with less than half a determined coefficient were
/// switched off, it followed rounding errors to a coefficient of 11 mrad and the run refused its
/// own result ("the identified joint maps are not plausible"). Now it is kept at zero and the
/// others are identified.
#[test]
fn a_map_the_poses_do_not_determine_is_kept_at_zero() {
    let data = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/ipa-ur10-lasertracker/series-a-grid-200.csv"
    );
    let args = [
        "--robot",
        ROBOT,
        "--data",
        data,
        "--profile",
        POSITION,
        "--auto-mask",
        "--method",
        "lm",
        "--model",
        "joint-maps",
    ];
    let c = calibrate::calibrate(&parse::<CalibrateOptions>(&args)).unwrap();
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
    let file =
        host_tools::robot_file::RobotFile::parse(&c.robot_toml, std::path::Path::new("a.toml"))
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
