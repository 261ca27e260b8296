//! The registry at fleet scale (issue 55): 10,000 robots with 10 calibrations each, every record
//! the size of a real one (the README's UR10 calibration: its report without the per-pose
//! lists, its identified file with the covariance), and the commands a user runs on it, each a
//! whole `calib` process: `registry list` (all 100,000 lines), `list --serial` (one robot's
//! ten), `show ID`, `compare A B` and the fleet page (`registry fleet`: every robot's row). The
//! goal: each under 1 s.
//!
//! The registry is built once (about 10 GB, a few minutes) in Cargo's temporary folder for
//! benchmarks (`target/tmp/registry-bench/fleet.db`) and kept for later runs (migrated to this
//! version's schema when an earlier one built it); its size is printed.
//!
//! Run: `cargo bench -p host-tools --bench registry`.

// Set-up of fixed, valid inputs: a failure here is a bug in the benchmark itself.
#![allow(clippy::unwrap_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use host_tools::registry::record::{NewRecord, RecordFiles, sha256};
use host_tools::registry::{Access, Registry};
use std::path::{Path, PathBuf};
use std::process::Command;

const CALIB: &str = env!("CARGO_BIN_EXE_calib");
const ROBOTS: usize = 10_000;
const CALIBRATIONS: usize = 10;

/// Runs `calib` with `args`; its standard output's length (the run must succeed).
fn calib(args: &[&str]) -> usize {
    let out = Command::new(CALIB).args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout.len()
}

/// The README's calibration's record, as `calib registry add` makes it.
fn template(dir: &Path) -> NewRecord {
    let manifest = env!("CARGO_MANIFEST_DIR");
    let (report, identified) = (dir.join("ur10.json"), dir.join("ur10-identified.toml"));
    calib(&[
        "calibrate",
        "--robot",
        &format!("{manifest}/robots/ur10.toml"),
        "--data",
        &format!("{manifest}/data/ipa-ur10-lasertracker/series-b-joint-configurations.csv"),
        "--profile",
        &format!("{manifest}/profiles/ipa-ur10-lasertracker.toml"),
        "--validate",
        "0.9666",
        "--report",
        report.to_str().unwrap(),
        "--out",
        identified.to_str().unwrap(),
    ]);
    NewRecord::from_files(&RecordFiles {
        report: Some(&report),
        identified: Some(&identified),
        serial: Some("TEMPLATE"),
        ..RecordFiles::default()
    })
    .unwrap()
}

/// The fleet's registry, built when missing.
fn fleet() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("registry-bench");
    let db = dir.join("fleet.db");
    if db.exists() {
        // Built by an earlier version: migrated to this schema, as a registration would.
        drop(Registry::open(&db, Access::Write).unwrap());
        return db;
    }
    std::fs::create_dir_all(&dir).unwrap();
    let template = template(&dir);
    let partial = dir.join("fleet.db.partial");
    let _ = std::fs::remove_file(&partial);
    let mut registry = Registry::open(&partial, Access::Write).unwrap();
    let started = std::time::Instant::now();
    for robot in 0..ROBOTS {
        let records: Vec<NewRecord> = (0..CALIBRATIONS)
            .map(|k| NewRecord {
                serial: format!("UR10-{robot:05}"),
                calibrated_at: format!("{}-0{}-15T08:00:00Z", 2016 + k, 1 + robot % 9),
                held_out_mm: template.held_out_mm.map(|v| v * (1.0 + 0.01 * k as f64)),
                report_sha256: sha256(format!("{robot} {k}").as_bytes()),
                ..template.clone()
            })
            .collect();
        registry.add_all(&records).unwrap();
    }
    drop(registry);
    std::fs::rename(&partial, &db).unwrap();
    let size = std::fs::metadata(&db).unwrap().len();
    println!(
        "built {} records in {:.0} s: {:.2} GB, {:.1} kB per calibration",
        ROBOTS * CALIBRATIONS,
        started.elapsed().as_secs_f64(),
        size as f64 / 1e9,
        size as f64 / (ROBOTS * CALIBRATIONS) as f64 / 1e3
    );
    db
}

fn registry(c: &mut Criterion) {
    let db = fleet();
    let db = db.to_str().unwrap();
    println!(
        "registry: {:.2} GB",
        std::fs::metadata(db).unwrap().len() as f64 / 1e9
    );
    let mut group = c.benchmark_group("registry_100000_calibrations");
    group.sample_size(10);
    group.bench_function("list_all", |b| {
        b.iter(|| calib(&["registry", "list", "--db", db]))
    });
    group.bench_function("list_one_robot", |b| {
        b.iter(|| calib(&["registry", "list", "--serial", "UR10-07777", "--db", db]))
    });
    group.bench_function("show", |b| {
        b.iter(|| calib(&["registry", "show", "77777", "--db", db]))
    });
    group.bench_function("compare_1000_configurations", |b| {
        b.iter(|| calib(&["registry", "compare", "77771", "77777", "--db", db]))
    });
    let page = Path::new(env!("CARGO_TARGET_TMPDIR")).join("registry-bench/fleet.html");
    let page = page.to_str().unwrap();
    group.bench_function("fleet_page", |b| {
        b.iter(|| calib(&["registry", "fleet", "--out", page, "--db", db]))
    });
    group.finish();
}

criterion_group!(benches, registry);
criterion_main!(benches);
