//! Reading an input file whole, within a size limit.
//!
//! Every file `calib` reads is read whole, so an input the size of the machine's memory (a
//! runaway export, a wrong path to a disk image, a device file) would exhaust it. Each read
//! here first checks the file's size against the limit of its kind and then reads at most one
//! byte past it (a pipe or a device states no size), so the memory an input can take is bounded
//! before a byte of it is parsed.
//!
//! Two kinds, two default limits: [`Input::Data`] (tracker data, candidate configurations, JSON
//! reports: 1 GiB, which holds some four million 6-DoF poses of our CSV) and [`Input::Document`]
//! (robot files, data profiles, UR calibrations: 16 MiB, far beyond any real one). A user with a
//! larger file raises both with `calib --max-input-mb <MiB>` ([`set_limit_mib`]).

use std::io::Read as _;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// What an input holds, which sets its default size limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    /// Measured or candidate poses, or a JSON report over them: grows with the poses.
    Data,
    /// A robot file, a data profile or a UR calibration: a page of text.
    Document,
}

/// Default limit of [`Input::Data`], bytes.
pub(crate) const DATA_LIMIT: u64 = 1 << 30;
/// Default limit of [`Input::Document`], bytes.
pub(crate) const DOCUMENT_LIMIT: u64 = 16 << 20;

/// The limit set by [`set_limit_mib`], bytes; 0 while the defaults hold.
static LIMIT: AtomicU64 = AtomicU64::new(0);

/// Sets the size limit of every input to `mib` MiB (`calib --max-input-mb`), for the rest of the
/// process.
pub fn set_limit_mib(mib: u64) {
    LIMIT.store(mib.saturating_mul(1 << 20).max(1), Ordering::Relaxed);
}

/// The size limit of an input of kind `input`, bytes.
pub fn limit(input: Input) -> u64 {
    match (LIMIT.load(Ordering::Relaxed), input) {
        (0, Input::Data) => DATA_LIMIT,
        (0, Input::Document) => DOCUMENT_LIMIT,
        (set, _) => set,
    }
}

/// The bytes of the file at `path`, or an error of kind [`std::io::ErrorKind::FileTooLarge`]
/// naming the size and the limit when it holds more than [`limit`]`(input)` bytes. The caller
/// names the file in its own error.
pub fn read(path: &Path, input: Input) -> std::io::Result<Vec<u8>> {
    let limit = limit(input);
    let file = std::fs::File::open(path)?;
    let stated = file.metadata()?.len();
    if stated > limit {
        return Err(too_large(Some(stated), limit));
    }
    let mut bytes = Vec::with_capacity(usize::try_from(stated).unwrap_or(0));
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(None, limit));
    }
    remember(path, &bytes);
    Ok(bytes)
}

/// The SHA-256 (64 lowercase hexadecimal digits) of the bytes first read from each path in this
/// process, as given: what the provenance records, so that it is the hash of the bytes the run
/// used, not of the file opened again afterwards (piped input would hash empty, a file replaced
/// during the run its replacement, and a named pipe would block).
static READ_HASHES: std::sync::Mutex<Vec<(std::path::PathBuf, String)>> =
    std::sync::Mutex::new(Vec::new());

/// Records the hash of `bytes`, read from `path`, unless that path was read before.
fn remember(path: &Path, bytes: &[u8]) {
    use sha2::Digest as _;
    let mut hashes = READ_HASHES
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    if hashes.iter().any(|(p, _)| p == path) {
        return;
    }
    let digest = sha2::Sha256::digest(bytes);
    let hex = digest.iter().map(|b| format!("{b:02x}")).collect();
    hashes.push((path.to_path_buf(), hex));
}

/// The SHA-256 of the bytes this process first read from `path` (as given), if it read any.
pub(crate) fn sha256_of_read(path: &Path) -> Option<String> {
    READ_HASHES
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .iter()
        .find(|(p, _)| p == path)
        .map(|(_, h)| h.clone())
}

/// The text of the file at `path`, as [`read`]; invalid UTF-8 is an error of kind
/// [`std::io::ErrorKind::InvalidData`].
pub(crate) fn read_text(path: &Path, input: Input) -> std::io::Result<String> {
    String::from_utf8(read(path, input)?).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "byte {} is not UTF-8 text; save the file as UTF-8",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

fn too_large(stated: Option<u64>, limit: u64) -> std::io::Error {
    let mib = |bytes: u64| bytes as f64 / f64::from(1 << 20);
    let size = match stated {
        Some(bytes) => format!("the file holds {:.1} MiB, more than", mib(bytes)),
        None => "the input (not a regular file) goes on past".to_string(),
    };
    std::io::Error::new(
        std::io::ErrorKind::FileTooLarge,
        format!(
            "{size} the {:.0} MiB an input of this kind may hold; if the input is right, raise \
             the limit with calib --max-input-mb <MiB>",
            mib(limit)
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_over_the_limit_is_refused_before_it_is_read() {
        let dir = std::env::temp_dir().join(format!("calib-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("robot.toml");
        std::fs::write(&path, vec![b'#'; (DOCUMENT_LIMIT + 1) as usize]).unwrap();
        let error = read(&path, Input::Document).unwrap_err();
        assert_eq!(error.kind(), std::io::ErrorKind::FileTooLarge);
        assert!(error.to_string().contains("16.0 MiB"), "{error}");
        assert!(error.to_string().contains("--max-input-mb"), "{error}");
        assert_eq!(
            read(&path, Input::Data).unwrap().len() as u64,
            DOCUMENT_LIMIT + 1
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
