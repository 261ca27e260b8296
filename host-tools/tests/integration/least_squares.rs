//! Least squares, identifiability, robust losses and uncertainty, end to end through the library
//! functions behind `calib simulate`, `calib calibrate` and `calib check`, checked against the
//! independent float64 reference optimiser and the known truth.

use crate::common;
use common::{ROBOT, simulate};

use host_tools::analysis::identifiability::IdentifiabilityReport;
use host_tools::analysis::reference;
use host_tools::calibration::Calibrated as Calibration;
use host_tools::calibration::{CalibrationConfig, LossChoice, Method};
use host_tools::io::robot_file::RobotFile;
use host_tools::io::tracker_data::TrackerData;
use std::path::Path;

/// The ER10L-C10 calibrated on `data` with `config`, compared with the known errors of `truth`.
fn calibrate(data: &Path, truth: &Path, config: CalibrationConfig) -> Calibration {
    let dataset = common::read(ROBOT, data.to_str().unwrap(), None).unwrap();
    let mut session = common::session(dataset, config);
    session.truth = Some(common::truth(truth));
    session.run().unwrap()
}

/// What the poses of `data` determine (`calib check --robot ROBOT --data DATA`).
fn check(data: &Path) -> IdentifiabilityReport {
    let dataset = common::read(ROBOT, data.to_str().unwrap(), None).unwrap();
    let k = calib_core::identify::objective::DEFAULT_K;
    host_tools::analysis::identifiability::check(&dataset, None, k).unwrap()
}

/// Writes the identified robot file and returns it parsed.
fn identified(c: &Calibration, dir: &Path, name: &str) -> RobotFile {
    let path = dir.join(name);
    std::fs::write(&path, c.robot_toml()).unwrap();
    RobotFile::read(&path).unwrap()
}

#[test]
fn tracker_noise_scenario_matches_the_reference_and_the_statistics() {
    let dir = tempfile::tempdir().unwrap();
    let noise = [
        "--position-sigma-mm",
        "0.02",
        "--orientation-sigma-rad",
        "1e-4",
    ];
    let (mut covered, mut total) = (0, 0);
    for seed in 1..=5u64 {
        let s = seed.to_string();
        let h = (100 + seed).to_string();
        let (data, truth) = simulate(
            dir.path(),
            &format!("cal{seed}"),
            &[&["--poses", "50", "--seed", &s][..], &noise].concat(),
        );
        let (holdout, _) = simulate(
            dir.path(),
            &format!("hold{seed}"),
            &[&["--poses", "200", "--seed", &h][..], &noise].concat(),
        );
        let c = calibrate(&data, &truth, CalibrationConfig::default());
        let names = c.result.names();
        let nominal = RobotFile::read(Path::new(ROBOT)).unwrap();
        let cal = TrackerData::read(&data).unwrap();
        let fit = reference::fit(&nominal, &names, &cal, 1e6, &vec![0.0; names.len()]).unwrap();
        let reference_file = nominal.with_errors(
            &{
                let mut e =
                    calib_core::ParameterErrors::<f64, nalgebra::Dyn>::zeros_for(nalgebra::Dyn(6));
                for (n, v) in &fit.errors {
                    e.set(calib_core::Parameter::from_name(n, 6).unwrap(), *v);
                }
                e
            },
            std::iter::empty(),
            &[],
            "reference",
            ROBOT,
        );
        let held = TrackerData::read(&holdout).unwrap();
        let rms_core =
            reference::rms_position_error(&identified(&c, dir.path(), "core.toml"), &held);
        let rms_reference = reference::rms_position_error(&reference_file, &held);
        let rms_truth = reference::rms_position_error(&RobotFile::read(&truth).unwrap(), &held);
        let lm = c.result.least_squares.as_ref().unwrap();
        println!(
            "seed {seed}: held-out RMS core {rms_core:.5} mm, reference {rms_reference:.5} mm, truth {rms_truth:.5} mm \
             (ratio {:.3}); cost core {:.10e} reference {:.10e}; sigma {:.4}",
            rms_core / rms_truth,
            lm.cost_final,
            fit.cost,
            lm.sigma_mm
        );
        assert!(
            (rms_core - rms_reference).abs() <= 0.01 * rms_reference,
            "seed {seed}"
        );
        assert!(
            rms_core <= 1.3 * rms_truth,
            "seed {seed}: {rms_core} vs truth {rms_truth}"
        );
        assert!(
            (lm.cost_final - fit.cost).abs() <= 1e-8 * fit.cost,
            "seed {seed}: {} vs {}",
            lm.cost_final,
            fit.cost
        );
        for row in c.truth.as_ref().unwrap() {
            let se = c.result.parameter(&row.name).unwrap().std_error.unwrap();
            total += 1;
            if row.difference.abs() <= 3.0 * se {
                covered += 1;
            }
        }
    }
    println!("true value within 3 standard errors: {covered} of {total}");
    assert!(
        covered as f64 >= 0.95 * total as f64,
        "{covered} of {total}"
    );
}

