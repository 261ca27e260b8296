//! Output files and standard output are never lost or damaged (issue 13, defects 2 to 6): each
//! test is named after the defect it reproduces and fails on the code before the fix.

use crate::common;
use common::{ROBOT, calib};
use std::os::unix::fs::{FileTypeExt, PermissionsExt};
use std::path::Path;
use std::process::{Command, Stdio};

const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/er10l-c10-sim32.csv");

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A calibration by least squares on the bundled data (fast), writing `--out` and `--report`.
fn calibrate_args<'a>(out: &'a str, report: &'a str) -> Vec<&'a str> {
    vec![
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        DATA,
        "--method",
        "lm",
        "--out",
        out,
        "--report",
        report,
    ]
}

/// `calib export` of the nominal robot as TOML to `out`.
fn export_toml_to(out: &Path) -> std::process::Output {
    calib(&[
        "export",
        "--params",
        ROBOT,
        "--format",
        "toml",
        "--out",
        str(out),
    ])
}

fn str(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Files in `dir` whose names say they are temporary.
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp"))
        .collect()
}

#[test]
fn defect_2_a_closed_standard_output_neither_panics_nor_loses_the_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let (out, report) = (dir.path().join("x.toml"), dir.path().join("y.json"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(calibrate_args(str(&out), str(&report)))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader goes away at once, as `| true` does
    let status = child.wait_with_output().unwrap();
    assert!(
        status.status.success(),
        "{:?}: {}",
        status.status,
        stderr(&status)
    );
    assert!(out.exists() && report.exists());
}

#[test]
fn defect_2_a_full_standard_output_is_an_error_after_the_outputs_are_written() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        return; // no /dev/full on this system
    };
    let dir = tempfile::tempdir().unwrap();
    let (out, report) = (dir.path().join("x.toml"), dir.path().join("y.json"));
    let result = Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(calibrate_args(str(&out), str(&report)))
        .stdout(full)
        .output()
        .unwrap();
    assert_eq!(result.status.code(), Some(1), "{}", stderr(&result));
    assert!(
        stderr(&result).contains("writing to standard output"),
        "{}",
        stderr(&result)
    );
    assert!(out.exists() && report.exists());
}

/// Run as root, the old code turned a device node into a regular file. The test makes its own
/// null device in a temporary directory (so a regression cannot damage /dev/null); without the
/// right to make one it checks /dev/null read-only.
#[test]
fn defect_3_a_device_is_never_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let device = dir.path().join("null");
    let made = Command::new("mknod")
        .args([str(&device), "c", "1", "3"])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !made {
        return; // not root: no device node to offer
    }
    let out = export_toml_to(&device);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("not a regular file"),
        "{}",
        stderr(&out)
    );
    let kind = std::fs::symlink_metadata(&device).unwrap().file_type();
    assert!(kind.is_char_device());
}

#[test]
fn defect_3_a_fifo_is_refused_and_kept() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe");
    if !Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        return; // no mkfifo here
    }
    let out = export_toml_to(&fifo);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("not a regular file"),
        "{}",
        stderr(&out)
    );
    assert!(
        std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo()
    );
}

#[test]
fn defect_3_a_symlink_is_followed_to_its_target() {
    let dir = tempfile::tempdir().unwrap();
    let (target, link) = (dir.path().join("target.toml"), dir.path().join("link.toml"));
    std::fs::write(&target, "old").unwrap();
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let out = export_toml_to(&link);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(
        std::fs::read_to_string(&target)
            .unwrap()
            .contains("[[joint]]")
    );
}

#[test]
fn defect_3_an_existing_files_permissions_are_kept() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("private.toml");
    std::fs::write(&file, "old").unwrap();
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).unwrap();
    let out = export_toml_to(&file);
    assert!(out.status.success(), "{}", stderr(&out));
    let mode = std::fs::metadata(&file).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    assert!(
        std::fs::read_to_string(&file)
            .unwrap()
            .contains("[[joint]]")
    );
}

#[test]
fn defect_4_two_outputs_on_one_path_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let same = dir.path().join("same");
    let out = calib(&calibrate_args(str(&same), str(&same)));
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("name the same file"),
        "{}",
        stderr(&out)
    );
    assert!(!same.exists());
    let out = calib(&[
        "simulate",
        "--robot",
        ROBOT,
        "--out",
        str(&same),
        "--truth-out",
        str(&same),
    ]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("name the same file"),
        "{}",
        stderr(&out)
    );
    assert!(!same.exists());
    assert!(
        leftovers(dir.path()).is_empty(),
        "{:?}",
        leftovers(dir.path())
    );
}

