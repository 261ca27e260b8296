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
//!
//! Nothing but the outputs asked for is touched, whatever else is in their directories: a
//! temporary is created new (exclusively: never opened through a file or symbolic link planted at
//! its name, which is skipped for the next name), with the permissions of the file it replaces,
//! so a private file stays private while staged; a journal is followed only when it is a regular
//! file of the user running, every temporary it names is one of that run's (its name, beside its
//! target, a regular file of the user) and every copy it names is one of its own names in an
//! output's directory. Anything else is left alone with a note: a planted journal can move or
//! delete no file.

use crate::error::Context;
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
pub fn clean_up_on_interrupt() -> crate::Result<()> {
    ctrlc::set_handler(|| {
        INTERRUPTED.store(true, Ordering::SeqCst);
        if !BUSY.load(Ordering::SeqCst) {
            exit_if_interrupted();
        }
    })
    .map_err(|e| std::io::Error::other(e.to_string()))
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
    }
    let scratch = SCRATCH_DIRS
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    for dir in scratch.iter() {
        let _ = std::fs::remove_dir_all(dir);
    }
    std::process::exit(INTERRUPTED_STATUS)
}

/// Scratch directories of this process (the PDF's), removed with the temporaries when the
/// process is interrupted.
static SCRATCH_DIRS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// A new private directory (mode 0700 on Unix) named `{prefix}-{pid}-{n}` in the system's
/// temporary directory, removed when an interruption ends the process and when the returned
/// guard is dropped.
pub(crate) fn scratch_dir(prefix: &str) -> std::io::Result<ScratchDir> {
    let base = std::env::temp_dir();
    let mut list = SCRATCH_DIRS
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    for n in 0..1000u32 {
        let dir = base.join(format!("{prefix}-{}-{n}", std::process::id()));
        let mut builder = std::fs::DirBuilder::new();
        #[cfg(unix)]
        {
            use std::os::unix::fs::DirBuilderExt;
            builder.mode(0o700);
        }
        match builder.create(&dir) {
            Ok(()) => {
                list.push(dir.clone());
                return Ok(ScratchDir(dir));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other("no free scratch directory name"))
}

/// A private scratch directory ([`scratch_dir`]), removed with its content when dropped.
pub(crate) struct ScratchDir(pub(crate) PathBuf);

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
        SCRATCH_DIRS
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .retain(|d| d != &self.0);
    }
}

/// [`create_new`], and the file added to the list of temporaries, under that list's lock: an
/// interruption that removes the temporaries either sees this one or ends the process before it
/// exists.
fn create_tracked(path: &Path, mode: Option<u32>) -> std::io::Result<std::fs::File> {
    let mut list = TEMPORARIES
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let file = create_new(path, mode)?;
    list.push(path.to_path_buf());
    Ok(file)
}

fn untrack(path: &Path) {
    TEMPORARIES
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .retain(|p| p != path);
}

/// Longest target name kept whole in the names of its temporaries, bytes: a temporary adds up to
/// 40 bytes (`.`, `.calib-<pid>-<n>.tmp`; earlier versions' plots `.tmp.png`) and a file name holds at most 255 on common file
/// systems, so a legal target name of up to 255 bytes still has legal temporaries.
const LONGEST_STEM: usize = 200;

/// The target's name as its temporaries carry it (`.<stem>.calib-<pid>-<n>.tmp`): the name
/// itself up to [`LONGEST_STEM`] bytes, else its start and a 64-bit FNV-1a hash of the whole name
/// (distinct targets keep distinct temporaries).
fn temporary_stem(file_name: &str) -> String {
    if file_name.len() <= LONGEST_STEM {
        return file_name.to_string();
    }
    let mut cut = LONGEST_STEM - 17;
    while !file_name.is_char_boundary(cut) {
        cut -= 1;
    }
    let hash = file_name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    format!("{}~{hash:016x}", &file_name[..cut])
}

/// Removes the temporaries that processes which have ended left beside `file_name` in `dir`
/// (killed while writing it). Only names of our own pattern, of processes no longer running.
fn remove_stale_temporaries(dir: &Path, file_name: &str) {
    let prefix = format!(".{}.calib-", temporary_stem(file_name));
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(&prefix)) else {
            continue;
        };
        // `.tmp.png`: the plots' second temporaries of earlier versions.
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

