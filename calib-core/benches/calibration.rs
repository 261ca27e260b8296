//! Calibration benchmarks on the paper's 32-pose scenario (Table 2 errors, noise-free), f64 and
//! f32: one eq. (7) evaluation, the paper's whole swarm run (20 particles, 24 parameters, 2000
//! generations), and Levenberg-Marquardt from the nominal parameters.
//!
//! Run: `cargo bench -p calib-core --bench calibration`.

// Set-up of fixed, valid inputs: a failure here is a bug in the benchmark itself.
#![allow(clippy::unwrap_used)]

use calib_core::Problem;
use calib_core::identify::ipso::{self, IpsoSettings, SearchSpace, Silent};
use calib_core::identify::lm::{LeastSquares, LmSettings};
use calib_core::identify::objective::{
    DEFAULT_K, Measurement, MeasurementSet, Objective, PoseLanes,
};
use calib_core::model::paper::{er10l_c10, table2};
use calib_core::{Kinematics, ParameterErrors, ParameterSet, Real};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::U6;
use nalgebra::allocator::Allocator;
use nalgebra::{DVector, DefaultAllocator, Dim, Dyn, OVector, SVector, U24};
use std::hint::black_box;

fn measurements<T: Real>() -> MeasurementSet<T, U6, 32> {
    let truth = Kinematics::new(&er10l_c10::<T>(), &table2::<T>()).unwrap();
    let mut set = MeasurementSet::new();
    for i in 0..32 {
        let q = std::array::from_fn(|j| T::of(((i * 6 + j) as f64 * 2.399_963).sin() * 3.1));
        set.push(Measurement::from_pose(&q, &truth.forward(&q).unwrap()).unwrap())
            .unwrap();
    }
    set
}

fn paper_run<T: Real>(c: &mut Criterion, name: &str) {
    let robot = er10l_c10::<T>();
    let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
    let data = measurements::<T>();
    let problem = Problem::new(
        &robot,
        &ParameterErrors::zero(),
        set,
        data.as_slice(),
        T::of(DEFAULT_K),
    )
    .unwrap();
    let objective = Objective::new(&problem);
    let space = SearchSpace::paper(&set);
    let x = SVector::<T, 24>::repeat(T::of(1e-3));
    c.bench_function(&format!("objective_32_poses_{name}"), |b| {
        b.iter(|| objective.value(black_box(&x)))
    });
    let mut group = c.benchmark_group("paper_run");
    group.sample_size(10);
    group.bench_function(format!("ipso_20x24x2000_32_poses_{name}"), |b| {
        b.iter(|| {
            let mut cost = |x: &SVector<T, 24>| objective.value(x);
            ipso::optimize::<T, 20, U24>(&mut cost, &space, &IpsoSettings::paper(), &mut Silent)
                .unwrap()
        })
    });
    let problem = Problem::new(
        &robot,
        &ParameterErrors::zero(),
        set,
        data.as_slice(),
        T::of(DEFAULT_K),
    )
    .unwrap();
    let least_squares = LeastSquares::new(&problem);
    group.bench_function(format!("lm_from_nominal_24_32_poses_{name}"), |b| {
        b.iter(|| {
            least_squares
                .solve(black_box(&SVector::zeros()), &LmSettings::default())
                .unwrap()
        })
    });
    group.finish();
}

