//! `calib plan`'s selection from 1,000 candidates (issue 18: under 1 s): a UR10, candidates
//! generated within its joint limits, 30 fitted poses (12 D-optimal core, 18 fill) and 15
//! verification poses, 6-DoF measurements, with the prediction.
//!
//! Run: `cargo bench -p host-tools --bench plan`.

// Set-up of fixed, valid inputs: a failure here is a bug in the benchmark itself.
#![allow(clippy::unwrap_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use host_tools::io::robot_file::RobotFile;
use host_tools::planning::{self, Measure, PlanModel, PlanSettings};
use std::path::Path;

fn plan_from_1000_candidates(c: &mut Criterion) {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/robots/ur10.toml"));
    let file = RobotFile::read(path).unwrap();
    let candidates = planning::generate(&file, path, 1000, None).unwrap();
    let settings = PlanSettings {
        poses: 30,
        core: planning::DEFAULT_CORE,
        verify: planning::DEFAULT_VERIFY,
        min_distance_deg: planning::DEFAULT_MIN_DISTANCE_DEG,
        measure: Measure::Pose,
        model: PlanModel::Geometric,
        noise_mm: 0.3,
        noise_deg: 0.04,
        k: calib_core::identify::objective::DEFAULT_K,
        seed: 1,
    };
    c.bench_function("plan_1000_candidates_30_poses", |b| {
        b.iter(|| planning::plan(&file, path, &candidates, &settings).unwrap())
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = plan_from_1000_candidates
}
criterion_main!(benches);
