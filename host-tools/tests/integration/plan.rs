//! Measurement planning (issue 18) on the real UR10 data: poses planned from joint values and
//! the nominal model only, "measured" by taking the dataset's measurement of each chosen pose,
//! calibrated, and judged on poses no plan could see.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use crate::common;
use common::{calib, ok};

use host_tools::calibration::{self, CalibrationConfig, ErrorModel, HoldOut, Method};
use host_tools::io::profile::DataProfile;
use host_tools::io::robot_file::RobotFile;
use host_tools::io::tracker_data::{Role, TrackerData};
use host_tools::measurement::dataset::Dataset;
use host_tools::planning::{
    self, Candidates, Measure, Noise, PlanModel, PlanRequest, PlanSettings,
};
use std::collections::HashMap;
use std::path::Path;

const ROBOT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml");
const SERIES_B: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv"
);
const SERIES_A: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/ipa-ur10-lasertracker/series-a-grid.csv"
);
const SERIES_D: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/data/ipa-ur10-lasertracker/series-d-iso-cubes.csv"
);
const PROFILE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/profiles/ipa-ur10-lasertracker.toml"
);
const POSITION: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/profiles/ipa-ur10-lasertracker-position.toml"
);

/// Noise levels assumed by the plans, per position coordinate (mm) and orientation axis (deg):
/// those `calib plan --noise-from` takes from a previous calibration of the same robot, 50
/// random poses of Series A (another session; `calibrate --robot robots/ur10.toml --data
/// data/ipa-ur10-lasertracker/series-a-grid.csv --profile profiles/ipa-ur10-lasertracker.toml
/// --method lm --validate 0.9958 --report a.json`; `plan_measure_calibrate_end_to_end` takes
/// them from that report and checks these values). The robot's non-geometric error, which the model cannot describe, acts as noise.
const NOISE_MM: f64 = 0.2956;
const NOISE_DEG: f64 = 0.0369;

fn load(data: &str) -> Dataset {
    let profile = DataProfile::load(Some(Path::new(PROFILE))).unwrap();
    Dataset::load_with(Path::new(ROBOT), Path::new(data), &profile).unwrap()
}

/// Calibrates the poses of `fit` (least squares, the tool's defaults otherwise) and returns the
/// mean held-out position error on `validation`, mm.
fn held_out_mean(fit: &Dataset, validation: &Dataset) -> f64 {
    let config = CalibrationConfig {
        method: Method::Lm,
        ..CalibrationConfig::default()
    };
    held_out_mean_with(fit, validation, &config)
}

/// [`held_out_mean`] with `config`.
fn held_out_mean_with(fit: &Dataset, validation: &Dataset, config: &CalibrationConfig) -> f64 {
    let result = calibration::calibrate(fit.clone(), Some(validation.clone()), config).unwrap();
    result.result.validation.unwrap().after.position_mm.mean
}

/// The poses of `dataset` at `indices`, in the dataset's order.
fn subset(dataset: &Dataset, indices: &[usize]) -> Dataset {
    dataset.partition(indices).1
}

/// One split's numbers: held-out means (mm) of the planned and random sets on the split's
/// validation poses, and the plans' predictions against their verification poses.
struct Split {
    planned: [f64; 3],
    random: [f64; 2],
    /// Per plan size: (predicted verification mean, 95 % range, measured verification mean).
    verification: Vec<(f64, (f64, f64), f64)>,
}

/// Split `seed` of `dataset`: 60 % pool, 40 % validation. Plans of 12, 30 and 50 poses (cores
/// as [`core`], 15 verification poses) from the pool's joint values; random sets of 12 and 50
/// pool poses.
fn split(dataset: &Dataset, seed: u64) -> Split {
    let (pool, validation) = host_tools::measurement::dataset::split(dataset, 0.4, seed).unwrap();
    let candidates: Vec<(String, Vec<f64>)> = pool
        .data
        .records
        .iter()
        .map(|r| (r.id.clone(), r.q.clone()))
        .collect();
    let file = pool.robot.file.clone();
    let mut planned = [0.0; 3];
    let mut verification = Vec::new();
    for (slot, poses) in [12, 30, 50].into_iter().enumerate() {
        let settings = PlanSettings {
            poses,
            core: core(poses),
            verify: planning::DEFAULT_VERIFY,
            min_distance_deg: planning::DEFAULT_MIN_DISTANCE_DEG,
            measure: Measure::Pose,
            model: PlanModel::Geometric,
            noise_mm: NOISE_MM,
            noise_deg: NOISE_DEG,
            k: calib_core::identify::objective::DEFAULT_K,
            seed,
        };
        let p = planning::plan(&file, Path::new(ROBOT), &candidates, &settings).unwrap();
        let of = |role: Role| -> Vec<usize> { p.of_role(role).map(|q| q.candidate).collect() };
        let mut fitted = of(Role::Core);
        fitted.extend(of(Role::Fill));
        assert_eq!(fitted.len(), poses);
        let fit = subset(&pool, &fitted);
        planned[slot] = held_out_mean(&fit, &validation);
        let verify = subset(&pool, &of(Role::Verify));
        let measured = held_out_mean(&fit, &verify);
        let v = p.prediction.verification.unwrap();
        verification.push((v.mean_mm, (v.low_mm, v.high_mm), measured));
    }
    let order = host_tools::measurement::dataset::shuffled(pool.readings.len(), seed + 1000);
    let random = [12, 50].map(|n| {
        let mut indices = order[..n].to_vec();
        indices.sort_unstable();
        held_out_mean(&subset(&pool, &indices), &validation)
    });
    Split {
        planned,
        random,
        verification,
    }
}

/// The core of a plan of `poses`: all of them at 12 and 30 (pure D-optimal, `--core 30`), the
/// default 12 at 50 (the rest random fill). At 30 poses the default core of 12 with 18 fill
/// poses gave 0.4523 mm on Series B, above random-50's 0.4308 mm (measured once, this test with
/// that core).
fn core(poses: usize) -> usize {
    match poses {
        30 => 30,
        n => n.min(planning::DEFAULT_CORE),
    }
}

fn average(values: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = values.collect();
    v.iter().sum::<f64>() / v.len() as f64
}