/// Eq. (7) in f64 from lanes collected once (`Objective::value_of_lanes`), compiled for the
/// baseline (SSE2), for AVX2, and for AVX2 with AVX-512VL's 32 vector registers (lanes of 4 poses
/// in 256-bit vectors, and of 8 poses in AVX-512's 512-bit vectors).
fn objective_lanes(c: &mut Criterion) {
    let robot = er10l_c10::<f64>();
    let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
    let data = measurements::<f64>();
    let problem = Problem::new(
        &robot,
        &ParameterErrors::zero(),
        set,
        data.as_slice(),
        DEFAULT_K,
    )
    .unwrap();
    let objective = Objective::new(&problem);
    let lanes: Vec<PoseLanes<f64, U6>> = objective.lanes().collect();
    let lanes8: Vec<PoseLanes<f64, U6, 8>> = objective.lanes().collect();
    let x = SVector::<f64, 24>::repeat(1e-3);
    c.bench_function("candidate_model_f64", |b| {
        b.iter(|| problem.kinematics(black_box(&x)))
    });
    // The count at run time, as a host runs it.
    let dynamic_problem = Problem::new(
        &robot,
        &ParameterErrors::zero(),
        ParameterSet::<U6, Dyn>::default_for(&robot).unwrap(),
        data.as_slice(),
        DEFAULT_K,
    )
    .unwrap();
    let dynamic = Objective::new(&dynamic_problem);
    let dynamic_x = DVector::<f64>::repeat(24, 1e-3);
    c.bench_function("candidate_model_f64_dyn", |b| {
        b.iter(|| dynamic_problem.kinematics(black_box(&dynamic_x)))
    });
    c.bench_function("objective_32_poses_f64_lanes_baseline", |b| {
        b.iter(|| objective.value_of_lanes(black_box(&x), &lanes))
    });
    #[cfg(target_arch = "x86_64")]
    {
        #[target_feature(enable = "avx2")]
        fn avx2(
            o: &Objective<'_, f64, U6, U24>,
            x: &SVector<f64, 24>,
            l: &[PoseLanes<f64, U6>],
        ) -> f64 {
            o.value_of_lanes(x, l)
        }
        #[target_feature(enable = "avx2,avx512f,avx512vl")]
        fn avx512<const L: usize, D: Dim>(
            o: &Objective<'_, f64, U6, D>,
            x: &OVector<f64, D>,
            l: &[PoseLanes<f64, U6, L>],
        ) -> f64
        where
            DefaultAllocator: Allocator<D>,
        {
            o.value_of_lanes(x, l)
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            c.bench_function("objective_32_poses_f64_lanes_avx2", |b| {
                // SAFETY: AVX2 detected above.
                b.iter(|| unsafe { avx2(&objective, black_box(&x), &lanes) })
            });
        }
        if std::arch::is_x86_feature_detected!("avx512vl") {
            c.bench_function("objective_32_poses_f64_lanes_avx512vl", |b| {
                // SAFETY: AVX-512VL (and so AVX2 and AVX-512F) detected above.
                b.iter(|| unsafe { avx512(&objective, black_box(&x), &lanes) })
            });
            c.bench_function("objective_32_poses_f64_lanes_avx512vl_dyn", |b| {
                // SAFETY: as above.
                b.iter(|| unsafe { avx512(&dynamic, black_box(&dynamic_x), &lanes) })
            });
            c.bench_function("objective_32_poses_f64_lanes8_avx512", |b| {
                // SAFETY: as above.
                b.iter(|| unsafe { avx512(&objective, black_box(&x), &lanes8) })
            });
        }
    }
}

/// The swarm's own work in the paper's run (velocity and position updates, random numbers,
/// bests: 20 particles, 24 parameters, 2000 generations) with a cost that is almost free (the
/// sum of the coordinates), so the time is what the swarm adds to 40,020 objective evaluations.
fn swarm_alone(c: &mut Criterion) {
    let robot = er10l_c10::<f64>();
    let set = ParameterSet::<U6, U24>::default_for(&robot).unwrap();
    let space = SearchSpace::paper(&set);
    let mut group = c.benchmark_group("paper_run");
    group.bench_function("ipso_20x24x2000_update_only_f64", |b| {
        b.iter(|| {
            let mut cost = |x: &SVector<f64, 24>| x.sum().abs();
            ipso::optimize::<f64, 20, U24>(&mut cost, &space, &IpsoSettings::paper(), &mut Silent)
                .unwrap()
        })
    });
    group.finish();
}

fn benches(c: &mut Criterion) {
    swarm_alone(c);
    objective_lanes(c);
    paper_run::<f64>(c, "f64");
    paper_run::<f32>(c, "f32");
}

criterion_group!(swarm, benches);
criterion_main!(swarm);
