//! A whole `calib calibrate --model joint-maps` (and `joint-maps+compliance`) run (files read,
//! geometric calibration by least squares, then the maps with the evidence and the
//! cross-validation check) on 50 and on 1000 random poses of the real UR10 Series B,
//! position-only profile, `--auto-mask --method lm`: the speed goals of issue 14 (under 2 s and
//! under 30 s) and issue 56 (1000 poses, compliance included, under 5 s).
//!
//! Run: `cargo bench -p host-tools --bench joint_maps`.

// Set-up of fixed, valid inputs: a failure here is a bug in the benchmark itself.
#![allow(clippy::unwrap_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use host_tools::calibration::{CalibrationConfig, ErrorModel, Method, calibrate};
use host_tools::io::profile::DataProfile;
use host_tools::measurement::dataset::{Dataset, split};
use std::path::Path;

fn joint_maps(c: &mut Criterion) {
    let robot = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml"));
    let data = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv"
    ));
    let profile = DataProfile::load(Some(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/profiles/ipa-ur10-lasertracker-position.toml"
    ))))
    .unwrap();
    let mut group = c.benchmark_group("joint_maps");
    group.sample_size(10);
    let models = [
        ("joint_maps", ErrorModel::JointMaps),
        ("joint_maps_compliance", ErrorModel::JointMapsCompliance),
    ];
    for ((name, model), poses) in models
        .iter()
        .flat_map(|m| [50usize, 1000].map(|poses| (*m, poses)))
    {
        let config = CalibrationConfig {
            method: Method::Lm,
            model,
            auto_mask: true,
            ..CalibrationConfig::default()
        };
        group.bench_function(format!("calibrate_{name}_series_b_{poses}_poses"), |b| {
            b.iter(|| {
                // As `calib calibrate --validate` runs: the file read, the poses drawn.
                let all = Dataset::load_with(robot, data, &profile).unwrap();
                let n = all.readings.len();
                let (calibration, _) = split(&all, (n - poses) as f64 / n as f64, 0).unwrap();
                calibrate(calibration, None, &config).unwrap()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, joint_maps);
criterion_main!(benches);
