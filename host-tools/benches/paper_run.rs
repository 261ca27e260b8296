//! The paper's whole swarm run (20 particles, 24 parameters, 2000 generations, 32 poses, f64) as
//! `calib calibrate` runs it: the core's IPSO with the particles evaluated on all cores.
//!
//! Run: `cargo bench -p host-tools --bench paper_run`.

// Set-up of fixed, valid inputs: a failure here is a bug in the benchmark itself.
#![allow(clippy::unwrap_used)]

use calib_core::ipso::{self, IpsoSettings, SearchSpace, Silent};
use calib_core::objective::{DEFAULT_K, Measurement, Objective};
use calib_core::{ParameterErrors, ParameterMask, ParameterSet};
use criterion::{Criterion, criterion_group, criterion_main};
use host_tools::calibrate::Parallel;
use host_tools::tracker_data::TrackerData;
use nalgebra::Vector3;
use std::path::Path;

fn paper_run(c: &mut Criterion) {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/er10l-c10-sim32.csv"
    ));
    let data = TrackerData::read(path).unwrap();
    let measurements: Vec<Measurement<f64, 6>> = data
        .records
        .iter()
        .map(|r| {
            let q: [f64; 6] = std::array::from_fn(|i| r.q[i]);
            Measurement::new(&q, Vector3::from(r.position), r.rotation, 1.0).unwrap()
        })
        .collect();
    let robot = calib_core::paper::er10l_c10::<f64>();
    let set = ParameterSet::<6, 24>::from_mask(&ParameterMask::default_for(&robot)).unwrap();
    let objective = Objective::new(
        &robot,
        &ParameterErrors::zero(),
        set,
        &measurements,
        DEFAULT_K,
    )
    .unwrap();
    let space = SearchSpace::paper(&set);
    let mut group = c.benchmark_group("paper_run");
    group.sample_size(10);
    group.bench_function("ipso_20x24x2000_32_poses_f64_parallel", |b| {
        b.iter(|| {
            ipso::optimize::<f64, 20, 24>(
                &mut Parallel(&objective),
                &space,
                &IpsoSettings::paper(),
                &mut Silent,
            )
            .unwrap()
        })
    });
    group.finish();
}

criterion_group!(benches, paper_run);
criterion_main!(benches);
