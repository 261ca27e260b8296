//! The core's forward kinematics against the independent f64 reference on 10,000 random joint
//! configurations of the ER10L-C10 with Table 2 errors applied, in f64 and in f32.

use calib_core::{FramePose, Kinematics, ParameterErrors, Real, Robot};
use calib_tests::{distance, er10l_file, table2, table2_errors, uniform};
use host_tools::analysis::reference::{self, RefModel};
use host_tools::io::robot_file::{FrameEntry, RobotFile, RobotModel};
use nalgebra::U6;
use rand_core::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::PI;
use std::path::Path;

const CONFIGURATIONS: usize = 10_000;

/// Largest position (mm) and rotation (rad) disagreement over random configurations.
fn worst_disagreement<T: Real>(
    file: &RobotFile,
    errors: &ParameterErrors<T, U6>,
    reference: &RefModel,
    seed: u64,
) -> (f64, f64) {
    let model = file.to_model(Path::new("test")).unwrap();
    let robot: Robot<T, U6> = convert(&model.robot.recount().unwrap());
    let kinematics = Kinematics::new(&robot, errors).unwrap();
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let (mut worst_p, mut worst_r) = (0.0f64, 0.0f64);
    for _ in 0..CONFIGURATIONS {
        let q: [T; 6] = std::array::from_fn(|_| T::of(uniform(&mut rng, -PI, PI)));
        // The reference sees exactly the readings the core sees (rounded to T).
        let q64: Vec<f64> = q.iter().map(|v| v.to_f64()).collect();
        let (dp, dr) = distance(&kinematics.forward(&q).unwrap(), &reference.forward(&q64));
        worst_p = worst_p.max(dp);
        worst_r = worst_r.max(dr);
    }
    (worst_p, worst_r)
}

fn convert<T: Real>(robot: &Robot<f64, U6>) -> Robot<T, U6> {
    let mut out = Robot::from_joints(robot.joints.map(|j| calib_core::MdhJoint {
        a: T::of(j.a),
        alpha: T::of(j.alpha),
        theta_offset: T::of(j.theta_offset),
        d: T::of(j.d),
        beta: T::of(j.beta),
    }));
    let frame = |f: &FramePose<f64>| FramePose {
        xyz: f.xyz.map(T::of),
        rpy: f.rpy.map(T::of),
    };
    out.base = frame(&robot.base);
    out.tool = frame(&robot.tool);
    out
}

#[test]
fn f64_core_agrees_with_reference_on_10000_configurations() {
    let file = er10l_file();
    let reference = reference::model(&file, &table2(), &[0.0; 6], &[0.0; 6]);
    let (dp, dr) = worst_disagreement::<f64>(&file, &table2_errors(), &reference, 1);
    println!("f64: worst position {dp:.3e} mm, worst rotation {dr:.3e} rad");
    assert!(dp < 1e-9, "position disagreement {dp} mm");
    assert!(dr < 1e-12, "rotation disagreement {dr} rad");
}

#[test]
fn f32_core_agrees_with_reference_on_10000_configurations() {
    let file = er10l_file();
    // The f32 core adds nominal and error in f32; the reference uses the exact f64 values.
    let reference = reference::model(&file, &table2(), &[0.0; 6], &[0.0; 6]);
    let (dp, dr) = worst_disagreement::<f32>(&file, &table2_errors(), &reference, 2);
    println!("f32: worst position {dp:.3e} mm, worst rotation {dr:.3e} rad");
    assert!(dp < 2e-3, "position disagreement {dp} mm");
    assert!(dr < 2e-6, "rotation disagreement {dr} rad");
}

#[test]
fn f64_core_agrees_with_reference_with_base_and_tool_frames() {
    let mut file = er10l_file();
    file.base = Some(FrameEntry {
        xyz_mm: [2500.0, -800.0, 300.0],
        rpy_deg: [3.0, -88.0, 135.0],
    });
    file.tool = Some(FrameEntry {
        xyz_mm: [10.0, -25.0, 140.0],
        rpy_deg: [-170.0, 45.0, 20.0],
    });
    let base_errors = [0.7, -0.3, 0.2, 0.004, -0.002, 0.006];
    let tool_errors = [-0.2, 0.4, -0.6, -0.003, 0.005, 0.001];
    let reference = reference::model(&file, &table2(), &base_errors, &tool_errors);
    let mut errors = table2_errors::<f64>();
    errors.base.translation = [0.7, -0.3, 0.2];
    errors.base.rotation = [0.004, -0.002, 0.006];
    errors.tool.translation = [-0.2, 0.4, -0.6];
    errors.tool.rotation = [-0.003, 0.005, 0.001];
    let (dp, dr) = worst_disagreement::<f64>(&file, &errors, &reference, 3);
    println!("f64 with frames: worst position {dp:.3e} mm, worst rotation {dr:.3e} rad");
    assert!(dp < 1e-9, "position disagreement {dp} mm");
    assert!(dr < 1e-12, "rotation disagreement {dr} rad");
}

#[test]
fn nominal_model_file_loads_with_table1_values() {
    let model = RobotModel::load(&calib_tests::repo("host-tools/robots/er10l-c10.toml")).unwrap();
    assert_eq!(model.name, "Efort ER10L-C10");
    assert_eq!(model.robot.joints[1].a, 780.0);
    assert_eq!(model.robot.joints[1].theta_offset, -PI / 2.0);
    assert_eq!(model.robot.joints[3].d, 1060.0);
    assert_eq!(model.mask.count(), 24);
}

#[test]
fn core_paper_tables_equal_the_robot_file_and_table2_csv() {
    let model = RobotModel::load(&calib_tests::repo("host-tools/robots/er10l-c10.toml")).unwrap();
    assert_eq!(
        calib_core::model::paper::er10l_c10::<f64>().recount(),
        Some(model.robot)
    );
    assert_eq!(
        calib_core::model::paper::table2::<f64>(),
        table2_errors::<f64>()
    );
}