/// The comparison on one series over 5 splits; returns the averages
/// `[planned 12, planned 30, planned 50, random 12, random 50]`.
fn compare(name: &str, data: &str) -> [f64; 5] {
    let dataset = load(data);
    let splits: Vec<Split> = (0..5).map(|seed| split(&dataset, seed)).collect();
    println!(
        "{name}: held-out mean position error on the 40 % validation poses, mm (6-DoF, least squares)"
    );
    println!("split  plan-12  plan-30  plan-50  random-12  random-50");
    for (seed, s) in splits.iter().enumerate() {
        println!(
            "{seed:>5}  {:>7.4}  {:>7.4}  {:>7.4}  {:>9.4}  {:>9.4}",
            s.planned[0], s.planned[1], s.planned[2], s.random[0], s.random[1]
        );
    }
    let averages = [
        average(splits.iter().map(|s| s.planned[0])),
        average(splits.iter().map(|s| s.planned[1])),
        average(splits.iter().map(|s| s.planned[2])),
        average(splits.iter().map(|s| s.random[0])),
        average(splits.iter().map(|s| s.random[1])),
    ];
    println!(
        " mean  {:>7.4}  {:>7.4}  {:>7.4}  {:>9.4}  {:>9.4}",
        averages[0], averages[1], averages[2], averages[3], averages[4]
    );
    println!(
        "{name}: the plans' 15 verification poses, predicted (noise {NOISE_MM} mm) against measured mean, mm"
    );
    for (seed, s) in splits.iter().enumerate() {
        for ((predicted, (low, high), measured), poses) in s.verification.iter().zip([12, 30, 50]) {
            println!(
                "  split {seed}, plan-{poses}: predicted {predicted:.4} ({low:.4} ... {high:.4}), measured {measured:.4}{}",
                if measured > high {
                    "  (above the range)"
                } else {
                    ""
                }
            );
            assert!(predicted.is_finite() && *measured > 0.0);
        }
    }
    averages
}

/// Series B: the targets.
#[test]
fn series_b_planned_poses_against_random_poses() {
    let [p12, p30, p50, r12, r50] = compare("Series B", SERIES_B);
    assert!(p12 <= 0.52, "plan-12 {p12} mm, target 0.52 mm");
    assert!(
        p12 < r12,
        "plan-12 {p12} mm not better than random-12 {r12} mm"
    );
    assert!(p30 <= r50, "plan-30 {p30} mm above random-50 {r50} mm");
    assert!(p50 <= r50, "plan-50 {p50} mm above random-50 {r50} mm");
}

/// Series D: the same comparison, reported (no target was set in advance); the sanity bound is
/// the nominal model's error with fitted frames (above 1 mm on these data).
#[test]
fn series_d_planned_poses_against_random_poses() {
    let averages = compare("Series D", SERIES_D);
    assert!(
        averages.iter().all(|a| *a > 0.0 && *a < 1.0),
        "{averages:?}"
    );
}

/// `calib plan` -> the tracker fills the file -> `calibrate` holds out the verification poses
/// and puts their error next to the prediction. An unfilled plan is refused.
#[test]
fn plan_measure_calibrate_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    // The noise levels from a previous calibration: 50 poses of Series A.
    let report = dir.path().join("series-a.json");
    ok(&calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        SERIES_A,
        "--profile",
        PROFILE,
        "--method",
        "lm",
        "--validate",
        "0.9958",
        "--report",
        report.to_str().unwrap(),
    ]));
    // 30 fitted and 15 verify poses of Series B, 6-DoF, with the noise levels of `noise`
    // (`calib plan --candidates SERIES_B --profile PROFILE --poses 30 --measure pose --out OUT`).
    let file = RobotFile::read(Path::new(ROBOT)).unwrap();
    let plan_series_b = |noise: Noise, out: &Path| {
        let candidates = Candidates::File {
            path: SERIES_B.into(),
            profile: Some(PROFILE.into()),
        };
        let request = PlanRequest::new(candidates, 30, Measure::Pose, noise);
        let plan = request.plan(&file, Path::new(ROBOT)).unwrap();
        std::fs::write(out, plan.csv(&[]).unwrap()).unwrap();
        plan
    };
    let plan_csv = dir.path().join("plan.csv");
    let residuals = calibration::Report::read(&report)
        .unwrap()
        .residuals(&report)
        .unwrap();
    let p = plan_series_b(Noise::Residuals(residuals), &plan_csv);
    println!("{}", p.text());
    let noise = (p.prediction.noise_mm, p.prediction.noise_deg.unwrap());
    println!("noise from the Series A calibration: {noise:?}");
    assert!((noise.0 - NOISE_MM).abs() < 5e-5 && (noise.1 - NOISE_DEG).abs() < 5e-5);
    assert_eq!(p.poses.len(), 45);
    assert_eq!(p.of_role(Role::Core).count(), 12);
    assert_eq!(p.of_role(Role::Verify).count(), 15);
    assert!(p.joint_travel_deg < p.joint_travel_unordered_deg);

    let lm = CalibrationConfig {
        method: Method::Lm,
        ..CalibrationConfig::default()
    };
    // `calib calibrate --robot ROBOT --data DATA --method lm`: a plan's verify poses held out.
    let calibrate = |data: &Path| {
        let files = (ROBOT, data.to_str().unwrap(), None);
        common::calibrate_files(files, lm.clone(), None)
    };
    let unfilled = calibrate(&plan_csv).map(|_| ()).unwrap_err().to_string();
    assert!(unfilled.contains("not been measured"), "{unfilled}");

    // The tracker software fills the measurement columns (here: from the dataset, by id).
    let profile = DataProfile::load(Some(Path::new(PROFILE))).unwrap();
    let measured: HashMap<String, _> = TrackerData::read_with(Path::new(SERIES_B), &profile)
        .unwrap()
        .records
        .into_iter()
        .map(|r| (r.id.clone(), r))
        .collect();
    let fill = |from: &Path, to: &Path| {
        let text = std::fs::read_to_string(from).unwrap();
        let mut filled = String::new();
        for line in text.lines() {
            let fields: Vec<&str> = line.split(',').collect();
            match measured.get(fields[0]) {
                Some(r) if !line.starts_with('#') => {
                    let q = nalgebra::UnitQuaternion::from_matrix(&r.rotation.unwrap());
                    let mut row: Vec<String> = fields[..8].iter().map(|s| s.to_string()).collect();
                    row.extend(r.position.iter().map(f64::to_string));
                    row.extend([q.w, q.i, q.j, q.k].map(|v| v.to_string()));
                    filled.push_str(&row.join(","));
                }
                _ => filled.push_str(line),
            }
            filled.push('\n');
        }
        std::fs::write(to, filled).unwrap();
    };
    let filled_csv = dir.path().join("measured.csv");
    fill(&plan_csv, &filled_csv);
    let c = calibrate(&filled_csv).unwrap();
    assert_eq!(c.result.calibration.poses, 30);
    let v = c.result.validation.as_ref().unwrap();
    assert_eq!(v.poses, 15);
    let check = c.result.plan_check.as_ref().unwrap();
    let predicted = p.prediction.verification.unwrap();
    assert_eq!(check.predicted, predicted);
    assert_eq!(check.measured_mean_mm, v.after.position_mm.mean);
    assert_eq!(check.gap, check.measured_mean_mm > predicted.high_mm);
    // A pose's leverage is between 0 and its 6 rows.
    assert_eq!(check.largest_leverage.len(), 3);
    assert!(check.leverage_note.is_none());
    assert!(
        check
            .largest_leverage
            .iter()
            .all(|(_, h, _)| h.is_some_and(|h| h > 0.0 && h <= 6.0))
    );
    assert!(
        c.text().contains("plan check: 15 verification poses"),
        "{}",
        c.text()
    );
    println!("{}", check.text());
    // The same plan with a noise level far below the data's: the measured verification error is
    // above the predicted range, flagged with the poses to look at first.
    let optimistic_csv = dir.path().join("optimistic-plan.csv");
    let given = Noise::Given {
        mm: 0.02,
        deg: Some(0.002),
    };
    let optimistic = plan_series_b(given, &optimistic_csv);
    let same = |p: &planning::Plan| p.poses.iter().map(|q| q.candidate).collect::<Vec<_>>();
    assert_eq!(
        same(&optimistic),
        same(&p),
        "the noise level changes the prediction only"
    );
    let measured_optimistic = dir.path().join("measured-optimistic.csv");
    fill(&optimistic_csv, &measured_optimistic);
    let c = calibrate(&measured_optimistic).unwrap();
    let check = c.result.plan_check.as_ref().unwrap();
    assert!(
        check.gap && check.measured_mean_mm > check.predicted.high_mm,
        "{check:?}"
    );
    assert!(
        c.text().contains("WARNING: the verification error is"),
        "{}",
        c.text()
    );
    assert!(c.text().contains("largest leverage:") && c.text().contains("largest residual:"));
    // The certificate's caveats carry the gap too (issue 41).
    let caveat = (c.result.caveats.iter())
        .find(|k| k.kind == host_tools::analysis::caveats::CaveatKind::PlanCheck)
        .unwrap();
    assert!(
        caveat.text.starts_with(&format!(
            "the plan's 15 verification poses measured {:.4} mm mean error, above the {:.4} mm",
            check.measured_mean_mm, check.predicted.high_mm
        )),
        "{}",
        caveat.text
    );
    assert!(
        c.text()
            .contains("caveats:\n  - the plan's 15 verification poses"),
        "{}",
        c.text()
    );
    // The poses listed by residual are the fitted poses of the largest residuals.
    let mut residuals: Vec<f64> = c.result.poses.iter().map(|p| p.after_mm).collect();
    residuals.sort_by(|a, b| b.total_cmp(a));
    let listed: Vec<f64> = check.largest_residual.iter().map(|r| r.2).collect();
    assert_eq!(listed, residuals[..3].to_vec());
    println!("{}", check.text());
    // With a hold-out of its own, the file's verify poses would be silently mixed: refused.
    let filled = common::read(ROBOT, filled_csv.to_str().unwrap(), None).unwrap();
    let mut session = common::session(filled, CalibrationConfig::default());
    session.hold_out = HoldOut::Fraction {
        fraction: 0.2,
        seed: 0,
    };
    let both = (session.run()).map(|_| ()).unwrap_err().to_string();
    assert!(both.contains("verify poses are the hold-out"), "{both}");
}

