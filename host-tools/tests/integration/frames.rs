//! Tracker and tool frames end to end: data simulated with Table 2 errors, the tracker 3 m away
//! at an arbitrary orientation and a reflector (or 6-DoF probe) 150 mm off the flange;
//! `calib calibrate` registers and identifies the frames with the geometry, and its held-out
//! error is compared with the independent float64 reference optimiser started at the true frames
//! and parameters.

use crate::common;
use common::ROBOT;

use host_tools::analysis::reference;
use host_tools::calibration::{CalibrationConfig, HoldOut};
use host_tools::io::robot_file::RobotFile;
use host_tools::io::tracker_data::TrackerData;
use host_tools::measurement::simulate::SimulationConfig;
use std::path::{Path, PathBuf};

/// Simulates `poses` poses in the tracker frame (tracker about 3 m away, turned arbitrarily;
/// reflector 150 mm off the flange); returns (data, truth file).
fn simulate(
    dir: &Path,
    name: &str,
    poses: usize,
    seed: u64,
    position_only: bool,
) -> (PathBuf, PathBuf) {
    let config = SimulationConfig {
        poses,
        seed,
        position_sigma_mm: 0.02,
        orientation_sigma_rad: 1e-4,
        position_only,
        ..SimulationConfig::default()
    }
    .in_realistic_cell();
    common::simulate_with(dir, name, &config)
}

#[test]
fn frames_and_geometry_reach_the_reference_optimum() {
    let dir = tempfile::tempdir().unwrap();
    for (position_only, seed) in [(true, 21), (false, 22)] {
        // 60 poses, 30 % held out.
        let (data, truth) = simulate(dir.path(), &format!("cal{seed}"), 42, seed, position_only);
        let (holdout, _) = simulate(
            dir.path(),
            &format!("hold{seed}"),
            18,
            seed + 100,
            position_only,
        );
        let text = std::fs::read_to_string(&data).unwrap();
        assert!(!text.contains("# frame: base"));
        // `calib calibrate --holdout FILE`: the held-out poses measured apart.
        let fitted = common::read(ROBOT, data.to_str().unwrap(), None).unwrap();
        let held = common::read(ROBOT, holdout.to_str().unwrap(), None).unwrap();
        let mut session = common::session(fitted, CalibrationConfig::default());
        session.hold_out = HoldOut::poses(held);
        let c = session.run().unwrap();
        let frames = &c.result.frames;
        assert_eq!(
            frames.identified,
            host_tools::measurement::frames::Frames::BaseTool
        );
        // The nominal robot registered onto the data: a few mm (Table 2), not metres.
        assert!(frames.registration_rms_mm < 20.0 && frames.registration_rms_mm > 1.0);
        let identified_path = dir.path().join(format!("identified{seed}.toml"));
        std::fs::write(&identified_path, c.robot_toml()).unwrap();
        let controller = RobotFile::read(&identified_path).unwrap();
        // The controller's frames are the robot file's (none); the measurement setup is apart.
        assert_eq!((&controller.base, &controller.tool), (&None, &None));
        let identified = controller.in_measurement_setup();
        // The identified tracker base is the tracker pose of the simulation.
        let base = identified.base.as_ref().unwrap();
        for (got, want) in base.xyz_mm.iter().zip([2500.0, -1500.0, 600.0]) {
            assert!((got - want).abs() < 2.0, "{:?}", base.xyz_mm);
        }

        // The reference optimiser, started at the truth (true joints and frames as its baseline,
        // zero errors), fitting the same parameters.
        let truth_file = RobotFile::read(&truth).unwrap();
        let names = c.result.names();
        let cal = TrackerData::read(&data).unwrap();
        let fit = reference::fit(&truth_file, &names, &cal, 1e6, &vec![0.0; names.len()]).unwrap();
        let mut errors =
            calib_core::ParameterErrors::<f64, nalgebra::Dyn>::zeros_for(nalgebra::Dyn(6));
        for (n, v) in &fit.errors {
            errors.set(calib_core::Parameter::from_name(n, 6).unwrap(), *v);
        }
        let reference =
            truth_file.with_errors(&errors, std::iter::empty(), &[], "reference", ROBOT);
        let held = TrackerData::read(&holdout).unwrap();
        let rms_core = reference::rms_position_error(&identified, &held);
        let rms_reference = reference::rms_position_error(&reference, &held);
        let rms_truth = reference::rms_position_error(&truth_file, &held);
        let v = c.result.validation.as_ref().unwrap();
        println!(
            "{}: held-out RMS core {rms_core:.5} mm, reference from the truth {rms_reference:.5} mm, truth {rms_truth:.5} mm; \
             table mean {:.4} mm; registration {:.3} mm RMS; {} parameters",
            if position_only {
                "position only"
            } else {
                "6-DoF"
            },
            v.after.position_mm.mean,
            frames.registration_rms_mm,
            names.len()
        );
        assert!((v.after.position_mm.rms - rms_core).abs() < 1e-9);
        assert!(
            (rms_core - rms_reference).abs() <= 0.02 * rms_reference,
            "{rms_core} vs {rms_reference}"
        );
        assert!(rms_core < 0.06, "{rms_core}");
    }
}