#[test]
fn lm_from_nominal_reaches_the_reference_cost() {
    let dir = tempfile::tempdir().unwrap();
    let (data, truth) = simulate(
        dir.path(),
        "d",
        &[
            "--poses",
            "32",
            "--position-sigma-mm",
            "0.05",
            "--orientation-sigma-rad",
            "2e-4",
            "--seed",
            "11",
        ],
    );
    let lm = CalibrationConfig {
        method: Method::Lm,
        ..CalibrationConfig::default()
    };
    let c = calibrate(&data, &truth, lm);
    assert_eq!(c.report().generations, 0);
    let names = c.result.names();
    let fit = reference::fit(
        &RobotFile::read(Path::new(ROBOT)).unwrap(),
        &names,
        &TrackerData::read(&data).unwrap(),
        1e6,
        &[0.0; 24],
    )
    .unwrap();
    let core = c.result.least_squares.as_ref().unwrap().cost_final;
    println!("lm cost {core:.12e}, reference {:.12e}", fit.cost);
    assert!((core - fit.cost).abs() <= 1e-8 * fit.cost);
    for (name, value) in &fit.errors {
        let ours = c.result.parameter(name).unwrap().value;
        let se = c.result.parameter(name).unwrap().std_error.unwrap();
        assert!(
            (ours - value).abs() <= 1e-3 * se,
            "{name}: {ours} vs {value} (se {se})"
        );
    }
}

#[test]
fn huber_loss_survives_two_outliers_and_flags_them() {
    let dir = tempfile::tempdir().unwrap();
    let (data, truth) = simulate(
        dir.path(),
        "d",
        &[
            "--poses",
            "40",
            "--position-sigma-mm",
            "0.02",
            "--orientation-sigma-rad",
            "1e-4",
            "--seed",
            "21",
        ],
    );
    let rms = |c: &Calibration, angles: bool| -> f64 {
        let rows: Vec<f64> = c
            .truth
            .as_ref()
            .unwrap()
            .iter()
            .filter(|r| (r.unit == "rad") == angles)
            .map(|r| r.difference)
            .collect();
        (rows.iter().map(|d| d * d).sum::<f64>() / rows.len() as f64).sqrt()
    };
    let clean = calibrate(&data, &truth, CalibrationConfig::default());
    // Shift two poses by 5 mm along x.
    let text = std::fs::read_to_string(&data).unwrap();
    let shifted: Vec<String> = text
        .lines()
        .map(|line| {
            if line.starts_with("P005,") || line.starts_with("P017,") {
                let mut f: Vec<String> = line.split(',').map(String::from).collect();
                f[7] = (f[7].parse::<f64>().unwrap() + 5.0).to_string();
                f.join(",")
            } else {
                line.to_string()
            }
        })
        .collect();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, shifted.join("\n")).unwrap();
    let l2 = calibrate(&bad, &truth, CalibrationConfig::default());
    // Scale: about 3 times the typical clean pose residual (0.17 mm here).
    let huber_config = CalibrationConfig {
        loss: LossChoice::Huber,
        loss_scale_mm: Some(0.5),
        ..CalibrationConfig::default()
    };
    let huber = calibrate(&bad, &truth, huber_config);
    println!(
        "length RMS error clean {:.2e} l2 {:.2e} huber {:.2e}; angle clean {:.2e} l2 {:.2e} huber {:.2e}",
        rms(&clean, false),
        rms(&l2, false),
        rms(&huber, false),
        rms(&clean, true),
        rms(&l2, true),
        rms(&huber, true)
    );
    assert!(rms(&huber, false) <= 2.0 * rms(&clean, false));
    assert!(rms(&huber, true) <= 2.0 * rms(&clean, true));
    assert!(
        rms(&l2, false) > 2.0 * rms(&clean, false),
        "the outliers should hurt plain least squares"
    );
    let flagged: Vec<&str> = huber
        .result
        .outliers
        .iter()
        .map(|o| o.id.as_str())
        .collect();
    assert_eq!(flagged, ["P005", "P017"]);
    assert!(l2.result.outliers.is_empty());
}

