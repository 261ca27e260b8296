//! Kinematics benchmarks: one forward kinematics (f64, f32) and one pose error with its
//! parameter Jacobian (24 parameters) of the ER10L-C10.
//!
//! Run: `cargo bench -p calib-core --bench kinematics`.

// Set-up of fixed, valid inputs: a failure here is a bug in the benchmark itself.
#![allow(clippy::unwrap_used)]

use calib_core::kinematics::JointAngles;
use calib_core::kinematics::pose_error::pose_error_jacobian;
use calib_core::model::paper::er10l_c10 as er10l;
use calib_core::{Kinematics, ParameterErrors, ParameterSet, Real};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::U6;
use nalgebra::U24;
use std::hint::black_box;

fn errors<T: Real>() -> ParameterErrors<T, U6> {
    let mut e = ParameterErrors::zero();
    for (i, j) in e.joints.iter_mut().enumerate() {
        let s = i as f64 + 1.0;
        j.da = T::of(0.1 * s);
        j.dalpha = T::of(0.001 * s);
        j.dtheta = T::of(-0.002 * s);
        j.dd = T::of(0.05 * s);
    }
    e
}

fn forward<T: Real>(c: &mut Criterion, name: &str) {
    let kinematics = Kinematics::new(&er10l::<T>(), &errors()).unwrap();
    let q = [0.3, -0.7, 1.1, 2.0, -1.4, 0.6].map(T::of);
    c.bench_function(name, |b| {
        b.iter(|| black_box(&kinematics).forward(black_box(&q)))
    });
    let angles = JointAngles::new(&q).unwrap();
    c.bench_function(&format!("{name}_precomputed_sin_cos"), |b| {
        b.iter(|| black_box(&kinematics).forward_angles(black_box(&angles)))
    });
    let prepared = calib_core::PreparedRobot::new(&er10l::<T>());
    let e = errors::<T>();
    c.bench_function(&format!("prepare_actual_model_{name}"), |b| {
        b.iter(|| black_box(&prepared).actual(black_box(&e)))
    });
}

fn benches(c: &mut Criterion) {
    forward::<f64>(c, "forward_kinematics_f64");
    forward::<f32>(c, "forward_kinematics_f32");

    let robot = er10l::<f64>();
    let kinematics = Kinematics::nominal(&robot).unwrap();
    let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
    let q = [0.3, -0.7, 1.1, 2.0, -1.4, 0.6];
    let measured = Kinematics::new(&robot, &errors())
        .unwrap()
        .forward(&q)
        .unwrap();
    let angles = JointAngles::new(&q).unwrap();
    c.bench_function("pose_error_and_parameter_jacobian_24_f64", |b| {
        b.iter(|| pose_error_jacobian(black_box(&kinematics), &set, black_box(&angles), &measured))
    });
}

/// One joint-space compensation and one pre-distortion of the ER10L-C10 with Table 2 errors, for
/// a target the nominal controller planned at fixed joints (away from singularities).
fn compensation<T: Real>(c: &mut Criterion, name: &str) {
    use calib_core::controller::compensate::{CompensationSettings, compensate_joints, predistort};
    let nominal = Kinematics::nominal(&er10l::<T>()).unwrap();
    let actual = Kinematics::new(&er10l::<T>(), &calib_core::model::paper::table2::<T>()).unwrap();
    let limits = [calib_core::JointLimits::unlimited(); 6];
    let q = [0.3, -0.4, 0.5, 0.6, -0.7, 0.8].map(T::of);
    let target = nominal.forward(&q).unwrap();
    let settings = CompensationSettings {
        max_correction_mm: T::of(50.0),
        max_correction_rad: T::of(0.1),
        ..CompensationSettings::default()
    };
    c.bench_function(&format!("compensate_joints_{name}"), |b| {
        b.iter(|| {
            compensate_joints(
                &nominal,
                &actual,
                &limits,
                black_box(&target),
                &q,
                &settings,
            )
            .unwrap()
        })
    });
    c.bench_function(&format!("predistort_{name}"), |b| {
        b.iter(|| {
            predistort(
                &nominal,
                &actual,
                &limits,
                black_box(&target),
                &q,
                &settings,
            )
            .unwrap()
        })
    });
}

fn compensation_benches(c: &mut Criterion) {
    compensation::<f64>(c, "f64");
    compensation::<f32>(c, "f32");
}

criterion_group!(kinematics, benches, compensation_benches);
criterion_main!(kinematics);