/// Issue 39, N12: large geometric errors are not a wrong frame. The 12 poses of
/// er10l-c10-sim32.csv (in the base frame, the paper's Table 2 errors) that the nominal model
/// misses most (20.3 mm RMS) were refused as "in another frame" although registering them
/// explains them only 1.8 times better (11.1 mm); now they calibrate in the base frame and the
/// identified errors are Table 2's. Data in a tracker frame are still refused
/// (`real_cell::tracker_data_calibrate_export_compensate_reaches_the_targets`).
#[test]
fn n12_large_geometric_errors_in_the_base_frame_are_not_refused() {
    use calib_core::Kinematics;
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/data/er10l-c10-sim32.csv");
    let dataset =
        host_tools::measurement::dataset::Dataset::load(Path::new(ROBOT), Path::new(data)).unwrap();
    let nominal = Kinematics::nominal(&dataset.robot.model.robot).unwrap();
    let mut misses: Vec<(f64, u64)> = dataset
        .readings
        .iter()
        .zip(&dataset.data.records)
        .map(|(m, r)| {
            let error = m.error_of(&nominal.forward_angles(&m.angles));
            (error.position.norm(), r.line)
        })
        .collect();
    misses.sort_by(|a, b| b.0.total_cmp(&a.0));
    let worst: Vec<u64> = misses.iter().take(12).map(|(_, line)| *line).collect();
    let rms = (misses.iter().take(12).map(|(m, _)| m * m).sum::<f64>() / 12.0).sqrt();
    assert!(rms > 20.0, "{rms} mm RMS: beyond the registration limit");
    let text = std::fs::read_to_string(data).unwrap();
    let kept: String = text
        .lines()
        .enumerate()
        .filter(|(i, l)| {
            l.starts_with('#') || l.starts_with("id,") || worst.contains(&(*i as u64 + 1))
        })
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("worst.csv");
    std::fs::write(&file, kept).unwrap();
    let out = dir.path().join("identified.toml");
    let stdout = common::ok(&common::calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        file.to_str().unwrap(),
        "--method",
        "lm",
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(stdout.contains("(12 poses)"), "{stdout}");
    let identified = RobotFile::read(&out).unwrap();
    let errors = identified.calibration.unwrap().errors;
    let table2 = calib_core::model::paper::table2::<f64>();
    for (j, joint) in table2.joints.iter().enumerate() {
        let da = errors[&format!("da{}", j + 1)].as_float().unwrap();
        assert!(
            (da - joint.da).abs() < 1e-6,
            "da{} {da} mm, Table 2 {} mm",
            j + 1,
            joint.da
        );
    }
}
