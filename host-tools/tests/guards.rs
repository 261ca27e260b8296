//! Real-cell guards of issue 13 that are statistical in nature, checked on simulated cells with
//! known truth: the cross-validation estimate flags small pose sets whose calibration makes the
//! robot less accurate.

mod common;
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