#[test]
fn defect_5_an_output_on_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data.csv");
    std::fs::copy(DATA, &data).unwrap();
    let before = std::fs::read(&data).unwrap();
    let report = dir.path().join("r.json");
    let out = calib(&[
        "calibrate",
        "--robot",
        ROBOT,
        "--data",
        str(&data),
        "--method",
        "lm",
        "--out",
        str(&data),
        "--report",
        str(&report),
    ]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("is the input --data"),
        "{}",
        stderr(&out)
    );
    assert_eq!(std::fs::read(&data).unwrap(), before);
    assert!(!report.exists());
}

#[test]
fn defect_6_a_failing_output_replaces_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (out, report) = (dir.path().join("x.toml"), dir.path().join("y.json"));
    std::fs::write(&out, "old").unwrap();
    // --plot names an existing file, so the plot directory cannot be made.
    let plot = dir.path().join("not-a-directory");
    std::fs::write(&plot, "").unwrap();
    let mut args = calibrate_args(str(&out), str(&report));
    args.extend(["--plot", str(&plot)]);
    let result = calib(&args);
    assert!(!result.status.success());
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "old");
    assert!(!report.exists());
    assert!(
        leftovers(dir.path()).is_empty(),
        "{:?}",
        leftovers(dir.path())
    );
    // simulate: the data file is not written when the truth file cannot be.
    let data = dir.path().join("data.csv");
    let truth = plot.join("truth.toml");
    let result = calib(&[
        "simulate",
        "--robot",
        ROBOT,
        "--out",
        str(&data),
        "--truth-out",
        str(&truth),
    ]);
    assert!(!result.status.success());
    assert!(!data.exists());
    assert!(
        leftovers(dir.path()).is_empty(),
        "{:?}",
        leftovers(dir.path())
    );
}

/// The process id of a process that has ended.
fn ended_pid() -> u32 {
    let mut child = Command::new("true").spawn().unwrap();
    let pid = child.id();
    child.wait().unwrap();
    pid
}

#[test]
fn defect_14_temporaries_of_a_killed_run_are_removed_by_the_next() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.toml");
    // What a run killed with -9 while writing x.toml leaves, and what a running one holds.
    let stale = dir
        .path()
        .join(format!(".x.toml.calib-{}-0.tmp", ended_pid()));
    let stale_png = dir
        .path()
        .join(format!(".x.toml.calib-{}-1.tmp.png", ended_pid()));
    let running = dir
        .path()
        .join(format!(".x.toml.calib-{}-0.tmp", std::process::id()));
    let other = dir.path().join(".y.toml.calib-1-0.tmp");
    for path in [&stale, &stale_png, &running, &other] {
        std::fs::write(path, "partial").unwrap();
    }
    common::ok(&export_toml_to(&out));
    assert!(!stale.exists() && !stale_png.exists());
    // A running process's temporary and another file's are not touched.
    assert!(running.exists() && other.exists());
}

#[test]
fn defect_14_an_interrupted_run_leaves_no_temporary_and_no_mixed_outputs() {
    // The interruption can arrive after the run has finished on a loaded machine: try until one
    // run is interrupted; every run must leave consistent outputs and no temporary.
    let interrupted = (0..5).filter(|_| interrupt_one_run()).count();
    assert!(interrupted >= 1);
}

/// Interrupts one calibration while it stages its outputs; `true` when the interruption took effect.
fn interrupt_one_run() -> bool {
    let dir = tempfile::tempdir().unwrap();
    let (out, report) = (dir.path().join("x.toml"), dir.path().join("y.json"));
    std::fs::write(&out, "old").unwrap();
    let plots = dir.path().join("plots");
    let mut args = calibrate_args(str(&out), str(&report));
    args.extend(["--plot", str(&plots)]);
    let mut child = Command::new(env!("CARGO_BIN_EXE_calib"))
        .args(&args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Interrupt while the outputs are staged (the plots take the longest).
    let started = std::time::Instant::now();
    let staging = |d: &Path| d.exists() && !leftovers(d).is_empty();
    while !(staging(dir.path()) || staging(&plots)) {
        assert!(
            child.try_wait().unwrap().is_none(),
            "the run ended before its outputs were staged"
        );
        assert!(started.elapsed().as_secs() < 120);
        std::thread::sleep(std::time::Duration::from_micros(200));
    }
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = child.wait().unwrap();
    assert!(matches!(status.code(), Some(130 | 0)), "{status:?}");
    assert!(
        leftovers(dir.path()).is_empty(),
        "{:?}",
        leftovers(dir.path())
    );
    if plots.exists() {
        assert!(leftovers(&plots).is_empty(), "{:?}", leftovers(&plots));
    }
    // Nothing was committed, or everything was: never the old x.toml with a new y.json.
    let old = std::fs::read_to_string(&out).unwrap() == "old";
    assert_eq!(old, !report.exists());
    status.code() == Some(130)
}