impl Journal {
    /// Whether this is a journal that process `pid` could have written: every temporary is
    /// named as that process names them (`.<target>.calib-<pid>-<n>.tmp`) and lies beside its
    /// target, and every copy of the journal is named as the process names it and lies in the
    /// directory of an output. A planted journal that names any other file is refused whole,
    /// so completing a commit can only put a run's own temporaries in place of their targets.
    fn is_of(&self, pid: u32) -> bool {
        let outputs_ok = self.outputs.iter().all(|(temporary, target)| {
            let (Some(name), Some(dir)) = (target.file_name(), target.parent()) else {
                return false;
            };
            let prefix = format!(".{}.calib-{pid}-", temporary_stem(&name.to_string_lossy()));
            temporary.parent() == Some(dir)
                && temporary
                    .file_name()
                    .and_then(|n| n.to_str())
                    .and_then(|n| n.strip_prefix(&prefix))
                    .and_then(|n| n.strip_suffix(".tmp"))
                    .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
        });
        let name = journal_name(pid);
        let journals_ok = self.journals.iter().all(|copy| {
            copy.file_name().is_some_and(|n| n == name.as_str())
                && self
                    .outputs
                    .iter()
                    .any(|(_, target)| target.parent() == copy.parent())
        });
        !self.outputs.is_empty() && outputs_ok && journals_ok
    }
}

/// Whether `path` is a regular file (not a symbolic link) owned by the user this process runs
/// as: what a run of ours leaves. Where the owner cannot be known, a regular file is enough.
fn ours(path: &Path) -> bool {
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return false;
    };
    if !meta.file_type().is_file() {
        return false;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        // The owner of /proc/self is the user this process runs as (Linux).
        if let Ok(me) = std::fs::metadata("/proc/self") {
            return meta.uid() == me.uid();
        }
    }
    true
}

/// The journal name of process `pid`.
fn journal_name(pid: u32) -> String {
    format!(".calib-commit-{pid}.journal")
}

