//! The C API from C on the host: compiles `firmware-c/src/checks.c` (the C firmware's checks:
//! bit-identical compensation, A/B storage, kinematics, f64, refusals) with `tests/c/host_main.c`
//! and links this crate's static library, then runs it. Without a C compiler (`$CC`, else `cc`)
//! the test says so and passes, unless `CALIB_REQUIRE_CC=1` (set by `.ci/run`), where it fails.

// A test's helpers may panic: a failure is the test's result.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// The static library cargo built with this test: the newest `libcalib_ffi*.a` next to the test
/// executable (`deps/`) or one level up.
fn static_library() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    let deps = exe.parent()?;
    let mut found: Vec<(std::time::SystemTime, PathBuf)> = Vec::new();
    for dir in [deps, deps.parent()?] {
        for entry in std::fs::read_dir(dir).ok()?.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            if name.starts_with("libcalib_ffi") && name.ends_with(".a") {
                let modified = entry.metadata().and_then(|m| m.modified()).ok()?;
                found.push((modified, entry.path()));
            }
        }
    }
    found.into_iter().max().map(|(_, path)| path)
}

fn compiler() -> String {
    std::env::var("CC").unwrap_or_else(|_| "cc".to_string())
}

#[test]
fn the_c_checks_pass_on_the_host() {
    let cc = compiler();
    let required = std::env::var("CALIB_REQUIRE_CC").as_deref() == Ok("1");
    if Command::new(&cc).arg("--version").output().is_err() {
        assert!(
            !required,
            "CALIB_REQUIRE_CC=1 but no C compiler `{cc}`: install gcc (apt-get install gcc)"
        );
        println!("skipped: no C compiler `{cc}` (install gcc, or set CC) to run the C API checks");
        return;
    }
    let library = static_library().expect(
        "libcalib_ffi*.a not found next to the test executable: cargo builds it with the test \
         (crate-type staticlib)",
    );
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let exe = Path::new(env!("CARGO_TARGET_TMPDIR")).join("calib-c-api-checks");
    let output = Command::new(&cc)
        .args([
            "-std=c11",
            "-O2",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-pedantic",
        ])
        .arg("-I")
        .arg(root.join("calib-ffi/include"))
        .arg("-I")
        .arg(root.join("firmware-c/src"))
        .arg(root.join("firmware-c/src/checks.c"))
        .arg(root.join("calib-ffi/tests/c/host_main.c"))
        .arg(&library)
        .args(["-lpthread", "-ldl", "-lm", "-lrt"])
        .arg("-o")
        .arg(&exe)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{cc} failed:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let run = Command::new(&exe).output().unwrap();
    let log = String::from_utf8_lossy(&run.stdout);
    println!("{log}");
    assert!(run.status.success(), "the C checks failed:\n{log}");
    assert!(
        log.contains("failed checks: 0") && log.trim_end().ends_with("PASS"),
        "{log}"
    );
    assert!(!log.contains("FAIL "), "{log}");
}

#[test]
fn the_readme_c_example_compiles() {
    let cc = compiler();
    if Command::new(&cc).arg("--version").output().is_err() {
        assert!(std::env::var("CALIB_REQUIRE_CC").as_deref() != Ok("1"));
        println!("skipped: no C compiler `{cc}`");
        return;
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let start = readme.find("```c\n").expect("the README has a C example") + 5;
    let end = start + readme[start..].find("```").unwrap();
    // The example's one free name: the controller's logger.
    let source = format!(
        "#include <stddef.h>\n#include <stdint.h>\nvoid log_error(const char *message);\n{}",
        &readme[start..end]
    );
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let file = dir.join("readme_example.c");
    std::fs::write(&file, source).unwrap();
    let output = Command::new(&cc)
        .args(["-std=c11", "-Wall", "-Wextra", "-Werror", "-pedantic", "-c"])
        .arg("-I")
        .arg(root.join("calib-ffi/include"))
        .arg(&file)
        .arg("-o")
        .arg(dir.join("readme_example.o"))
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "the README's C example does not compile:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
}
