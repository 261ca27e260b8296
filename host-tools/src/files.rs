//! Output files, safely: every output of a command is written into a temporary file beside its
//! target, and all of them replace their targets together only when every one is ready
//! ([`Outputs`]), so a failure leaves every previous file untouched and a reader never sees a
//! half-written file. Before anything is written the targets are checked: a target must be a
//! regular file or a new path (a symbolic link is followed to its target; a device, FIFO or
//! directory is refused), no two outputs may name the same file, and no output may be one of the
//! command's inputs. An existing file keeps its permissions.
//!
//! Interruptions: [`clean_up_on_interrupt`] makes Ctrl-C (SIGINT) and SIGTERM remove the
//! temporaries staged so far, and wait for a commit under way to finish, so the outputs of one
//! run are replaced all together or not at all. A process killed outright (`kill -9`) cannot clean
//! up: its temporaries (`.<name>.calib-<pid>-<n>.tmp`) are removed by the next run that writes the
//! same file once that process has ended.
//!
//! A process killed outright in the middle of a commit of several files (after renaming some of
//! them) would leave outputs of two runs side by side. Before its first rename, a commit of more
//! than one file therefore writes a journal, `.calib-commit-<pid>.journal`, into the directory of
//! every output, naming each temporary and its target; the journal is removed when the commit
//! ends. The next run that writes into one of those directories finds the journal of the ended
//! process and completes its commit (every temporary is complete before the journal is written),
//! so the outputs of one run always stand together.

use anyhow::{Context, bail};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// Temporaries staged and not yet committed or removed, of every [`Outputs`] of this process.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// `true` while a file is staged or [`Outputs::commit`] renames: an interruption then waits for
/// that step to end.
static BUSY: AtomicBool = AtomicBool::new(false);

/// `true` once an interruption arrived while busy: the process cleans up and exits when the step
/// ends.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Exit status after an interruption (128 + SIGINT).
const INTERRUPTED_STATUS: i32 = 130;

/// Installs the handler of Ctrl-C (SIGINT) and SIGTERM: staged temporaries are removed and the
/// process exits with status 130; while a file is being staged or the outputs committed, that step
/// finishes first. Call once, at the start of the program.
pub fn clean_up_on_interrupt() -> anyhow::Result<()> {
    ctrlc::set_handler(|| {
        INTERRUPTED.store(true, Ordering::SeqCst);
        if !BUSY.load(Ordering::SeqCst) {
            exit_if_interrupted();
        }
    })
    .context("installing the interrupt handler")
}

/// After an interruption: removes the staged temporaries and exits with status 130.
fn exit_if_interrupted() {
    if INTERRUPTED.load(Ordering::SeqCst) {
        exit_removing_temporaries();
    }
}

/// Runs `step` with interruptions deferred to its end.
fn uninterrupted<R>(step: impl FnOnce() -> R) -> R {
    BUSY.store(true, Ordering::SeqCst);
    let result = step();
    BUSY.store(false, Ordering::SeqCst);
    exit_if_interrupted();
    result
}

/// Removes every staged temporary of this process and exits with status 130, holding the list
/// of temporaries so that no new one is started meanwhile.
fn exit_removing_temporaries() -> ! {
    let mut list = TEMPORARIES
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    for path in list.drain(..) {
        let _ = std::fs::remove_file(&path);
        let _ = std::fs::remove_file(path.with_extension("tmp.png"));
    }
    std::process::exit(INTERRUPTED_STATUS)
}

fn track(path: &Path) {
    TEMPORARIES
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .push(path.to_path_buf());
}

fn untrack(path: &Path) {
    TEMPORARIES
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .retain(|p| p != path);
}

/// Removes the temporaries that processes which have ended left beside `file_name` in `dir`
/// (killed while writing it). Only names of our own pattern, of processes no longer running.
fn remove_stale_temporaries(dir: &Path, file_name: &str) {
    let prefix = format!(".{file_name}.calib-");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(&prefix)) else {
            continue;
        };
        if !(rest.ends_with(".tmp") || rest.ends_with(".tmp.png")) {
            continue;
        }
        let Some(pid) = rest.split('-').next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        if pid != std::process::id() && !process_running(pid) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Whether process `pid` runs; where that cannot be known, `true` (nothing is removed).
fn process_running(pid: u32) -> bool {
    if cfg!(target_os = "linux") && Path::new("/proc/self").exists() {
        Path::new("/proc").join(pid.to_string()).exists()
    } else {
        true
    }
}