/// The largest gap between the readings of `poses` in each joint, as a fraction of the joint's
/// range over `all` (its ends count as readings of the range), averaged over the joints.
fn coverage_gap(all: &Dataset, poses: &[usize]) -> f64 {
    let mut total = 0.0;
    for j in 0..6 {
        let readings: Vec<f64> = all.data.records.iter().map(|r| r.q[j]).collect();
        let (low, high) = readings
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
        let mut chosen: Vec<f64> = poses.iter().map(|i| readings[*i]).collect();
        chosen.push(low);
        chosen.push(high);
        chosen.sort_by(f64::total_cmp);
        let gap = chosen.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
        total += gap / (high - low);
    }
    total / 6.0
}

/// Item 4, joint maps: 50 poses planned for the maps (core 12, fill covering each joint's range)
/// against 50 planned for the geometry (random fill) and 50 random poses, calibrated with
/// `--model joint-maps` (least squares, `--auto-mask`, positions only, as the joint-map tests),
/// 5 splits of Series B, held out on 40 %.
#[test]
fn series_b_plan_for_joint_maps() {
    let profile = DataProfile::load(Some(Path::new(POSITION))).unwrap();
    let dataset = Dataset::load_with(Path::new(ROBOT), Path::new(SERIES_B), &profile).unwrap();
    let config = CalibrationConfig {
        method: Method::Lm,
        model: ErrorModel::JointMaps,
        auto_mask: true,
        ..CalibrationConfig::default()
    };
    println!(
        "Series B, joint maps, 50 poses: held-out mean position error (mm) and mean largest gap in each joint's readings (fraction of its range)"
    );
    println!("split  plan-maps      plan-geometry  random");
    let mut sums = [[0.0; 2]; 3];
    for seed in 0..5 {
        let (pool, validation) =
            host_tools::measurement::dataset::split(&dataset, 0.4, seed).unwrap();
        let candidates: Vec<(String, Vec<f64>)> = (pool.data.records.iter())
            .map(|r| (r.id.clone(), r.q.clone()))
            .collect();
        let mut row = Vec::new();
        for model in [PlanModel::JointMaps, PlanModel::Geometric] {
            let settings = PlanSettings {
                poses: 50,
                core: planning::DEFAULT_CORE,
                verify: planning::DEFAULT_VERIFY,
                min_distance_deg: planning::DEFAULT_MIN_DISTANCE_DEG,
                measure: Measure::Position,
                model,
                noise_mm: NOISE_MM,
                noise_deg: NOISE_DEG,
                k: calib_core::identify::objective::DEFAULT_K,
                seed,
            };
            let p =
                planning::plan(&pool.robot.file, Path::new(ROBOT), &candidates, &settings).unwrap();
            let mut fitted: Vec<usize> = (p.poses.iter())
                .filter(|q| q.role != Role::Verify)
                .map(|q| q.candidate)
                .collect();
            fitted.sort_unstable();
            row.push((
                held_out_mean_with(&subset(&pool, &fitted), &validation, &config),
                coverage_gap(&pool, &fitted),
            ));
        }
        let order = host_tools::measurement::dataset::shuffled(pool.readings.len(), seed + 1000);
        let mut random = order[..50].to_vec();
        random.sort_unstable();
        row.push((
            held_out_mean_with(&subset(&pool, &random), &validation, &config),
            coverage_gap(&pool, &random),
        ));
        println!(
            "{seed:>5}  {:.4} {:.3}   {:.4} {:.3}   {:.4} {:.3}",
            row[0].0, row[0].1, row[1].0, row[1].1, row[2].0, row[2].1
        );
        for (sum, (mean, gap)) in sums.iter_mut().zip(&row) {
            sum[0] += mean / 5.0;
            sum[1] += gap / 5.0;
        }
        // The fill covers each joint's range: its largest gap is below random poses'.
        assert!(row[0].1 < row[2].1, "split {seed}: {row:?}");
    }
    println!(
        " mean  {:.4} {:.3}   {:.4} {:.3}   {:.4} {:.3}",
        sums[0][0], sums[0][1], sums[1][0], sums[1][1], sums[2][0], sums[2][1]
    );
    // Well below the geometric calibration's 0.43 mm (README: joint maps from 50 random poses
    // 0.233 mm on all others).
    assert!(sums.iter().all(|s| s[0] < 0.35), "{sums:?}");
}

