//! Records the git commit `calib` is built from (`CALIB_COMMIT`, "unknown" outside a git
//! checkout), so that a report states exactly which code wrote it.

use std::path::Path;
use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "unknown".to_string());
    println!("cargo:rustc-env=CALIB_COMMIT={commit}");
    // Built again when HEAD moves: HEAD itself, the branch it names, and packed refs. Only files
    // that exist are watched: cargo takes a missing one as changed and would build the tool again
    // on every command (a fresh `git init` has no packed-refs; after `git gc` a branch has no file).
    let git = Path::new("../.git");
    let mut watched = vec![git.join("HEAD"), git.join("packed-refs")];
    if let Ok(head) = std::fs::read_to_string(git.join("HEAD"))
        && let Some(branch) = head.trim().strip_prefix("ref: ")
    {
        watched.push(git.join(branch));
    }
    for file in watched.iter().filter(|file| file.exists()) {
        println!("cargo:rerun-if-changed={}", file.display());
    }
}
