//! Kinematics benchmarks: one forward kinematics (f64, f32) and one pose error with its
//! parameter Jacobian (24 parameters) of the ER10L-C10.
//!
//! Run: `cargo bench -p calib-core --bench kinematics`.

// Set-up of fixed, valid inputs: a failure here is a bug in the benchmark itself.
#![allow(clippy::unwrap_used)]

use calib_core::kinematics::JointAngles;
use calib_core::paper::er10l_c10 as er10l;
use calib_core::pose_error::pose_error_jacobian;
use calib_core::{Kinematics, ParameterErrors, ParameterMask, ParameterSet, Real};
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

fn errors<T: Real>() -> ParameterErrors<T, 6> {
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
    let set = ParameterSet::<6, 24>::from_mask(&ParameterMask::default_for(&robot)).unwrap();
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

criterion_group!(kinematics, benches);
criterion_main!(kinematics);