/// What `calib plan` cannot stand behind it refuses, saying what to change, and writes nothing.
#[test]
fn plan_refuses_what_it_cannot_stand_behind() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let refused = |args: &[&str]| {
        let all = [
            &["plan", "--robot", ROBOT, "--measure", "pose"][..],
            &["--noise-mm", "0.05", "--out", out.to_str().unwrap()][..],
            args,
        ]
        .concat();
        let run = calib(&all);
        assert_eq!(run.status.code(), Some(1), "{args:?} was planned");
        let message = String::from_utf8_lossy(&run.stderr).into_owned();
        assert!(!out.exists(), "{message}");
        message
    };
    let few = refused(&["--generate", "30", "--poses", "20"]);
    assert!(
        few.contains("30 candidates cannot give 20 fitted and 15 verification poses"),
        "{few}"
    );
    // 5 6-DoF poses: 30 equations for the UR10's 30 parameters, no redundancy left.
    let square = refused(&["--generate", "100", "--poses", "5"]);
    assert!(square.contains("plan at least 6 poses"), "{square}");
    let far = refused(&[
        "--generate",
        "100",
        "--poses",
        "20",
        "--box-mm",
        "5000,6000,0,1,0,1",
    ]);
    assert!(far.contains("widen the box"), "{far}");
    let crowded = refused(&[
        "--generate",
        "40",
        "--poses",
        "20",
        "--min-distance-deg",
        "250",
    ]);
    assert!(crowded.contains("lower --min-distance-deg"), "{crowded}");
    // A 7-joint robot is planned for joint maps too (issue 37: maps for any joint count).
    let iiwa = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/kuka-iiwa14.toml");
    let all = [
        "plan",
        "--robot",
        iiwa,
        "--measure",
        "pose",
        "--noise-mm",
        "0.05",
        "--out",
        out.to_str().unwrap(),
        "--generate",
        "200",
        "--poses",
        "40",
        "--model",
        "joint-maps",
    ];
    let planned = ok(&calib(&all));
    assert!(planned.contains("for joint maps"), "{planned}");
    assert!(out.exists());
}

/// The leverages of a fit are the diagonal of its hat matrix: they sum to the number of
/// parameters (its trace), here the UR10's 30 with 6-DoF data and 25 with positions only.
#[test]
fn leverages_sum_to_the_parameter_count() {
    let dataset = load(SERIES_B);
    let q: Vec<Vec<f64>> = dataset
        .data
        .records
        .iter()
        .take(40)
        .map(|r| r.q.clone())
        .collect();
    for (measure, parameters) in [(Measure::Pose, 30.0), (Measure::Position, 25.0)] {
        let k = calib_core::identify::objective::DEFAULT_K;
        let h = planning::leverages(&dataset.robot.file, Path::new(ROBOT), &q, measure, k).unwrap();
        let sum: f64 = h.iter().sum();
        println!("{measure:?}: 40 poses, leverages sum to {sum:.12}");
        assert!((sum - parameters).abs() < 1e-9, "{sum}");
        assert!(
            h.iter()
                .all(|h| *h > 0.0 && *h <= measure.rows() as f64 + 1e-12)
        );
    }
}

/// Issue 39, N8 and N17: counts beyond any candidate file are refused with the reason instead of
/// overflowing (a panic), and a `--core` above `--poses` is refused instead of cut to it.
#[test]
fn huge_counts_and_a_core_above_the_poses_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let out = out.to_str().unwrap();
    let plan = |extra: &[&str]| {
        let mut args = vec![
            "plan",
            "--robot",
            ROBOT,
            "--generate",
            "100",
            "--measure",
            "position",
            "--noise-mm",
            "0.02",
            "--out",
            out,
        ];
        args.extend_from_slice(extra);
        common::calib(&args)
    };
    let huge = "18446744073709551615";
    for (extra, expected) in [
        (vec!["--poses", huge], format!("cannot give {huge} fitted")),
        (
            vec!["--poses", "30", "--verify", huge],
            format!("30 fitted and {huge} verification"),
        ),
        (
            vec!["--poses", "30", "--core", "31"],
            "--core 31 is more than --poses 30".to_string(),
        ),
    ] {
        let result = plan(&extra);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(1), "{extra:?}: {stderr}");
        assert!(stderr.contains(&expected), "{extra:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(!Path::new(out).exists());
    }
}

