//! Numerical inverse kinematics on the shipped 7-joint robots (`calib_core::controller::
//! numerical_ik`): 1,000 random reachable targets per robot (the forward kinematics of random
//! joints within the limits), each solution checked independently by forward kinematics against
//! its target and against the joint limits.

use calib_core::Kinematics;
use calib_core::controller::numerical_ik::{NumericalIkSettings, numerical_inverse_kinematics};
use calib_core::kinematics::pose_error::PoseError;
use calib_core::model::JointVec;
use host_tools::io::robot_file::{RobotFile, RobotModel};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::path::Path;

fn reach(file: &str) -> (usize, usize, u32) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("robots")
        .join(file);
    let model: RobotModel = RobotFile::read(&path).unwrap().to_model(&path).unwrap();
    let kinematics = Kinematics::nominal(&model.robot).unwrap();
    let limits = model.robot.limits;
    // The documented reference posture: the middle of each joint's range.
    let reference = calib_core::model::JointVec::<f64>::from_fn(7, |j| {
        0.5 * (limits[j].lower + limits[j].upper)
    });
    let settings = NumericalIkSettings::default();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(15);
    let (mut reached, mut refused, mut most_seeds) = (0, 0, 0);
    for _ in 0..1000 {
        let q = calib_core::model::JointVec::<f64>::from_fn(7, |j| {
            rng.random_range(limits[j].lower..limits[j].upper)
        });
        let target = kinematics.forward(&q).unwrap();
        match numerical_inverse_kinematics(&kinematics, &limits, &target, &reference, &settings) {
            Ok(solution) => {
                let pose = kinematics.forward(&solution.q).unwrap();
                let e = PoseError::between(&target, &pose);
                assert!(
                    e.position.norm() <= 1e-3 && e.rotation.norm() <= 1e-6,
                    "{file}: {} mm {} rad",
                    e.position.norm(),
                    e.rotation.norm()
                );
                assert!(
                    solution.q.iter().zip(&limits).all(|(v, l)| l.contains(*v)),
                    "{file}: outside the limits {:?}",
                    solution.q
                );
                most_seeds = most_seeds.max(solution.seed + 1);
                reached += 1;
            }
            Err(e) => {
                println!("{file}: refused: {e}");
                refused += 1;
            }
        }
    }
    println!(
        "{file}: {reached} of 1000 reached to 1e-3 mm within the limits, {refused} refused, at most {most_seeds} seeds used"
    );
    (reached, refused, most_seeds)
}

#[test]
fn the_reference_posture_wins_and_an_unreachable_target_is_an_error() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("robots/kuka-iiwa14.toml");
    let model: RobotModel = RobotFile::read(&path).unwrap().to_model(&path).unwrap();
    let kinematics = Kinematics::nominal(&model.robot).unwrap();
    let settings = NumericalIkSettings::default();
    let reference = JointVec::from_slice(&[0.3, 0.5, -0.2, -1.2, 0.4, 0.9, 0.1]).unwrap();
    // A target a little away from the reference's pose: solved from the reference (seed 0),
    // and the minimum-norm steps stay near it.
    let near = JointVec::from_slice(&[0.32, 0.48, -0.18, -1.25, 0.42, 0.87, 0.12]).unwrap();
    let target = kinematics.forward(&near).unwrap();
    let solution = numerical_inverse_kinematics(
        &kinematics,
        &model.robot.limits,
        &target,
        &reference,
        &settings,
    )
    .unwrap();
    assert_eq!(solution.seed, 0);
    let moved = solution
        .q
        .iter()
        .zip(&reference)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(moved < 0.2, "{moved} rad from the reference");
    // 5 m away: out of reach of a 1.3 m arm, refused after every seed.
    let far = calib_core::Pose::from_parts(
        nalgebra::Translation3::new(5000.0, 0.0, 0.0),
        nalgebra::Rotation3::identity(),
    );
    let e = numerical_inverse_kinematics(
        &kinematics,
        &model.robot.limits,
        &far,
        &reference,
        &settings,
    )
    .unwrap_err();
    assert_eq!(
        e,
        calib_core::controller::numerical_ik::NumericalIkError::NotFound { seeds: 128 }
    );
}

#[test]
fn seven_joint_robots_reach_999_of_1000_random_targets() {
    for file in ["franka-panda.toml", "kuka-iiwa14.toml", "barrett-wam.toml"] {
        let (reached, refused, _) = reach(file);
        assert_eq!(reached + refused, 1000);
        assert!(reached >= 999, "{file}: {reached} of 1000");
    }
}
