//! The ISO 9283 pose test (issue 55, item 4) through the command line: a cube planned on the
//! ER10L-C10, its run simulated on a robot with known errors in a tracker frame, and the run
//! evaluated. The characteristics are checked against the independent reference kinematics of
//! the true robot (AP, AD: noise-free closed forms; RP: the noise's), and the refusals leave no
//! file behind.

use crate::common;

use common::{ROBOT, calib, drifting_run, ok, simulate};
use host_tools::analysis::reference::{self, Mat4};
use host_tools::io::robot_file::RobotFile;
use std::path::Path;

fn s(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// A 4x4 transform's translation.
fn translation(m: &Mat4) -> [f64; 3] {
    [m[0][3], m[1][3], m[2][3]]
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// A planned point: id, position (mm), quaternion (w, x, y, z), joints (deg).
type PlannedPoint = (String, [f64; 3], [f64; 4], Vec<f64>);

/// The plan's targets and the joints of each point, from the targets file and the run file.
fn plan_of(targets: &Path, run: &Path) -> Vec<PlannedPoint> {
    let text = std::fs::read_to_string(targets).unwrap();
    let run = std::fs::read_to_string(run).unwrap();
    (text.lines().filter(|l| l.starts_with('P')))
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let v: Vec<f64> = f[1..].iter().map(|x| x.parse().unwrap()).collect();
            let row = (run.lines())
                .find(|l| l.starts_with(&format!("{}-c", f[0])))
                .unwrap();
            let q: Vec<f64> = (row.split(',').skip(1).take(6))
                .map(|x| x.parse().unwrap())
                .collect();
            (
                f[0].to_string(),
                [v[0], v[1], v[2]],
                [v[3], v[4], v[5], v[6]],
                q,
            )
        })
        .collect()
}