/// Writes the journal of a commit of `staged` into every directory of an output, each copy
/// complete before it appears under its name; none for a single output (one rename is atomic).
/// Returns the journals written.
fn write_journals(staged: &[Staged]) -> crate::Result<Vec<PathBuf>> {
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
        let written = (|| -> std::io::Result<()> {
            // Created new and tracked as a run's temporaries are, never through a link planted at
            // its name (that is removed: the name is this live process's own).
            let mut file = match create_tracked(&partial, Some(0o600)) {
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    std::fs::remove_file(&partial)?;
                    create_tracked(&partial, Some(0o600))?
                }
                other => other?,
            };
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
            return Err(crate::Error::from(e).context(format!("writing {}", path.display())));
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
        // A journal names a few paths: a larger file is not one of ours (and is not read).
        let small = entry.metadata().is_ok_and(|m| m.len() <= MAX_JOURNAL_BYTES);
        let journal: Option<Journal> = (small && ours(&entry.path()))
            .then(|| std::fs::read(entry.path()).ok())
            .flatten()
            .and_then(|bytes| serde_json::from_slice(&bytes).ok());
        let Some(journal) = journal.filter(|j| j.is_of(pid)) else {
            // Not one of ours (another user's, a planted or damaged file): leave it, touch
            // nothing it names.
            eprintln!(
                "note: left {} alone: it is not the commit journal of an earlier run of calib",
                entry.path().display()
            );
            continue;
        };
        // Only the outputs in this folder: a journal found here never replaces a file
        // elsewhere (each folder of a commit holds its own copy of the journal, and completes
        // its own outputs when a later run writes there).
        let here = std::fs::canonicalize(dir).ok();
        let in_this_folder = |path: &Path| {
            let parent = match path.parent() {
                Some(p) if !p.as_os_str().is_empty() => p,
                _ => Path::new("."),
            };
            here.is_some() && std::fs::canonicalize(parent).ok() == here
        };
        let mut completed = Vec::new();
        for (temporary, target) in &journal.outputs {
            if in_this_folder(temporary)
                && in_this_folder(target)
                && ours(temporary)
                && std::fs::rename(temporary, target).is_ok()
            {
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
        let _ = std::fs::remove_file(entry.path());
    }
}

/// The largest commit journal read, bytes: a journal names a few paths.
const MAX_JOURNAL_BYTES: u64 = 1 << 20;

/// Names tried for one output's temporary file before giving up (the others taken by files of
/// other runs or planted there).
const MAX_TEMPORARY_TRIES: usize = 64;

/// Creates `path` as a new file for writing, failing with `AlreadyExists` when anything (a file,
/// a directory, a symbolic link, even a dangling one) has that name; with `mode` (Unix
/// permissions) when given.
fn create_new(path: &Path, mode: Option<u32>) -> std::io::Result<std::fs::File> {
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    if let Some(mode) = mode {
        use std::os::unix::fs::OpenOptionsExt;
        options.mode(mode);
    }
    #[cfg(not(unix))]
    let _ = mode;
    options.open(path)
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
    /// Directories created for the outputs, outermost first: removed again (when empty) unless
    /// the outputs are committed.
    created_dirs: Vec<PathBuf>,
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
            created_dirs: Vec::new(),
        }
    }

    /// Stages `bytes` for `path`, asked for by `name` (such as `--out`).
    pub fn stage(&mut self, name: &str, path: &Path, bytes: &[u8]) -> crate::Result<()> {
        uninterrupted(|| {
            self.stage_now(name, path, |mut file| {
                file.write_all(bytes)?;
                file.sync_all()?;
                Ok(())
            })
        })
    }

    fn stage_now(
        &mut self,
        name: &str,
        path: &Path,
        write: impl FnOnce(std::fs::File) -> crate::Result<()>,
    ) -> crate::Result<()> {
        let (target, permissions) = self.checked_target(name, path)?;
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        self.create_dirs(&dir)?;
        let file_name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let stem = temporary_stem(&file_name);
        complete_interrupted_commits(&dir);
        remove_stale_temporaries(&dir, &file_name);
        // A new file, created by this process with the permissions of the file it replaces (a
        // private target stays private while staged), never opened through a link planted at its
        // name: a name taken by anything is skipped for the next.
        #[cfg(unix)]
        let mode = {
            use std::os::unix::fs::PermissionsExt;
            // The owner may write it while staging (restored exactly at the commit).
            permissions.as_ref().map(|p| (p.mode() & 0o7777) | 0o600)
        };
        #[cfg(not(unix))]
        let mode = None;
        let mut created = None;
        for n in self.staged.len()..self.staged.len() + MAX_TEMPORARY_TRIES {
            let temporary = dir.join(format!(".{stem}.calib-{}-{n}.tmp", std::process::id()));
            match create_tracked(&temporary, mode) {
                Ok(file) => {
                    created = Some((temporary, file));
                    break;
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
                Err(e) => {
                    return Err(crate::Error::from(e)
                        .context(format!("writing {} ({name})", path.display())));
                }
            }
        }
        let Some((temporary, file)) = created else {
            return Err(crate::refused!(output path;
                "writing {} ({name}): {MAX_TEMPORARY_TRIES} names for its temporary file are taken in {}; remove the files named .{stem}.calib-*.tmp there",
                path.display(),
                dir.display()
            ));
        };
        if let Err(e) = write(file) {
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
    ) -> crate::Result<(PathBuf, Option<std::fs::Permissions>)> {
        // `dir/` names a directory: never written as a file called `dir` (issue 39, N19).
        if path
            .as_os_str()
            .to_string_lossy()
            .ends_with(std::path::is_separator)
        {
            return Err(crate::refused!(output path;
                "{name} {}: ends with a path separator, so it names a directory; give the path of a file",
                path.display()
            ));
        }
        let target = resolved(path);
        let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
        if is_link && std::fs::metadata(path).is_err() {
            return Err(crate::refused!(output path;
                "{name} {}: a symbolic link to a missing file; give the path of a file",
                path.display()
            ));
        }
        let permissions = match std::fs::metadata(&target) {
            Ok(meta) if meta.is_file() => Some(meta.permissions()),
            Ok(_) => {
                return Err(crate::refused!(output path;
                    "{name} {}: not a regular file (a directory, device or FIFO); give the path of a file",
                    path.display()
                ));
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(e).with_context(|| format!("{name} {}", path.display())),
        };
        if let Some(other) = self.staged.iter().find(|s| s.target == target) {
            return Err(crate::refused!(output path;
                "{name} and {} name the same file {}; give each output its own path",
                other.name,
                path.display()
            ));
        }
        if let Some((input, _)) = self.inputs.iter().find(|(_, p)| *p == target) {
            return Err(crate::refused!(output path;
                "{name} {} is the input {input}; writing it would destroy the input, give another path",
                path.display()
            ));
        }
        Ok((target, permissions))
    }

    /// Replaces every target by its staged file; returns the paths written.
    /// An interruption during the commit takes effect when it ends.
    pub fn commit(mut self) -> crate::Result<Vec<PathBuf>> {
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
                    return Err(crate::Error::from(e)
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
        if committed.is_ok() {
            self.created_dirs.clear();
        }
        drop(self);
        exit_if_interrupted();
        committed.map(|()| written)
    }

    /// Creates `dir` and its missing ancestors, remembering those it created.
    fn create_dirs(&mut self, dir: &Path) -> crate::Result<()> {
        let missing: Vec<&Path> = dir
            .ancestors()
            .take_while(|d| !d.as_os_str().is_empty() && !d.exists())
            .collect();
        for d in missing.into_iter().rev() {
            match std::fs::create_dir(d) {
                Ok(()) => self.created_dirs.push(d.to_path_buf()),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && d.is_dir() => {}
                Err(e) => {
                    return Err(crate::Error::from(e)
                        .context(format!("creating directory {}", d.display())));
                }
            }
        }
        Ok(())
    }
}

impl Drop for Outputs {
    /// Outputs not committed leave nothing behind: no temporary, and no directory created for
    /// them (one that holds anything else stays).
    fn drop(&mut self) {
        for staged in &self.staged {
            let _ = std::fs::remove_file(&staged.temporary);
            untrack(&staged.temporary);
        }
        for dir in self.created_dirs.iter().rev() {
            let _ = std::fs::remove_dir(dir);
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
pub fn write_atomic(path: &Path, bytes: &[u8]) -> crate::Result<()> {
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
        let (ours, theirs) = (
            format!(".calib-{}-", std::process::id()),
            format!(".calib-{ended}-"),
        );
        for d in [dir.path().to_path_buf(), dir.path().join("sub")] {
            let text = read(&d.join(&journal))
                .replace(&journal, &journal_name(ended))
                .replace(&ours, &theirs);
            std::fs::remove_file(d.join(&journal)).unwrap();
            std::fs::write(d.join(journal_name(ended)), text).unwrap();
            for name in leftovers(&d) {
                if name.contains(&ours) {
                    std::fs::rename(d.join(&name), d.join(name.replace(&ours, &theirs))).unwrap();
                }
            }
        }
        // A run in each folder completes that folder's outputs (issue 52: a journal found in
        // one folder never replaces a file in another).
        write_atomic(&dir.path().join("sub/z.txt"), b"z").unwrap();
        write_atomic(&dir.path().join("w.txt"), b"w").unwrap();
        assert_eq!((read(&x), read(&y)), ("new x".into(), "new y".into()));
        assert!(
            leftovers(dir.path()).is_empty(),
            "{:?}",
            leftovers(dir.path())
        );
        let sub = dir.path().join("sub");
        assert!(leftovers(&sub).is_empty(), "{:?}", leftovers(&sub));
    }

    /// The pid of a process that has ended.
    fn ended_process() -> u32 {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        pid
    }

    /// A journal planted in an output directory (issue 39, N1) that names files elsewhere moves
    /// and deletes nothing: the next run leaves it, and every file it names, alone.
    #[test]
    fn a_planted_journal_moves_and_deletes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let elsewhere = tempfile::tempdir().unwrap();
        let (evil, passwd, delete_me) = (
            dir.path().join("evil.txt"),
            elsewhere.path().join("passwd"),
            elsewhere.path().join("delete_me"),
        );
        std::fs::write(&evil, "evil").unwrap();
        std::fs::write(&passwd, "root").unwrap();
        std::fs::write(&delete_me, "keep").unwrap();
        let pid = ended_process();
        // The attack of the report, and one that follows our naming but crosses directories.
        let crossing = dir.path().join(format!(".passwd.calib-{pid}-0.tmp"));
        std::fs::write(&crossing, "evil").unwrap();
        for (k, outputs) in [
            vec![(evil.clone(), passwd.clone())],
            vec![(crossing.clone(), passwd.clone())],
        ]
        .into_iter()
        .enumerate()
        {
            let journal = Journal {
                outputs,
                journals: vec![delete_me.clone()],
            };
            let planted = dir.path().join(journal_name(pid));
            std::fs::write(&planted, serde_json::to_string(&journal).unwrap()).unwrap();
            write_atomic(&dir.path().join("x.json"), b"x").unwrap();
            assert_eq!(read(&passwd), "root", "attack {k}");
            assert_eq!(read(&delete_me), "keep", "attack {k}");
            assert_eq!(read(&evil), "evil", "attack {k}");
            assert!(
                planted.exists(),
                "attack {k}: the planted journal is left for its owner"
            );
            std::fs::remove_file(&planted).unwrap();
        }
        assert_eq!(read(&dir.path().join("x.json")), "x");
    }

    /// Issue 52, V2: a journal of our own user in folder D that names a target in folder E,
    /// with a temporary named as ours beside it, replaces nothing in E when a run writes into D;
    /// and a journal larger than [`MAX_JOURNAL_BYTES`] is not read (V11).
    #[test]
    fn a_journal_completes_only_the_outputs_of_its_own_folder() {
        let d = tempfile::tempdir().unwrap();
        let e = tempfile::tempdir().unwrap();
        let pid = ended_process();
        let target = e.path().join("t.toml");
        std::fs::write(&target, "the user's file").unwrap();
        let temporary = e.path().join(format!(".t.toml.calib-{pid}-0.tmp"));
        std::fs::write(&temporary, "replacement").unwrap();
        let journal = Journal {
            outputs: vec![(temporary.clone(), target.clone())],
            journals: vec![e.path().join(journal_name(pid))],
        };
        let planted = d.path().join(journal_name(pid));
        std::fs::write(&planted, serde_json::to_string(&journal).unwrap()).unwrap();
        write_atomic(&d.path().join("x.json"), b"x").unwrap();
        assert_eq!(read(&target), "the user's file");
        assert!(temporary.exists());
        assert_eq!(read(&d.path().join("x.json")), "x");
        // A journal of 2 MiB: left alone, unread.
        let large = d.path().join(journal_name(ended_process()));
        std::fs::write(&large, vec![b' '; 2 << 20]).unwrap();
        write_atomic(&d.path().join("y.json"), b"y").unwrap();
        assert!(large.exists());
    }

    /// Symbolic links planted at the names of a run's temporaries (issue 39, N2) are never
    /// written through: the run takes other names, the links' targets stay as they were.
    #[cfg(unix)]
    #[test]
    fn links_planted_at_temporary_names_are_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let victim = dir.path().join("victim");
        std::fs::write(&victim, "safe").unwrap();
        let pid = std::process::id();
        for name in [
            format!(".x2.json.calib-{pid}-0.tmp"),
            format!(".y.json.calib-{pid}-1.tmp"),
            format!("{}.tmp", journal_name(pid)),
        ] {
            std::os::unix::fs::symlink(&victim, dir.path().join(name)).unwrap();
        }
        let mut outputs = Outputs::default();
        outputs
            .stage("--out", &dir.path().join("x2.json"), b"x2")
            .unwrap();
        outputs
            .stage("--report", &dir.path().join("y.json"), b"y")
            .unwrap();
        outputs.commit().unwrap();
        assert_eq!(read(&victim), "safe");
        assert_eq!(read(&dir.path().join("x2.json")), "x2");
        assert_eq!(read(&dir.path().join("y.json")), "y");
    }

    /// A private target stays private while its replacement is staged (issue 39, N2) and after.
    #[cfg(unix)]
    #[test]
    fn the_staged_copy_of_a_private_file_is_private() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("secret.toml");
        std::fs::write(&target, "old").unwrap();
        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o600)).unwrap();
        let mut outputs = Outputs::default();
        outputs.stage("--out", &target, b"new").unwrap();
        let staged = leftovers(dir.path());
        assert_eq!(staged.len(), 1, "{staged:?}");
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&dir.path().join(&staged[0])), 0o600);
        outputs.commit().unwrap();
        assert_eq!((read(&target), mode(&target)), ("new".into(), 0o600));
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