#[cfg(test)]
thread_local! {
    /// Tests: the commit stops (as if killed) after this many renames.
    static STOP_AFTER_RENAMES: std::cell::Cell<Option<usize>> = const { std::cell::Cell::new(None) };
}

/// The record of a commit under way (see the module documentation).
#[derive(serde::Serialize, serde::Deserialize)]
struct Journal {
    /// Each output: its complete temporary and its target.
    outputs: Vec<(PathBuf, PathBuf)>,
    /// The copies of this journal, one per directory of an output.
    journals: Vec<PathBuf>,
}

/// The journal name of process `pid`.
fn journal_name(pid: u32) -> String {
    format!(".calib-commit-{pid}.journal")
}

/// Writes the journal of a commit of `staged` into every directory of an output, each copy
/// complete before it appears under its name; none for a single output (one rename is atomic).
/// Returns the journals written.
fn write_journals(staged: &[Staged]) -> anyhow::Result<Vec<PathBuf>> {
    if staged.len() < 2 {
        return Ok(Vec::new());
    }
    let mut dirs: Vec<PathBuf> = staged
        .iter()
        .filter_map(|s| s.target.parent().map(Path::to_path_buf))
        .collect();
    dirs.sort();
    dirs.dedup();
    let name = journal_name(std::process::id());
    let journal = Journal {
        outputs: staged
            .iter()
            .map(|s| (resolved(&s.temporary), s.target.clone()))
            .collect(),
        journals: dirs.iter().map(|d| d.join(&name)).collect(),
    };
    let Ok(text) = serde_json::to_string(&journal) else {
        // A path that is not UTF-8 cannot be journaled: commit as a single rename would.
        return Ok(Vec::new());
    };
    for path in &journal.journals {
        let partial = path.with_extension("journal.tmp");
        track(&partial);
        let written = (|| -> std::io::Result<()> {
            let mut file = std::fs::File::create(&partial)?;
            file.write_all(text.as_bytes())?;
            file.sync_all()?;
            std::fs::rename(&partial, path)
        })();
        untrack(&partial);
        if let Err(e) = written {
            let _ = std::fs::remove_file(&partial);
            for done in &journal.journals {
                let _ = std::fs::remove_file(done);
            }
            return Err(anyhow::Error::new(e).context(format!("writing {}", path.display())));
        }
    }
    Ok(journal.journals)
}

/// Completes the commits that processes which have ended left unfinished in `dir` (killed
/// between two renames): every temporary named in their journal still present replaces its
/// target, then the journals are removed. Says on standard error what was completed.
fn complete_interrupted_commits(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(".calib-commit-")) else {
            continue;
        };
        let (pid, partial) = match (
            rest.strip_suffix(".journal"),
            rest.strip_suffix(".journal.tmp"),
        ) {
            (Some(pid), _) => (pid, false),
            (None, Some(pid)) => (pid, true),
            (None, None) => continue,
        };
        let Ok(pid) = pid.parse::<u32>() else {
            continue;
        };
        if pid == std::process::id() || process_running(pid) {
            continue;
        }
        if partial {
            // Killed while writing its journal, before any rename: nothing to complete.
            let _ = std::fs::remove_file(entry.path());
            continue;
        }
        let journal: Option<Journal> = std::fs::read(entry.path())
            .ok()
            .and_then(|bytes| serde_json::from_slice(&bytes).ok());
        let Some(journal) = journal else {
            // Not ours or unreadable: leave it.
            continue;
        };
        let mut completed = Vec::new();
        for (temporary, target) in &journal.outputs {
            if temporary.exists() && std::fs::rename(temporary, target).is_ok() {
                completed.push(target.display().to_string());
            }
        }
        if !completed.is_empty() {
            eprintln!(
                "note: completed the outputs of an earlier run (process {pid}) that was killed while \
                 replacing them, so that they stand together: {}",
                completed.join(", ")
            );
        }
        for copy in journal.journals.iter().chain([&entry.path()]) {
            let _ = std::fs::remove_file(copy);
        }
    }
}

/// One staged output: its temporary file and where it goes.
struct Staged {
    /// The flag or name that asked for it, for messages.
    name: String,
    /// The file written so far.
    temporary: PathBuf,
    /// The resolved target (a symbolic link followed).
    target: PathBuf,
    /// The permissions of the file it replaces, if any.
    permissions: Option<std::fs::Permissions>,
}