/// Issue 39, N15 and N17: `--generate` draws within limits beyond half a turn (joint 1 limited to
/// [190, 350] deg: every candidate was clamped to 180 deg and then refused as outside the limits,
/// "<memory>:1"); a candidate file's configuration outside the limits is refused with the file's
/// line; `--box-mm` with `--candidates` (silently ignored) and `--k` outside [1e-6, 1e12]
/// mm^2/rad^2 (1e300 accepted, 0 blamed on the noise or the data's rank) are refused, naming the
/// option.
#[test]
fn limits_beyond_half_a_turn_and_options_that_were_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let robot = d.join("robot.toml");
    let text = std::fs::read_to_string(ROBOT).unwrap();
    std::fs::write(
        &robot,
        text.replacen(
            "limits_deg = [-360.0, 360.0]",
            "limits_deg = [190.0, 350.0]",
            1,
        ),
    )
    .unwrap();
    let robot = robot.to_str().unwrap();
    let out = d.join("plan.csv");
    let out = out.to_str().unwrap();
    let plan = |extra: &[&str]| {
        let mut args = vec![
            "plan",
            "--robot",
            robot,
            "--measure",
            "pose",
            "--noise-mm",
            "0.02",
            "--poses",
            "30",
            "--out",
            out,
        ];
        args.extend_from_slice(extra);
        common::calib(&args)
    };
    common::ok(&plan(&["--generate", "300"]));
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .from_path(out)
        .unwrap();
    let column = reader
        .headers()
        .unwrap()
        .iter()
        .position(|h| h == "q1_deg")
        .unwrap();
    let mut rows = 0;
    for record in reader.records() {
        let q1: f64 = record.unwrap()[column].parse().unwrap();
        assert!((190.0..=350.0).contains(&q1), "q1 = {q1} deg");
        rows += 1;
    }
    assert!(
        rows >= 30,
        "{rows} poses: 30 fitted and the verification poses"
    );
    std::fs::remove_file(out).unwrap();
    // A candidate outside the limits, on the file's third line.
    let candidates = d.join("candidates.csv");
    let mut text = String::from("id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n");
    for i in 0..40 {
        let q1 = if i == 1 {
            100.0
        } else {
            200.0 + 3.0 * i as f64
        };
        text.push_str(&format!(
            "c{i},{q1},{},{},{},{},{}\n",
            i * 2,
            -i,
            i * 3,
            10 + i,
            i
        ));
    }
    std::fs::write(&candidates, text).unwrap();
    let candidates = candidates.to_str().unwrap();
    for (extra, expected, status) in [
        (
            vec!["--candidates", candidates],
            "candidates.csv:3: candidate c1: q1 = 100.0000 deg is outside the joint limits [190, 350] deg",
            1,
        ),
        (
            vec!["--candidates", candidates, "--box-mm", "0,1,0,1,0,1"],
            "--box-mm selects among generated candidates",
            1,
        ),
        (
            vec!["--generate", "100", "--k", "1e300"],
            "invalid value '1e300' for '--k <K>': 1e300 mm^2/rad^2 is outside [1e-6, 1e12]",
            2,
        ),
        (
            vec!["--generate", "100", "--k", "0"],
            "invalid value '0' for '--k <K>'",
            2,
        ),
    ] {
        let result = plan(&extra);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(status), "{extra:?}: {stderr}");
        assert!(stderr.contains(expected), "{extra:?}: {stderr}");
        assert!(!stderr.contains("<memory>"), "{stderr}");
        assert!(!Path::new(out).exists());
    }
}

/// Issue 40, item 3: plan -> robot program -> tracker export -> merge -> calibrate, on the bundled
/// Series B rows. The plan of 30 poses (and 15 verification poses) from Series B's joints is
/// written as URScript and as joint targets in the planned order; the "tracker export" is Series
/// B's own file cut to the planned rows in that order (no id column, joints and points in the
/// IPA format); `calib merge --by order` pairs them, keeps the roles and the prediction, and the
/// result calibrates with the verification poses held out. Rows out of order, a missing row and
/// pairing by a missing id column are refused with the row.
#[test]
fn plan_to_robot_program_and_back_by_merge() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (data, profile, ur10) = (SERIES_B, PROFILE, ROBOT);
    let path = |name: &str| d.join(name).to_str().unwrap().to_string();
    common::ok(&common::calib(&[
        "plan",
        "--robot",
        ur10,
        "--candidates",
        data,
        "--profile",
        profile,
        "--poses",
        "30",
        "--measure",
        "pose",
        "--noise-mm",
        "0.3",
        "--out",
        &path("plan.csv"),
        "--urscript",
        &path("plan.script"),
        "--joint-targets",
        &path("targets.csv"),
    ]));
    let plan = TrackerData::read_joints(&d.join("plan.csv"), &DataProfile::default()).unwrap();
    assert_eq!(plan.records.len(), 45);
    // The program: one movej per pose in the plan's order, at the plan's joints (rad).
    let script = std::fs::read_to_string(d.join("plan.script")).unwrap();
    let moves: Vec<Vec<f64>> = script
        .lines()
        .filter_map(|l| l.trim().strip_prefix("movej(["))
        .map(|l| {
            l.split(']')
                .next()
                .unwrap()
                .split(", ")
                .map(|v| v.parse().unwrap())
                .collect()
        })
        .collect();
    assert_eq!(moves.len(), 45);
    for (q, r) in moves.iter().zip(&plan.records) {
        assert!(
            q.iter().zip(&r.q).all(|(a, b)| (a - b).abs() < 1e-8),
            "{q:?} {:?}",
            r.q
        );
    }
    assert!(script.ends_with("end\ncalib_plan()\n") && script.matches("sleep(2)").count() == 45);
    let targets = std::fs::read_to_string(d.join("targets.csv")).unwrap();
    let ids: Vec<&str> = targets
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    let planned: Vec<&str> = plan.records.iter().map(|r| r.id.as_str()).collect();
    assert_eq!(ids, planned);
    // The export: Series B's rows of the planned poses (the plan's ids are their lines), in order.
    let source: Vec<&str> = std::fs::read_to_string(data)
        .unwrap()
        .leak()
        .lines()
        .collect();
    let export = |order: &[usize]| -> String {
        let mut text = format!("{}\n", source[0]);
        for &i in order {
            let line: usize = planned[i].parse().unwrap();
            text.push_str(source[line - 1]);
            text.push('\n');
        }
        text
    };
    let in_order: Vec<usize> = (0..45).collect();
    std::fs::write(d.join("export.csv"), export(&in_order)).unwrap();
    let merge = |export: &str, by: &str, out: &str| {
        common::calib(&[
            "merge",
            "--plan",
            &path("plan.csv"),
            "--measured",
            &path(export),
            "--profile",
            profile,
            "--by",
            by,
            "--out",
            &path(out),
        ])
    };
    assert!(common::ok(&merge("export.csv", "order", "measured.csv")).contains("merged 45"));
    let merged = TrackerData::read(&d.join("measured.csv")).unwrap();
    let measured = TrackerData::read_with(
        &d.join("export.csv"),
        &DataProfile::read(Path::new(profile)).unwrap(),
    )
    .unwrap();
    assert_eq!(merged.planned, plan.planned);
    for ((m, p), e) in merged
        .records
        .iter()
        .zip(&plan.records)
        .zip(&measured.records)
    {
        assert_eq!((&m.id, m.role), (&p.id, p.role));
        assert!(
            m.position
                .iter()
                .zip(&e.position)
                .all(|(a, b)| (a - b).abs() < 1e-9)
        );
        let (a, b) = (m.rotation.unwrap(), e.rotation.unwrap());
        assert!((a - b).norm() < 1e-12);
    }
    assert_eq!(
        merged
            .records
            .iter()
            .filter(|r| r.role == Some(Role::Verify))
            .count(),
        15
    );
    let text = common::ok(&common::calib(&[
        "calibrate",
        "--robot",
        ur10,
        "--data",
        &path("measured.csv"),
        "--out",
        &path("m.toml"),
    ]));
    assert!(text.contains("plan check: 15 verification poses"), "{text}");
    // Refusals, nothing written.
    let mut swapped = in_order.clone();
    swapped.swap(2, 3);
    std::fs::write(d.join("swapped.csv"), export(&swapped)).unwrap();
    std::fs::write(d.join("short.csv"), export(&in_order[..44])).unwrap();
    for (file, by, says) in [
        ("swapped.csv", "order", "swapped.csv:4: q"),
        ("short.csv", "order", "has 44 points and the plan"),
        (
            "export.csv",
            "id",
            "has no id column naming the planned poses",
        ),
    ] {
        let out = merge(file, by, "x.csv");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(says), "{says}: {stderr}");
        assert!(!d.join("x.csv").exists());
    }
}

