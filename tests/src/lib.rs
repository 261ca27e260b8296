//! Shared helpers of the cross-crate tests: test data paths, the paper's tables, seeded random
//! joint configurations, and small comparisons.

use calib_core::{JointErrors, ParameterErrors, Pose, Real};
use host_tools::analysis::reference::Mat4;
use host_tools::io::robot_file::RobotFile;
use nalgebra::U6;
use rand_core::Rng;
use std::path::PathBuf;

/// Path of a file under `tests/data/` (the test data with their sources and licences, in the
/// repository so that a fresh clone passes alone).
pub fn data(relative: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("data")
        .join(relative)
}

/// Path of a file under the repository root.
pub fn repo(relative: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(relative)
}

/// The ER10L-C10 robot file (Table 1).
pub fn er10l_file() -> RobotFile {
    RobotFile::read(&repo("host-tools/robots/er10l-c10.toml")).expect("robot file")
}

/// Rows of a CSV file with a header, skipping `#` comments: (header, rows of fields).
pub fn read_csv(relative: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(data(relative)).expect("test data");
    let mut lines = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    let header = lines
        .next()
        .expect("header")
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect();
    (header, rows)
}

/// Table 2 of the paper as `[da, dalpha, dtheta, dd, dbeta]` per joint (mm, rad), read from the
/// copy of the paper's table.
pub fn table2() -> Vec<[f64; 5]> {
    let (header, rows) = read_csv("paper/er10l-c10-table2-errors.csv");
    assert_eq!(
        header,
        [
            "joint",
            "da_mm",
            "dalpha_rad",
            "dtheta_rad",
            "dd_mm",
            "dbeta_rad"
        ]
    );
    rows.iter()
        .map(|r| {
            let v: Vec<f64> = r[1..].iter().map(|s| s.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3], v[4]]
        })
        .collect()
}

/// Table 2 as core parameter errors in scalar `T`.
pub fn table2_errors<T: Real>() -> ParameterErrors<T, U6> {
    let mut errors = ParameterErrors::zero();
    for (e, t) in errors.joints.iter_mut().zip(table2()) {
        *e = JointErrors {
            da: T::of(t[0]),
            dalpha: T::of(t[1]),
            dtheta: T::of(t[2]),
            dd: T::of(t[3]),
            dbeta: T::of(t[4]),
        };
    }
    errors
}

/// A uniform value in `[lo, hi)` from a seeded generator.
pub fn uniform(rng: &mut impl Rng, lo: f64, hi: f64) -> f64 {
    let unit = (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
    lo + (hi - lo) * unit
}

/// Position distance (mm) and rotation angle (rad) between a core pose and a reference transform.
/// The angle comes from the Frobenius norm, `|R1 - R2|_F = 2 sqrt(2) sin(angle / 2)`, which is
/// accurate for small angles (unlike `acos` of the trace).
pub fn distance<T: Real>(core: &Pose<T>, reference: &Mat4) -> (f64, f64) {
    let p = core.translation.vector;
    let r = core.rotation.matrix();
    let mut dp2 = 0.0;
    let mut dr2 = 0.0;
    for i in 0..3 {
        dp2 += (p[i].to_f64() - reference[i][3]).powi(2);
        for j in 0..3 {
            dr2 += (r[(i, j)].to_f64() - reference[i][j]).powi(2);
        }
    }
    let angle = 2.0 * (dr2.sqrt() / (2.0 * 2f64.sqrt())).asin();
    (dp2.sqrt(), angle)
}

/// Whether `program args` runs and succeeds (a tool is installed).
pub fn have(program: &str, args: &[&str]) -> bool {
    std::process::Command::new(program)
        .args(args)
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Whether the emulator test `test` can run: `false` (after saying SKIPPED with `install`, how to
/// get what is missing) when a tool of `programs` or the target is missing, unless
/// `CALIB_REQUIRE_QEMU=1` (as `.ci/run` sets), where that is a failure.
pub fn embedded_tools_present(test: &str, programs: &[&str], install: &str) -> bool {
    let missing = missing_embedded_tools(programs);
    if missing.is_empty() {
        return true;
    }
    let message = format!("SKIPPED {test}: missing {} ({install})", missing.join(", "));
    assert!(
        std::env::var("CALIB_REQUIRE_QEMU").as_deref() != Ok("1"),
        "{message}"
    );
    eprintln!("{message}");
    false
}

/// The emulator tests' tools that are missing: the thumbv7em-none-eabihf target, and each
/// program of `programs` (run with `--version`).
fn missing_embedded_tools<'a>(programs: &[&'a str]) -> Vec<&'a str> {
    let target_installed = std::process::Command::new("rustup")
        .args(["target", "list", "--installed"])
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("thumbv7em-none-eabihf"));
    let mut missing: Vec<&str> = programs
        .iter()
        .copied()
        .filter(|p| !have(p, &["--version"]))
        .collect();
    if !target_installed {
        missing.push("the thumbv7em-none-eabihf target");
    }
    missing
}

/// Runs `firmware-c/run.sh` or `firmware/run.sh` (`script`, from the repository root) with
/// `--size`, without the outer cargo's settings (they must not leak into the firmware's own
/// build); prints and returns its standard output and whether it succeeded.
pub fn run_firmware_script(script: &str) -> (String, bool) {
    run_firmware_script_with(script, &[])
}

/// [`run_firmware_script`] with further arguments `args` (e.g. `--bin seven-joints`).
pub fn run_firmware_script_with(script: &str, args: &[&str]) -> (String, bool) {
    let mut command = std::process::Command::new("bash");
    command.arg(repo(script)).arg("--size").args(args);
    for (key, _) in std::env::vars() {
        if key.starts_with("CARGO") || key == "RUSTFLAGS" || key == "RUSTC_WRAPPER" {
            command.env_remove(key);
        }
    }
    let output = command.output().expect("bash runs");
    let log = String::from_utf8_lossy(&output.stdout).into_owned();
    println!("{log}\n{}", String::from_utf8_lossy(&output.stderr));
    (log, output.status.success())
}

/// The integer that follows `prefix` in a firmware's log (the first occurrence; spaces after the
/// prefix skipped). Panics, printing the log, when there is none.
pub fn number_after(log: &str, prefix: &str) -> u64 {
    log.split(prefix)
        .nth(1)
        .and_then(|rest| {
            rest.trim_start()
                .split(|c: char| !c.is_ascii_digit())
                .next()
        })
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no number after {prefix:?} in the log:\n{log}"))
}