/// Position-only data of a point on the flange's axis (the simulated ER10L-C10's tool): joint 6
/// does not move it, so the default identification set leaves out what then acts alike or not at
/// all, and `check` says so; the calibration needs no `--auto-mask`.
#[test]
fn position_only_data_of_a_point_on_the_last_axis() {
    let dir = tempfile::tempdir().unwrap();
    let (data, truth) = simulate(
        dir.path(),
        "d",
        &[
            "--poses",
            "32",
            "--position-only",
            "--position-sigma-mm",
            "0.02",
            "--seed",
            "1",
        ],
    );
    let report = check(&data);
    assert_eq!((report.parameters, report.rank), (20, 20));
    assert!(report.undetermined.is_empty());
    let reflector = report.reflector_on_last_axis.as_ref().unwrap();
    assert!(reflector.distance_mm < 1e-9, "{}", reflector.distance_mm);
    let left_out: Vec<String> = reflector
        .not_identified
        .iter()
        .map(|u| format!("{} {}", u.parameter, u.status))
        .collect();
    assert_eq!(
        left_out,
        [
            "dd5 redundant",
            "dtheta5 redundant",
            "dalpha6 not identifiable",
            "dtheta6 not identifiable"
        ]
    );
    let partners = |i: usize| -> Vec<String> {
        reflector.not_identified[i]
            .with
            .iter()
            .map(|w| w.0.to_string())
            .collect()
    };
    assert_eq!(
        (partners(0), partners(1)),
        (vec!["dalpha5".to_string()], vec!["da5".to_string()])
    );
    assert!(
        report.text().contains("reflector 0.0 mm from the last joint's axis (below 10 mm)")
            && report.text().contains("not identified (kept nominal): dd5 (acts like dalpha5), dtheta5 (acts like da5), dalpha6 (does not move it), dtheta6 (does not move it)"),
        "{}",
        report.text()
    );

    let c = calibrate(&data, &truth, CalibrationConfig::default());
    assert!(c.report().dropped.is_empty());
    assert_eq!(c.result.parameters.len(), 20);
    let sigma = c.result.least_squares.as_ref().unwrap().sigma_mm;
    // At the noise floor: the residual standard deviation is the tracker's 0.02 mm.
    assert!((0.015..0.025).contains(&sigma), "sigma {sigma}");
    let after = c.result.calibration.after.position_mm.mean;
    assert!(after < 0.05, "mean position error after {after} mm");
}

#[test]
fn full_poses_determine_all_24_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let (data, _) = simulate(dir.path(), "d", &["--poses", "32"]);
    let report = check(&data);
    assert_eq!(report.rank, 24);
    let condition = report.condition_number.unwrap();
    println!(
        "scaled condition number {condition:.3}, O1 {:.4}",
        report.observability_index
    );
    assert!((2.0..10.0).contains(&condition), "{condition}");
    assert!(report.undetermined.is_empty());
}

#[test]
fn too_few_poses_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let (data, _) = simulate(dir.path(), "d", &["--poses", "3"]);
    let files = (ROBOT, data.to_str().unwrap(), None);
    let e = common::calibrate_files(files, CalibrationConfig::default(), None)
        .err()
        .unwrap()
        .to_string();
    assert_eq!(
        e,
        "3 poses give 18 equations, fewer than the 24 identified parameters"
    );
}
