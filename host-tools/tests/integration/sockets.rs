//! Calibration without an instrument on real data (issue 54, first figures): the MUKCa sockets
//! of two Franka Pandas (bundled with their licence in data/mukca-sockets/), a ball on the
//! flange held in two sockets 50 mm apart from 20-31 configurations each, joint readings only.
//! The geometry is fitted on one placement of the sockets by the core's common-point kind
//! (`calib_core::identify::common_point`, least squares from the nominal Panda) and judged on
//! the other placements by the authors' protocol: the mean distance of the ball points from
//! their socket's mean (MAE, after their outlier rule) and the error of the 50 mm distance, with
//! and without that distance in the fit.

use calib_core::identify::common_point::{CommonPoints, KnownDistance, Touch};
use calib_core::identify::lm::{LeastSquares, LmResult, LmSettings};
use calib_core::model::JointVec;
use calib_core::model::parameters::{FrameParameter, JointParameter};
use calib_core::{Kinematics, Parameter, ParameterErrors, ParameterSet, Robot};
use host_tools::io::robot_file::RobotFile;
use nalgebra::Dyn;
use std::path::Path;

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/mukca-sockets");
const PANDA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/franka-panda.toml");

/// The authors' ball: `ball_link` of their `panda.urdf`, in the flange frame (`panda_link8`: the
/// hand turned -45 deg about z, the TCP 103.4 mm along it, the ball 30.13 mm further and 0.08 mm
/// aside), mm.
fn ball_mm() -> [f64; 3] {
    let (x, y, z) = (
        7.773732033005863e-2,
        -4.214022515884392e-2,
        30.128297908475325,
    );
    let c = std::f64::consts::FRAC_1_SQRT_2;
    [c * x + c * y, -c * x + c * y, 103.4 + z]
}

/// The nominal Panda with the authors' ball as its tool.
fn panda_with_ball(dir: &Path) -> Robot<f64, Dyn> {
    let ball = ball_mm();
    let text = std::fs::read_to_string(PANDA).unwrap();
    let with_ball = format!(
        "{text}\n[tool]\nxyz_mm = [{}, {}, {}]\nrpy_deg = [0.0, 0.0, 0.0]\n",
        ball[0], ball[1], ball[2]
    );
    let path = dir.join("panda-ball.toml");
    std::fs::write(&path, with_ball).unwrap();
    RobotFile::read(&path)
        .unwrap()
        .to_model(&path)
        .unwrap()
        .robot
}

/// The configurations of one socket file (radians, one per line, no header), read by the
/// library's reader of the layout.
fn configurations(robot: &str, placement: &str, hole: u16) -> Vec<Vec<f64>> {
    let path = format!("{DATA}/{robot}/{placement}/hole_{hole}.csv");
    let socket = host_tools::io::sockets::read_socket(Path::new(&path), 7).unwrap();
    socket.readings.into_iter().map(|r| r.q_rad).collect()
}

/// The touches of both sockets of a placement (socket 0, then socket 1).
fn touches(robot: &str, placement: &str) -> Vec<Touch<f64, Dyn>> {
    (0..2)
        .flat_map(|hole| {
            configurations(robot, placement, hole)
                .into_iter()
                .map(move |q| Touch::new(&JointVec::from_slice(&q).unwrap(), hole, 1.0).unwrap())
        })
        .collect()
}

/// What one placement's touches can determine of a 7-joint arm in our convention (standard DH):
/// the joints' parameters but joint 1's `theta` and `d` (they turn and lift the whole arm, the
/// sockets along) and joint 7's (after the last axis: the ball's offset takes them), and `dd5`
/// only with a known length (`scale`; without one the scale is free, and one length fixed holds
/// it); the ball's offset.
fn identifiable(robot: &Robot<f64, Dyn>, scale: bool) -> ParameterSet<Dyn, Dyn> {
    let mut mask = ParameterSet::<Dyn, Dyn>::default_for(robot).unwrap().mask();
    let joint = |joint, kind| Parameter::Joint { joint, kind };
    let all = [
        JointParameter::A,
        JointParameter::Alpha,
        JointParameter::Theta,
        JointParameter::D,
        JointParameter::Beta,
    ];
    for kind in [JointParameter::Theta, JointParameter::D] {
        mask.set(joint(1, kind), false);
    }
    for kind in all {
        mask.set(joint(7, kind), false);
    }
    mask.set(joint(5, JointParameter::D), scale);
    for axis in [FrameParameter::Tx, FrameParameter::Ty, FrameParameter::Tz] {
        mask.set(Parameter::Tool(axis), true);
    }
    ParameterSet::from_mask(&mask).unwrap()
}

/// The geometry of `panda` with the parameters `set` fitted to `touches` and the known
/// distances `gauges` by least squares from the nominal model, and the fit.
fn fit(
    panda: &Robot<f64, Dyn>,
    set: &ParameterSet<Dyn, Dyn>,
    touches: &[Touch<f64, Dyn>],
    gauges: &[KnownDistance<f64>],
) -> (Kinematics<f64, Dyn>, LmResult<f64, Dyn>) {
    let fixed = ParameterErrors::zeros_for(panda.joint_count());
    let problem = CommonPoints::new(panda, &fixed, set.clone(), touches)
        .unwrap()
        .with_distances(gauges)
        .unwrap();
    let fit = LeastSquares::new(&problem)
        .solve(&set.zeros(), &LmSettings::default())
        .unwrap();
    (problem.kinematics(&fit.x).unwrap(), fit)
}

/// The sockets' known distance: 50 mm (the authors' caliper), weight 4 (balls scattered about
/// 0.1 mm, the distance known to 0.05 mm: `(0.1 / 0.05)^2`), between a placement's sockets 0, 1.
const GAUGE: KnownDistance<f64> = KnownDistance {
    points: [0, 1],
    mm: 50.0,
    weight: 4.0,
};

/// The figures of a placement under `model`: (MAE by the authors' rule, MAE of every point,
/// distance error), mm, by the library's `analysis::consistency`. The authors' rule keeps, per
/// socket, the points within 2 interquartile ranges of the quartiles on every axis, and averages
/// the distances from the kept points' mean over both sockets.
fn figures(model: &Kinematics<f64, Dyn>, touches: &[Touch<f64, Dyn>]) -> (f64, f64, f64) {
    let c = host_tools::analysis::consistency::consistency(model, touches, &[GAUGE]);
    assert_eq!(c.sockets.len(), 2);
    assert_eq!(c.distortion_mm.len(), 1);
    (c.authors_mean_mm, c.mean_mm, c.distortion_mm[0].1.abs())
}

