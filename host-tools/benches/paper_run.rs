//! The paper's whole swarm run (20 particles, 24 parameters, 2000 generations, 32 poses, f64) as
//! `calib calibrate` runs it: the core's IPSO with the particles evaluated on all cores by a
//! `SwarmTeam` (and on one thread, in AVX-512 and in SSE2, for comparison); then the same
//! scenario end to end: the library's `calibrate` with `--method ipso` and the whole
//! `calib calibrate --method ipso` process (issue 19's goal: at most 20 ms).
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
use calib_core::identify::objective::{DEFAULT_K, Objective};
use calib_core::{ParameterErrors, ParameterSet};
use criterion::{Criterion, criterion_group, criterion_main};
use host_tools::measurement::dataset::Dataset;
use host_tools::runtime::lanes::{LaneObjective, Vectors};
use host_tools::runtime::swarm_team::{SwarmTeam, team_size};
use nalgebra::{DVector, Dyn};
use std::path::Path;

fn paper_run(c: &mut Criterion) {
    let path = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/er10l-c10-sim32.csv"
    ));
    let robot_file = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/robots/er10l-c10.toml"
    ));
    let dataset = Dataset::load(robot_file, path).unwrap();
    let (measurements, robot) = (dataset.readings, dataset.robot.model.robot);
    // The counts at run time, as `calibrate` has them.
    let set = ParameterSet::<Dyn, Dyn>::default_for(&robot).unwrap();
    let problem = Problem::new(
        &robot,
        &ParameterErrors::zeros_for(robot.joint_count()),
        set,
        &measurements,
        DEFAULT_K,
    )
    .unwrap();
    let objective = Objective::new(&problem);
    let space = SearchSpace::paper(problem.set());
    let mut group = c.benchmark_group("paper_run");
    group.sample_size(10);
    let lanes = LaneObjective::new(&objective);
    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
    let settings = IpsoSettings::paper();
    let swarm = |lanes: &LaneObjective<'_, '_>, threads: usize| {
        SwarmTeam::run(lanes, threads, |team| {
            let mut x: [DVector<f64>; 20] = std::array::from_fn(|_| DVector::zeros(24));
            let (mut v, mut best) = (x.clone(), x.clone());
            let (mut costs, mut best_costs) = ([0.0; 20], [0.0; 20]);
            let memory =
                ipso::SwarmMemory::new(&mut x, &mut v, &mut best, &mut costs, &mut best_costs)
                    .unwrap();
            team.optimize(memory, &space, &settings, &mut Silent)
                .unwrap()
        })
    };
    group.bench_function("ipso_20x24x2000_32_poses_f64_all_cores", |b| {
        b.iter(|| swarm(&lanes, team_size(cores, 20)))
    });
    group.bench_function("ipso_20x24x2000_32_poses_f64_one_thread", |b| {
        b.iter(|| swarm(&lanes, 1))
    });
    // What the lanes' wider vectors earn: the same on one thread in the baseline's SSE2 (the
    // objective and the swarm's update; AVX-512 where the CPU has it is the default above).
    let baseline = LaneObjective::with_vectors(&objective, Vectors::Baseline);
    group.bench_function("ipso_20x24x2000_32_poses_f64_one_thread_sse2", |b| {
        b.iter(|| swarm(&baseline, 1))
    });
    group.finish();

    // End to end, as `calib calibrate --robot robots/er10l-c10.toml --data
    // data/er10l-c10-sim32.csv --method ipso` runs it: in the library, and as a whole process.
    use host_tools::calibration::{CalibrationConfig, Method, calibrate};
    let config = CalibrationConfig {
        method: Method::Ipso,
        ..CalibrationConfig::default()
    };
    let mut group = c.benchmark_group("paper_run_end_to_end");
    group.sample_size(20);
    group.bench_function("calibrate_ipso_library", |b| {
        b.iter(|| {
            let dataset = Dataset::load(robot_file, path).unwrap();
            calibrate(dataset, None, &config).unwrap()
        })
    });
    let out = tempfile::tempdir().unwrap();
    let model = out.path().join("model.toml");
    group.bench_function("calib_calibrate_ipso_process", |b| {
        b.iter(|| {
            let status = std::process::Command::new(env!("CARGO_BIN_EXE_calib"))
                .arg("calibrate")
                .arg("--robot")
                .arg(robot_file)
                .arg("--data")
                .arg(path)
                .args(["--method", "ipso", "--out"])
                .arg(&model)
                .stdout(std::process::Stdio::null())
                .status()
                .unwrap();
            assert!(status.success());
        })
    });
    group.finish();
}

fn calibrate_runs(c: &mut Criterion) {
    use host_tools::calibration::{CalibrationConfig, calibrate};
    use host_tools::io::profile::DataProfile;
    use host_tools::io::robot_file::RobotFile;
    use host_tools::measurement::dataset::Dataset;
    use host_tools::measurement::simulate::{self, SimulationConfig};
    use std::path::Path;
    let dir = tempfile::tempdir().unwrap();
    let robot = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/robots/er10l-c10.toml"
    ));
    let data = dir.path().join("cell100.csv");
    let config = SimulationConfig {
        poses: 100,
        seed: 5,
        position_sigma_mm: 0.02,
        orientation_sigma_rad: 1e-4,
        ..SimulationConfig::default()
    }
    .in_realistic_cell();
    simulate::simulate(&RobotFile::read(robot).unwrap(), robot, &config)
        .unwrap()
        .write(&data, &dir.path().join("cell100-truth.toml"), robot)
        .unwrap();
    let ur10 = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml"));
    let series_b = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv"
    ));
    let profile = DataProfile::load(Some(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/profiles/ipa-ur10-lasertracker.toml"
    ))))
    .unwrap();
    // As `calib calibrate` runs: the files read, then the calibration with the default settings.
    let run = |robot: &Path, data: &Path, profile: &DataProfile| {
        let dataset = Dataset::load_with(robot, data, profile).unwrap();
        calibrate(dataset, None, &CalibrationConfig::default()).unwrap()
    };
    let mut group = c.benchmark_group("calibrate");
    group.sample_size(10);
    group.bench_function("calibrate_100_poses_tracker_frame_ipso_lm", |b| {
        b.iter(|| run(robot, &data, &DataProfile::default()))
    });
    group.bench_function("calibrate_ur10_series_b_1495_poses_ipso_lm", |b| {
        b.iter(|| run(ur10, series_b, &profile))
    });
    group.finish();
}

criterion_group!(benches, paper_run, calibrate_runs);
criterion_main!(benches);