/// Issue 40, item 3 (the README's real-cell rehearsal, which CI also runs as written): a plan of
/// 40 poses (and 15 verification poses) generated for the UR10 is "measured" by `calib simulate
/// --joints-from` (random true errors, the tracker 2.5 m away, 0.02 mm and 0.1 mrad noise): the
/// points keep the plan's ids and joints; merged by id and calibrated, the verification poses are
/// held out and miss by less than the plan predicted at its assumed 0.05 mm noise.
#[test]
fn a_plan_rehearsed_by_simulation_calibrates_with_its_verification_held_out() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |args: &[&str]| common::ok(&common::calib_in(d, args));
    run(&[
        "plan",
        "--robot",
        ROBOT,
        "--generate",
        "2000",
        "--poses",
        "40",
        "--measure",
        "pose",
        "--noise-mm",
        "0.05",
        "--out",
        "plan.csv",
        "--joint-targets",
        "program.csv",
    ]);
    run(&[
        "simulate",
        "--robot",
        ROBOT,
        "--joints-from",
        "plan.csv",
        "--errors",
        "random",
        "--tracker-xyz-mm",
        "2500,300,-400",
        "--tracker-rpy-deg",
        "0,0,120",
        "--position-sigma-mm",
        "0.02",
        "--orientation-sigma-rad",
        "0.0001",
        "--out",
        "tracker.csv",
        "--truth-out",
        "truth.toml",
    ]);
    let plan = TrackerData::read_joints(&d.join("plan.csv"), &DataProfile::default()).unwrap();
    let measured = TrackerData::read(&d.join("tracker.csv")).unwrap();
    assert_eq!(measured.records.len(), plan.records.len());
    for (m, p) in measured.records.iter().zip(&plan.records) {
        assert_eq!(m.id, p.id);
        assert!(m.q.iter().zip(&p.q).all(|(a, b)| (a - b).abs() < 1e-12));
    }
    run(&[
        "merge",
        "--plan",
        "plan.csv",
        "--measured",
        "tracker.csv",
        "--by",
        "id",
        "--out",
        "measured.csv",
    ]);
    let text = run(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        "measured.csv",
        "--out",
        "cell.toml",
    ]);
    assert!(text.contains("plan check: 15 verification poses"), "{text}");
    let measured_mm: f64 = text
        .split("measured mean position error ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    let predicted_high_mm: f64 = text
        .split("95 % range ")
        .nth(1)
        .and_then(|t| t.split(" ... ").nth(1))
        .and_then(|t| t.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    println!(
        "verification poses: {measured_mm} mm measured, predicted at most {predicted_high_mm} mm"
    );
    assert!(measured_mm < predicted_high_mm, "{text}");
    // The program corrected (`compensate --joint-targets`): each pose the nominal model meant at
    // the program's joints, reached by the identified robot. Checked with the independent
    // reference kinematics of the identified file (cell.toml) at the joints written: the nominal
    // pose at the program's joints missed by the residual each row states (within 1e-6 mm),
    // at most 0.002 mm; targets the robot cannot be corrected
    // at (near a singularity) are refused with the reason. (The true robot of the simulation is
    // not the check: with data in a tracker's frame, dd1, dtheta1 and the flange-side errors are
    // absorbed by the registration and the probe, and are not part of the controller's model.)
    let out = common::calib_in(
        d,
        &[
            "compensate",
            "--robot",
            ROBOT,
            "--params",
            "cell.toml",
            "--targets",
            "program.csv",
            "--joint-targets",
            "--max-correction-mm",
            "15",
            "--max-correction-deg",
            "2",
            "--out",
            "program-compensated.csv",
        ],
    );
    let summary = common::ok(&out);
    println!("{summary}");
    use host_tools::analysis::reference;
    use host_tools::io::robot_file::RobotFile;
    let no_errors = |file: &RobotFile| reference::model(file, &[], &[0.0; 6], &[0.0; 6]);
    let nominal = no_errors(&RobotFile::read(Path::new(ROBOT)).unwrap());
    let identified = no_errors(&RobotFile::read(&d.join("cell.toml")).unwrap());
    let mut reader = csv::Reader::from_path(d.join("program-compensated.csv")).unwrap();
    let (mut compensated, mut worst) = (0, 0.0f64);
    for (record, planned) in reader.records().zip(&plan.records) {
        let record = record.unwrap();
        assert_eq!(&record[0], planned.id.as_str());
        let status = &record[9];
        if status != "ok" {
            assert!(
                status.contains("singularity") || status.contains("no convergence"),
                "{status}"
            );
            continue;
        }
        let q: Vec<f64> = (1..=6)
            .map(|j| record[j].parse::<f64>().unwrap().to_radians())
            .collect();
        let e = reference::pose_error(&nominal.forward(&planned.q), &identified.forward(&q));
        let miss = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
        let stated: f64 = record[7].parse().unwrap();
        assert!((miss - stated).abs() < 1e-6, "{miss} {stated}");
        worst = worst.max(miss);
        compensated += 1;
    }
    println!(
        "program corrected: {compensated} of {} poses, worst miss of the identified robot {worst:.2e} mm",
        plan.records.len()
    );
    // 47 of 55 with the plan above the base's mounting plane (issue 52; 52 before, with 26 of
    // the poses below it): the refused ones lie within degrees of a singularity.
    assert!(compensated >= 45 && worst < 2e-3, "{compensated} {worst}");
    // A program's joints outside the nominal limits, and joint targets said to be in the
    // tracker's frame, are refused; nothing written.
    std::fs::write(
        d.join("beyond.csv"),
        "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\nP1,0,-90,90,-90,-90,0\nP2,400,-90,90,-90,-90,0\n",
    )
    .unwrap();
    for (targets, extra, says) in [
        (
            "beyond.csv",
            None,
            "beyond.csv:3: q1 = 400.0000 deg is outside the joint limits",
        ),
        (
            "program.csv",
            Some(["--targets-frame", "tracker"]),
            "the targets are the nominal poses of the joints, in the base frame",
        ),
    ] {
        let mut args = vec![
            "compensate",
            "--robot",
            ROBOT,
            "--params",
            "cell.toml",
            "--targets",
            targets,
            "--joint-targets",
            "--out",
            "x.csv",
        ];
        args.extend(extra.iter().flatten());
        let out = common::calib_in(d, &args);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains(says), "{says}: {stderr}");
        assert!(!d.join("x.csv").exists());
    }
}

