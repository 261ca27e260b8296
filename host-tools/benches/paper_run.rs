//! The paper's whole swarm run (20 particles, 24 parameters, 2000 generations, 32 poses, f64) as
//! `calib calibrate` runs it: the core's IPSO with the particles evaluated on all cores.
//!
//! Also a whole `calib calibrate` run on 100 poses measured in the tracker's frame (default
//! method ipso+lm, frames registered and identified, files read and checked), and on the real
//! UR10 Series B file (1495 poses, data profile).
//!
//! Run: `cargo bench -p host-tools --bench paper_run`.

// Set-up of fixed, valid inputs: a failure here is a bug in the benchmark itself.
#![allow(clippy::unwrap_used)]

use calib_core::Problem;
use calib_core::identify::ipso::{self, IpsoSettings, SearchSpace, Silent};
use calib_core::identify::objective::{DEFAULT_K, Measurement, Objective};
use calib_core::{ParameterErrors, ParameterSet};
use criterion::{Criterion, criterion_group, criterion_main};
use host_tools::calibration::Parallel;
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
    let robot = calib_core::model::paper::er10l_c10::<f64>();
    let set = ParameterSet::<6, 24>::default_for(&robot).unwrap();
    let problem = Problem::new(
        &robot,
        &ParameterErrors::zero(),
        set,
        &measurements,
        DEFAULT_K,
    )
    .unwrap();
    let objective = Objective::new(&problem);
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

#[derive(clap::Parser)]
#[command(no_binary_name = true)]
struct Wrap<T: clap::Args> {
    #[command(flatten)]
    inner: T,
}

fn calibrate_runs(c: &mut Criterion) {
    use clap::Parser;
    use host_tools::calibrate::{self, CalibrateOptions};
    use host_tools::simulate::{self, Simulation};
    let dir = tempfile::tempdir().unwrap();
    let robot = concat!(env!("CARGO_MANIFEST_DIR"), "/robots/er10l-c10.toml");
    let data = dir.path().join("cell100.csv");
    let truth = dir.path().join("cell100-truth.toml");
    let data = data.to_str().unwrap();
    let head = [
        "--robot",
        robot,
        "--poses",
        "100",
        "--seed",
        "5",
        "--position-sigma-mm",
        "0.02",
        "--orientation-sigma-rad",
        "1e-4",
    ];
    let tail = ["--out", data, "--truth-out", truth.to_str().unwrap()];
    let args = [&head[..], &simulate::REALISTIC_CELL, &tail].concat();
    simulate::simulate(&Wrap::<Simulation>::parse_from(args).inner).unwrap();
    let options =
        Wrap::<CalibrateOptions>::parse_from(["--robot", robot, "--data", data, "--quiet"]).inner;
    let ur10 = Wrap::<CalibrateOptions>::parse_from([
        "--robot",
        concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml"),
        "--data",
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv"
        ),
        "--profile",
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/profiles/ipa-ur10-lasertracker.toml"
        ),
        "--quiet",
    ])
    .inner;
    let mut group = c.benchmark_group("calibrate");
    group.sample_size(10);
    group.bench_function("calibrate_100_poses_tracker_frame_ipso_lm", |b| {
        b.iter(|| calibrate::calibrate(&options).unwrap())
    });
    group.bench_function("calibrate_ur10_series_b_1495_poses_ipso_lm", |b| {
        b.iter(|| calibrate::calibrate(&ur10).unwrap())
    });
    group.finish();
}

criterion_group!(benches, paper_run, calibrate_runs);
criterion_main!(benches);