/// Plans a 400 mm cube, simulates 30 cycles on a robot with random errors (seed 5) in a tracker
/// frame with 0.002 mm noise and a probe 150 mm off the flange, and evaluates the run in the
/// true measurement setup: AP per point equals the reference kinematics' noise-free error of
/// the true robot to 0.002 mm, AD the reference's distance error, RP the noise's `mean(l) + 3 S_l`
/// (3.62 sigma for isotropic noise), the drift none beyond the noise; the JSON report holds the
/// same figures as the text.
#[test]
fn the_characteristics_equal_the_reference_kinematics_of_the_true_robot() {
    let dir = tempfile::tempdir().unwrap();
    let (targets, run) = (dir.path().join("targets.csv"), dir.path().join("run.csv"));
    ok(&calib(&[
        "iso9283",
        "plan",
        "--robot",
        ROBOT,
        "--centre-mm",
        "1200,0,800",
        "--edge-mm",
        "400",
        "--near-deg",
        "0,-30,30,0,60,0",
        "--targets",
        s(&targets),
        "--out",
        s(&run),
    ]));
    let sigma = 0.002;
    let (measured, truth) = simulate(
        dir.path(),
        "measured",
        &[
            "--errors",
            "random",
            "--seed",
            "5",
            "--joints-from",
            s(&run),
            "--position-only",
            "--position-sigma-mm",
            &sigma.to_string(),
            "--tracker-xyz-mm",
            "2500,-800,300",
            "--tracker-rpy-deg",
            "1,-2,150",
            "--tool-xyz-mm",
            "10,20,150",
        ],
    );
    // The true measurement setup: the truth's base is the robot's base in the tracker's frame,
    // its tool the probe; the controller's model is the nominal robot (no base, no tool).
    let truth_file = RobotFile::read(&truth).unwrap();
    let setup = dir.path().join("setup.toml");
    let nominal = std::fs::read_to_string(ROBOT).unwrap();
    std::fs::write(
        &setup,
        format!(
            "{nominal}\n[measurement]\nframes = \"base+tool\"\n\n[measurement.tracker_base]\nxyz_mm = [2500.0, -800.0, 300.0]\nrpy_deg = [1.0, -2.0, 150.0]\n\n[measurement.flange_tool]\nxyz_mm = [10.0, 20.0, 150.0]\nrpy_deg = [0.0, 0.0, 0.0]\n"
        ),
    )
    .unwrap();
    let report = dir.path().join("test.json");
    let text = ok(&calib(&[
        "iso9283",
        "evaluate",
        "--targets",
        s(&targets),
        "--data",
        s(&measured),
        "--robot",
        s(&setup),
        "--report",
        s(&report),
    ]));
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let points = json["characteristics"]["points"].as_array().unwrap();
    // The true robot in its own base frame: the reference model with the truth's base taken out.
    let mut truth_model = reference::model(&truth_file, &[], &[0.0; 6], &[0.0; 6]);
    truth_model.base = reference::IDENTITY;
    let plan = plan_of(&targets, &run);
    let mut attained = std::collections::BTreeMap::new();
    for ((id, position, [w, x, y, z], q), point) in plan.iter().zip(points) {
        assert_eq!(point["point"], id.as_str());
        assert_eq!(point["cycles"], 30);
        let q: Vec<f64> = q.iter().map(|v| v.to_radians()).collect();
        let reached = translation(&truth_model.forward(&q));
        // The probe commanded: the target pose carried 150 mm along its own axes.
        let r =
            nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(*w, *x, *y, *z));
        let probe = r * nalgebra::Vector3::new(10.0, 20.0, 150.0);
        let commanded = [
            position[0] + probe.x,
            position[1] + probe.y,
            position[2] + probe.z,
        ];
        let expected_ap = distance(reached, commanded);
        let ap = point["ap_mm"].as_f64().unwrap();
        assert!(
            (ap - expected_ap).abs() < 0.002,
            "{id}: AP {ap} mm, reference {expected_ap} mm"
        );
        assert!(
            expected_ap > 1.0,
            "{id}: the true robot's errors are mm-level"
        );
        let rp = point["rp_mm"].as_f64().unwrap();
        assert!(
            (2.0 * sigma..6.0 * sigma).contains(&rp),
            "{id}: RP {rp} mm for noise {sigma} mm"
        );
        assert!(text.contains(&format!("{ap:.4}")), "{text}");
        attained.insert(id.clone(), (reached, commanded));
    }
    let distance_json = &json["characteristics"]["distance"];
    let (p2, p4) = (attained["P2"], attained["P4"]);
    let expected_ad = distance(p2.0, p4.0) - distance(p2.1, p4.1);
    let ad = distance_json["ad_mm"].as_f64().unwrap();
    assert!(
        (ad - expected_ad).abs() < 0.002,
        "AD {ad} mm, reference {expected_ad} mm"
    );
    assert!(
        (distance_json["commanded_mm"].as_f64().unwrap() - 0.8 * 400.0 * 3f64.sqrt()).abs() < 1e-6
    );
    let drift = &json["characteristics"]["drift"];
    assert_eq!(drift["block_cycles"], 10);
    assert!(drift["dap_mm"].as_f64().unwrap() < 3.0 * sigma, "{drift}");
    assert!(text.contains("distance P2-P4 (30 cycles)"), "{text}");
}