/// Issue 40, item 3: merging by timestamp. The tracker measured continuously (points while the
/// robot moved between poses too) and exported its points sorted by value, not by time; the
/// robot's log says when it stood at each planned pose. Each planned pose gets the point measured
/// nearest its logged time; the points taken in motion are left out and counted. A pose with no
/// point within the tolerance, two poses nearest one point, a log whose joints are not the plan's,
/// and files without a time column are refused, naming the row.
#[test]
fn merge_by_time_pairs_each_logged_pose_with_the_point_measured_then() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let write = |name: &str, text: &str| std::fs::write(d.join(name), text).unwrap();
    write(
        "plan.csv",
        "# plan prediction: verification_mean_mm=0.1 low_mm=0.05 high_mm=0.2 noise_mm=0.02\n\
         id,role,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n\
         p1,core,0,-90,90,-90,-90,0\n\
         p2,fill,10,-80,80,-90,-90,0\n\
         p3,verify,20,-70,70,-90,-90,0\n\
         p4,core,30,-60,60,-90,-90,0\n",
    );
    // The points the tracker took at the four poses (x = 100 * pose), and three in motion.
    write(
        "export.csv",
        "time_ms,x_mm,y_mm,z_mm\n\
         40020,400,1,2\n\
         15000,150,1,2\n\
         10200,100,1,2\n\
         35000,350,1,2\n\
         20100,200,1,2\n\
         25000,250,1,2\n\
         29700,300,1,2\n",
    );
    let log = |rows: &str| format!("id,time_s,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n{rows}");
    write(
        "log.csv",
        &log("p1,10,0,-90,90,-90,-90,0\n\
              p2,20,10,-80,80,-90,-90,0\n\
              p3,30,20,-70,70,-90,-90,0\n\
              p4,40,30,-60,60,-90,-90,0\n"),
    );
    let merge = |export: &str, log: Option<&str>, extra: &[&str]| {
        let mut args = vec![
            "merge",
            "--plan",
            "plan.csv",
            "--measured",
            export,
            "--by",
            "time",
        ];
        if let Some(log) = log {
            args.extend(["--robot-log", log]);
        }
        args.extend(["--time-tolerance-s", "0.5", "--out", "measured.csv"]);
        args.extend(extra);
        common::calib_in(d, &args)
    };
    assert!(common::ok(&merge("export.csv", Some("log.csv"), &[])).contains("merged 4"));
    let merged = TrackerData::read(&d.join("measured.csv")).unwrap();
    let got: Vec<(&str, f64, Option<Role>)> = merged
        .records
        .iter()
        .map(|r| (r.id.as_str(), r.position[0], r.role))
        .collect();
    assert_eq!(
        got,
        [
            ("p1", 100.0, Some(Role::Core)),
            ("p2", 200.0, Some(Role::Fill)),
            ("p3", 300.0, Some(Role::Verify)),
            ("p4", 400.0, Some(Role::Core))
        ]
    );
    assert!((merged.records[1].q[0].to_degrees() - 10.0).abs() < 1e-12);
    let text = std::fs::read_to_string(d.join("measured.csv")).unwrap();
    assert!(
        text.contains("# 3 points of the export were measured at no logged pose"),
        "{text}"
    );
    assert!(
        text.contains("# plan prediction: verification_mean_mm=0.1"),
        "{text}"
    );
    std::fs::remove_file(d.join("measured.csv")).unwrap();
    // Refusals, nothing written.
    write(
        "late.csv",
        &log("p1,10,0,-90,90,-90,-90,0\n\
              p2,20,10,-80,80,-90,-90,0\n\
              p3,31,20,-70,70,-90,-90,0\n\
              p4,40,30,-60,60,-90,-90,0\n"),
    );
    write(
        "twice.csv",
        &log("p1,10,0,-90,90,-90,-90,0\n\
              p2,10.4,10,-80,80,-90,-90,0\n\
              p3,30,20,-70,70,-90,-90,0\n\
              p4,40,30,-60,60,-90,-90,0\n"),
    );
    write(
        "elsewhere.csv",
        &log("p1,10,0,-90,90,-90,-90,0\n\
              p2,20,10,-80,80,-90,-90,0\n\
              p3,30,20,-70,75,-90,-90,0\n\
              p4,40,30,-60,60,-90,-90,0\n"),
    );
    write(
        "untimed.csv",
        "x_mm,y_mm,z_mm\n100,1,2\n200,1,2\n300,1,2\n400,1,2\n",
    );
    for (export, log, says) in [
        (
            "export.csv",
            Some("late.csv"),
            "late.csv:4: the robot stood at the planned pose p3 at 31 s, but export.csv has no point within \
             --time-tolerance-s 0.5 of it (the nearest, line 8, is 1.300 s away)",
        ),
        (
            "export.csv",
            Some("twice.csv"),
            "export.csv:4: the point is the nearest in time to two planned poses, p1 (log line 2) and p2 (log line 3)",
        ),
        (
            "export.csv",
            Some("elsewhere.csv"),
            "elsewhere.csv:4: q3 = 75.0000 deg, but the planned pose p3 it is paired with has 70.0000 deg",
        ),
        // (--time-tolerance-s, given by `merge` here, needs the log: issue 52, V10.)
        ("export.csv", None, "--robot-log"),
        (
            "untimed.csv",
            Some("log.csv"),
            "untimed.csv has no time column",
        ),
    ] {
        let out = merge(export, log, &[]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        // A usage error (the options themselves) exits with 2, a refused input with 1.
        let code = if log.is_none() { 2 } else { 1 };
        assert_eq!(out.status.code(), Some(code), "{stderr}");
        assert!(stderr.contains(says), "{says}: {stderr}");
        assert!(!d.join("measured.csv").exists());
    }
}