/// Fits the geometry on `train` of `robot` and returns, per other placement, (placement, MAE by
/// the authors' rule, MAE of every point, distance error); prints them with the nominal's.
fn train_and_test(
    panda: &Robot<f64, Dyn>,
    robot: &str,
    train: &str,
    gauge: Option<KnownDistance<f64>>,
) -> Vec<(String, f64, f64, f64)> {
    let set = identifiable(panda, gauge.is_some());
    let fixed = ParameterErrors::zeros_for(panda.joint_count());
    let training = touches(robot, train);
    let gauges: Vec<KnownDistance<f64>> = gauge.into_iter().collect();
    let (fitted, fit) = fit(panda, &set, &training, &gauges);
    let nominal = Kinematics::new(panda, &fixed).unwrap();
    let (before, _, _) = figures(&nominal, &training);
    let (after, _, distortion) = figures(&fitted, &training);
    // Measured: 3.315 -> 0.149 (panda_3), 8.207 -> 0.155 (panda_2), 10.338 -> 0.192 mm (panda_1).
    assert!(
        before > 3.0 && after < 0.05 * before,
        "{robot}: {before} -> {after} mm"
    );
    println!(
        "{robot}, trained on {train} ({} touches, {} parameters, {} iterations, {:?}, gauge {gauge:?}): MAE {before:.3} -> {after:.3} mm, distance error {distortion:.3} mm",
        training.len(),
        set.len(),
        fit.iterations,
        fit.stop
    );
    let mut placements: Vec<String> = std::fs::read_dir(format!("{DATA}/{robot}"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|p| p != train)
        .collect();
    placements.sort();
    placements
        .into_iter()
        .map(|placement| {
            let test = touches(robot, &placement);
            let (nominal_mae, _, _) = figures(&nominal, &test);
            let (mae, all, distance) = figures(&fitted, &test);
            println!(
                "  {placement}: MAE {nominal_mae:.3} -> {mae:.3} mm (every point {all:.3} mm), distance error {distance:.3} mm"
            );
            (placement, mae, all, distance)
        })
        .collect()
}

/// The mean over the test placements of (MAE by the authors' rule, MAE of every point).
fn means(results: &[(String, f64, f64, f64)]) -> (f64, f64) {
    let n = results.len() as f64;
    (
        results.iter().map(|r| r.1).sum::<f64>() / n,
        results.iter().map(|r| r.2).sum::<f64>() / n,
    )
}

/// `panda_3` trained on `frontcenter` and `panda_2` on `front_center`, tested on their other
/// placements. The authors' calibrated models reach a test MAE of 0.221 and 0.427 mm (issue 54;
/// a plain geometric model with a weak prior: 0.221 and 0.430 mm). Ours, plain least squares from
/// the nominal Panda without a prior, measured: 0.2209 and 0.4361 mm (every point kept: 0.2395
/// and 0.4592 mm), from 3.3 and 8.2 mm nominal on the training placements; held here within 1 %
/// and 3 % of the authors' figures. Beating them is issue 54's goal, not yet reached.
#[test]
fn pandas_trained_on_one_placement_tested_on_the_others() {
    let dir = tempfile::tempdir().unwrap();
    let panda = panda_with_ball(dir.path());
    for (robot, train, authors, within) in [
        ("panda_3", "frontcenter", 0.221, 1.01),
        ("panda_2", "front_center", 0.427, 1.03),
    ] {
        let results = train_and_test(&panda, robot, train, None);
        let (mae, all) = means(&results);
        println!(
            "{robot}: test MAE {mae:.4} mm (authors' model {authors} mm), every point {all:.4} mm"
        );
        assert!(mae <= authors * within, "{robot}: {mae} mm");
        // Every test placement gains on the nominal model's several millimetres.
        assert!(results.iter().all(|r| r.1 < 1.1), "{results:?}");
    }
}

/// With the sockets' known distance (50 mm; weight 4: balls scattered about 0.1 mm, the
/// distance known to 0.05 mm) the scale is determined, so `dd5` is fitted too, and the distance
/// holds on the training placement: 0.007 and 0.001 mm measured (goal 0.05 mm; 0.010 and 0.136
/// mm without it), the test MAE unchanged (0.2208 and 0.4378 mm) and the test placements'
/// distance errors 0.055 and 0.172 mm on average. Weights 0.25 to 100 measured: training
/// distance error 0.148 -> 0.002 mm (panda_3), test MAE within 0.0007 mm.
#[test]
fn the_known_distance_holds_the_scale() {
    let dir = tempfile::tempdir().unwrap();
    let panda = panda_with_ball(dir.path());
    for (robot, train, authors, within) in [
        ("panda_3", "frontcenter", 0.221, 1.01),
        ("panda_2", "front_center", 0.427, 1.03),
    ] {
        let results = train_and_test(&panda, robot, train, Some(GAUGE));
        let (mae, _) = means(&results);
        assert!(mae <= authors * within, "{robot}: {mae} mm");
    }
}

/// The touches of several placements, each placement's two sockets its own two points (2i and
/// 2i + 1), with each placement's known distance.
fn placements(robot: &str, names: &[&str]) -> (Vec<Touch<f64, Dyn>>, Vec<KnownDistance<f64>>) {
    let mut all = Vec::new();
    let mut gauges = Vec::new();
    for (i, name) in names.iter().enumerate() {
        let base = 2 * i as u16;
        all.extend(touches(robot, name).into_iter().map(|mut t| {
            t.point += base;
            t
        }));
        gauges.push(KnownDistance {
            points: [base, base + 1],
            ..GAUGE
        });
    }
    (all, gauges)
}

/// Each placement of `robot` left out in turn: the test MAE (authors' rule) of the geometry fitted
/// to all the others (their sockets and distances), printed with every point's and the distance
/// error.
fn left_out_maes(panda: &Robot<f64, Dyn>, robot: &str, names: &[&str]) -> Vec<f64> {
    let set = identifiable(panda, true);
    names
        .iter()
        .map(|left_out| {
            let others: Vec<&str> = names.iter().copied().filter(|n| n != left_out).collect();
            let (training, gauges) = placements(robot, &others);
            let (fitted, _) = fit(panda, &set, &training, &gauges);
            let (mae, all, distance) = figures(&fitted, &touches(robot, left_out));
            println!(
                "{robot} without {left_out}: test MAE {mae:.4} mm (every point {all:.4}), distance error {distance:.3} mm"
            );
            mae
        })
        .collect()
}

/// Leave one placement out (issue 54): trained on all other placements (their sockets and
/// distances), tested on the one left out by the authors' protocol, for every placement of
/// `panda_2` and `panda_3` (distance weight 4, `dd5` fitted). Measured, mean / worst test MAE
/// over the placements: `panda_3` 0.1943 / 0.2187 mm (one placement: 0.2208 mm on the others),
/// `panda_2` 0.3579 / 1.0408 mm (0.4378 mm; the worst is `high`, 1.04 mm from one placement or
/// from all eight others alike: that placement disagrees with the rest). Held here: the mean at
/// most the one-placement figure.
#[test]
fn leave_one_placement_out() {
    let dir = tempfile::tempdir().unwrap();
    let panda = panda_with_ball(dir.path());
    for (robot, one_placement) in [("panda_3", 0.2208), ("panda_2", 0.4378)] {
        let mut names: Vec<String> = std::fs::read_dir(format!("{DATA}/{robot}"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let maes = left_out_maes(&panda, robot, &names);
        let mean = maes.iter().sum::<f64>() / maes.len() as f64;
        let worst = maes.iter().fold(0.0f64, |m, v| m.max(*v));
        println!(
            "{robot}: leave one placement out, test MAE mean {mean:.4} mm, worst {worst:.4} mm (one placement: {one_placement} mm)"
        );
        assert!(mean <= one_placement, "{robot}: {mean} mm");
    }
}

/// `panda_1`, reported as measured (issue 54: its placements disagree). Trained on `front`
/// alone its other placements come out at 0.6317 mm (the independent figure: about 0.61);
/// trained on the two others, each left-out placement at 0.9486 (`back-high`), 0.6780 (`front`)
/// and 0.7309 mm (`right`), mean 0.7858 (the issue: about 0.78): more data predict worse. The
/// data say where: `back-high` is predicted worst by every model trained elsewhere (0.86 to 1.04
/// mm), and there the 50 mm between its sockets comes out 0.95 to 1.05 mm off, while a model
/// trained on `back-high` keeps it to 0.04 mm and misses the others by 1.2 to 1.6 mm: that
/// placement's balls do not lie where the other placements' geometry puts them (a tool or ball
/// moved between sessions, or joint deflection the geometry does not model), not scattered
/// outliers (every point kept: the same figures within 0.012 mm).
#[test]
fn panda_1_placements_disagree() {
    let dir = tempfile::tempdir().unwrap();
    let panda = panda_with_ball(dir.path());
    let (front_alone, _) = means(&train_and_test(&panda, "panda_1", "front", Some(GAUGE)));
    let left_out_maes = left_out_maes(&panda, "panda_1", &["back-high", "front", "right"]);
    let mean = left_out_maes.iter().sum::<f64>() / 3.0;
    println!("panda_1: front alone {front_alone:.4} mm, leave one placement out {mean:.4} mm");
    assert!(mean > front_alone + 0.1, "{mean} vs {front_alone}");
    assert!(left_out_maes[0] > left_out_maes[1].max(left_out_maes[2]));
}

/// The library's calibration from touches (`calibration::touches::TouchSession`, what `calib
/// sockets` runs) against the calibration built by hand above: the same parameter set (what
/// touches leave free taken out by the kind, nothing else undetermined with the 50 mm gauge),
/// the gauge weighed by the touches' own scatter, and then the same held-out figures as the hand
/// fit with that weight, to 1e-6 mm (measured: within 2e-9 mm, the solver's stopping tolerance). Without the gauge the analysis finds the scale undetermined
/// and drops one parameter for it.
#[test]
fn the_library_session_calibrates_from_touches() {
    use host_tools::calibration::touches::TouchSession;
    let dir = tempfile::tempdir().unwrap();
    let panda = panda_with_ball(dir.path());
    for (robot, train, authors, within) in [
        ("panda_3", "frontcenter", 0.221, 1.0),
        ("panda_2", "front_center", 0.427, 1.03),
    ] {
        let session = panda_session(robot, train, [0, 1]);
        // The calibration's default drops what the data barely determine (as on tracker data).
        let thinned = session.run().unwrap();
        let held_out_mean = |c: &host_tools::calibration::touches::TouchCalibrated| {
            c.held_out
                .iter()
                .map(|f| f.identified.authors_mean_mm)
                .sum::<f64>()
                / c.held_out.len() as f64
        };
        println!(
            "{robot}: default selection ({} parameters, dropped {:?}, scaled condition {:?} -> {:?}): held-out mean MAE {:.4} mm, training distortion {:.4} mm",
            thinned.fit.parameters.len(),
            thinned.selection.dropped,
            thinned.selection.identifiability.condition_number,
            thinned
                .selection
                .identifiability
                .condition_number_after_drop,
            held_out_mean(&thinned),
            thinned.fitted[0].identified.distortion_mm[0].1
        );
        // Measured: 0.2191 and 0.4380 mm (authors 0.221 and 0.427), training distortion 0.0065
        // and 0.0008 mm (goal: at most 0.05 mm).
        assert!(held_out_mean(&thinned) <= authors * within, "{robot}");
        assert!(thinned.fitted[0].identified.distortion_mm[0].1.abs() < 0.05);
        let session = TouchSession {
            config: host_tools::calibration::CalibrationConfig {
                keep_ill_conditioned: true,
                ..Default::default()
            },
            ..session
        };
        let calibrated = session.run().unwrap();
        let weight = calibrated.gauge_weight.unwrap();
        // The ball placed through the Craig file's flange row, as the hand-built model has it:
        // the nominal figures equal (panda_3 3.315 mm on frontcenter).
        let nominal =
            Kinematics::new(&panda, &ParameterErrors::zeros_for(panda.joint_count())).unwrap();
        let by_hand =
            host_tools::analysis::consistency::consistency(&nominal, &touches(robot, train), &[]);
        assert!(
            (calibrated.fitted[0].nominal.authors_mean_mm - by_hand.authors_mean_mm).abs() < 1e-9
        );
        let sd = calibrated.touch_sd_mm.unwrap();
        println!(
            "{robot}: touch sd {sd:.4} mm, gauge weight {weight:.3}, {} parameters, {} iterations, {:.4} s",
            calibrated.fit.parameters.len(),
            calibrated.fit.least_squares.iterations,
            calibrated.fit.seconds
        );
        assert!(
            calibrated.selection.dropped.is_empty(),
            "{:?} {:?}",
            calibrated.selection.dropped,
            calibrated.selection.identifiability.text()
        );
        let left_free = &calibrated.selection.identifiability.left_free;
        // Joint 1's theta and d and joint 7's five (the file identifies theta, d, a, alpha of
        // joint 7 by default: four), the tool's orientation is not in the file's mask.
        let names: Vec<String> = left_free.iter().map(|f| f.parameter.to_string()).collect();
        assert!(
            names.contains(&"dtheta1".to_string()) && names.contains(&"dd1".to_string()),
            "{names:?}"
        );
        assert!(
            names.iter().all(|n| n.ends_with('1') || n.ends_with('7')),
            "{names:?}"
        );
        let set = identifiable(&panda, true);
        assert_eq!(calibrated.fit.set.parameters(), set.parameters());
        let gauge = KnownDistance { weight, ..GAUGE };
        let (hand, _) = fit(&panda, &set, &touches(robot, train), &[gauge]);
        assert_eq!(
            calibrated.held_out.len() + 1,
            std::fs::read_dir(format!("{DATA}/{robot}"))
                .unwrap()
                .count()
        );
        for figures in &calibrated.held_out {
            let test = touches(robot, &figures.placement);
            let by_hand = host_tools::analysis::consistency::consistency(&hand, &test, &[gauge]);
            let ours = &figures.identified;
            assert!(
                (ours.authors_mean_mm - by_hand.authors_mean_mm).abs() < 1e-6,
                "{} {} {}",
                figures.placement,
                ours.authors_mean_mm,
                by_hand.authors_mean_mm
            );
            assert!((ours.mean_mm - by_hand.mean_mm).abs() < 1e-6);
            assert!(figures.nominal.authors_mean_mm > 1.0);
        }
        let mean = calibrated
            .held_out
            .iter()
            .map(|f| f.identified.authors_mean_mm)
            .sum::<f64>()
            / calibrated.held_out.len() as f64;
        println!("{robot}: held-out mean MAE {mean:.4} mm");
        // Without the gauge the longest length holds the scale (the Panda's d5, 384 mm): the
        // hand-built set without `dd5`.
        let scale_free = TouchSession {
            gauge: None,
            ..session
        }
        .run()
        .unwrap();
        let held: Vec<String> = (scale_free.selection.identifiability.left_free.iter())
            .map(|f| f.parameter.to_string())
            .collect();
        assert!(held.contains(&"dd5".to_string()), "{held:?}");
        assert_eq!(
            scale_free.fit.set.parameters(),
            identifiable(&panda, false).parameters()
        );
    }
}

/// `dinova_1` (Kinova Gen3 lite), its robot imported from the authors' URDF and the ball of their
/// `ball_link` (0.3886, -0.5823, 180.1962 mm from the flange), each placement trained in turn with
/// the 50 mm: the touches scatter 0.77-2.6 mm per coordinate about the best geometry (the
/// Pandas: 0.10-0.11 mm) and the models predict the other placements 3.7-6.2 mm off on average,
/// trained on `front` worse than the nominal model on `lower_left` (9.90 against 5.61 mm):
/// training on one placement over-fits this robot (issue 54; the authors name backlash).
/// Measured and held here: every residual sd above 0.5 mm, every held-out mean above 3 mm.
#[test]
fn dinova_1_over_fits_one_placement() {
    use host_tools::calibration::touches::{Gauge, TouchSession};
    let urdf = format!("{DATA}/urdf/gen3lite.urdf");
    let toml = host_tools::formats::urdf_import::import_urdf_file(
        Path::new(&urdf),
        "kinova_base_link",
        "end_effector_link",
    )
    .unwrap();
    let robot = RobotFile::parse(&toml, Path::new("gen3.toml")).unwrap();
    let placements =
        host_tools::io::sockets::read_layout(Path::new(&format!("{DATA}/dinova_1")), 6).unwrap();
    let mut worse_than_nominal = 0;
    for train in ["front", "left", "lower_left", "raised_back"] {
        let calibrated = TouchSession {
            robot: robot.clone(),
            robot_path: "gen3.toml".into(),
            ball_mm: [0.388606, -0.582285, 180.196206],
            placements: placements.clone(),
            train: vec![train.to_string()],
            gauge: Some(Gauge {
                sockets: [0, 1],
                mm: 50.0,
                sd_mm: 0.05,
            }),
            datums: Vec::new(),
            config: Default::default(),
            compliance: false,
        }
        .run()
        .unwrap();
        let held = &calibrated.held_out;
        let mean = held
            .iter()
            .map(|f| f.identified.authors_mean_mm)
            .sum::<f64>()
            / held.len() as f64;
        worse_than_nominal += (held.iter())
            .filter(|f| f.identified.authors_mean_mm > f.nominal.authors_mean_mm)
            .count();
        println!(
            "dinova_1 trained on {train}: residual sd {:.3} mm, held-out mean {mean:.3} mm, dropped {:?}",
            calibrated.fit.sigma_mm, calibrated.selection.dropped
        );
        assert!(calibrated.fit.sigma_mm > 0.5, "{train}");
        assert!(mean > 3.0, "{train}");
    }
    assert!(worse_than_nominal >= 1);
}

/// A known distance between sockets no placement has is refused, not silently dropped.
#[test]
fn a_distance_between_sockets_nobody_touched_is_refused() {
    let session = panda_session("panda_3", "frontcenter", [0, 2]);
    let e = session.run().unwrap_err();
    assert!(
        matches!(&e, host_tools::Error::InvalidOption { option, .. } if option == "--distance-between"),
        "{e}"
    );
    assert!(
        e.to_string()
            .contains("no placement has both sockets (hole_0.csv and hole_2.csv)"),
        "{e}"
    );
}

/// The library's session of the Panda `robot`'s placements with the authors' ball, trained on
/// `train`, the 50 mm (+- 0.05 mm) between `sockets`, the default settings.
fn panda_session(
    robot: &str,
    train: &str,
    sockets: [u16; 2],
) -> host_tools::calibration::touches::TouchSession {
    host_tools::calibration::touches::TouchSession {
        robot: RobotFile::read(Path::new(PANDA)).unwrap(),
        robot_path: PANDA.into(),
        ball_mm: ball_mm(),
        placements: host_tools::io::sockets::read_layout(Path::new(&format!("{DATA}/{robot}")), 7)
            .unwrap(),
        train: vec![train.to_string()],
        gauge: Some(host_tools::calibration::touches::Gauge {
            sockets,
            mm: 50.0,
            sd_mm: 0.05,
        }),
        datums: Vec::new(),
        config: Default::default(),
        compliance: false,
    }
}

/// Uniform random errors in every parameter of `set` (lengths within 0.3 mm, angles within 1
/// mrad, the ball's offset within 0.5 mm), packed in the set's order.
fn random_truth(set: &ParameterSet<Dyn, Dyn>, seed: u64) -> nalgebra::DVector<f64> {
    use rand::RngExt;
    use rand_core::SeedableRng;
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    nalgebra::DVector::from_iterator(
        set.len(),
        set.parameters().iter().map(|p| {
            let half = match (p, host_tools::analysis::truth::unit_of(*p)) {
                (Parameter::Tool(_), _) => 0.5,
                (_, "mm") => 0.3,
                _ => 1e-3,
            };
            rng.random_range(-half..half)
        }),
    )
}

/// How far a fit's parameters lie from the truth `truth_x` (packed as the fit's set) in its
/// covariance: the Mahalanobis distance (squared) and the largest difference in standard errors.
fn distance_from_truth(
    fit: &host_tools::calibration::fit::KindFit,
    truth_x: &nalgebra::DVector<f64>,
) -> (f64, f64) {
    let estimate =
        nalgebra::DVector::from_iterator(truth_x.len(), fit.parameters.iter().map(|p| p.value));
    let difference = estimate - truth_x;
    let covariance = fit.covariance.clone().unwrap();
    let mahalanobis = (difference.transpose()
        * covariance.clone().cholesky().unwrap().inverse()
        * &difference)[(0, 0)];
    let worst_z = (0..truth_x.len())
        .map(|i| difference[i].abs() / covariance[(i, i)].sqrt())
        .fold(0.0, f64::max);
    (mahalanobis, worst_z)
}

/// The `p` quantile of the chi-squared distribution with `k` degrees of freedom, by Wilson and
/// Hilferty's cube-root approximation (within 1 % for `k` above 10); `z` the normal quantile.
fn chi_squared_quantile(k: f64, z: f64) -> f64 {
    let h = 2.0 / (9.0 * k);
    k * (1.0 - h + z * h.sqrt()).powi(3)
}

/// Simulation with known truth (issue 54): the Panda with uniform random errors in every
/// parameter the real `panda_3` calibration determines (lengths within 0.3 mm, angles within
/// 1 mrad, the ball within 0.5 mm), its touches simulated near the real configurations of the
/// six placements with the ball's play 0.02 and 0.05 mm, sockets 50 mm apart; fitted on
/// `frontcenter` by the library's session. The identified parameters equal the truth within
/// their covariance (Mahalanobis distance below chi-squared's 99.9 % point, no parameter more
/// than four standard errors off) and the consistency predicted on the five held-out placements
/// matches the measured within 20 %.
#[test]
fn simulated_touches_give_back_the_truth_within_their_uncertainty() {
    use host_tools::measurement::simulate_touches::{TouchSimulation, simulate_touches};
    let real_session = panda_session("panda_3", "frontcenter", [0, 1]);
    let real = real_session.run().unwrap();
    let set = real.fit.set.clone();
    let robot = real_session.ball_model().unwrap().robot;
    for (play, seed) in [(0.02, 1u64), (0.05, 2)] {
        let truth_x = random_truth(&set, seed);
        let simulation = TouchSimulation {
            truth: set.unpack(&truth_x).unwrap(),
            play_sd_mm: play,
            gauge: Some(([0, 1], 50.0)),
            planes: Vec::new(),
            seed,
        };
        let simulated = simulate_touches(&robot, &simulation, &real_session.placements).unwrap();
        let session = host_tools::calibration::touches::TouchSession {
            placements: simulated.into_iter().map(|s| s.placement).collect(),
            ..panda_session("panda_3", "frontcenter", [0, 1])
        };
        let fitted = session.run().unwrap();
        assert_eq!(fitted.fit.set.parameters(), set.parameters());
        let (mahalanobis, worst_z) = distance_from_truth(&fitted.fit, &truth_x);
        let limit = chi_squared_quantile(set.len() as f64, 3.09);
        println!(
            "play {play} mm: {} parameters, Mahalanobis {mahalanobis:.2} (99.9 % point {limit:.1}), worst {worst_z:.2} standard errors, residual sd {:.4} mm",
            set.len(),
            fitted.fit.sigma_mm
        );
        assert!(mahalanobis < limit && worst_z < 4.0);
        for f in &fitted.held_out {
            let predicted = f.predicted.unwrap();
            let ratio = f.identified.mean_mm / predicted.mean_mm;
            println!(
                "  {:<12} measured {:.4} mm, predicted {:.4} mm (scatter alone {:.4}): {ratio:.3}",
                f.placement, f.identified.mean_mm, predicted.mean_mm, predicted.scatter_mean_mm
            );
            assert!((ratio - 1.0).abs() < 0.2, "{}: {ratio}", f.placement);
        }
    }
}

/// Leave one placement out through `calib sockets --leave-one-out` (each placement judged by the
/// library's session trained on all the others, 50 mm gauge weighed by the touches' scatter).
/// Measured: `panda_3` mean 0.1943 mm by the authors' rule (one placement, `frontcenter`: 0.2190),
/// every placement within 16 % of its predicted consistency (0.90 to 1.16 times): with five
/// placements the geometry and the touches' scatter explain nearly all that is left. `panda_2` mean 0.3600 mm (one placement:
/// 0.4380), worst `high` at 1.0446 mm against 0.29 predicted: the one placement the others'
/// geometry does not explain (and, fitted with the rest, it inflates the scatter the others are
/// predicted with to about 0.47 mm). Held: the report's figures equal the library's, `panda_3`'s
/// mean below the one-placement figure and each within 20 % of its prediction, `panda_2`'s
/// `high` the only placement more than twice its prediction.
#[test]
fn leave_one_placement_out_through_calib_sockets() {
    let dir = tempfile::tempdir().unwrap();
    for (robot, one_placement) in [("panda_3", 0.2190), ("panda_2", 0.4380)] {
        let report = dir.path().join(format!("{robot}.json"));
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
            .args([
                "sockets",
                "--robot",
                PANDA,
                "--data",
                &format!("{DATA}/{robot}"),
            ])
            .args([
                "--ball-mm",
                "0.025171,-0.084766,133.528298",
                "--distance",
                "50",
            ])
            .args(["--leave-one-out", "--report", report.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains("leave one placement out"), "{text}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        let folds = json["leave_one_out"].as_array().unwrap();
        let mut session = panda_session(robot, "", [0, 1]);
        session.train.clear();
        session.ball_mm = [0.025171, -0.084766, 133.528298];
        let library = session.leave_one_out().unwrap();
        assert_eq!(folds.len(), library.len());
        for (fold, figures) in folds.iter().zip(&library) {
            assert_eq!(fold["placement"], figures.placement.as_str());
            let authors = fold["identified"]["authors_mean_mm"].as_f64().unwrap();
            assert_eq!(authors, figures.identified.authors_mean_mm);
        }
        let mean = library
            .iter()
            .map(|f| f.identified.authors_mean_mm)
            .sum::<f64>()
            / library.len() as f64;
        println!("{robot}: leave one placement out {mean:.4} mm (one placement {one_placement})");
        assert!(mean < one_placement, "{robot}: {mean}");
        let ratio = |f: &host_tools::calibration::touches::PlacementFigures| {
            f.identified.mean_mm / f.predicted.unwrap().mean_mm
        };
        if robot == "panda_3" {
            assert!(library.iter().all(|f| (ratio(f) - 1.0).abs() < 0.2));
        } else {
            let flagged: Vec<&str> = (library.iter())
                .filter(|f| ratio(f) > 2.0)
                .map(|f| f.placement.as_str())
                .collect();
            assert_eq!(flagged, ["high"]);
        }
    }
}

/// Planes (issue 54): the Panda with random errors, its ball pressed on planes through each of
/// the six `panda_3` placements (contacts simulated near the real configurations, spread 160 mm
/// over each plane, the ball's play 0.03 mm along the normal), every placement fitted. Two
/// cases: three planes alone (normals along the base's z, x and y; no distance, so a length
/// holds the scale), and the sockets with their 50 mm and a table top (normal z). The set is the
/// one the selection keeps for the same configurations of the nominal robot; the truth has
/// errors in every parameter of it. The identified parameters equal the truth within their
/// covariance (Mahalanobis distance below chi-squared's 99.9 % point, no parameter more than
/// four standard errors off), and the planes come out flat to the play.
#[test]
fn plane_contacts_give_back_the_truth_within_their_uncertainty() {
    use host_tools::calibration::touches::TouchSession;
    use host_tools::measurement::simulate_touches::{TouchSimulation, simulate_touches};
    let template = panda_session("panda_3", "frontcenter", [0, 1]);
    let robot = template.ball_model().unwrap().robot;
    let cases: [(&str, Vec<[f64; 3]>, bool); 2] = [
        (
            "three planes",
            vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            false,
        ),
        ("sockets and a table", vec![[0.0, 0.0, 1.0]], true),
    ];
    for (case, normals, sockets) in cases {
        let session_of = |simulation: &TouchSimulation| {
            let simulated = simulate_touches(&robot, simulation, &template.placements).unwrap();
            TouchSession {
                placements: (simulated.into_iter())
                    .map(|s| {
                        let mut placement = s.placement;
                        if !sockets {
                            placement.sockets.clear();
                        }
                        placement
                    })
                    .collect(),
                train: Vec::new(),
                gauge: template.gauge.filter(|_| sockets),
                ..template.clone()
            }
        };
        let nominal = TouchSimulation {
            truth: ParameterErrors::zeros_for(robot.joint_count()),
            play_sd_mm: 0.03,
            gauge: Some(([0, 1], 50.0)),
            planes: normals.clone(),
            seed: 7,
        };
        let set = session_of(&nominal).run().unwrap().fit.set;
        let truth_x = random_truth(&set, 7);
        let simulation = TouchSimulation {
            truth: set.unpack(&truth_x).unwrap(),
            ..nominal
        };
        let fitted = session_of(&simulation).run().unwrap();
        assert_eq!(fitted.fit.set.parameters(), set.parameters(), "{case}");
        let (mahalanobis, worst_z) = distance_from_truth(&fitted.fit, &truth_x);
        let limit = chi_squared_quantile(set.len() as f64, 3.09);
        let flat = (fitted.fitted.iter())
            .flat_map(|f| &f.identified.planes)
            .map(|p| p.mean_mm)
            .fold(0.0, f64::max);
        let before = (fitted.fitted.iter())
            .flat_map(|f| &f.nominal.planes)
            .map(|p| p.mean_mm)
            .fold(0.0, f64::max);
        println!(
            "{case}: {} parameters (left free {}), Mahalanobis {mahalanobis:.2} (99.9 % point {limit:.1}), worst {worst_z:.2} standard errors, residual sd {:.4} mm, planes flat to {flat:.4} mm (nominal {before:.4})",
            set.len(),
            fitted.selection.identifiability.left_free.len(),
            fitted.fit.sigma_mm
        );
        assert!(mahalanobis < limit && worst_z < 4.0, "{case}");
        // The mean distance of a Gaussian's values from 0 is sqrt(2/pi) sd: 0.024 mm for 0.03.
        assert!(flat < 0.03 && before > 0.1, "{case}: {flat} {before}");
    }
}

/// Plane contacts through `calib sockets`: the Panda's ball pressed on three planes at each
/// `panda_3` placement (simulated, 0.3 mm off in every length of the arm, 0.03 mm play), written
/// as our CSV with the column `plane`, read and calibrated by the command: the text reports each
/// plane's flatness, the identified one at the play, the nominal one not.
#[test]
fn calib_sockets_calibrates_from_plane_contacts() {
    use host_tools::measurement::simulate_touches::{TouchSimulation, simulate_touches};
    let template = panda_session("panda_3", "frontcenter", [0, 1]);
    let robot = template.ball_model().unwrap().robot;
    let mut truth = ParameterErrors::zeros_for(robot.joint_count());
    for joint in 2..=6 {
        truth.set(
            Parameter::Joint {
                joint,
                kind: JointParameter::D,
            },
            0.3,
        );
    }
    let simulation = TouchSimulation {
        truth,
        play_sd_mm: 0.03,
        gauge: None,
        planes: vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        seed: 3,
    };
    let simulated = simulate_touches(&robot, &simulation, &template.placements).unwrap();
    let mut csv =
        String::from("placement,plane,q1_rad,q2_rad,q3_rad,q4_rad,q5_rad,q6_rad,q7_rad\n");
    for s in &simulated {
        for (k, plane) in s.placement.planes.iter().enumerate() {
            for r in &plane.readings {
                let q: Vec<String> = r.q_rad.iter().map(|v| format!("{v:?}")).collect();
                csv.push_str(&format!("{},{k},{}\n", s.placement.name, q.join(",")));
            }
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("planes.csv");
    std::fs::write(&data, csv).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
        .args([
            "sockets",
            "--robot",
            PANDA,
            "--data",
            data.to_str().unwrap(),
        ])
        .args(["--ball-mm", "0.025171,-0.084766,133.528298"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<(f64, f64)> = (text.lines())
        .skip_while(|l| !l.starts_with("planes (distance"))
        .skip(2)
        .take_while(|l| l.ends_with("fitted"))
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f[3].parse().unwrap(), f[4].parse().unwrap())
        })
        .collect();
    assert_eq!(rows.len(), 18, "{text}");
    assert!(
        rows.iter()
            .all(|(nominal, identified)| *nominal > 0.1 && *identified < 0.04),
        "{text}"
    );
}

/// Planning touches (issue 54): the two sockets of `panda_3`'s `frontcenter` (where the nominal
/// Panda puts the ball on average over the real configurations, 50 mm apart), 25 configurations
/// each chosen from those 400 Halton starts reach. Held: every planned configuration puts the
/// nominal ball at its socket (to 1e-6 mm, by forward kinematics) within the joint limits; the
/// plan's predicted standard errors are below those of the first 25 reachable configurations
/// (geometric mean); and simulated with a known truth (random errors in the planned set, the
/// ball's play the planned scatter), the calibration from the planned touches measures, on the
/// same configurations touched again, the consistency the plan predicted within 20 %.
#[test]
fn a_plan_of_touches_predicts_what_its_calibration_measures() {
    use host_tools::calibration::touch_plan::{TouchPlanRequest, plan_touches};
    use host_tools::measurement::simulate_touches::{TouchSimulation, simulate_touches};
    let session = panda_session("panda_3", "frontcenter", [0, 1]);
    let ball = session.ball_model().unwrap();
    let nominal = Kinematics::nominal(&ball.robot).unwrap();
    let sockets_of = |name: &str| -> Vec<[f64; 3]> {
        let placement = session.placements.iter().find(|p| p.name == name).unwrap();
        (placement.sockets.iter())
            .map(|s| {
                let sum: nalgebra::Vector3<f64> = (s.readings.iter())
                    .map(|r| {
                        let q = JointVec::from_slice(&r.q_rad).unwrap();
                        nominal.forward(&q).unwrap().translation.vector
                    })
                    .sum();
                (sum / s.readings.len() as f64).into()
            })
            .collect()
    };
    let sockets_mm = sockets_of("frontcenter");
    let next = vec![
        sockets_of("backright")[0],
        sockets_of("frontleft")[0],
        [2000.0, 0.0, 0.0],
    ];
    let request = TouchPlanRequest {
        robot: session.robot.clone(),
        robot_path: session.robot_path.clone(),
        ball_mm: session.ball_mm,
        sockets_mm: sockets_mm.clone(),
        per_socket: 25,
        starts: 400,
        touch_sd_mm: 0.1,
        gauge: session.gauge,
        next,
    };
    println!("sockets at {sockets_mm:.3?} mm");
    let started = std::time::Instant::now();
    let plan = plan_touches(&request).unwrap();
    let seconds = started.elapsed().as_secs_f64();
    assert_eq!(plan.touches.len(), 50);
    for t in &plan.touches {
        let q = JointVec::from_slice(&t.q_rad).unwrap();
        let at = nominal.forward(&q).unwrap().translation.vector;
        assert!((at - nalgebra::Vector3::from(sockets_mm[usize::from(t.socket)])).norm() < 1e-6);
        for (v, l) in t.q_rad.iter().zip(&ball.robot.limits) {
            assert!((l.lower..=l.upper).contains(v));
        }
    }
    let geometric = |p: &host_tools::calibration::touch_plan::TouchPrediction| {
        (p.std_errors.iter().map(|(_, s)| s.ln()).sum::<f64>() / p.std_errors.len() as f64).exp()
    };
    let (planned, first) = (geometric(&plan.predicted), geometric(&plan.first_reachable));
    let consistency = plan.predicted.consistency.unwrap();
    println!(
        "plan: {:?} reachable, {} parameters (dropped {:?}), {seconds:.2} s; geometric mean standard error {planned:.3e} against {first:.3e} for the first reachable; predicted consistency {:.4} mm (first reachable {:.4}), distance sd {:.4} mm (first reachable {:.4})",
        plan.reachable,
        plan.predicted.std_errors.len(),
        plan.dropped,
        consistency.mean_mm,
        plan.first_reachable.consistency.unwrap().mean_mm,
        plan.predicted.distance_sd_mm.unwrap(),
        plan.first_reachable.distance_sd_mm.unwrap()
    );
    assert!(planned < first);
    // The next placement: out of reach last, the others ranked by what they add.
    for n in &plan.next {
        println!(
            "next placement at {:.1?} mm: {} reachable, geometric mean standard error {:?} (plan alone {planned:.3e})",
            n.first_socket_mm, n.reachable, n.geometric_std_error
        );
    }
    assert_eq!(plan.next.len(), 3);
    assert_eq!(plan.next[2].first_socket_mm, [2000.0, 0.0, 0.0]);
    assert!(plan.next[2].geometric_std_error.is_none() && plan.next[2].reachable == 0);
    assert!(
        plan.next[..2]
            .iter()
            .all(|n| n.geometric_std_error.unwrap() < planned)
    );
    assert!(plan.next[0].geometric_std_error <= plan.next[1].geometric_std_error);
    // The planned touches simulated with a known truth, calibrated, and touched again.
    let as_placement = |name: &str| host_tools::io::sockets::Placement {
        name: name.into(),
        sockets: (0..2u16)
            .map(|s| host_tools::io::sockets::Socket {
                path: format!("planned/hole_{s}.csv").into(),
                readings: (plan.touches.iter().filter(|t| t.socket == s).enumerate())
                    .map(|(i, t)| host_tools::io::sockets::Reading {
                        line: i as u64 + 1,
                        q_rad: t.q_rad.clone(),
                    })
                    .collect(),
            })
            .collect(),
        planes: Vec::new(),
    };
    let set = plan.set.clone();
    let truth_x = random_truth(&set, 11);
    let mut measured = Vec::new();
    for seed in [21, 22] {
        let simulation = TouchSimulation {
            truth: set.unpack(&truth_x).unwrap(),
            play_sd_mm: 0.1,
            gauge: Some(([0, 1], 50.0)),
            planes: Vec::new(),
            seed,
        };
        let templates = [as_placement("recorded"), as_placement("again")];
        let simulated = simulate_touches(&ball.robot, &simulation, &templates).unwrap();
        let calibrated = host_tools::calibration::touches::TouchSession {
            placements: simulated.into_iter().map(|s| s.placement).collect(),
            train: vec!["recorded".into()],
            ..session.clone()
        }
        .run()
        .unwrap();
        measured.push(calibrated.held_out[0].identified.mean_mm);
    }
    let mean = measured.iter().sum::<f64>() / measured.len() as f64;
    println!(
        "measured again after the calibration: {measured:?} mm, predicted {:.4}",
        consistency.mean_mm
    );
    assert!(
        (mean / consistency.mean_mm - 1.0).abs() < 0.2,
        "{mean} against {consistency:?}"
    );
}

/// `calib sockets` on `panda_3` trained on `frontcenter` (the authors' ball), run in `dir`, with
/// the options `extra`.
fn calib_sockets_on_panda_3(dir: &Path, extra: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
        .current_dir(dir)
        .args([
            "sockets",
            "--robot",
            PANDA,
            "--data",
            &format!("{DATA}/panda_3"),
        ])
        .args([
            "--ball-mm",
            "0.025171,-0.084766,133.528298",
            "--train",
            "frontcenter",
        ])
        .args(extra)
        .output()
        .unwrap()
}

/// The certificate of a calibration from touches (issue 54, item 3): `calib sockets --html` on
/// `panda_3` trained on `frontcenter`, parsed as HTML. Every held-out placement's row shows the
/// JSON report's figures (to the printed digit), the summary's held-out mean is their mean and
/// the distance's worst error is the report's largest, the page says these are not absolute
/// accuracy and names every parameter left free and dropped, the scale's source, and the inputs
/// with the SHA-256 of their bytes; `calib report --from` renders the same page from the JSON.
/// Without the known distance it says the scale is not determined. No external reference.
#[test]
fn the_certificate_of_touches_states_what_they_are() {
    use scraper::{Html, Selector};
    use sha2::Digest as _;
    let dir = tempfile::tempdir().unwrap();
    let run = |extra: &[&str], name: &str| {
        let html = format!("{name}.html");
        let written = ["--report", &format!("{name}.json"), "--html", &html];
        let out = calib_sockets_on_panda_3(dir.path(), &[&written[..], extra].concat());
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let page = std::fs::read_to_string(dir.path().join(format!("{name}.html"))).unwrap();
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join(format!("{name}.json"))).unwrap(),
        )
        .unwrap();
        (page, json)
    };
    let (page, json) = run(&["--distance", "50"], "gauged");
    let html = Html::parse_document(&page);
    let cells = |css: &str| -> Vec<String> {
        let s = Selector::parse(css).unwrap();
        html.select(&s)
            .map(|e| e.text().collect::<String>())
            .collect()
    };
    let rows: Vec<Vec<String>> = {
        let row = Selector::parse("table tr").unwrap();
        let td = Selector::parse("td").unwrap();
        (html.select(&row))
            .map(|r| r.select(&td).map(|c| c.text().collect()).collect())
            .collect()
    };
    let held = json["held_out"].as_array().unwrap();
    assert_eq!(held.len(), 5);
    let mut mean = 0.0;
    for f in held {
        let name = f["placement"].as_str().unwrap();
        let identified = f["identified"]["mean_mm"].as_f64().unwrap();
        let p95 = f["identified"]["p95_mm"].as_f64().unwrap();
        let predicted = f["predicted"]["mean_mm"].as_f64().unwrap();
        mean += identified / held.len() as f64;
        let row = rows
            .iter()
            .find(|r| r.first().map(String::as_str) == Some(name))
            .unwrap_or_else(|| panic!("no row for {name}"));
        assert_eq!(row[3], format!("{identified:.4}"), "{row:?}");
        assert_eq!(row[4], format!("{p95:.4}"), "{row:?}");
        assert_eq!(row[7], format!("{predicted:.4}"), "{row:?}");
    }
    let paragraphs = cells("p").join("\n");
    assert!(paragraphs.contains(&format!("Held-out consistency (mean over the held-out placements of each one's mean distance from the socket): {mean:.4} mm")), "{paragraphs}");
    let worst = (held.iter())
        .map(|f| {
            f["identified"]["distortion_mm"][0][1]
                .as_f64()
                .unwrap()
                .abs()
        })
        .fold(0.0, f64::max);
    assert!(
        paragraphs.contains(&format!("at most {worst:.4} mm")),
        "{paragraphs}"
    );
    assert!(paragraphs.contains("not absolute accuracy"));
    let undetermined = cells("#undetermined + ul li").join("\n");
    for free in json["identifiability"]["left_free"].as_array().unwrap() {
        assert!(
            undetermined.contains(free["name"].as_str().unwrap()),
            "{undetermined}"
        );
    }
    for dropped in json["dropped"].as_array().unwrap() {
        assert!(
            undetermined.contains(dropped.as_str().unwrap()),
            "{undetermined}"
        );
    }
    assert!(undetermined.contains("base frame") && undetermined.contains("known distance alone"));
    // The inputs: the robot file and the twelve files of touches, hashed as sha256sum would.
    let inputs = json["inputs"].as_array().unwrap();
    assert_eq!(inputs.len(), 1 + 12);
    for input in inputs {
        let bytes = std::fs::read(input["path"].as_str().unwrap()).unwrap();
        let hash: String = (sha2::Sha256::digest(&bytes).iter())
            .map(|b| format!("{b:02x}"))
            .collect();
        assert_eq!(input["sha256"], hash.as_str());
        assert!(page.contains(&hash));
    }
    assert!(!page.contains("http") && !page.contains("<script") && !page.contains("src="));
    // Rendered again from the JSON report: the same page but for the rendering's date.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
        .current_dir(dir.path())
        .args(["report", "--from", "gauged.json", "--html", "again.html"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let again = std::fs::read_to_string(dir.path().join("again.html")).unwrap();
    let body = |p: &str| {
        p.lines()
            .filter(|l| !l.contains("rendered by"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(body(&again), body(&page));
    // Without the distance: the scale is not certified. Printed to a PDF where Chromium is.
    let printed = host_tools::report::pdf::browser().is_some();
    let (free, _) = run(if printed { &["--pdf", "free.pdf"] } else { &[] }, "free");
    assert!(free.contains("The scale is not determined"));
    assert!(free.contains("none: the scale is not determined"));
    if printed {
        let pdf = std::fs::read(dir.path().join("free.pdf")).unwrap();
        assert!(pdf.starts_with(b"%PDF-"));
    }
}

/// Tracker positions and touches in one calibration (issue 54, item 5), with known truth: the
/// Panda with random errors in the 23 parameters `panda_3` determines, its touches simulated on
/// the six placements (play 0.03 mm, 50 mm between the sockets), and twelve positions of the
/// same ball measured by a tracker 2.5 m away and turned 120 degrees (0.02 mm per coordinate) at
/// real configurations; fitted on `frontcenter` with the tracker positions. The geometry equals
/// the truth within its covariance (Mahalanobis distance below chi-squared's 99.9 % point over
/// the shared parameters, none more than four standard errors off), the robot is placed in the
/// tracker's frame (which touches alone cannot do) to within 0.1 mm and 0.1 mrad, and the
/// tracker fixes the scale: the identified lengths' standard errors fall against the touches
/// alone. Fewer than three tracker positions are refused.
#[test]
fn tracker_positions_and_touches_in_one_calibration() {
    use host_tools::calibration::mixed::{MixedSession, TrackerPoint};
    use host_tools::measurement::simulate_touches::{TouchSimulation, simulate_touches};
    use rand::RngExt;
    use rand_core::SeedableRng;
    let real_session = panda_session("panda_3", "frontcenter", [0, 1]);
    let set = real_session.run().unwrap().fit.set.clone();
    let robot = real_session.ball_model().unwrap().robot;
    // The tracker: 2.5 m away, turned 120 degrees about its vertical, 0.02 mm per coordinate.
    let tracker = nalgebra::IsometryMatrix3::new(
        nalgebra::Vector3::new(2500.0, 300.0, -400.0),
        nalgebra::Vector3::new(0.0, 0.0, 120f64.to_radians()),
    );
    // The touches and the tracker positions a robot with the errors `truth_x` (of `set`) gives.
    let simulate = |set: &ParameterSet<Dyn, Dyn>, truth_x: &nalgebra::DVector<f64>| {
        let truth = set.unpack(truth_x).unwrap();
        let simulation = TouchSimulation {
            truth,
            play_sd_mm: 0.03,
            gauge: Some(([0, 1], 50.0)),
            planes: Vec::new(),
            seed: 7,
        };
        let simulated = simulate_touches(&robot, &simulation, &real_session.placements).unwrap();
        let true_model = Kinematics::new(&robot, &truth).unwrap();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
        let points: Vec<TrackerPoint> = (real_session.placements.iter())
            .flat_map(|p| p.sockets.iter().map(|s| s.readings[0].q_rad.clone()))
            .map(|q| {
                let q_vec = JointVec::from_slice(&q).unwrap();
                let ball = true_model.forward(&q_vec).unwrap().translation.vector;
                let noise = nalgebra::Vector3::from_fn(|_, _| {
                    0.02 * (-2.0 * rng.random::<f64>().ln()).sqrt()
                        * (std::f64::consts::TAU * rng.random::<f64>()).cos()
                });
                let measured = tracker * nalgebra::Point3::from(ball) + noise;
                TrackerPoint {
                    q_rad: q,
                    position_mm: measured.coords.into(),
                }
            })
            .collect::<Vec<_>>();
        let touches = host_tools::calibration::touches::TouchSession {
            placements: simulated.into_iter().map(|s| s.placement).collect(),
            ..panda_session("panda_3", "frontcenter", [0, 1])
        };
        let alone = touches.run().unwrap();
        let mixed = MixedSession {
            touches,
            tracker: points.clone(),
            tracker_sd_mm: 0.02,
        }
        .run()
        .unwrap();
        (alone, mixed, points)
    };
    // The mixed fit selects its own set (the tracker changes what is barely determined): the
    // truth is drawn again with errors only in the parameters both fits identify.
    let first = simulate(&set, &random_truth(&set, 7)).1.calibrated.fit.set;
    let mut truth_x = random_truth(&set, 7);
    for (i, p) in set.parameters().iter().enumerate() {
        if !first.parameters().contains(p) {
            truth_x[i] = 0.0;
        }
    }
    let (alone, mixed, points) = simulate(&set, &truth_x);
    let tracker_figures = mixed.tracker.clone();
    let mixed = mixed.calibrated;
    assert_eq!(points.len(), 12);
    let truth_of =
        |p: &Parameter| (set.parameters().iter().position(|q| q == p)).map_or(0.0, |i| truth_x[i]);
    // The identified geometry and ball against the truth, in the mixed fit's covariance (the
    // base, measurement setup, judged below as a pose).
    let covariance = mixed.fit.covariance.clone().unwrap();
    let shared: Vec<usize> = (mixed.fit.set.parameters().iter().enumerate())
        .filter(|(_, p)| !matches!(p, Parameter::Base(_)))
        .map(|(i, _)| i)
        .collect();
    let difference = nalgebra::DVector::from_iterator(
        shared.len(),
        (shared.iter()).map(|m| {
            let p = &mixed.fit.parameters[*m];
            p.value - truth_of(&p.parameter)
        }),
    );
    let block = nalgebra::DMatrix::from_fn(shared.len(), shared.len(), |r, c| {
        covariance[(shared[r], shared[c])]
    });
    let mahalanobis = (difference.transpose()
        * block.clone().cholesky().unwrap().inverse()
        * &difference)[(0, 0)];
    let worst_z = (0..shared.len())
        .map(|i| difference[i].abs() / block[(i, i)].sqrt())
        .fold(0.0, f64::max);
    let limit = chi_squared_quantile(shared.len() as f64, 3.09);
    // Where the robot stands: the identified registration against the tracker's true pose.
    let registration = calib_core::FramePose {
        xyz: tracker_figures.registration_xyz_mm,
        rpy: tracker_figures.registration_rpy_rad,
    }
    .isometry();
    let offset_mm = (registration.translation.vector - tracker.translation.vector).norm();
    let turn_rad = (registration.rotation.inverse() * tracker.rotation).angle();
    // The lengths' standard errors, mixed against the touches alone.
    let length_se = |fit: &host_tools::calibration::fit::KindFit| -> f64 {
        let logs: Vec<f64> = (fit.parameters.iter())
            .filter(|p| {
                matches!(
                    p.parameter,
                    Parameter::Joint {
                        kind: JointParameter::A | JointParameter::D,
                        ..
                    }
                )
            })
            .map(|p| p.std_error.unwrap().ln())
            .collect();
        (logs.iter().sum::<f64>() / logs.len() as f64).exp()
    };
    println!(
        "mixed: {} parameters ({} of the geometry and the ball), Mahalanobis {mahalanobis:.2} (99.9 % point {limit:.1}), worst {worst_z:.2} standard errors; registration off by {offset_mm:.4} mm and {turn_rad:.2e} rad; tracker residual RMS {:.4} mm; lengths' standard errors (geometric mean) {:.3e} mm against {:.3e} mm from the touches alone; touch weight {:.4} (touch sd {:.4} mm)",
        mixed.fit.set.len(),
        shared.len(),
        tracker_figures.rms_mm,
        length_se(&mixed.fit),
        length_se(&alone.fit),
        tracker_figures.touch_weight,
        mixed.touch_sd_mm.unwrap()
    );
    assert!(mahalanobis < limit && worst_z < 4.0);
    assert!(offset_mm < 0.1 && turn_rad < 1e-4);
    assert!(length_se(&mixed.fit) < 0.8 * length_se(&alone.fit));
    assert!(tracker_figures.rms_mm < 0.05);
    // Two tracker positions cannot place the robot: refused, saying so.
    let two = MixedSession {
        touches: panda_session("panda_3", "frontcenter", [0, 1]),
        tracker: points[..2].to_vec(),
        tracker_sd_mm: 0.02,
    };
    let error = two.run().unwrap_err().to_string();
    assert!(error.contains("at least three"), "{error}");
}

/// `calib sockets --tracker` on the real `panda_3` touches with twelve tracker positions of the
/// ball at real configurations, computed from the touches' own calibration and moved into a
/// tracker's frame (2 m away, turned 90 degrees): the command places the robot in that frame to
/// within 0.05 mm, fits the positions to under 0.1 mm RMS, writes the tracker's figures in the
/// report and the certificate, and hashes the tracker file among the inputs. A file of tracker
/// positions with a wrong header or two positions is refused, naming the file and line.
#[test]
fn calib_sockets_fits_tracker_positions_with_the_touches() {
    let dir = tempfile::tempdir().unwrap();
    let session = panda_session("panda_3", "frontcenter", [0, 1]);
    let touches = session.run().unwrap();
    let robot = session.ball_model().unwrap().robot;
    let model = Kinematics::new(&robot, &touches.fit.errors).unwrap();
    let tracker = nalgebra::IsometryMatrix3::new(
        nalgebra::Vector3::new(2000.0, -500.0, 100.0),
        nalgebra::Vector3::new(0.0, 0.0, 90f64.to_radians()),
    );
    let header = "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,q7_deg,x_mm,y_mm,z_mm\n";
    let mut csv = header.to_string();
    for p in &session.placements {
        for s in &p.sockets {
            let q = &s.readings[0].q_rad;
            let ball = model.forward(&JointVec::from_slice(q).unwrap()).unwrap();
            let m = tracker * nalgebra::Point3::from(ball.translation.vector);
            let degrees: Vec<String> = q.iter().map(|v| format!("{:.9}", v.to_degrees())).collect();
            csv.push_str(&format!(
                "{},{:.6},{:.6},{:.6}\n",
                degrees.join(","),
                m.x,
                m.y,
                m.z
            ));
        }
    }
    std::fs::write(dir.path().join("tracker.csv"), &csv).unwrap();
    let calib = |tracker_file: &str| {
        calib_sockets_on_panda_3(
            dir.path(),
            &[
                "--distance",
                "50",
                "--tracker",
                tracker_file,
                "--report",
                "r.json",
                "--html",
                "c.html",
            ],
        )
    };
    let out = calib("tracker.csv");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("r.json")).unwrap()).unwrap();
    let t = &json["tracker"];
    let xyz: Vec<f64> = (0..3)
        .map(|i| t["registration_xyz_mm"][i].as_f64().unwrap())
        .collect();
    let offset = (nalgebra::Vector3::from_column_slice(&xyz) - tracker.translation.vector).norm();
    let yaw = t["registration_rpy_rad"][2].as_f64().unwrap();
    println!(
        "calib sockets --tracker: registration off by {offset:.4} mm, yaw {:.5} deg; positions RMS {:.4} mm, largest {:.4} mm; touch weight {:.4}",
        yaw.to_degrees(),
        t["rms_mm"].as_f64().unwrap(),
        t["max_mm"].as_f64().unwrap(),
        t["touch_weight"].as_f64().unwrap()
    );
    assert_eq!(t["positions"], 12);
    assert!(offset < 0.05 && (yaw.to_degrees() - 90.0).abs() < 0.01);
    assert!(t["rms_mm"].as_f64().unwrap() < 0.1);
    let inputs = json["inputs"].as_array().unwrap();
    assert_eq!(inputs.last().unwrap()["flag"], "--tracker");
    let page = std::fs::read_to_string(dir.path().join("c.html")).unwrap();
    assert!(page.contains("Tracker positions of the ball</b>: 12 fitted"));
    assert!(page.contains("determined by the 12 tracker positions"));
    assert!(!page.contains("The scale rests on the known distance alone"));
    // Refused, naming the file and line: a wrong header; two positions.
    std::fs::write(dir.path().join("bad.csv"), csv.replace("x_mm", "x")).unwrap();
    let out = calib("bad.csv");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("bad.csv:1:"),
        "{stderr}"
    );
    let two: String = csv.lines().take(3).map(|l| format!("{l}\n")).collect();
    std::fs::write(dir.path().join("two.csv"), two).unwrap();
    let out = calib("two.csv");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("at least three"),
        "{stderr}"
    );
}

/// A datum plane (issue 54, item 1: points on a known plane): the Panda with random errors in
/// the 23 parameters `panda_3` determines, its touches simulated on the six placements (play
/// 0.03 mm, 50 mm between the sockets) and, on `frontcenter`, 68 contacts with the horizontal
/// plane through its first socket, given as known (`DatumPlane`, the plane's true offset).
/// Fitted on `frontcenter`: the known plane sees where the arm stands along its normal, so
/// joint 1's lift (`dd1`, left free by touches alone) is identified; the geometry equals the
/// truth within its covariance and the contacts lie on the known plane to the play. Without
/// the datum (the same contacts as an unknown plane), `dd1` stays free.
#[test]
fn a_datum_plane_determines_the_lift_touches_leave_free() {
    use host_tools::calibration::touches::{DatumPlane, TouchSession};
    use host_tools::measurement::simulate_touches::{TouchSimulation, simulate_touches};
    let real_session = panda_session("panda_3", "frontcenter", [0, 1]);
    let set = real_session.run().unwrap().fit.set.clone();
    let robot = real_session.ball_model().unwrap().robot;
    let truth_x = random_truth(&set, 11);
    let simulation = TouchSimulation {
        truth: set.unpack(&truth_x).unwrap(),
        play_sd_mm: 0.03,
        gauge: Some(([0, 1], 50.0)),
        planes: vec![[0.0, 0.0, 1.0]],
        seed: 11,
    };
    let simulated = simulate_touches(&robot, &simulation, &real_session.placements).unwrap();
    let table_z = (simulated.iter())
        .find(|s| s.placement.name == "frontcenter")
        .unwrap()
        .centres_mm[0][2];
    let placements: Vec<_> = (simulated.into_iter())
        .map(|s| {
            let mut placement = s.placement;
            if placement.name != "frontcenter" {
                placement.planes.clear();
            }
            placement
        })
        .collect();
    let session = TouchSession {
        placements,
        datums: vec![DatumPlane {
            plane: 0,
            normal: [0.0, 0.0, 1.0],
            offset_mm: table_z,
        }],
        ..panda_session("panda_3", "frontcenter", [0, 1])
    };
    let fitted = session.run().unwrap();
    let lift = Parameter::Joint {
        joint: 1,
        kind: JointParameter::D,
    };
    let truth_of =
        |p: &Parameter| (set.parameters().iter().position(|q| q == p)).map_or(0.0, |i| truth_x[i]);
    let n = fitted.fit.set.len();
    let difference = nalgebra::DVector::from_iterator(
        n,
        (fitted.fit.parameters.iter()).map(|p| p.value - truth_of(&p.parameter)),
    );
    let covariance = fitted.fit.covariance.clone().unwrap();
    let mahalanobis = (difference.transpose()
        * covariance.clone().cholesky().unwrap().inverse()
        * &difference)[(0, 0)];
    let worst_z = (0..n)
        .map(|i| difference[i].abs() / covariance[(i, i)].sqrt())
        .fold(0.0, f64::max);
    let limit = chi_squared_quantile(n as f64, 3.09);
    let dd1 = (fitted.fit.parameters.iter())
        .find(|p| p.parameter == lift)
        .expect("dd1 identified with the datum");
    let on_plane = &fitted.fitted[0].identified.known_planes[0];
    println!(
        "datum plane: {n} parameters, dd1 {:+.4} +- {:.4} mm (truth 0), Mahalanobis {mahalanobis:.2} (99.9 % point {limit:.1}), worst {worst_z:.2} standard errors; {} contacts off the known plane {:.4} mm mean (nominal {:.4})",
        dd1.value,
        dd1.std_error.unwrap(),
        on_plane.contacts,
        on_plane.mean_mm,
        fitted.fitted[0].nominal.known_planes[0].mean_mm
    );
    assert!(mahalanobis < limit && worst_z < 4.0);
    assert!(on_plane.mean_mm < 0.05 && on_plane.contacts >= 25);
    // The same contacts as an unknown plane: the lift is left free.
    let unknown = TouchSession {
        datums: Vec::new(),
        ..session
    }
    .run()
    .unwrap();
    assert!(!unknown.fit.set.parameters().contains(&lift));
    assert!(
        unknown
            .selection
            .identifiability
            .left_free
            .iter()
            .any(|f| f.parameter == lift)
    );
}

/// The authors' rule (per socket, the points within 2 interquartile ranges of the quartiles on
/// every axis; the mean distance from the kept points' mean over the sockets), computed here
/// from ball positions, mm.
fn authors_mae(sockets: &[Vec<nalgebra::Vector3<f64>>]) -> f64 {
    use host_tools::analysis::consistency::quantile;
    let (mut sum, mut count) = (0.0, 0usize);
    for balls in sockets {
        let axis = |k: usize| balls.iter().map(|b| b[k]).collect::<Vec<f64>>();
        let bounds: Vec<(f64, f64)> = (0..3)
            .map(|k| {
                let (q1, q3) = (quantile(&axis(k), 0.25), quantile(&axis(k), 0.75));
                (q1 - 2.0 * (q3 - q1), q3 + 2.0 * (q3 - q1))
            })
            .collect();
        let kept: Vec<&nalgebra::Vector3<f64>> = (balls.iter())
            .filter(|b| (0..3).all(|k| b[k] >= bounds[k].0 && b[k] <= bounds[k].1))
            .collect();
        let mean = kept.iter().copied().sum::<nalgebra::Vector3<f64>>() / kept.len() as f64;
        sum += kept.iter().map(|b| (*b - mean).norm()).sum::<f64>();
        count += kept.len();
    }
    sum / count as f64
}

/// The joints' torsion under gravity on the real Pandas (`calib sockets --compliance`, the
/// library's session): trained on one placement as the authors were, it earns its place on
/// left-out touches of that placement, its gains are not negative, and the held-out placements
/// come out below the authors' calibrated models (0.221 and 0.427 mm) and below our geometry
/// alone. Measured: `panda_3` 0.1726 mm (geometry 0.2190; 20 % below the authors is 0.177),
/// `panda_2` 0.4121 (0.4380). The held-out figure is recomputed here from the identified robot
/// file as written (its geometry and its `[compliance]`) through the controller's deflection
/// (`Compliance::forward`), to within the fit's stated difference from it.
#[test]
fn the_joints_torsion_earns_its_place_on_the_real_pandas() {
    for (robot, train, authors) in [
        ("panda_3", "frontcenter", 0.221),
        ("panda_2", "front_center", 0.427),
    ] {
        let geometry = panda_session(robot, train, [0, 1]).run().unwrap();
        let session = host_tools::calibration::touches::TouchSession {
            compliance: true,
            ..panda_session(robot, train, [0, 1])
        };
        let calibrated = session.run().unwrap();
        let torsion = calibrated.torsion.clone().unwrap();
        let held = |c: &host_tools::calibration::touches::TouchCalibrated| {
            let h = &c.held_out;
            h.iter().map(|f| f.identified.authors_mean_mm).sum::<f64>() / h.len() as f64
        };
        let (ours, alone) = (held(&calibrated), held(&geometry));
        println!(
            "{robot} on {train}: held out {ours:.4} mm (geometry alone {alone:.4}, authors {authors}); left-out touches {:.4} -> {:.4} mm; gains {:?} +- {:?} urad/(N m) for joints {:?}; controller {:.1e} mm",
            torsion.cross_validated_mm[0],
            torsion.cross_validated_mm[1],
            torsion.gains_urad_per_nm,
            torsion.std_errors_urad_per_nm,
            torsion.joints,
            torsion.controller_difference_mm
        );
        assert!(torsion.kept && torsion.cross_validated_mm[1] < torsion.cross_validated_mm[0]);
        assert!(
            torsion
                .gains_urad_per_nm
                .iter()
                .all(|g| (0.0..=1000.0).contains(g))
        );
        assert!(ours < authors && ours < alone, "{ours} {alone}");
        // The identified file through the controller's model.
        let path = Path::new("identified.toml");
        let file = &calibrated.file;
        let mut actual = file.to_model(path).unwrap().robot;
        let flange = actual.tool.isometry();
        actual.tool = calib_core::FramePose {
            xyz: (flange * nalgebra::Point3::from(calibrated.ball_mm))
                .coords
                .into(),
            rpy: actual.tool.rpy,
        };
        let compliance = (file.gravity_compliance(path, 7).unwrap().unwrap())
            .to_core::<f64>(7)
            .unwrap();
        let geometry_of_file = Kinematics::nominal(&actual).unwrap();
        let mut worst = 0.0f64;
        for figures in &calibrated.held_out {
            let placement = (session.placements.iter())
                .find(|p| p.name == figures.placement)
                .unwrap();
            let balls: Vec<Vec<nalgebra::Vector3<f64>>> = (placement.sockets.iter())
                .map(|s| {
                    (s.readings.iter())
                        .map(|r| {
                            let q = calib_core::model::JointVec::from_slice(&r.q_rad).unwrap();
                            let pose = compliance.forward(&geometry_of_file, &q).unwrap();
                            pose.translation.vector
                        })
                        .collect()
                })
                .collect();
            let recomputed = authors_mae(&balls);
            worst = worst.max((recomputed - figures.identified.authors_mean_mm).abs());
        }
        println!(
            "  recomputed through the controller's deflection: worst difference {worst:.1e} mm"
        );
        assert!(
            worst <= torsion.controller_difference_mm.max(1e-9),
            "{worst}"
        );
    }
}

/// Known truth for the torsion: the Panda with random errors in the 23 parameters `panda_3`
/// determines and its joints 3 and 4 twisted by 40 and 20 urad per N m under gravity (the
/// readings are what the arm reads where the twisted arm puts the ball at its socket), touches
/// with 0.03 mm play on the six placements, fitted on `frontcenter` with `compliance`. The
/// torsion is kept, each gain lies within four standard errors of the truth, the geometry
/// within the chi-squared 99.9 % point; with no torsion in the truth, any gain fitted lies
/// within four standard errors of zero.
#[test]
fn simulated_torsion_is_given_back_within_its_uncertainty() {
    use host_tools::calibration::torsion::TorsionModel;
    use host_tools::measurement::simulate_touches::{TouchSimulation, simulate_touches};
    let real_session = panda_session("panda_3", "frontcenter", [0, 1]);
    let real = real_session.run().unwrap();
    let set = real.fit.set.clone();
    let robot = real_session.ball_model().unwrap().robot;
    let file = RobotFile::read(Path::new(PANDA)).unwrap();
    let model =
        TorsionModel::new(file.dynamics.as_ref().unwrap().to_gravity(7).unwrap(), 7).unwrap();
    assert_eq!(model.joints(), vec![2, 3, 4, 5]);
    for (truth_gains, seed) in [([0.0, 40.0, 20.0, 0.0], 5u64), ([0.0; 4], 6)] {
        let truth_x = random_truth(&set, seed);
        let truth = set.unpack(&truth_x).unwrap();
        let simulation = TouchSimulation {
            truth,
            play_sd_mm: 0.03,
            gauge: Some(([0, 1], 50.0)),
            planes: Vec::new(),
            seed,
        };
        let mut placements: Vec<_> =
            simulate_touches(&robot, &simulation, &real_session.placements)
                .unwrap()
                .into_iter()
                .map(|s| s.placement)
                .collect();
        // The readings: q = q_kinematic - turns(q) k, solved by iteration.
        for reading in placements
            .iter_mut()
            .flat_map(|p| p.sockets.iter_mut())
            .flat_map(|s| s.readings.iter_mut())
        {
            let kinematic = reading.q_rad.clone();
            for _ in 0..4 {
                let q = calib_core::model::JointVec::from_slice(&reading.q_rad).unwrap();
                let turns = model.turns((&robot, &truth), &q).unwrap();
                reading.q_rad = kinematic.clone();
                for ((joint, _), (turn, gain)) in
                    model.torsions.iter().zip(turns.iter().zip(&truth_gains))
                {
                    reading.q_rad[joint - 1] -= turn * gain;
                }
            }
        }
        let session = host_tools::calibration::touches::TouchSession {
            placements,
            compliance: true,
            ..panda_session("panda_3", "frontcenter", [0, 1])
        };
        let fitted = session.run().unwrap();
        let torsion = fitted.torsion.clone().unwrap();
        println!(
            "truth {truth_gains:?}: kept {}, gains {:?} +- {:?}, left-out touches {:.4} -> {:.4} mm",
            torsion.kept,
            torsion.gains_urad_per_nm,
            torsion.std_errors_urad_per_nm,
            torsion.cross_validated_mm[0],
            torsion.cross_validated_mm[1]
        );
        for ((gain, se), truth) in (torsion.gains_urad_per_nm.iter())
            .zip(&torsion.std_errors_urad_per_nm)
            .zip(&truth_gains)
        {
            if let Some(se) = se {
                assert!(
                    (gain - truth).abs() < 4.0 * se,
                    "{gain} +- {se} against {truth}"
                );
            }
        }
        if truth_gains[1] > 0.0 {
            assert!(torsion.kept && torsion.fitted[1] && torsion.fitted[2]);
            let (mahalanobis, worst_z) = distance_from_truth(&fitted.fit, &truth_x);
            let limit = chi_squared_quantile(set.len() as f64, 3.09);
            println!(
                "  geometry: Mahalanobis {mahalanobis:.2} (99.9 % point {limit:.1}), worst {worst_z:.2} standard errors"
            );
            assert!(mahalanobis < limit && worst_z < 4.0);
        }
    }
}

/// `--compliance` needs the robot file's masses: without `[dynamics]` it is refused, naming
/// the section and the file, and nothing is written.
#[test]
fn compliance_without_masses_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(PANDA).unwrap();
    let cut = text.find("[dynamics]").unwrap();
    let start = text[..cut].rfind("\n\n").unwrap();
    let robot = dir.path().join("panda-without-masses.toml");
    std::fs::write(&robot, &text[..start]).unwrap();
    let out = dir.path().join("identified.toml");
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(["sockets", "--robot"])
        .arg(&robot)
        .args([
            "--data",
            &format!("{DATA}/panda_3"),
            "--ball-mm",
            "0.025171,-0.084766,133.528298",
        ])
        .args([
            "--train",
            "frontcenter",
            "--distance",
            "50",
            "--compliance",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    println!("{stderr}");
    assert!(!output.status.success());
    assert!(stderr.contains("[dynamics]") && stderr.contains("panda-without-masses.toml"));
    assert!(!out.exists());
    // Too few touches per socket to judge the torsion on left-out ones.
    let mut session = host_tools::calibration::touches::TouchSession {
        compliance: true,
        train: vec!["frontcenter".into(), "backcenter".into()],
        ..panda_session("panda_3", "frontcenter", [0, 1])
    };
    for placement in session
        .placements
        .iter_mut()
        .filter(|p| p.name == "backcenter")
    {
        placement.sockets[1].readings.truncate(4);
    }
    let error = session.run().unwrap_err().to_string();
    assert!(
        error.contains("has 4 touches") && error.contains("at least 5"),
        "{error}"
    );
}