/// A 6-cycle run drifting 0.05 mm per cycle along x at P1 (noise-free, in the base frame):
/// dAP over the first and last 2 cycles is the closed form |mean shift| difference.
#[test]
fn a_drifting_run_states_its_drift() {
    let dir = tempfile::tempdir().unwrap();
    let (targets, data) = drifting_run(dir.path());
    let out = ok(&calib(&[
        "iso9283",
        "evaluate",
        "--targets",
        s(&targets),
        "--data",
        s(&data),
        "--robot",
        ROBOT,
        "--json",
    ]));
    let json: serde_json::Value = serde_json::from_str(&out).unwrap();
    let drift = &json["characteristics"]["drift"];
    // First two cycles' mean shift 0.075 mm, last two 0.275 mm; RP of two points 0.05 apart:
    // l = 0.025 each, S_l = 0, RP = 0.025 mm in both blocks.
    assert!(
        (drift["ap_mm"][0].as_f64().unwrap() - 0.075).abs() < 1e-9,
        "{drift}"
    );
    assert!(
        (drift["dap_mm"].as_f64().unwrap() - 0.2).abs() < 1e-9,
        "{drift}"
    );
    assert!(
        (drift["rp_mm"][1].as_f64().unwrap() - 0.025).abs() < 1e-9,
        "{drift}"
    );
    assert!(drift["drp_mm"].as_f64().unwrap() < 1e-9, "{drift}");
    // P1's AP over all 6 cycles: mean shift 0.175 mm; its RP: l = |dx - 0.175|.
    let p1 = &json["characteristics"]["points"][0];
    assert!((p1["ap_mm"].as_f64().unwrap() - 0.175).abs() < 1e-9);
    let l: Vec<f64> = (1..=6).map(|c| (0.05 * c as f64 - 0.175).abs()).collect();
    let mean = l.iter().sum::<f64>() / 6.0;
    let sd = (l.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 5.0).sqrt();
    assert!((p1["rp_mm"].as_f64().unwrap() - (mean + 3.0 * sd)).abs() < 1e-9);
    // The distance P2-P4 grows as P2 rises: D_j from the closed form.
    let d: Vec<f64> = (1..=6)
        .map(|c| {
            distance(
                [900.0, -100.0, 400.0 + 0.05 * c as f64],
                [1100.3, 100.0, 600.0],
            )
        })
        .collect();
    let d_mean = d.iter().sum::<f64>() / 6.0;
    let d_sd = (d.iter().map(|v| (v - d_mean).powi(2)).sum::<f64>() / 5.0).sqrt();
    let commanded = distance([900.0, -100.0, 400.0], [1100.0, 100.0, 600.0]);
    let distance_json = &json["characteristics"]["distance"];
    assert!((distance_json["ad_mm"].as_f64().unwrap() - (d_mean - commanded)).abs() < 1e-9);
    assert!((distance_json["rd_mm"].as_f64().unwrap() - 3.0 * d_sd).abs() < 1e-9);
    assert!(
        json["characteristics"]["notes"][0]
            .as_str()
            .unwrap()
            .contains("6 cycles")
    );
}