/// The outputs of one command, committed together.
#[derive(Default)]
pub struct Outputs {
    /// The command's inputs, resolved: no output may replace one.
    inputs: Vec<(String, PathBuf)>,
    staged: Vec<Staged>,
}

impl Outputs {
    /// Outputs that must not replace any of `inputs` (each named by its flag in messages).
    pub fn new(inputs: &[(&str, &Path)]) -> Self {
        Self {
            inputs: inputs
                .iter()
                .map(|(name, path)| ((*name).to_string(), resolved(path)))
                .collect(),
            staged: Vec::new(),
        }
    }

    /// Stages `bytes` for `path`, asked for by `name` (such as `--out`).
    pub fn stage(&mut self, name: &str, path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
        self.stage_with(name, path, |temporary| {
            let mut file = std::fs::File::create(temporary)?;
            file.write_all(bytes)?;
            file.sync_all()?;
            Ok(())
        })
    }

    /// Stages the file that `write` writes at the temporary path it is given.
    pub fn stage_with(
        &mut self,
        name: &str,
        path: &Path,
        write: impl FnOnce(&Path) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        uninterrupted(|| self.stage_now(name, path, write))
    }

    fn stage_now(
        &mut self,
        name: &str,
        path: &Path,
        write: impl FnOnce(&Path) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        let (target, permissions) = self.checked_target(name, path)?;
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("creating directory {}", dir.display()))?;
        let file_name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        complete_interrupted_commits(&dir);
        remove_stale_temporaries(&dir, &file_name);
        let temporary = dir.join(format!(
            ".{file_name}.calib-{}-{}.tmp",
            std::process::id(),
            self.staged.len()
        ));
        track(&temporary);
        if let Err(e) = write(&temporary) {
            let _ = std::fs::remove_file(&temporary);
            untrack(&temporary);
            return Err(e.context(format!("writing {} ({name})", path.display())));
        }
        self.staged.push(Staged {
            name: name.to_string(),
            temporary,
            target,
            permissions,
        });
        Ok(())
    }

    /// The target of `path` after the checks, and the permissions of the file it would replace.
    fn checked_target(
        &self,
        name: &str,
        path: &Path,
    ) -> anyhow::Result<(PathBuf, Option<std::fs::Permissions>)> {
        let target = resolved(path);
        let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
        if is_link && std::fs::metadata(path).is_err() {
            bail!(
                "{name} {}: a symbolic link to a missing file; give the path of a file",
                path.display()
            );
        }
        let permissions = match std::fs::metadata(&target) {
            Ok(meta) if meta.is_file() => Some(meta.permissions()),
            Ok(_) => bail!(
                "{name} {}: not a regular file (a directory, device or FIFO); give the path of a file",
                path.display()
            ),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(e).with_context(|| format!("{name} {}", path.display())),
        };
        if let Some(other) = self.staged.iter().find(|s| s.target == target) {
            bail!(
                "{name} and {} name the same file {}; give each output its own path",
                other.name,
                path.display()
            );
        }
        if let Some((input, _)) = self.inputs.iter().find(|(_, p)| *p == target) {
            bail!(
                "{name} {} is the input {input}; writing it would destroy the input, give another path",
                path.display()
            );
        }
        Ok((target, permissions))
    }

    /// Replaces every target by its staged file; returns the paths written.
    /// An interruption during the commit takes effect when it ends.
    pub fn commit(mut self) -> anyhow::Result<Vec<PathBuf>> {
        let mut written = Vec::with_capacity(self.staged.len());
        // An interruption before the commit: nothing is replaced.
        exit_if_interrupted();
        BUSY.store(true, Ordering::SeqCst);
        let committed = (|| {
            for staged in &self.staged {
                if let Some(permissions) = &staged.permissions {
                    std::fs::set_permissions(&staged.temporary, permissions.clone())
                        .with_context(|| format!("writing {}", staged.target.display()))?;
                }
            }
            let journals = write_journals(&self.staged)?;
            while !self.staged.is_empty() {
                #[cfg(test)]
                if STOP_AFTER_RENAMES.with(|stop| stop.get()) == Some(written.len()) {
                    // As if killed here: the journal stays, the rest is not renamed.
                    self.staged.clear();
                    return Ok(());
                }
                let staged = self.staged.remove(0);
                let renamed = std::fs::rename(&staged.temporary, &staged.target);
                untrack(&staged.temporary);
                if let Err(e) = renamed {
                    let _ = std::fs::remove_file(&staged.temporary);
                    return Err(anyhow::Error::new(e)
                        .context(format!("writing {}", staged.target.display())));
                }
                written.push(staged.target);
            }
            for journal in &journals {
                let _ = std::fs::remove_file(journal);
            }
            Ok(())
        })();
        BUSY.store(false, Ordering::SeqCst);
        drop(self);
        exit_if_interrupted();
        committed.map(|()| written)
    }
}

