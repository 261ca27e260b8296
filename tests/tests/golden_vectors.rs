//! The core against the golden vectors of an independent numpy implementation
//! (tests/data/vectors, with their README: how and by what they were computed).

use calib_core::kinematics::pose_error::pose_error;
use calib_core::{Kinematics, ParameterErrors, Pose};
use calib_tests::{er10l_file, read_csv, table2_errors};
use host_tools::io::robot_file::RobotModel;
use nalgebra::U6;
use nalgebra::{Matrix3, Vector3};
use std::path::Path;

fn models() -> (Kinematics<f64, U6>, Kinematics<f64, U6>) {
    let model: RobotModel = er10l_file().to_model(Path::new("er10l-c10.toml")).unwrap();
    // The file's robot (a joint count known at run time) as the paper's 6-joint robot.
    let robot = model.robot.recount::<U6>().unwrap();
    (
        Kinematics::new(&robot, &ParameterErrors::zero()).unwrap(),
        Kinematics::new(&robot, &table2_errors()).unwrap(),
    )
}

fn numbers(row: &[String]) -> Vec<f64> {
    row.iter().map(|s| s.parse().unwrap()).collect()
}

fn radians(degrees: &[f64]) -> [f64; 6] {
    std::array::from_fn(|i| degrees[i].to_radians())
}

#[test]
fn forward_kinematics_matches_golden_vectors() {
    let (nominal, actual) = models();
    let (header, rows) = read_csv("vectors/fk-er10l-c10.csv");
    assert_eq!(header[0], "model");
    assert_eq!(rows.len(), 48);
    let mut worst = (0.0f64, 0.0f64);
    for row in &rows {
        let v = numbers(&row[1..]);
        let q = radians(&v[0..6]);
        let kinematics = match row[0].as_str() {
            "nominal" => &nominal,
            "actual" => &actual,
            other => panic!("unknown model {other}"),
        };
        let pose = kinematics.forward(&q).unwrap();
        let position = Vector3::new(v[6], v[7], v[8]);
        let rotation = Matrix3::from_row_slice(&v[9..18]);
        worst.0 = worst.0.max((pose.translation.vector - position).norm());
        worst.1 = worst.1.max((pose.rotation.matrix() - rotation).abs().max());
        // The quaternion column (scalar first) describes the same rotation, up to sign.
        let q_golden = nalgebra::Quaternion::new(v[18], v[19], v[20], v[21]);
        let q_core = nalgebra::UnitQuaternion::from_rotation_matrix(&pose.rotation);
        assert!(q_core.coords.dot(&q_golden.coords).abs() > 1.0 - 1e-15);
    }
    assert!(worst.0 < 1e-9, "position {} mm", worst.0);
    assert!(worst.1 < 1e-13, "rotation entry {}", worst.1);
}

#[test]
fn pose_error_matches_golden_vectors() {
    let (nominal, actual) = models();
    let (header, rows) = read_csv("vectors/pose-error-er10l-c10.csv");
    assert_eq!(header.len(), 12);
    assert_eq!(rows.len(), 24);
    for row in &rows {
        let v = numbers(row);
        let q = radians(&v[0..6]);
        let measured = actual.forward(&q).unwrap();
        let e = pose_error(&nominal, &q, &measured).unwrap();
        for (k, (core, golden)) in e.position.iter().zip(&v[6..9]).enumerate() {
            assert!((core - golden).abs() < 1e-9, "dp[{k}] {core} vs {golden}");
        }
        for (k, (core, golden)) in e.rotation.iter().zip(&v[9..12]).enumerate() {
            assert!((core - golden).abs() < 1e-13, "dr[{k}] {core} vs {golden}");
        }
    }
}

/// Eq. (7), `f = sum_j sqrt(k |dr_j|^2 + |dp_j|^2)`, over the 24 golden configurations, evaluated
/// from the core's pose errors (the objective module of the swarm issue is checked again there).
#[test]
fn objective_of_pose_errors_matches_golden_values() {
    let (nominal, actual) = models();
    let (_, rows) = read_csv("vectors/pose-error-er10l-c10.csv");
    let text =
        std::fs::read_to_string(calib_tests::data("vectors/objective-er10l-c10.txt")).unwrap();
    let mut checked = 0;
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let fields: Vec<&str> = line.split_whitespace().collect();
        let k: f64 = fields[0].trim_start_matches("k=").parse().unwrap();
        let at_truth = fields[1] == "x=table2";
        let golden: f64 = fields[2].trim_start_matches("f=").parse().unwrap();
        let candidate = if at_truth { &actual } else { &nominal };
        let f: f64 = rows
            .iter()
            .map(|row| {
                let q = radians(&numbers(&row[0..6]));
                let e = pose_error(candidate, &q, &actual.forward(&q).unwrap()).unwrap();
                (k * e.rotation.norm_squared() + e.position.norm_squared()).sqrt()
            })
            .sum();
        assert!(
            (f - golden).abs() <= 1e-10 * golden.max(1.0),
            "k={k}: {f} vs {golden}"
        );
        checked += 1;
    }
    assert_eq!(checked, 4);
}

#[test]
fn pose_helpers_are_consistent() {
    // A pose error of a pose against itself is zero, exactly.
    let (nominal, _) = models();
    let q = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6];
    let pose: Pose<f64> = nominal.forward(&q).unwrap();
    let e = pose_error(&nominal, &q, &pose).unwrap();
    assert_eq!(e.position.norm(), 0.0);
    assert!(e.rotation.norm() < 1e-15);
}