/// Refused, and no report written: a run in a tracker frame evaluated with a robot file that
/// does not place the tracker; a row of no target; a point measured once; a cube point out of
/// reach.
#[test]
fn what_cannot_be_evaluated_is_refused_with_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let targets = dir.path().join("targets.csv");
    std::fs::write(
        &targets,
        "id,x_mm,y_mm,z_mm,qw,qx,qy,qz\nP1,1000,0,500,1,0,0,0\n",
    )
    .unwrap();
    let report = dir.path().join("test.json");
    let cases = [
        (
            "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm\nP1-c1,0,0,0,0,0,0,1,2,3\nP1-c2,0,0,0,0,0,0,1,2,3\n",
            "no [measurement] section",
        ),
        (
            "# frame: base\nid,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm\nP1-c1,0,0,0,0,0,0,1,2,3\nP9-c1,0,0,0,0,0,0,1,2,3\n",
            "names no target",
        ),
        (
            "# frame: base\nid,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm\nP1-c1,0,0,0,0,0,0,1,2,3\n",
            "at least 2 cycles",
        ),
    ];
    for (run, message) in cases {
        let data = dir.path().join("run.csv");
        std::fs::write(&data, run).unwrap();
        let out = calib(&[
            "iso9283",
            "evaluate",
            "--targets",
            s(&targets),
            "--data",
            s(&data),
            "--robot",
            ROBOT,
            "--report",
            s(&report),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && stderr.contains(message),
            "{message}: {stderr}"
        );
        assert!(!report.exists());
    }
    let out = calib(&[
        "iso9283",
        "plan",
        "--robot",
        ROBOT,
        "--centre-mm",
        "1200,0,800",
        "--edge-mm",
        "3000",
        "--near-deg",
        "0,-30,30,0,60,0",
        "--targets",
        s(&targets),
        "--out",
        s(&report),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("cannot be reached"),
        "{stderr}"
    );
    assert!(!report.exists());
}

/// A test recorded in the registry is listed with its cycles and largest AP and RP, shown whole
/// as evaluated; the same run recorded again is refused and its report left as it was.
#[test]
fn a_pose_test_is_recorded_once_and_listed() {
    let dir = tempfile::tempdir().unwrap();
    let (targets, data) = drifting_run(dir.path());
    let (db, report) = (dir.path().join("calib.db"), dir.path().join("test.json"));
    let evaluate = [
        "iso9283",
        "evaluate",
        "--targets",
        s(&targets),
        "--data",
        s(&data),
        "--robot",
        ROBOT,
        "--report",
        s(&report),
        "--registry",
        s(&db),
        "--serial",
        "ER-7",
        "--tested-at",
        "2026-11-29T06:00:00Z",
    ];
    let text = ok(&calib(&evaluate));
    assert!(text.contains("recorded as pose test 1 of ER-7"), "{text}");
    let evaluated: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let points = evaluated["characteristics"]["points"].as_array().unwrap();
    let largest = |key: &str| {
        points
            .iter()
            .map(|p| p[key].as_f64().unwrap())
            .fold(0.0, f64::max)
    };
    let listed: serde_json::Value = serde_json::from_str(&ok(&calib(&[
        "registry",
        "pose-tests",
        "--serial",
        "ER-7",
        "--json",
        "--db",
        s(&db),
    ])))
    .unwrap();
    assert_eq!(listed[0]["cycles"], 6);
    assert_eq!(listed[0]["tested_at"], "2026-11-29T06:00:00Z");
    assert_eq!(listed[0]["ap_max_mm"].as_f64().unwrap(), largest("ap_mm"));
    assert_eq!(listed[0]["rp_max_mm"].as_f64().unwrap(), largest("rp_mm"));
    let whole: serde_json::Value = serde_json::from_str(&ok(&calib(&[
        "registry",
        "pose-tests",
        "--serial",
        "ER-7",
        "--id",
        "1",
        "--json",
        "--db",
        s(&db),
    ])))
    .unwrap();
    assert_eq!(whole, evaluated);
    std::fs::write(&report, "kept").unwrap();
    let again = calib(&evaluate);
    let stderr = String::from_utf8_lossy(&again.stderr);
    assert!(
        !again.status.success() && stderr.contains("already recorded for ER-7 as pose test 1"),
        "{stderr}"
    );
    assert_eq!(std::fs::read_to_string(&report).unwrap(), "kept");
}

/// The certificate of a calibration with its pose test (`calib report --pose-test`): the
/// section follows the held-out accuracy and states each point's AP and RP as evaluated; a
/// file that is not a pose test is refused and no page written.
#[test]
fn the_certificate_shows_the_pose_test() {
    let dir = tempfile::tempdir().unwrap();
    let (targets, data) = drifting_run(dir.path());
    let test = dir.path().join("test.json");
    ok(&calib(&[
        "iso9283",
        "evaluate",
        "--targets",
        s(&targets),
        "--data",
        s(&data),
        "--robot",
        ROBOT,
        "--report",
        s(&test),
    ]));
    let (calibration_data, _) = simulate(
        dir.path(),
        "cal",
        &["--poses", "40", "--within-limits", "--seed", "2"],
    );
    let report = dir.path().join("cal.json");
    ok(&calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        s(&calibration_data),
        "--method",
        "lm",
        "--out",
        s(&dir.path().join("cal.toml")),
        "--report",
        s(&report),
        "--quiet",
    ]));
    let html = dir.path().join("certificate.html");
    ok(&calib(&[
        "report",
        "--from",
        s(&report),
        "--pose-test",
        s(&test),
        "--html",
        s(&html),
    ]));
    let page = std::fs::read_to_string(&html).unwrap();
    let ids: Vec<&str> = page
        .split("<h2 id=\"")
        .skip(1)
        .map(|rest| &rest[..rest.find('"').unwrap()])
        .collect();
    let at = ids.iter().position(|id| *id == "pose-test").unwrap();
    assert_eq!(ids[at - 1], "accuracy", "{ids:?}");
    let evaluated: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&test).unwrap()).unwrap();
    for p in evaluated["characteristics"]["points"].as_array().unwrap() {
        let row = format!(
            "<tr><td>{}</td><td>6</td><td>{:.4}</td>",
            p["point"].as_str().unwrap(),
            p["ap_mm"].as_f64().unwrap()
        );
        assert!(page.contains(&row), "{row}");
        assert!(page.contains(&format!("{:.4}</td>", p["rp_mm"].as_f64().unwrap())));
    }
    assert!(page.contains("dAP 0.2000&nbsp;mm"), "the drift in words");
    std::fs::remove_file(&html).unwrap();
    let out = calib(&[
        "report",
        "--from",
        s(&report),
        "--pose-test",
        s(&report),
        "--html",
        s(&html),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("not the JSON of calib iso9283 evaluate"),
        "{stderr}"
    );
    assert!(!html.exists());
}