impl Drop for Outputs {
    /// Outputs not committed leave nothing behind.
    fn drop(&mut self) {
        for staged in &self.staged {
            let _ = std::fs::remove_file(&staged.temporary);
            untrack(&staged.temporary);
        }
    }
}

/// `path` made absolute, with a symbolic link followed to its target and every existing
/// directory resolved, so that two names of one file compare equal.
fn resolved(path: &Path) -> PathBuf {
    if let Ok(canonical) = std::fs::canonicalize(path) {
        return canonical;
    }
    // A new file: resolve its directory when that exists.
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    match (absolute.parent(), absolute.file_name()) {
        (Some(dir), Some(name)) => std::fs::canonicalize(dir)
            .map(|d| d.join(name))
            .unwrap_or(absolute),
        _ => absolute,
    }
}

/// Writes `bytes` to `path` as the only output of a command (see [`Outputs`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let mut outputs = Outputs::default();
    outputs.stage("output", path, bytes)?;
    outputs.commit().map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(path: &Path) -> String {
        std::fs::read_to_string(path).unwrap()
    }

    /// Names in `dir` that are not outputs: temporaries and journals.
    fn leftovers(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with('.'))
            .collect()
    }

    #[test]
    fn a_commit_killed_between_two_renames_is_completed_by_the_next_run() {
        let dir = tempfile::tempdir().unwrap();
        let (x, y) = (dir.path().join("x.toml"), dir.path().join("sub/y.json"));
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        std::fs::write(&x, "old x").unwrap();
        std::fs::write(&y, "old y").unwrap();
        let mut outputs = Outputs::default();
        outputs.stage("--out", &x, b"new x").unwrap();
        outputs.stage("--report", &y, b"new y").unwrap();
        // Killed after the first rename: x is new, y is old, the journals say what is missing.
        STOP_AFTER_RENAMES.with(|stop| stop.set(Some(1)));
        outputs.commit().unwrap();
        STOP_AFTER_RENAMES.with(|stop| stop.set(None));
        assert_eq!((read(&x), read(&y)), ("new x".into(), "old y".into()));
        let journal = journal_name(std::process::id());
        assert!(dir.path().join(&journal).exists());
        assert!(dir.path().join("sub").join(&journal).exists());
        // The next run sees the journal of an ended process: rename it as if written by one.
        let ended = {
            let mut child = std::process::Command::new("true").spawn().unwrap();
            let pid = child.id();
            child.wait().unwrap();
            pid
        };
        for d in [dir.path().to_path_buf(), dir.path().join("sub")] {
            let text = read(&d.join(&journal)).replace(&journal, &journal_name(ended));
            std::fs::remove_file(d.join(&journal)).unwrap();
            std::fs::write(d.join(journal_name(ended)), text).unwrap();
        }
        write_atomic(&dir.path().join("sub/z.txt"), b"z").unwrap();
        assert_eq!((read(&x), read(&y)), ("new x".into(), "new y".into()));
        assert!(
            leftovers(dir.path()).is_empty(),
            "{:?}",
            leftovers(dir.path())
        );
        let sub = dir.path().join("sub");
        assert!(leftovers(&sub).is_empty(), "{:?}", leftovers(&sub));
    }

    #[test]
    fn a_complete_commit_leaves_no_journal_and_a_partial_journal_is_removed() {
        let dir = tempfile::tempdir().unwrap();
        let partial = dir.path().join(".calib-commit-4294967295.journal.tmp");
        std::fs::write(&partial, "{").unwrap();
        let mut outputs = Outputs::default();
        outputs.stage("--out", &dir.path().join("a"), b"a").unwrap();
        outputs
            .stage("--report", &dir.path().join("b"), b"b")
            .unwrap();
        outputs.commit().unwrap();
        assert_eq!(
            (read(&dir.path().join("a")), read(&dir.path().join("b"))),
            ("a".into(), "b".into())
        );
        assert!(
            leftovers(dir.path()).is_empty(),
            "{:?}",
            leftovers(dir.path())
        );
    }
}