/// Issue 52 (V8, V10): the URScript's speed, acceleration and settle time are bounded by what a
/// controller accepts (no 301-digit literal in a program), and refused without `--urscript`,
/// which alone uses them; nothing is written either way.
#[test]
fn urscript_settings_are_bounded_and_need_urscript() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let script = dir.path().join("plan.script");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "plan",
            "--robot",
            ROBOT,
            "--generate",
            "100",
            "--poses",
            "20",
            "--measure",
            "position",
            "--noise-mm",
            "0.02",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        common::calib(&args)
    };
    let s = script.to_str().unwrap();
    for (extra, says) in [
        (
            vec!["--urscript", s, "--speed-rad-s", "1e300"],
            "outside (0, 3.2] rad/s",
        ),
        (
            vec!["--urscript", s, "--speed-rad-s", "0"],
            "outside (0, 3.2] rad/s",
        ),
        (
            vec!["--urscript", s, "--settle-s", "1e300"],
            "outside (0, 600] s",
        ),
        (
            vec!["--urscript", s, "--acceleration-rad-s2", "-1"],
            "outside (0, 40] rad/s^2",
        ),
        (vec!["--settle-s", "3"], "--urscript"),
        (vec!["--speed-rad-s", "0.2"], "--urscript"),
        (vec!["--acceleration-rad-s2", "0.2"], "--urscript"),
    ] {
        let result = run(&extra);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(!result.status.success(), "{extra:?}");
        assert!(stderr.contains(says), "{extra:?}: {stderr}");
        assert!(!out.exists() && !script.exists(), "{extra:?}");
    }
    let result = run(&["--urscript", s, "--speed-rad-s", "1.0", "--settle-s", "0.5"]);
    assert!(
        result.status.success(),
        "{}",
        String::from_utf8_lossy(&result.stderr)
    );
    let program = std::fs::read_to_string(&script).unwrap();
    assert!(program.contains("v=1"), "{program}");
}

/// A plan of 20 poses (and 15 verification poses) of the bundled robot in `d` (`plan.csv`) and its
/// simulated measurement (`tracker.csv`, with the plan's ids, in plan order; `truth.toml`).
fn plan_and_measure(d: &Path) {
    let path = |name: &str| d.join(name).to_str().unwrap().to_string();
    common::ok(&common::calib(&[
        "plan",
        "--robot",
        ROBOT,
        "--generate",
        "200",
        "--poses",
        "20",
        "--measure",
        "pose",
        "--noise-mm",
        "0.05",
        "--out",
        &path("plan.csv"),
    ]));
    common::ok(&common::calib(&[
        "simulate",
        "--robot",
        ROBOT,
        "--joints-from",
        &path("plan.csv"),
        "--errors",
        "random",
        "--out",
        &path("tracker.csv"),
        "--truth-out",
        &path("truth.toml"),
    ]));
}

/// Issue 52 (V4): an export whose id column names the plan's poses and contradicts its order
/// (two neighbours swapped) is refused by `merge --by order`, naming the line, instead of pairing
/// points with the wrong poses; `--by id` pairs it; an export in plan order passes `--by order`.
#[test]
fn merge_by_order_checks_the_ids_it_has() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = |name: &str| d.join(name).to_str().unwrap().to_string();
    plan_and_measure(d);
    let merge = |measured: &str, by: &str| {
        common::calib(&[
            "merge",
            "--plan",
            &path("plan.csv"),
            "--measured",
            &path(measured),
            "--by",
            by,
            "--out",
            &path("merged.csv"),
        ])
    };
    common::ok(&merge("tracker.csv", "order"));
    // Rows 3 and 4 of the export swapped (lines: comments, header, then the rows).
    let text = std::fs::read_to_string(d.join("tracker.csv")).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    let first = lines.iter().position(|l| !l.starts_with('#')).unwrap() + 1;
    lines.swap(first + 2, first + 3);
    std::fs::write(d.join("swapped.csv"), lines.join("\n") + "\n").unwrap();
    std::fs::remove_file(d.join("merged.csv")).unwrap();
    let refused = merge("swapped.csv", "order");
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success());
    assert!(
        stderr.contains(&format!("swapped.csv:{}:", first + 3)) && stderr.contains("merge --by id"),
        "{stderr}"
    );
    assert!(!d.join("merged.csv").exists());
    common::ok(&merge("swapped.csv", "id"));
}

/// Issue 52 (V7): `merge --by time` takes a robot log without joint columns (`time_s,id`, as help
/// and USAGE say) and ISO 8601 timestamps, as tracker software writes them, in the log and the
/// export; every planned pose gets the point measured 0.2 s after the log says the robot stood
/// there (checked by its measured position, the simulated export's own row).
#[test]
fn merge_by_time_takes_a_log_without_joints_and_iso_8601_times() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let path = |name: &str| d.join(name).to_str().unwrap().to_string();
    plan_and_measure(d);
    let plan = TrackerData::read_joints(&d.join("plan.csv"), &DataProfile::default()).unwrap();
    let stamp = |i: usize, extra_ds: usize| {
        let tenths = i * 100 + extra_ds;
        format!(
            "2026-11-27T10:{:02}:{:02}.{}Z",
            tenths / 600,
            (tenths / 10) % 60,
            tenths % 10
        )
    };
    let mut log = String::from("time_s,id\n");
    for (i, r) in plan.records.iter().enumerate() {
        log.push_str(&format!("{},{}\n", stamp(i, 0), r.id));
    }
    std::fs::write(d.join("log.csv"), log).unwrap();
    // The export: the simulated rows in plan order with a time column 0.2 s after the log's.
    let text = std::fs::read_to_string(d.join("tracker.csv")).unwrap();
    let mut export = String::new();
    let mut row = 0;
    for line in text.lines() {
        if line.starts_with('#') {
            continue;
        }
        if export.is_empty() {
            export.push_str(&format!("{line},time_s\n"));
        } else {
            export.push_str(&format!("{line},{}\n", stamp(row, 2)));
            row += 1;
        }
    }
    assert_eq!(row, plan.records.len());
    std::fs::write(d.join("export.csv"), export).unwrap();
    common::ok(&common::calib(&[
        "merge",
        "--plan",
        &path("plan.csv"),
        "--measured",
        &path("export.csv"),
        "--by",
        "time",
        "--robot-log",
        &path("log.csv"),
        "--out",
        &path("merged.csv"),
    ]));
    let merged = TrackerData::read_with(&d.join("merged.csv"), &DataProfile::default()).unwrap();
    let simulated =
        TrackerData::read_with(&d.join("tracker.csv"), &DataProfile::default()).unwrap();
    assert_eq!(merged.records.len(), plan.records.len());
    for (m, s) in merged.records.iter().zip(&simulated.records) {
        assert_eq!(m.id, s.id);
        assert_eq!(m.position, s.position);
    }
}
